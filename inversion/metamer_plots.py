"""Figures for tactile metameres: target vs match readouts, and singular spectra vs the noise floor."""

from __future__ import annotations

import numpy as np


def _figure(width: float, height: float):
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), layout="constrained")


def plot_pair(pair, path) -> None:
    """Target and match readouts at each depth against receptor x (mm); strain on the y axis.

    Parameters
    ----------
    pair : MetamerPair
    path : str or Path
        PNG file to write.
    """
    h = pair.hypothesis
    rec = np.asarray(pair.receptors)
    x = rec * 1e3 if rec.ndim == 1 else np.arange(rec.shape[0])
    xlabel = "receptor x (mm)" if rec.ndim == 1 else "receptor index"
    t = pair.target_readout.reshape(h.n_depths, h.n_components, -1)
    m = pair.match_readout.reshape(h.n_depths, h.n_components, -1)
    fig = _figure(max(5.5 * h.n_depths, 6.5), 4.3)  # + the legend's rows below
    axes = np.atleast_1d(fig.subplots(1, h.n_depths, squeeze=False)[0])
    colours = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:gray")
    for d, ax in enumerate(axes):
        for c, name in enumerate(h.components):
            col = colours[c % len(colours)]
            ax.plot(x, t[d, c], color=col, lw=2.0, label=f"{name} target ({pair.target.family.name})")
            ax.plot(x, m[d, c], color=col, lw=1.2, ls="--", label=f"{name} metamer ({pair.match.family.name})")
        tractors = getattr(pair.match.family, "tractor_x", None)
        if tractors is not None and rec.ndim == 1:
            inside = tractors[(tractors >= rec.min()) & (tractors <= rec.max())]
            ax.plot(inside * 1e3, np.zeros_like(inside), "k^", ms=5, label="tractors")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(_strain_label(h))
        ax.set_title(f"depth {h.depths[d] * 1e3:.3g} mm")
        ax.grid(alpha=0.3)
    d_text = "" if pair.dprime is None else f", d' = {pair.dprime:.3g}"
    fig.suptitle(f"{h}: relative residual {pair.relative_residual:.3g}{d_text}")
    # beside the panels, never over the curves or the tractors
    fig.legend(*axes[0].get_legend_handles_labels(), fontsize=7, ncols=3, loc="outside lower center")
    fig.savefig(path, dpi=110)


def _strain_label(h) -> str:
    """The y label: strain, naming the shear convention only when a shear component is drawn."""
    shear = [c for c in h.components if c[0] != c[1]]
    return f"strain ({h.shear} shear in {', '.join(shear)})" if shear else "strain"


def plot_spectrum(values, path, *, rho=None, mode_s=None, title: str = "") -> None:
    """Whitened singular values, descending, against the noise floor s = 1 (and per wavenumber).

    Parameters
    ----------
    values : ndarray
        Singular values of the whitened readout map (dimensionless), descending.
    path : str or Path
        PNG file to write.
    rho, mode_s : ndarray, optional
        Wavenumber of each mode (rad/m) and its singular values (n_modes, n_load), for a second
        panel against wavenumber (periodic families).
    """
    periodic = rho is not None
    fig = _figure(10 if periodic else 5.5, 3.8)
    axes = np.atleast_1d(fig.subplots(1, 2 if periodic else 1))
    s = np.asarray(values, float)
    tiny = max(s.max(), 1.0) * 1e-16 if s.size else 1e-16
    k = np.arange(1, s.size + 1)
    ax = axes[0]
    ax.semilogy(k, np.maximum(s, tiny), ".", ms=3, label="singular values")
    ax.axhline(1.0, color="k", ls="--", label="noise floor (s = 1)")
    ax.set_xlabel("index (descending)")
    ax.set_ylabel("whitened singular value s (1)")
    ax.set_title(f"{int(np.sum(s > 1))} of {s.size} directions resolved")
    ax.text(0.02, 0.07, "values below 1e-16 x max drawn at that floor", transform=ax.transAxes, fontsize=7)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    if periodic:
        ax = axes[1]
        order = np.argsort(rho)
        for j in range(mode_s.shape[1]):
            ax.semilogy(rho[order] * 1e-3, np.maximum(mode_s[order, j], tiny), lw=1.2, label=f"mode singular value {j + 1}")
        ax.axhline(1.0, color="k", ls="--", label="noise floor (s = 1)")
        ax.set_xlabel("wavenumber |k| (rad/mm)")
        ax.set_ylabel("whitened singular value s (1)")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3, which="both")
    fig.suptitle(title)
    fig.savefig(path, dpi=110)

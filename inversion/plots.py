"""Figures of inversion results (PNG, mm axes): profile with credible band, corner plot."""

from __future__ import annotations

import numpy as np

SCALE = {"x0": (1e3, "mm"), "y0": (1e3, "mm"), "depth": (1e3, "mm"), "young_modulus": (1e-6, "MPa"),
         "normal_force": (1.0, "N"), "friction": (1.0, "-"), "amplitude": (1e6, "mm^2")}

__all__ = ["plot_profile", "plot_corner"]


def plot_profile(x, mean, std, path, *, truth=None, ylabel="load density (mm^2 / mm)", yscale=1e3,
                 title="Profile with 95% credible band", true_label="truth") -> None:
    """Posterior mean with a pointwise 95% band (mean +- 1.96 std) against x in mm."""
    from matplotlib.figure import Figure

    x_mm = np.asarray(x) * 1e3
    fig = Figure(figsize=(8, 4))
    ax = fig.subplots()
    lo, hi = (np.asarray(mean) - 1.96 * np.asarray(std)) * yscale, (np.asarray(mean) + 1.96 * np.asarray(std)) * yscale
    ax.fill_between(x_mm, lo, hi, color="C0", alpha=0.3, label="95% credible band")
    ax.plot(x_mm, np.asarray(mean) * yscale, "C0-", label="posterior mean")
    if truth is not None:
        ax.plot(x_mm, np.asarray(truth) * yscale, "k--", lw=1, label=true_label)
    ax.set(xlabel="x (mm)", ylabel=ylabel, title=title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def plot_corner(tree, path, *, truth: dict | None = None, bins: int = 30) -> None:
    """Corner plot of every posterior variable of an arviz DataTree (units from SCALE)."""
    from matplotlib.figure import Figure

    post = tree["posterior"]
    names = list(post.data_vars)
    k = len(names)
    vals = {}
    for n in names:
        s, _ = SCALE.get(n, (1.0, ""))
        vals[n] = np.asarray(post[n].values).ravel() * s
    fig = Figure(figsize=(2.4 * k + 1, 2.4 * k + 1))
    axes = fig.subplots(k, k, squeeze=False)
    for i, yi in enumerate(names):
        for j, xj in enumerate(names):
            ax = axes[i, j]
            if j > i:
                ax.axis("off")
                continue
            if i == j:
                ax.hist(vals[xj], bins=bins, color="C0", histtype="stepfilled", alpha=0.7)
                if truth and xj in truth:
                    ax.axvline(truth[xj] * SCALE.get(xj, (1.0, ""))[0], color="k", ls="--")
            else:
                ax.hist2d(vals[xj], vals[yi], bins=bins, cmap="Blues")
                if truth and xj in truth and yi in truth:
                    ax.plot(truth[xj] * SCALE.get(xj, (1.0, ""))[0], truth[yi] * SCALE.get(yi, (1.0, ""))[0], "k+",
                            ms=12)
            if i == k - 1:
                ax.set_xlabel(f"{xj} ({SCALE.get(xj, (1.0, '-'))[1]})", fontsize=8)
            if j == 0 and i > 0:
                ax.set_ylabel(f"{yi} ({SCALE.get(yi, (1.0, '-'))[1]})", fontsize=8)
            ax.tick_params(labelsize=7)
    fig.suptitle("Posterior (emcee, all ensembles)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)

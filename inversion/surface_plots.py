"""The figure of a surface posterior: mm along the surface, um for heights."""

from __future__ import annotations

import pathlib

import numpy as np


def _stretches(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return list(zip(edges[::2], edges[1::2] - 1))


def plot_surface(post, path: pathlib.Path, truth=None) -> pathlib.Path:
    """Profile (line) or maps (patch) of a :class:`SurfacePosterior`; returns ``path``."""
    from matplotlib.figure import Figure  # never pyplot: the caller's backend stays as it is

    x_mm = post.x * 1e3
    if post.y is not None:
        fig = Figure(figsize=(13, 4), constrained_layout=True)
        axes = fig.subplots(1, 3 if truth is not None else 2)
        extent = (x_mm[0], x_mm[-1], post.y[0] * 1e3, post.y[-1] * 1e3)
        panels = [(post.mean, "posterior mean (um)"), (post.std, "posterior sd (um)")]
        if truth is not None:
            panels.insert(0, (truth, "truth (um)"))
        for ax, (img, title) in zip(axes, panels):
            im = ax.imshow(img * 1e6, origin="lower", extent=extent, aspect="auto")
            ax.contour(post.x * 1e3, post.y * 1e3, post.touched.astype(float), levels=[0.5], colors="w")
            ax.set(title=title, xlabel="x (mm)", ylabel="y (mm)")
            fig.colorbar(im, ax=ax)
        fig.suptitle("surface posterior (white: edge of the touched area)")
    else:
        fig = Figure(figsize=(10, 6), constrained_layout=True)
        ax, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1))
        lower, upper = post.band(0.9)
        untouched = ~post.touched
        for k, (i, j) in enumerate(_stretches(untouched)):
            lo, hi = x_mm[max(i - 1, 0)], x_mm[min(j + 1, x_mm.size - 1)]
            ax.axvspan(lo, hi, color="0.9", zorder=0, label="untouched" if k == 0 else None)
            ax2.axvspan(lo, hi, color="0.9", zorder=0)
        finite = np.isfinite(lower)
        ax.fill_between(x_mm, np.where(finite, lower, np.nan) * 1e6, upper * 1e6, color="C0", alpha=0.3,
                        label="90 % band")
        ax.plot(x_mm, post.mean * 1e6, "C0", lw=1.2, label="posterior mean")
        if untouched.any():
            ax.plot(x_mm, np.where(untouched, post.upper_bound, np.nan) * 1e6, "k:", lw=1,
                    label="upper bound (skin)")
        if truth is not None:
            ax.plot(x_mm, np.asarray(truth) * 1e6, "k--", lw=1, label="truth")
        ax.set(ylabel="height (um)", title=f"surface posterior ({post.method}); touched "
                                           f"{100 * post.touched_fraction:.0f} % of the nodes")
        ax.legend(loc="best", fontsize=8)
        ax2.plot(x_mm, post.std * 1e6, "C0", lw=1)
        ax2.set(xlabel="x (mm)", ylabel="sd (um)")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path

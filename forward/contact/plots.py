"""Figures of a solved contact: the pressure map (kPa) and the stick/slip zones, axes in mm.

Figures are ``matplotlib.figure.Figure`` objects saved directly (no pyplot, no backend switch).
"""

from __future__ import annotations

import pathlib

import numpy as np


def plot_solution(sol, path: pathlib.Path) -> pathlib.Path:
    """Save ``sol`` (a ContactSolution) as a PNG at ``path``: pressure and zones; returns the path."""
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure

    path.parent.mkdir(parents=True, exist_ok=True)
    x_mm = sol.x * 1e3
    fig = Figure(figsize=(10, 4.2), layout="constrained")
    ax_p, ax_z = fig.subplots(1, 2)
    title = f"{sol.condition}, force {sol.normal_force:.3g} {'N/m' if sol.y is None else 'N'}"
    if sol.y is None:
        ax_p.plot(x_mm, sol.pressure * 1e-3, label="pressure p")
        ax_p.plot(x_mm, sol.qx * 1e-3, label="traction qx")
        ax_p.set_xlabel("x (mm)")
        ax_p.set_ylabel("traction on the skin (kPa)")
        ax_p.legend()
        zone = np.where(sol.stick, 2, np.where(sol.slip, 1, 0))
        ax_z.step(x_mm, zone, where="mid")
        ax_z.set_yticks([0, 1, 2], ["no contact", "slip", "stick"])
        ax_z.set_xlabel("x (mm)")
    else:
        y_mm = sol.y * 1e3
        extent = (x_mm[0], x_mm[-1], y_mm[0], y_mm[-1])
        im = ax_p.imshow(sol.pressure * 1e-3, origin="lower", extent=extent, cmap="viridis", vmin=0)
        fig.colorbar(im, ax=ax_p, label="pressure on the skin (kPa)")
        zone = np.where(sol.stick, 2, np.where(sol.slip, 1, 0))
        cmap = ListedColormap(["#f0f0f0", "#e6862b", "#2b6fe6"])
        im2 = ax_z.imshow(zone, origin="lower", extent=extent, cmap=cmap, vmin=-0.5, vmax=2.5,
                          interpolation="nearest")
        bar = fig.colorbar(im2, ax=ax_z, ticks=[0, 1, 2])
        bar.ax.set_yticklabels(["no contact", "slip", "stick"])
        for ax in (ax_p, ax_z):
            ax.set_xlabel("x (mm)")
            ax.set_ylabel("y (mm)")
    ax_p.set_title(f"pressure ({title})")
    ax_z.set_title(f"contact zones (area {sol.area:.3g} {'m' if sol.y is None else 'm²'})")
    fig.savefig(path, dpi=110)
    return path

"""Figures of fields at depth: maps (2-D) and profiles (1-D), axes in mm, stress in kPa.

matplotlib is imported inside the functions with the Agg backend, so importing tactilab
never touches a display.
"""

from __future__ import annotations

import pathlib

import numpy as np
import xarray as xr


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _scale(da: xr.DataArray) -> tuple[float, str]:
    if da.attrs.get("quantity") == "stress" or da.attrs.get("units") == "Pa":
        return 1e-3, "kPa"
    return 1.0, "strain"


def plot_field(da: xr.DataArray, path: str | pathlib.Path, title: str = "") -> pathlib.Path:
    """Draw one panel per (depth, component) of a labelled field and save a PNG.

    Parameters
    ----------
    da : xarray.DataArray
        dims (depth, component, y, x) or (depth, component, x) (or without ``component``
        for a scalar invariant), coordinates in m.
    path : path-like
        PNG to write.
    title : str
        Figure title.
    """
    plt = _pyplot()
    if "component" not in da.dims:
        da = da.expand_dims(component=[da.name or "value"])
    factor, unit = _scale(da)
    depths, comps = da["depth"].values, list(da["component"].values)
    fig, axes = plt.subplots(len(depths), len(comps), figsize=(3.2 * len(comps) + 0.8, 2.8 * len(depths)),
                             squeeze=False, constrained_layout=True)
    x_mm = da["x"].values * 1e3
    for i, z in enumerate(depths):
        for j, comp in enumerate(comps):
            ax = axes[i, j]
            values = da.isel(depth=i).sel(component=comp).values * factor
            label = f"{comp} ({unit})"
            if "y" in da.dims:
                y_mm = da["y"].values * 1e3
                lim = np.abs(values).max() or 1.0
                mesh = ax.pcolormesh(x_mm, y_mm, values, shading="auto", cmap="RdBu_r", vmin=-lim, vmax=lim)
                fig.colorbar(mesh, ax=ax, label=label)
                ax.set_ylabel("y (mm)")
                ax.set_aspect("equal")
            else:
                ax.plot(x_mm, values)
                ax.set_ylabel(label)
            ax.set_xlabel("x (mm)")
            ax.set_title(f"{comp} at depth {z * 1e3:.2f} mm", fontsize=9)
    if title:
        fig.suptitle(title)
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

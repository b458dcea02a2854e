"""Figures of fields at depth: maps (2-D) and profiles (1-D), axes in mm, stress in kPa.

Figures are ``matplotlib.figure.Figure`` objects saved directly: no pyplot, no backend switch,
so the caller's matplotlib backend is never changed.
"""

from __future__ import annotations

import pathlib

import numpy as np
import xarray as xr


def _figure(**kwargs):
    """A new ``matplotlib.figure.Figure`` (matplotlib is imported on first use, never pyplot)."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)


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
    if "component" not in da.dims:
        da = da.expand_dims(component=[da.name or "value"])
    factor, unit = _scale(da)
    depths, comps = da["depth"].values, list(da["component"].values)
    fig = _figure(figsize=(3.2 * len(comps) + 0.8, 2.8 * len(depths)), layout="constrained")
    axes = fig.subplots(len(depths), len(comps), squeeze=False)
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
    return path

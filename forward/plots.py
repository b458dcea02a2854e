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


#: fields that are never negative (invariants and magnitudes): drawn on a sequential map from 0
NON_NEGATIVE = ("von_mises", "von mises", "max_shear", "energy_density", "magnitude", "equivalent")


def is_non_negative(name: str, values: np.ndarray) -> bool:
    """True for a field that cannot be negative by its name (von Mises, magnitudes), or has no negative value.

    Such fields get a sequential colour map from 0; signed fields a diverging one centred on 0.
    """
    lowered = str(name).lower()
    if any(key in lowered for key in NON_NEGATIVE):
        return True
    finite = np.asarray(values)[np.isfinite(values)]
    return finite.size > 0 and bool(finite.min() >= 0)


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

    Non-negative fields (von Mises, magnitudes; see :func:`is_non_negative`) use the sequential
    ``viridis`` map from 0; signed fields the diverging ``RdBu_r`` map centred on 0.
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
            convention = str(da.attrs.get("shear_convention", ""))
            if comp in ("yz", "zx", "xy") and convention:  # shear strain: say which convention
                label = f"{comp} ({unit}, {'engineering' if convention.startswith('engineering') else 'tensor'} shear)"
            if "y" in da.dims:
                y_mm = da["y"].values * 1e3
                lim = np.nanmax(np.abs(values)) or 1.0
                if is_non_negative(f"{da.name} {comp}", values):
                    mesh = ax.pcolormesh(x_mm, y_mm, values, shading="auto", cmap="viridis", vmin=0.0, vmax=lim)
                else:
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

"""Files of a contact solution: the solution as netCDF, maps of pressure and stick/slip, strain at depth.

Figures are ``matplotlib.figure.Figure`` objects saved directly (no pyplot, the caller's backend is
never changed); axes in mm, pressure and traction in kPa.
"""

from __future__ import annotations

import pathlib

import numpy as np

from tactilab.core.netcdf import write_netcdf

from .plots import _figure


def _axes_mm(solution) -> tuple[np.ndarray, np.ndarray | None]:
    return solution.x * 1e3, (None if solution.y is None else solution.y * 1e3)


def _extent(x_mm: np.ndarray, y_mm: np.ndarray) -> list[float]:
    hx, hy = (x_mm[1] - x_mm[0]) / 2, (y_mm[1] - y_mm[0]) / 2
    return [x_mm[0] - hx, x_mm[-1] + hx, y_mm[0] - hy, y_mm[-1] + hy]


def plot_contact_pressure(solution, path: str | pathlib.Path, title: str = "") -> pathlib.Path:
    """Draw the contact pressure (kPa) over the grid (mm), a map or a profile, and save a PNG.

    Parameters
    ----------
    solution : ContactSolution
        A solved contact (``pressure`` in Pa; ``load()`` gives the node coordinates in m).
    path : path-like
        PNG to write.
    title : str
        Figure title (the contact fraction and peak pressure are appended).
    """
    x_mm, y_mm = _axes_mm(solution)
    p_kpa = np.asarray(solution.pressure) / 1e3
    fig = _figure(figsize=(5.6, 4.4), layout="constrained")
    ax = fig.subplots()
    if y_mm is None:
        ax.plot(x_mm, p_kpa, color="C0")
        ax.fill_between(x_mm, 0, p_kpa, where=np.asarray(solution.contact), color="C0", alpha=0.2,
                        label="in contact")
        ax.set_ylabel("pressure (kPa)")
        ax.legend(loc="upper right")
    else:
        im = ax.imshow(p_kpa, origin="lower", extent=_extent(x_mm, y_mm), cmap="viridis", vmin=0,
                       interpolation="nearest")
        fig.colorbar(im, ax=ax, label="pressure (kPa)")
        ax.set_ylabel("y (mm)")
        ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_title(f"{title + ': ' if title else ''}contact {100 * float(solution.contact_fraction):.3g} %, "
                 f"peak {p_kpa.max():.4g} kPa", fontsize=10)
    fig.savefig(path, dpi=110)
    return pathlib.Path(path)


def plot_stick_slip(solution, path: str | pathlib.Path, friction: float, title: str = "") -> pathlib.Path:
    """Draw where the contact sticks and slips (a map, or traction profiles for a profile); save a PNG.

    A map colours each node out of contact, slipping or sticking; a profile draws the tangential
    traction |q| (kPa) under the Coulomb bound mu p (kPa), the stick zone shaded.
    """
    x_mm, y_mm = _axes_mm(solution)
    stick, slip = np.asarray(solution.stick, dtype=bool), np.asarray(solution.slip, dtype=bool)
    fig = _figure(figsize=(5.6, 4.4), layout="constrained")
    ax = fig.subplots()
    if y_mm is None:
        q = np.abs(np.asarray(solution.qx)) / 1e3
        ax.plot(x_mm, q, color="C3", label="|q|")
        if np.isfinite(friction):  # stuck (mu = inf) has no Coulomb bound to draw
            ax.plot(x_mm, friction * np.asarray(solution.pressure) / 1e3, "--", color="k", lw=1, label="mu p")
        ax.fill_between(x_mm, 0, q, where=stick, color="C2", alpha=0.3, label="stick")
        ax.set_ylabel("traction (kPa)")
        ax.legend(loc="upper right")
    else:
        from matplotlib.colors import ListedColormap

        zones = np.where(stick, 2, np.where(slip, 1, 0))
        cmap = ListedColormap(["#f0f0f0", "#e6550d", "#31a354"])
        im = ax.imshow(zones, origin="lower", extent=_extent(x_mm, y_mm), cmap=cmap, vmin=-0.5, vmax=2.5,
                       interpolation="nearest")
        bar = fig.colorbar(im, ax=ax, ticks=[0, 1, 2])
        bar.ax.set_yticklabels(["no contact", "slip", "stick"])
        ax.set_ylabel("y (mm)")
        ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_title(f"{title + ': ' if title else ''}stick {int(stick.sum())} nodes, slip {int(slip.sum())} nodes "
                 f"(mu = {friction:g})", fontsize=10)
    fig.savefig(path, dpi=110)
    return pathlib.Path(path)


def write_contact(solution, folder: str | pathlib.Path, *, skin=None, depths=(), friction: float | None = None,
                  title: str = "") -> list[pathlib.Path]:
    """Write a contact solution's files into ``folder``; return their paths.

    Parameters
    ----------
    solution : ContactSolution
        The solved contact.
    folder : path-like
        Output folder (created if missing).
    skin : HalfSpace, optional
        The skin that was solved; needed for the strain at ``depths``.
    depths : sequence of float, m
        Receptor depths of ``strain.nc`` / ``strain.png`` (nothing written when empty).
    friction : float, optional
        Coulomb coefficient drawn as the bound mu p (default ``solution.friction``); the stick/slip
        map is written for a frictional condition with mu > 0.
    title : str
        A label for the figure titles.

    Files: ``contact.nc`` (``solution.to_dataset()``, SI), ``pressure.png`` (mm, kPa), ``stick_slip.png``,
    and ``strain.nc`` + ``strain.png`` (the strain of ``solution.load()`` at ``depths``, requested to the
    contact's own error estimate, or 1e-6 when that is smaller; the field's error estimate covers the
    contact's).
    """
    from .load_files import write_field

    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    nc = folder / "contact.nc"
    write_netcdf(solution.to_dataset(), nc)
    written.append(nc)
    written.append(plot_contact_pressure(solution, folder / "pressure.png", title))
    mu = float(solution.friction) if friction is None else friction
    if mu > 0 and solution.condition != "frictionless":
        written.append(plot_stick_slip(solution, folder / "stick_slip.png", mu, title))
    if len(depths):
        if skin is None:
            raise ValueError("skin: the strain at depth needs the HalfSpace that was solved; "
                             "pass skin=HalfSpace(E, nu)")
        # no more accurate than the load it comes from: the contact's own error sets the field's tolerance
        tol = max(1e-6, float(solution.error_estimate))
        result = skin.strain(solution.load(), list(depths), tol=tol)
        written += write_field(result, folder, stem="strain")
    return written


"""The receptive field of a sensor at depth: its reading per unit point force as the force moves.

A sensor at ``(0, 0, Z)`` reads one component of stress or strain (or the equivalent strain); a
normal point force of 1 N at ``(x, y)`` on the surface gives it ``R(x, y)``. The skin is
translation-invariant, so ``R(x, y)`` is the field at ``(-x, -y, Z)`` of a unit force at the
origin: one field solve on a grid, with a single loaded node of pressure ``1 / cell area``. The
profile along x and its widths (where ``|R|`` falls to a half and to a tenth of its peak) compare
skins: docs/layered_skin.md tabulates a sensor 3 mm deep in a 4 mm pulp on bone against the
half-space's.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from tactilab.core import rules as check
from tactilab.forward.halfspace import SurfaceLoad

#: the readings a receptive field can be taken of: Voigt components and the equivalent strain
READINGS = ("xx", "yy", "zz", "yz", "zx", "xy", "von_mises")


@dataclass(frozen=True)
class ReceptiveField:
    """A sensor's reading per newton of normal force, along x through the sensor.

    Attributes
    ----------
    x : ndarray, shape (n,)
        Force positions along x, m (y = 0).
    profile : ndarray, shape (n,)
        Reading per N: Pa/N for stress, 1/N for strain (tensor shear).
    peak : float
        The largest ``|profile|``.
    half_width, tenth_width : float
        Largest ``|x|`` (m) where ``|profile|`` is still at least a half / a tenth of ``peak``.
    error_estimate : float
        The field solve's error estimate, relative to the field's peak.
    """

    x: np.ndarray
    profile: np.ndarray
    peak: float
    half_width: float
    tenth_width: float
    error_estimate: float


def _width(x: np.ndarray, profile: np.ndarray, fraction: float) -> float:
    """Largest |x| where |profile| >= fraction * max, linearly interpolated to the crossing."""
    mag = np.abs(profile)
    level = fraction * mag.max()
    above = np.flatnonzero(mag >= level)
    i = int(above[np.argmax(np.abs(x[above]))])
    j = i + (1 if x[i] >= 0 else -1)
    if j < 0 or j >= len(x):
        return float(abs(x[i]))
    t = (mag[i] - level) / (mag[i] - mag[j]) if mag[i] != mag[j] else 0.0
    return float(abs(x[i] + t * (x[j] - x[i])))


def receptive_field(skin, depth: float, reading: str = "zz", quantity: str = "strain", spacing: float = 1e-4,
                    half_extent: float = 15e-3, tol: float = 1e-4) -> ReceptiveField:
    """The receptive field of a sensor at ``depth`` for a normal point force.

    Parameters
    ----------
    skin : HalfSpace or LayeredHalfSpace
        Anything with ``strain`` / ``stress(load, depth, components=..., tol=...)``.
    depth : float
        Sensor depth, m.
    reading : str
        A Voigt component (``"zz"``, ...) or ``"von_mises"`` (the equivalent strain
        ``sqrt(2/3 e:e)`` of the deviatoric strain; needs ``quantity="strain"``).
    quantity : {"strain", "stress"}
    spacing : float
        Grid spacing, m (resolve the depth: ``spacing << depth``).
    half_extent : float
        The grid spans ``[-half_extent, half_extent]`` per axis, m.
    tol : float
        Requested relative error of the field solve.

    Returns
    -------
    ReceptiveField
    """
    depth = check.depth(depth)
    spacing = check.spacing(spacing, 1)[0]
    half_extent = check.positive(half_extent, "half_extent", "m", "give the half width of the grid in m")
    if reading not in READINGS:
        raise ValueError(f"reading: must be one of {READINGS}, got {reading!r}")
    if quantity not in ("strain", "stress") or (reading == "von_mises" and quantity != "strain"):
        raise ValueError(f"quantity: must be 'strain' or 'stress' ('strain' for von_mises), got {quantity!r}")
    n = 2 * int(round(half_extent / spacing)) + 1
    p = np.zeros((n, n))
    p[n // 2, n // 2] = 1.0 / spacing**2  # 1 N on one node
    load = SurfaceLoad(p=p, spacing=spacing)
    comps = None if reading == "von_mises" else (reading,)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a point load is not resolved at the surface; the depth is
        result = getattr(skin, quantity)(load, depth, components=comps, tol=tol)
    field = result.data[quantity].values[0]  # (n_comp, ny, nx)
    row = field[:, n // 2, :]
    if reading == "von_mises":
        e = {c: row[i] for i, c in enumerate(READINGS[:6])}
        mean = (e["xx"] + e["yy"] + e["zz"]) / 3.0
        dev2 = sum((e[c] - mean) ** 2 for c in ("xx", "yy", "zz")) + 2 * sum(e[c] ** 2 for c in ("yz", "zx", "xy"))
        profile = np.sqrt(2.0 / 3.0 * dev2)
    else:
        profile = row[0]
    x = load.x
    return ReceptiveField(x=x, profile=profile, peak=float(np.abs(profile).max()), half_width=_width(x, profile, 0.5),
                          tenth_width=_width(x, profile, 0.1), error_estimate=float(result.error_estimate))

"""Closed-form stress of concentrated surface loads on an elastic half-space (method 1).

Conventions (docs/theory.md section 1): x, y on the surface, z = depth into the skin (z > 0 inside).
A force ``(fx, fy, fz)`` is applied TO the skin surface: ``fz > 0`` pushes into the skin,
``fx``, ``fy`` act along +x, +y. Stress is in Pa, tension positive, Voigt order
``COMPONENTS`` (xx, yy, zz, yz, zx, xy, from tactilab.core.rules; tensor components, not engineering shear).

Point forces (N, 3-D): Boussinesq (normal) and Cerruti (tangential), Johnson, *Contact Mechanics*
(1985), eqs. 3.18 and 3.19, rewritten in direction cosines ``l, m, n = x/R, y/R, z/R`` so that
every term is ``F/R**2`` times a bounded function of the direction: no ``1/r`` with
``r = hypot(x, y)``, no cancellation of large terms, and no division by ``1 - 2 nu`` (nu = 0.5 is
exact). Line forces (N/m along y, plane strain): Flamant (normal, tangential, with
``sigma_yy = nu (sigma_xx + sigma_zz)``) and the antiplane line force ``fy`` (``sigma_yz``,
``sigma_xy`` only), written with ``l, n = x/r, z/r`` as ``F/r`` times a bounded function.

The formulas themselves live in :mod:`tactilab.forward.halfspace.kernel_formulas`; this module adds
input checks, the full-tensor functions, and method 1 (direct summation over load nodes).

Limits (documented, and tested):

* On the axis below a point force (r -> 0), the Boussinesq polar forms have removable 0/0
  terms; here they are already resolved: ``sigma_r = sigma_theta = P (1 - 2 nu) / (4 pi z**2)``
  at r = 0 (tension for nu < 1/2, zero for nu = 1/2), ``sigma_zz = -3 P / (2 pi z**2)``.
* On the surface away from the force (z = 0, R > 0) the formulas are finite and
  traction-free (``sigma_zz = sigma_zx = sigma_yz = 0``); at the force itself (R = 0) the stress
  is singular and the functions raise ``ValueError``.
* Far away, values decay like 1/R**2 (point) or 1/r (line) without overflow: distances fall
  back to ``hypot`` when squares would overflow, and the formulas only ever raise direction
  cosines (bounded by 1) to powers. The stress overflows only within R < 1e-154 m of the force.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .kernel_formulas import line_geometry, line_unit, point_geometry, point_unit
from .loads import SurfaceLoad

from tactilab.core import rules as check
from tactilab.core.rules import COMPONENTS
DIRECTIONS = ("x", "y", "z")

__all__ = [
    "COMPONENTS",
    "direct_stress",
    "direct_stress_from_forces",
    "DIRECTIONS",
    "point_load_stress",
    "line_load_stress",
    "point_green",
    "line_green",
    "active_pairs",
]


# ----------------------------------------------------------------------------- validation
def _check_coordinate(name: str, value) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    bad = ~np.isfinite(arr)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0]) if arr.ndim else ()
        raise ValueError(f"{name}: coordinates must be finite (in m), got {arr[idx]} at index {idx}")
    return arr


def _check_force(name: str, value) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: force must be finite, got {value!r}")
    return arr


# ----------------------------------------------------------------------------- point forces
def _check_point_coordinates(x, y, z):
    x = _check_coordinate("x", x)
    y = _check_coordinate("y", y)
    z = _check_coordinate("z", z)
    if np.any(z < 0):
        raise ValueError(
            f"z: depth must be >= 0 m (z > 0 inside the skin), got min {float(z.min())!r}"
        )
    hit = (x == 0) & (y == 0) & (z == 0)
    if np.any(hit):
        raise ValueError(
            "x, y, z: a point coincides with the point force (R = 0), where the stress is singular; "
            "evaluate at depth z > 0"
        )
    return x, y, z


def point_green(component: str, direction: str, x: ArrayLike, y: ArrayLike, z: ArrayLike,
                nu: float = 0.5) -> np.ndarray:
    """One stress component per unit point force (Pa/N), the Green's function of method 1.

    Parameters
    ----------
    component : str
        One of ``COMPONENTS``.
    direction : {"x", "y", "z"}
        Direction of the unit force applied to the surface at the origin ("z" pushes in).
    x, y, z : array_like
        Field points in m, broadcast together; ``z >= 0`` is depth, and ``R > 0``.
    nu : float
        Poisson's ratio in (-1, 0.5].

    Returns
    -------
    ndarray, shape ``broadcast(x, y, z)``, in Pa per N.
    """
    component = check.components((component,), "component")[0]
    if direction not in DIRECTIONS:
        raise ValueError(f"direction: force direction must be one of {DIRECTIONS}, got {direction!r}")
    nu = check.poisson_ratio(nu)
    x, y, z = _check_point_coordinates(x, y, z)
    return point_unit(component, direction, *point_geometry(x, y, z), nu)


def point_load_stress(x: ArrayLike, y: ArrayLike, z: ArrayLike, fx: ArrayLike = 0.0, fy: ArrayLike = 0.0,
                      fz: ArrayLike = 0.0, nu: float = 0.5) -> np.ndarray:
    """Stress of a point force applied to the surface at the origin (Boussinesq + Cerruti).

    Parameters
    ----------
    x, y, z : array_like
        Field points in m (z >= 0 is depth), broadcast together; not at the force (R > 0).
    fx, fy, fz : float or array_like
        Force on the skin in N: tangential along +x, +y, and normal (positive pushes into the
        skin). Arrays broadcast with the points.
    nu : float
        Poisson's ratio in (-1, 0.5]; 0.5 is exact.

    Returns
    -------
    ndarray, shape ``broadcast(x, y, z, fx, fy, fz) + (6,)``
        Stress in Pa, tension positive, Voigt order ``COMPONENTS`` (tensor shear).

    Notes
    -----
    On the axis (r = 0) the Boussinesq in-plane stresses are finite:
    ``sigma_xx = sigma_yy = sigma_r = sigma_theta = fz (1 - 2 nu) / (4 pi z^2)``.
    """
    nu = check.poisson_ratio(nu)
    x, y, z = _check_point_coordinates(x, y, z)
    forces = {"x": _check_force("fx", fx), "y": _check_force("fy", fy), "z": _check_force("fz", fz)}
    shape = np.broadcast_shapes(x.shape, y.shape, z.shape, *(f.shape for f in forces.values()))
    geometry = point_geometry(x, y, z)
    out = np.zeros(shape + (6,))
    for direction, force in forces.items():
        if not np.any(force):
            continue
        for k, comp in enumerate(COMPONENTS):
            out[..., k] += force * point_unit(comp, direction, *geometry, nu)
    return out


# ----------------------------------------------------------------------------- line forces
def _check_line_coordinates(x, z):
    x = _check_coordinate("x", x)
    z = _check_coordinate("z", z)
    if np.any(z < 0):
        raise ValueError(f"z: depth must be >= 0 m (z > 0 inside the skin), got min {float(z.min())!r}")
    if np.any((x == 0) & (z == 0)):
        raise ValueError(
            "x, z: a point coincides with the line force (r = 0), where the stress is singular; "
            "evaluate at depth z > 0"
        )
    return x, z


def line_green(component: str, direction: str, x: ArrayLike, z: ArrayLike, nu: float = 0.5) -> np.ndarray:
    """One stress component per unit line force (Pa per N/m), plane strain, force along y at x = 0.

    Parameters as ``point_green`` without ``y``; returns shape ``broadcast(x, z)``.
    """
    component = check.components((component,), "component")[0]
    if direction not in DIRECTIONS:
        raise ValueError(f"direction: force direction must be one of {DIRECTIONS}, got {direction!r}")
    nu = check.poisson_ratio(nu)
    x, z = _check_line_coordinates(x, z)
    return line_unit(component, direction, *line_geometry(x, z), nu)


def line_load_stress(x: ArrayLike, z: ArrayLike, fx: ArrayLike = 0.0, fy: ArrayLike = 0.0, fz: ArrayLike = 0.0,
                     nu: float = 0.5) -> np.ndarray:
    """Plane-strain stress of a line force along the y axis (Flamant and antiplane shear).

    Parameters
    ----------
    x, z : array_like
        Field points in m (z >= 0 is depth), broadcast together; not on the line (r > 0).
    fx, fy, fz : float or array_like
        Force per unit length in N/m on the skin: along +x (tangential Flamant), along +y
        (antiplane: only ``sigma_yz``, ``sigma_xy``) and normal (positive pushes in).
    nu : float
        Poisson's ratio in (-1, 0.5]; only ``sigma_yy = nu (sigma_xx + sigma_zz)`` depends on it.

    Returns
    -------
    ndarray, shape ``broadcast(x, z, fx, fy, fz) + (6,)``, stress in Pa, Voigt order ``COMPONENTS``.
    """
    nu = check.poisson_ratio(nu)
    x, z = _check_line_coordinates(x, z)
    forces = {"x": _check_force("fx", fx), "y": _check_force("fy", fy), "z": _check_force("fz", fz)}
    shape = np.broadcast_shapes(x.shape, z.shape, *(f.shape for f in forces.values()))
    geometry = line_geometry(x, z)
    out = np.zeros(shape + (6,))
    for direction, force in forces.items():
        if not np.any(force):
            continue
        for k, comp in enumerate(COMPONENTS):
            out[..., k] += force * line_unit(comp, direction, *geometry, nu)
    return out


def active_pairs(components: Sequence[str], directions: Sequence[str], ndim: int) -> list[tuple[str, str]]:
    """(component, direction) pairs whose Green's function is not identically zero.

    ``ndim`` is 2 for point forces and 1 for plane-strain line forces (where the antiplane
    force ``y`` only drives ``yz``, ``xy``, and the in-plane forces never do).
    """
    pairs = []
    for comp in components:
        for direction in directions:
            if ndim == 1 and (direction == "y") != (comp in ("yz", "xy")):
                continue
            pairs.append((comp, direction))
    return pairs


# ----------------------------------------------------------------------------- method 1
_PAIR_BUDGET = 1 << 17  # (point, force) pairs per block: bounds temporaries to a few MB each


def direct_stress_from_forces(forces: ArrayLike, positions: ArrayLike, points: ArrayLike, nu: float = 0.5,
                              components: Sequence[str] = COMPONENTS) -> np.ndarray:
    """Stress at sensor points from a few concentrated surface forces, by direct summation.

    Parameters
    ----------
    forces : array_like, shape (m, 3)
        ``(fx, fy, fz)`` per force: N for point forces, N/m for line forces (plane strain).
    positions : array_like, shape (m, 2) or (m,)
        Surface positions in m: ``(x, y)`` of point forces, or ``x`` of line forces along y
        (shape ``(m,)`` or ``(m, 1)``).
    points : array_like, shape (n, 3) or (n, 2)
        Sensor points in m: ``(x, y, z)`` for point forces, ``(x, z)`` for line forces; z > 0.
    nu : float
        Poisson's ratio in (-1, 0.5].
    components : sequence of str
        Names from ``COMPONENTS``; the output columns follow this order.

    Returns
    -------
    ndarray, shape (n, len(components)), stress in Pa (tension positive, tensor shear).
    """
    nu = check.poisson_ratio(nu)
    components = check.components(components)
    pos = _check_coordinate("positions", positions)
    if pos.ndim == 1:
        pos = pos[:, None]
    if pos.ndim != 2 or pos.shape[1] not in (1, 2):
        raise ValueError(
            f"positions: expected shape (m, 2) for point forces or (m,) for line forces, got {np.shape(positions)}"
        )
    force = _check_force("forces", forces)
    if force.shape != (pos.shape[0], 3):
        raise ValueError(
            f"forces: expected shape ({pos.shape[0]}, 3) of (fx, fy, fz), one row per position, got {force.shape}"
        )
    return _sum_forces(force, pos, _check_points(points, pos.shape[1]), nu, components)


def _sum_forces(force: np.ndarray, pos: np.ndarray, pts: np.ndarray, nu: float,
                components: tuple[str, ...]) -> np.ndarray:
    """The direct sum of :func:`direct_stress_from_forces` on checked inputs."""
    ndim = pos.shape[1]
    out = np.zeros((pts.shape[0], len(components)))
    keep = np.any(force != 0, axis=1)
    pos, force = pos[keep], force[keep]
    if not pos.shape[0] or not pts.shape[0]:
        return out
    directions = [d for k, d in enumerate(DIRECTIONS) if np.any(force[:, k])]
    pairs = active_pairs(components, directions, ndim)
    col = {d: k for k, d in enumerate(DIRECTIONS)}
    m_block = min(pos.shape[0], _PAIR_BUDGET)
    n_block = max(1, _PAIR_BUDGET // m_block)
    for j0 in range(0, pos.shape[0], m_block):
        src, f = pos[j0:j0 + m_block], force[j0:j0 + m_block]
        for i0 in range(0, pts.shape[0], n_block):
            p = pts[i0:i0 + n_block]
            dx = p[:, :1] - src[:, 0]
            if ndim == 2:
                geometry = point_geometry(dx, p[:, 1:2] - src[:, 1], p[:, 2:3])
                unit = point_unit
            else:
                geometry = line_geometry(dx, p[:, 1:2])
                unit = line_unit
            for comp, d in pairs:
                # A matrix-vector product sums over forces without another (n, m) temporary.
                out[i0:i0 + n_block, components.index(comp)] += unit(comp, d, *geometry, nu) @ f[:, col[d]]
    return out


def _check_points(points, ndim: int) -> np.ndarray:
    pts = _check_coordinate("points", points)
    want = 3 if ndim == 2 else 2
    if pts.ndim != 2 or pts.shape[1] != want:
        kind = "(n, 3) of (x, y, z) for a 2-D load" if ndim == 2 else "(n, 2) of (x, z) for a 1-D (plane-strain) load"
        raise ValueError(f"points: expected shape {kind}, got {pts.shape}")
    if pts.shape[0] and np.any(pts[:, -1] <= 0):
        raise ValueError(
            f"points: depth z must be > 0 m (inside the skin), got min {float(pts[:, -1].min())!r}; "
            "at the surface the stress of a sampled load is a distribution, not a value"
        )
    return pts


def direct_stress(load: SurfaceLoad, points: ArrayLike, nu: float = 0.5,
                  components: Sequence[str] = COMPONENTS) -> np.ndarray:
    """Method 1: stress at points as the sum of closed-form kernels over the load nodes.

    Each non-zero node carries its traction times the cell area (``dx * dy``; ``dx`` in 1-D)
    as a concentrated force at the node (``x_j = (j - nx // 2) dx``): the same sampled load
    that the DC-FFT convolution (``tactilab.forward.halfspace.dcfft``) sees, so the two agree to
    rounding. Cost O(n_points x n_loaded_nodes); memory is bounded by blocking.

    Parameters
    ----------
    load : SurfaceLoad
        Tractions in Pa on a 1-D (plane strain) or 2-D grid.
    points : array_like, shape (n, 3) of (x, y, z) for a 2-D load, (n, 2) of (x, z) for 1-D
        Sensor positions in m, depth z > 0.
    nu : float
        Poisson's ratio in (-1, 0.5].
    components : sequence of str
        Names from ``COMPONENTS``.

    Returns
    -------
    ndarray, shape (n, len(components)), stress in Pa.
    """
    if not isinstance(load, SurfaceLoad):
        raise ValueError(f"load: expected a SurfaceLoad, got {type(load).__name__}; build one with SurfaceLoad(p=..., spacing=...)")
    return nodal_stress(load, _check_points(points, load.ndim), check.poisson_ratio(nu), check.components(components))


def nodal_stress(load: SurfaceLoad, points: np.ndarray, nu: float, components: tuple[str, ...]) -> np.ndarray:
    """:func:`direct_stress` on inputs already checked by the caller (the facade's methods)."""
    arrays = load.components
    shape = load.shape
    force = np.zeros(shape + (3,))
    for k, name in enumerate(("qx", "qy", "p")):
        if name in arrays:
            force[..., k] = arrays[name] * load.cell_area
    if load.ndim == 2:
        yy, xx = np.meshgrid(load.y, load.x, indexing="ij")
        positions = np.stack([xx.ravel(), yy.ravel()], axis=1)
    else:
        positions = load.x
    if positions.ndim == 1:
        positions = positions[:, None]
    return _sum_forces(force.reshape(-1, 3), positions, points, nu, components)

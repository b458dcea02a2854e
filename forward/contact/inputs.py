"""Input rules of :func:`solve_contact`, checked once at entry; the memory estimate before any grid.

Each error names the argument, the rule, the value and the fix. The memory rule: a solve may use
at most half of the machine's available memory (``os.sysconf``; 8 GiB where the system does not
say), estimated from the grid before anything is allocated (see :func:`memory_estimate`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from tactilab.core import rules as check
from .hertz import CONDITIONS

#: fraction of the available memory a solve may use
MEMORY_FRACTION = 0.5


@dataclass(frozen=True)
class ContactInputs:
    """Checked arguments of a solve (SI units)."""

    gap: np.ndarray
    spacing: tuple
    periodic: bool
    total: float | None  # target sum of nodal pressures, Pa (force / cell area); None under approach control
    approach: float | None
    friction: float
    condition: str
    tangential_force: tuple | None  # (Qx,) in N/m (plane strain) or (Qx, Qy) in N
    direction: tuple  # unit slide direction, x first
    method: object
    tol: float
    max_iter: int
    initial: object

    @property
    def shape(self) -> tuple[int, ...]:
        return self.gap.shape


def memory_estimate(shape, periodic: bool, condition: str) -> int:
    """Bytes a solve needs, estimated from the grid alone.

    About 40 bytes per node of the FFT grid (zero-padded to twice each side when isolated: the
    kernel spectrum, the FFT's input and output and its work space) and 160 bytes per node of the
    grid (a dozen float64 work arrays); partial slip and stuck contacts add the tangential blocks
    (48 bytes per FFT node, 160 per grid node); the check solve on the grid of twice the spacing adds
    a quarter (a half in plane strain).
    """
    n = math.prod(shape)
    padded = n if periodic else n * 2 ** len(shape)
    per = (40 * padded + 160 * n) * (2 if condition in ("partial", "stuck") else 1)
    return int(per * (1.5 if len(shape) == 1 else 1.25))


def memory_limit() -> int:
    """Half of the available memory in bytes (8 GiB assumed where the system does not say)."""
    try:
        available = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        available = 16 * 2**30
    return int(MEMORY_FRACTION * available)


def _check_memory(shape, periodic: bool, condition: str) -> None:
    need, limit = memory_estimate(shape, periodic, condition), memory_limit()
    if need <= limit:
        return
    side = 1 << int(math.log2(max(limit / memory_estimate((1,) * len(shape), periodic, condition), 1.0))
                    / len(shape))
    while memory_estimate((2 * side,) * len(shape), periodic, condition) <= limit:
        side *= 2
    while side > 1 and memory_estimate((side,) * len(shape), periodic, condition) > limit:
        side //= 2
    kind = "periodic" if periodic else "isolated (zero-padded to twice each side)"
    fits = " x ".join([str(side)] * len(shape))
    raise ValueError(f"gap: a {kind} grid of shape {shape} needs about {need / 2**30:.3g} GiB, above the limit "
                     f"{limit / 2**30:.3g} GiB (half the available memory); the largest grid that fits is {fits}: "
                     "coarsen the spacing or crop the surface")


def check_inputs(skin, gap, spacing, *, normal_force, mean_pressure, approach, periodic, friction, condition,
                 tangential_force, slide_direction, method, tol, max_iter, initial) -> ContactInputs:
    """Validate every argument of :func:`solve_contact` (see there); returns them checked, in SI."""
    if not callable(getattr(skin, "surface_compliance", None)):
        raise ValueError(f"skin: needs a surface_compliance(kx, ky) method (the skin protocol), got "
                         f"{type(skin).__name__}; use HalfSpace(E, nu)")
    if not isinstance(periodic, (bool, np.bool_)):
        raise ValueError(f"periodic: must be True or False, got {periodic!r}")
    shape = np.shape(gap)
    if len(shape) not in (1, 2) or min(shape, default=0) < 2:
        raise ValueError(f"gap: expected shape (nx,) for plane strain or (ny, nx), at least 2 nodes per axis, "
                         f"got {shape}")
    if periodic and any(n % 2 for n in shape):
        raise ValueError(f"gap: a periodic grid needs an even number of nodes per axis (the error estimate solves on "
                         f"every other node), got shape {shape}; add or drop one node")
    if condition not in CONDITIONS:
        raise ValueError(f"condition: must be one of {CONDITIONS}, got {condition!r}")
    _check_memory(shape, bool(periodic), condition)
    g0 = np.ascontiguousarray(check.finite_array(gap, "gap", "m"))  # strided views slow every pass
    spacing = check.spacing(spacing, len(shape))
    given = {k: v for k, v in (("normal_force", normal_force), ("mean_pressure", mean_pressure),
                               ("approach", approach)) if v is not None}
    if len(given) != 1:
        raise ValueError(f"normal_force, mean_pressure, approach: give exactly one, got {sorted(given) or 'none'}")
    cell = math.prod(spacing)
    total = None
    if normal_force is not None:
        unit = "N/m" if len(shape) == 1 else "N"
        fix = f"give the total force pressing the skin in {unit}"
        total = check.positive(normal_force, "normal_force", unit, fix) / cell
    if mean_pressure is not None:
        if not periodic:
            raise ValueError(f"mean_pressure: is the load of a periodic cell, but periodic=False, got "
                             f"{mean_pressure!r}; give normal_force for an isolated contact, or set periodic=True")
        total = check.positive(mean_pressure, "mean_pressure", "Pa") * g0.size
    if approach is not None:
        if periodic:
            raise ValueError(f"approach: a periodic contact has no defined approach (the mean displacement of a "
                             f"half-space under a mean pressure is unbounded), got {approach!r}; give mean_pressure")
        approach = check.finite(approach, "approach", "m")
    mu = float(friction) if isinstance(friction, (int, float, np.integer, np.floating)) \
        and not isinstance(friction, (bool, np.bool_)) else math.nan
    if math.isnan(mu) or mu < 0 or (math.isinf(mu) and condition != "stuck"):
        raise ValueError(f"friction: the Coulomb coefficient must be >= 0 (inf only for condition='stuck'), got "
                         f"{friction!r}; use 0 for a frictionless contact")
    if condition == "sliding" and mu == 0:
        raise ValueError("friction: condition='sliding' needs friction > 0, got 0; use condition='frictionless'")
    Q = _tangential(tangential_force, condition, len(shape), mu, total, cell)
    direction = _direction(slide_direction, len(shape))
    if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not 0 < tol < 1:
        raise ValueError(f"tol: must be a relative tolerance in (0, 1), got {tol!r}; e.g. 1e-8")
    if max_iter is None:
        max_iter = 10_000
    elif isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ValueError(f"max_iter: must be a positive integer, got {max_iter!r}; or None for the default")
    if isinstance(initial, np.ndarray):  # a pressure field (Pa) to start from
        if initial.shape != shape or not np.all(np.isfinite(initial)) or np.any(initial < 0):
            raise ValueError(f"initial: a pressure start must be finite, >= 0 (Pa) and of the gap's shape {shape}, "
                             f"got shape {initial.shape}; e.g. an earlier solution's pressure")
    elif initial is not None and (getattr(initial, "pressure", None) is None or initial.pressure.shape != shape
                                  or tuple(initial.spacing) != spacing):
        got = getattr(getattr(initial, "pressure", None), "shape", None)
        raise ValueError("initial: must be a ContactSolution of the same shape and spacing as the gap (or its "
                         f"pressure array), got {type(initial).__name__} of shape {got}; solve once without "
                         "initial first")
    return ContactInputs(g0, spacing, bool(periodic), total, approach, mu, condition, Q, direction, method,
                         float(tol), int(max_iter), initial)


def _tangential(value, condition: str, ndim: int, mu: float, total: float | None, cell: float):
    if condition not in ("partial", "stuck"):
        if value is not None:
            raise ValueError(f"tangential_force: is for condition 'partial' or 'stuck', got {value!r} with "
                             f"condition={condition!r}; drop it, or change the condition")
        return None
    if value is None:
        raise ValueError(f"tangential_force: condition={condition!r} needs the total tangential force on the skin "
                         f"({'N/m' if ndim == 1 else '(Qx, Qy) in N'})")
    Q = np.atleast_1d(np.asarray(value, dtype=float))
    if Q.shape != (ndim,) or not np.all(np.isfinite(Q)):
        want = "one value in N/m" if ndim == 1 else "(Qx, Qy) in N"
        raise ValueError(f"tangential_force: expected {want}, finite, got {value!r}")
    if condition == "partial":
        if total is None:
            raise ValueError("tangential_force: a partial-slip contact needs normal_force or mean_pressure "
                             "(the friction limit mu P), not approach")
        limit = mu * total * cell
        if float(np.hypot.reduce(Q)) > limit * (1 + 1e-12):
            raise ValueError(f"tangential_force: |Q| = {float(np.hypot.reduce(Q)):g} exceeds the friction limit "
                             f"mu P = {limit:g}; the contact would slide: use condition='sliding', or lower Q / "
                             "raise friction")
    return tuple(float(q) for q in Q)


def _direction(value, ndim: int) -> tuple:
    d = np.asarray(value, dtype=float).ravel()
    if d.shape != (2,) or not np.all(np.isfinite(d)) or not np.hypot(*d) > 0:
        raise ValueError(f"slide_direction: expected a non-zero (dx, dy) direction, got {value!r}")
    if ndim == 1 and d[1] != 0:
        raise ValueError(f"slide_direction: a plane-strain contact slides along x only, got {value!r}; use (1, 0) "
                         "or (-1, 0)")
    return tuple(float(v) for v in d / np.hypot(*d))

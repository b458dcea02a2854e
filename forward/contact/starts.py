"""Where a contact solve starts: the grids, their operators and the starting pressures.

Every solve also solves the grid of twice the spacing (every other node, :func:`coarse_index`), the
check solve of the error estimate, whose solution comes back by linear interpolation
(:func:`prolong`). A cold check solve starts from a cascade of coarser grids (:func:`cascade`); a
warm one from the previous frame's check solution (:func:`coarse_start`); the solve itself from the
better of ``initial`` and the check solution (:func:`start_residual`). The grid operators are kept
for the next solve on an equal skin (:func:`grid_operator`).
"""

from __future__ import annotations

import collections

import numpy as np

from .compliance import ContactCompliance

#: the cold start's cascade of grids (:func:`cascade`): its tolerance and its smallest grid
CASCADE_TOL, CASCADE_MIN = 1e-4, 16


#: the last grid operators built (the grids of the last solve and its cascade), keyed by the skin's repr
_OPERATORS: collections.OrderedDict = collections.OrderedDict()


def grid_operator(skin, shape, spacing, periodic) -> ContactCompliance:
    """The grid operator, kept for the next solve on an equal skin and the same grid (a sequence of
    frames reuses its kernel spectra); keyed by the skin's type and repr (``HalfSpace(E=..., nu=...)``)."""
    key = (type(skin).__name__, repr(skin), tuple(shape), tuple(spacing), bool(periodic))
    if key in _OPERATORS:
        _OPERATORS.move_to_end(key)
        return _OPERATORS[key]
    operator = _OPERATORS[key] = ContactCompliance(skin, shape, spacing, periodic)
    while len(_OPERATORS) > 8:
        _OPERATORS.popitem(last=False)
    return operator


def coarse_index(shape) -> tuple[slice, ...]:
    """Every other node, keeping the origin node, so that the coarse grid is centred as SurfaceLoad centres it."""
    return tuple(slice((n // 2) % 2, None, 2) for n in shape)


def prolong(coarse: np.ndarray, shape, periodic: bool) -> np.ndarray:
    """Linear interpolation of a field on the coarse grid (every other node) onto the fine grid.

    Between two coarse nodes the mean of the two; beyond the last coarse node the nearest one
    (isolated) or the mean with the first node of the next period (periodic)."""
    out = coarse
    for axis, n in enumerate(shape):
        c = np.moveaxis(out, axis, 0)
        nxt = np.roll(c, -1, axis=0) if periodic else np.concatenate([c[1:], c[-1:]], axis=0)
        fine = np.empty((n,) + c.shape[1:])
        start = (n // 2) % 2
        fine[start::2] = c[: len(range(start, n, 2))]
        mid = 0.5 * (c + nxt)
        fine[start + 1::2] = mid[: len(range(start + 1, n, 2))]
        if start == 1:
            fine[0] = mid[-1] if periodic else c[0]
        out = np.moveaxis(fine, 0, axis)
    return np.ascontiguousarray(out)


def cascade(solver, skin, gap: np.ndarray, spacing, inp, total) -> np.ndarray:
    """A cold start for the solve of ``gap``: the frictionless solution on the grid of twice the
    spacing to the loose tolerance ``CASCADE_TOL`` (itself started this way), prolonged linearly;
    uniform below ``CASCADE_MIN`` nodes per axis. Each level costs a quarter of the one above, and
    a start within the discretisation error of the next grid is all a start can be."""
    if min(gap.shape) < 2 * CASCADE_MIN:
        return np.ones(gap.shape)
    sub = coarse_index(gap.shape)
    g = np.ascontiguousarray(gap[sub])
    h = tuple(2 * x for x in spacing)
    sub_total = None if total is None else total / 2 ** gap.ndim
    p0 = cascade(solver, skin, g, h, inp, sub_total)
    res = solver(grid_operator(skin, g.shape, h, inp.periodic), g, total=sub_total, approach=inp.approach,
                 tol=max(inp.tol, CASCADE_TOL), max_iter=inp.max_iter, p0=p0)
    return prolong(res.pressure, gap.shape, inp.periodic)


def start_residual(comp: ContactCompliance, g0: np.ndarray, p: np.ndarray, inp) -> float:
    """The normal solvers' gap residual (m) at the start ``p`` (scaled to the force): max |g| where
    ``p > 0``, max(-g) elsewhere. One compliance product."""
    if inp.total is not None:
        s = float(p.sum())
        p = p * (inp.total / s) if s > 0 else np.full(p.shape, inp.total / p.size)
    inside = p > 0
    g = g0 + comp.normal(p)
    delta = float(g[inside].mean()) if inp.approach is None and inside.any() else (inp.approach or 0.0)
    g -= delta
    return max(float(np.abs(g[inside]).max(initial=0.0)), float(-g[~inside].min(initial=0.0)))


def coarse_start(initial, shape) -> np.ndarray | None:
    """Start of the check solve on the grid of twice the spacing: the previous frame's own check
    solution when ``initial`` carries one of this shape, else None (then :func:`cascade`; the fine
    pressure's every other node is a worse start: the two grids' solutions differ by the
    discretisation error)."""
    previous = getattr(initial, "_coarse_pressure", None)
    if previous is not None and previous.shape == shape:
        return np.array(previous, dtype=float)
    return None

"""The facade's path for continuous loads: solve, bound the sampling error, refine the grid.

For a :class:`~.continuous.ContinuousLoad` the reported ``error_estimate`` is the chosen method's
estimate for the sampled nodal load plus the sampling error of representing the continuous load on
the grid: the smaller of two bounds, the Richardson bound from solves at spacing 2h and 4h
(:func:`~.continuous.sampling_error`, tight for rough loads) and the spectral bound from the load
sampled on a finer grid pushed through the depth's transfer (:func:`~.continuous.spectral_sampling_error`,
tight for smooth loads; skipped when the Richardson bound is already below the method's estimate).
When that finer sampling shows content beyond the grid's Nyquist wavenumber
(:func:`~.continuous.alias_check`), which aliases alike on the h, 2h and 4h grids, the Richardson
bound is not an upper bound: the spectral bound is computed and reported alone, and the halvings
the check shows to hold the content choose the refinement and the warning's grid.
Both are in the result's attributes (``sampling_richardson``, ``sampling_spectral``, NaN when
skipped); ``attrs["error_covers"]`` is ``"method+sampling"``. With ``method="auto"``, when the total exceeds
``tol``, the grid is refined (the spacing halved k times, k predicted from the observed convergence
order, then estimated again) as long as it stays within :data:`MAX_NODES`; otherwise an
:class:`AccuracyWarning` names the spacing predicted to meet ``tol``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from .continuous import (ALIAS_THRESHOLD, SPECTRAL_REFINEMENT, ContinuousLoad, alias_check, coarse_grid, refined_grid, sampling_error,
                         spectral_sampling_error)
from .fields import output_weights
from .methods import AccuracyWarning, user_stacklevel
from .solve import check_points, package, solve

#: largest grid (nodes) the automatic refinement of a continuous load may choose
MAX_NODES = 1 << 20
#: most refinement rounds (each: predict the halvings, refine, estimate again)
MAX_ROUNDS = 3


def _levels(E, nu, load: ContinuousLoad, shape, spacing, depths, comps, points, method, tol, quantity, invariants):
    """The solve on (shape, spacing) and the outputs at 2h and 4h (same points, or shared nodes)."""
    fine = load.sample(shape, spacing)
    pts = check_points(points, fine)
    sol = solve(E, nu, fine, depths, comps, pts, method, tol, quantity, invariants)
    levels, shapes = [sol.values], [fine.shape]
    grid = (fine.shape, fine.spacing)
    for _ in range(2):
        grid = coarse_grid(*grid, load.periodic)
        if grid is None:
            break
        coarse = load.sample(*grid)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", AccuracyWarning)
            try:
                v = solve(E, nu, coarse, depths, comps, pts, type(sol.chosen), tol, quantity, invariants).values
            except ValueError:  # the fine grid's method cannot run on the coarse one (off-grid sensors)
                v = solve(E, nu, coarse, depths, comps, pts, "auto", tol, quantity, invariants).values
        levels.append(v)
        shapes.append(coarse.shape)
    richardson, order = sampling_error(levels, None if pts is not None else shapes)
    aliased, alias_halvings, finer = alias_check(load, fine)
    trusted = aliased <= ALIAS_THRESHOLD  # content beyond Nyquist aliases alike on h, 2h, 4h: Richardson blind
    if trusted and richardson <= sol.err:  # the method's estimate dominates: the spectral one lowers it < 2x
        return fine, pts, sol, richardson, order, richardson, math.nan, alias_halvings
    weights = output_weights(sol.quantity, comps, E, nu)
    spectral = spectral_sampling_error(load, fine, depths, nu, weights, band_limited=sol.chosen.name == "spectral",
                                       peak=float(np.abs(sol.values).max()), fine=finer)
    sampling = min(richardson, spectral) if trusted else spectral
    return fine, pts, sol, sampling, order, richardson, spectral, alias_halvings


def _needed_halvings(total: float, target: float, order: float) -> int | None:
    """Halvings of the spacing predicted to bring ``total`` to ``target`` at the observed order
    (clipped to [1, 8]; 1 when unknown), or None when that cannot be predicted."""
    if not (target > 0 and math.isfinite(total) and total > target):
        return None
    p = min(max(order, 1.0), 8.0) if math.isfinite(order) else 1.0
    return max(1, math.ceil(math.log2(total / target) / p))


def continuous_field(E: float, nu: float, load: ContinuousLoad, depths, points, comps, method, tol, quantity,
                     invariants):
    """:meth:`HalfSpace.stress` / ``strain`` for a continuous load (see the module docstring).

    ``E`` (Pa) and ``nu`` are the half-space's; depths and components come checked.

    With ``method="auto"`` the grid is refined by the number of halvings predicted at the observed
    order, and the estimate recomputed on the new grid, for at most :data:`MAX_ROUNDS` rounds and
    :data:`MAX_NODES` nodes; the prediction only chooses the grid, the estimate on it decides.
    """
    shape, spacing = load.shape, load.spacing
    auto = isinstance(method, str) and method == "auto"
    refinements = rounds = 0
    while True:
        with warnings.catch_warnings(record=True) as caught:  # only the final grid's warnings reach the user
            warnings.simplefilter("always", AccuracyWarning)
            fine, pts, sol, sampling, order, richardson, spectral, alias_k = _levels(
                E, nu, load, shape, spacing, depths, comps, points, method, tol, quantity, invariants)
        total = sol.err + sampling
        # refining the grid shrinks the sampling error and the nodal methods' kernel-sampling error;
        # a load with content beyond the Nyquist box needs at least the halvings that bring it inside.
        # Where the finer sampling shows a grid that holds it, or the Richardson bound missed most of
        # the error (an alias sits alike on every nested grid), the observed order says nothing:
        # those halvings, and the estimate there, decide
        k = _needed_halvings(total, 0.5 * tol, order)
        if k is not None and alias_k != 0:
            steps = int(round(math.log2(SPECTRAL_REFINEMENT[fine.ndim])))
            if alias_k is None:  # content up to the fine grid's edge: at least that grid
                alias_k = steps if not richardson >= 0.1 * spectral else max(k, steps)
            k = alias_k
        if auto and k is not None and rounds < MAX_ROUNDS:
            new_shape, new_spacing = refined_grid(shape, spacing, load.periodic, k)
            if int(np.prod(new_shape)) <= MAX_NODES:
                shape, spacing = new_shape, new_spacing
                refinements, rounds = refinements + k, rounds + 1
                continue
        break
    for w in caught:
        warnings.warn(str(w.message), w.category, stacklevel=user_stacklevel())
    if total > tol and sampling > 0.5 * sol.err:
        _warn_sampling(sol, sampling, total, tol, shape, spacing, load, k)
    extra = {"sampling_order": order, "sampling_richardson": richardson, "sampling_spectral": spectral, "grid_refinements": refinements,
             "sampled_spacing_m": tuple(float(h) for h in fine.spacing)}
    return package(E, nu, fine, sol, depths, comps, pts, invariants, error_covers="method+sampling",
                   sampling_estimate=sampling, extra=extra)


def _warn_sampling(sol, sampling, total, tol, shape, spacing, load, k) -> None:
    if k is None:
        advice = "no finer grid is predicted to meet it; loosen tol"
    else:
        need_shape, need_spacing = refined_grid(shape, spacing, load.periodic, k)
        advice = (f"sampling the load at spacing {', '.join(f'{h:.3g}' for h in need_spacing)} m (shape "
                  f"{need_shape}, {int(np.prod(need_shape))} nodes) is predicted to meet it")
    warnings.warn(f"continuous load: error estimate {total:.1e} (sampling {sampling:.1e}, method {sol.err:.1e}) "
                  f"exceeds tol={tol:.0e} on the grid of spacing {', '.join(f'{h:.3g}' for h in spacing)} m; "
                  f"{advice}", AccuracyWarning, stacklevel=user_stacklevel())

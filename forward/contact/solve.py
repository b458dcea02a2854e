"""solve_contact: one function in front, a registry of normal-contact methods behind.

The steps (each on the grid and, for the error estimate, on the grid of twice the spacing):

1. the normal problem (:mod:`.normal`, Polonsky-Keer conjugate gradients) on the FFT compliance
   of the skin (:class:`ContactCompliance`, periodic or isolated);
2. friction: ``"sliding"`` sets ``q = mu p`` along the slide direction; at nu < 1/2 the normal
   displacement of that traction (the (1 - 2 nu) coupling) enters the gap, and the normal solve
   is repeated, warm-started, until the pressure stops changing; ``"partial"`` and ``"stuck"``
   solve the tangential problem (:mod:`.tangential`);
3. the error estimate: the solver's residual turned into a pressure bound, plus the difference
   between the solutions on the two grids (Richardson, order 1/2: the pressure's square-root
   edge), which also warm-starts the fine solve.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import ndimage

from ..halfspace import AccuracyWarning
from .compliance import ContactCompliance
from .inputs import check_inputs
from .normal import polonsky_keer
from .preconditioned import preconditioned_cg
from .solution import ContactSolution
from .starts import cascade, coarse_index, coarse_start, grid_operator, prolong, start_residual
from .tangential import solve_tangential

#: normal-contact methods by name; ``method="auto"`` picks ``"preconditioned_cg"``
METHODS = {"preconditioned_cg": preconditioned_cg, "polonsky_keer": polonsky_keer}
#: nodes across the largest contact patch below which an AccuracyWarning is raised
MIN_NODES_ACROSS = 8
#: Richardson factor for a pressure error of order h^(1/2): error(h) = diff / (sqrt(2) - 1)
RICHARDSON = 1.0 / (math.sqrt(2.0) - 1.0)
#: outer iterations of the normal-tangential coupling at nu < 1/2
MAX_COUPLING = 50


def solve_contact(skin, gap, spacing, *, normal_force=None, mean_pressure=None, approach=None, periodic=False,
                  friction=0.0, condition="frictionless", tangential_force=None, slide_direction=(1.0, 0.0),
                  method="auto", tol=1e-8, max_iter=None, initial=None, estimate_error=True) -> ContactSolution:
    """Solve the contact of the skin with a rigid surface.

    Conventions (docs/theory.md section 1): tractions act on the skin; ``p`` pushes into it;
    heights are positive towards the skin; ``uz`` is positive into the skin. The gap after
    loading is ``g = gap + uz - approach``; the solution has ``p >= 0``, ``g >= 0`` and
    ``p g = 0`` at every node.

    Parameters
    ----------
    skin : HalfSpace or a skin model with ``surface_compliance(kx, ky)``
        (and ``surface_influence`` for isolated contacts).
    gap : ndarray, shape (nx,) (plane strain) or (ny, nx)
        Initial separation (m) between the undeformed skin and the rigid surface at zero
        approach; for a fingertip on a texture ``r^2 / (2 R) - h(x, y)``. Node ``j`` sits at
        ``x_j = (j - nx // 2) dx`` (and likewise in y), as in ``SurfaceLoad``.
    spacing : float or (float, float)
        ``dx`` or ``(dx, dy)`` in m, x first.
    normal_force, mean_pressure, approach : float, optional
        Exactly one: total force on the skin (N; N/m in plane strain, > 0), the mean pressure of a
        periodic cell (Pa, > 0), or the rigid approach (m; isolated contacts only; at or below
        ``min(gap)`` the contact is empty, with a warning). In plane strain the displacement of
        a line load is defined up to a constant, taken as zero at one grid length from the load,
        so an approach there depends on the grid's length.
    periodic : bool
        True: the grid is one period (an even number of nodes per axis); False: an isolated
        contact (zero-padded, exact aperiodic convolution, as DC-FFT does).
    friction : float
        Coulomb coefficient mu >= 0 (inf only for ``"stuck"``).
    condition : {"frictionless", "sliding", "partial", "stuck"}
        As ``interfacial_traction`` names them.
    tangential_force : float or (float, float), optional
        Total tangential force on the skin for ``"partial"`` and ``"stuck"``: N/m in plane
        strain, ``(Qx, Qy)`` in N in 3-D.
    slide_direction : (float, float)
        For ``"sliding"``: the direction of the traction ON THE SKIN, x first; ``(1, 0)`` gives
        ``qx = +mu p`` (the sign convention of ``interfacial_traction``); in plane strain
        ``(1, 0)`` or ``(-1, 0)``.
    method : "auto", "preconditioned_cg", "polonsky_keer" or a callable
        ``"auto"`` is ``"preconditioned_cg"`` (:mod:`.preconditioned`); a callable takes the
        arguments of ``normal.polonsky_keer`` and returns a ``normal.NormalResult``.
    tol : float
        Relative gap residual: ``max |g|`` on the contact and ``max(-g)`` off it, at most
        ``tol * (max(gap) - min(gap))``.
    max_iter : int, optional
        Iteration limit of the normal solver (default 10000).
    initial : ContactSolution or ndarray, optional
        A solution of the same shape and spacing to start from, used as given (shift it yourself
        for a moving finger; ``dataclasses.replace(sol, pressure=...)``), or its pressure (Pa,
        shape of ``gap``; scaled to the force). The check solve on the grid of twice the spacing
        (the error estimate's) starts from ``initial``'s own check solution, which a
        ContactSolution carries privately (else from a cascade of coarser grids); the solve then
        starts from ``initial`` or from the check solve's solution, whichever has the smaller gap
        residual (one compliance product). Without ``initial`` the check solve starts from a
        cascade of coarser grids and its solution starts the solve.
    estimate_error : bool
        False: with ``initial`` given, skip the check solve (and its error estimate: the
        ``error_estimate`` and ``error_parts["discretisation"]`` are then NaN, "not estimated")
        and start from ``initial`` alone; the solution is the same to ``tol``. For repeated solves
        from a close start (an iteration's previous solution), where the check solve costs about
        as much as the solve. Without ``initial`` the check solve still runs (it is the start) and
        the estimate is reported.

    Returns
    -------
    ContactSolution

    Raises
    ------
    ValueError
        On any bad input (one line naming the argument, the rule, the value and the fix), and for
        a grid whose estimated memory exceeds half the available memory.

    Warns
    -----
    AccuracyWarning
        When the largest contact patch spans fewer than 8 nodes (naming the spacing that would
        do), when an isolated contact reaches the grid's outermost nodes (the grid is too small;
        naming a grid twice as wide), or when the solver did not converge.
    UserWarning
        When the approach leaves the contact empty.
    """
    inp = check_inputs(skin, gap, spacing, normal_force=normal_force, mean_pressure=mean_pressure,
                       approach=approach, periodic=periodic, friction=friction, condition=condition,
                       tangential_force=tangential_force, slide_direction=slide_direction, method=method, tol=tol,
                       max_iter=max_iter, initial=initial)
    solver = _method(inp.method)
    if inp.approach is not None and inp.approach <= float(inp.gap.min()):
        warnings.warn(f"approach: {inp.approach:g} m is at or below min(gap) = {float(inp.gap.min()):g} m, so "
                      "nothing touches: the contact is empty", UserWarning, stacklevel=2)
        return _empty(inp)
    fine = grid_operator(skin, inp.shape, inp.spacing, inp.periodic)
    coarse = None
    if min(inp.shape) >= 8 and (estimate_error or inp.initial is None):
        sub = coarse_index(inp.shape)
        c_comp = grid_operator(skin, inp.gap[sub].shape, tuple(2 * h for h in inp.spacing), inp.periodic)
        c_total = None if inp.total is None else inp.total / 2 ** len(inp.shape)
        c_gap = np.ascontiguousarray(inp.gap[sub])
        p0 = coarse_start(inp.initial, c_gap.shape)
        if p0 is None:
            p0 = cascade(solver, skin, c_gap, c_comp.spacing, inp, c_total)
        coarse = _solve_grid(solver, c_comp, c_gap, inp, c_total, p0)
    if inp.initial is not None:
        p0 = np.array(getattr(inp.initial, "pressure", inp.initial), dtype=float)
        if coarse is not None:  # the better start of the two (a shifted previous frame often is not)
            p1 = prolong(coarse["pressure"], inp.shape, inp.periodic)
            if start_residual(fine, inp.gap, p1, inp) < start_residual(fine, inp.gap, p0, inp):
                p0 = p1
    elif coarse is not None:
        p0 = prolong(coarse["pressure"], inp.shape, inp.periodic)
    else:
        p0 = np.ones(inp.shape)
    out = _solve_grid(solver, fine, inp.gap, inp, inp.total, p0)
    return _package(inp, fine, skin, out, coarse, estimated=coarse is not None or min(inp.shape) < 8)


def _method(method):
    if callable(method):
        return method
    name = "preconditioned_cg" if method == "auto" else method
    if name not in METHODS:
        raise ValueError(f"method: must be 'auto', one of {sorted(METHODS)} or a callable, got {method!r}")
    return METHODS[name]


def _solve_grid(solver, comp: ContactCompliance, g0: np.ndarray, inp, total, p0) -> dict:
    """Normal solve with the friction condition on one grid: pressure, tractions, masks and coupling."""
    res = solver(comp, g0, total=total, approach=inp.approach, tol=inp.tol, max_iter=inp.max_iter, p0=p0)
    iterations, coupling = res.iterations, {"force": 0.0, "area": 0.0}
    tangential_residual, converged = 0.0, res.converged
    mu, d = inp.friction, inp.direction
    qx, qy = np.zeros(g0.shape), (np.zeros(g0.shape) if g0.ndim == 2 else None)
    stick = np.zeros(g0.shape, dtype=bool)
    if inp.condition == "sliding":
        res0 = res
        if _coupled(comp):
            settled = False
            for _ in range(MAX_COUPLING):
                extra = _sliding_uz(comp, res.pressure, mu, d)
                new = solver(comp, g0, total=total, approach=inp.approach, tol=inp.tol, max_iter=inp.max_iter,
                             p0=res.pressure, extra_gap=extra)
                iterations += new.iterations
                change = float(np.abs(new.pressure - res.pressure).max())
                res = new
                settled = change <= inp.tol * float(res.pressure.max())
                if settled:
                    break
            coupling = _coupling(res0, res)
            converged = res.converged and settled
        qx = mu * d[0] * res.pressure
        if qy is not None:
            qy = mu * d[1] * res.pressure
    elif inp.condition in ("partial", "stuck"):
        res, tang, iterations, coupling, settled = _partial_or_stuck(solver, comp, g0, inp, total, res)
        qx, qy, stick = tang.qx, tang.qy, tang.stick
        tangential_residual = mu * tang.residual if math.isfinite(mu) else tang.residual
        converged = res.converged and tang.converged and settled
    contact = res.pressure > 0
    return dict(pressure=res.pressure, qx=qx, qy=qy, contact=contact, stick=stick & contact,
                slip=contact & ~stick, gap=np.maximum(res.gap, 0.0), approach=res.approach, iterations=iterations,
                converged=converged, residual=res.residual, coupling=coupling, tangential_residual=tangential_residual)


def _partial_or_stuck(solver, comp, g0, inp, total, res):
    """The tangential solve under the normal solution; at nu < 1/2, alternated with the normal solve
    (the tangential traction's normal displacement in the gap, the pressure change's tangential
    displacement in the tangential problem) until the pressure stops changing.

    Loading path (Mindlin's, the one Cattaneo-Mindlin describes): the normal load first, without
    tangential traction, then the tangential force. The tangential surface displacement that the first
    normal solution causes at nu < 1/2 is locked in before Q is applied (no slip measured from it);
    only the pressure change that Q causes enters the slip. Applying both loads together from rest would
    include the normal load's own (Spence) slip ring, which a fingertip pressed and then pulled does not
    see."""
    stuck = inp.condition == "stuck"
    kwargs = dict(stuck=stuck, tol=inp.tol, max_iter=inp.max_iter)
    tang = solve_tangential(comp, res.pressure, res.pressure > 0, inp.friction, inp.tangential_force, **kwargs)
    iterations, coupling = res.iterations + tang.iterations, {"force": 0.0, "area": 0.0}
    if not _coupled(comp):
        return res, tang, iterations, coupling, True
    res0, settled = res, False
    for _ in range(MAX_COUPLING):
        new = solver(comp, g0, total=total, approach=inp.approach, tol=inp.tol, max_iter=inp.max_iter,
                     p0=res.pressure, extra_gap=tang.normal_displacement)
        u_p = np.stack([u for u in comp.tangential_from_normal(new.pressure - res0.pressure) if u is not None])
        start = np.stack([q for q in (tang.qx, tang.qy) if q is not None])
        tang = solve_tangential(comp, new.pressure, new.pressure > 0, inp.friction, inp.tangential_force,
                                pressure_displacement=u_p, initial=start, **kwargs)
        iterations += new.iterations + tang.iterations
        change = float(np.abs(new.pressure - res.pressure).max())
        res = new
        settled = change <= inp.tol * float(res.pressure.max())
        if settled:
            break
    return res, tang, iterations, _coupling(res0, res), settled


def _coupled(comp: ContactCompliance) -> bool:
    """Whether tangential tractions move the surface normally (nu < 1/2 for a half-space)."""
    return bool(np.abs(comp.spectrum("uz", "qx")).max() > 0)


def _sliding_uz(comp, p, mu, d) -> np.ndarray:
    qy = mu * d[1] * p if p.ndim == 2 else None
    return comp.normal_from_tangential(mu * d[0] * p, qy)


def _coupling(uncoupled, coupled) -> dict:
    f0, f1 = float(uncoupled.pressure.sum()), float(coupled.pressure.sum())
    a0, a1 = int(np.count_nonzero(uncoupled.pressure)), int(np.count_nonzero(coupled.pressure))
    return {"force": (f1 - f0) / f0 if f0 else 0.0, "area": (a1 - a0) / a0 if a0 else 0.0}


def _solver_error(comp: ContactCompliance, skin, out: dict) -> float:
    """Bound on max |p error| / peak p from the gap residual: |dp| <= |A_II^-1| |g_res|_2.

    The smallest eigenvalue of the compliance is that of its largest wavenumber (the grid's corner),
    halved for the pixel averaging of an isolated grid."""
    k = [math.pi / h for h in comp.spacing]
    m = skin.surface_compliance(np.array(k[0]), None if len(k) == 1 else np.array(k[1]))
    lam = 0.5 * float(np.real(np.asarray(m)[..., 0, 0]))
    n_res = out["contact"].size
    peak = float(out["pressure"].max())
    if peak == 0 or lam <= 0:
        return 0.0 if peak == 0 else 1.0
    return out["residual"] * math.sqrt(n_res) / lam / peak


def _discretisation_error(inp, out: dict, coarse: dict | None) -> float:
    """Max difference between the solution and the one on the grid of twice the spacing, interpolated
    linearly onto this grid, relative to the peak pressure, times the Richardson factor of order 1/2.

    Against Hertz, the cylinder and Westergaard (tests/test_contact_normal.py) it is 1.1x to 10x the
    true error (the difference at the coinciding nodes alone was below it in some cases)."""
    peak = float(out["pressure"].max())
    if coarse is None or peak == 0:
        return 1.0 if peak else 0.0
    diff = 0.0
    for name in ("pressure", "qx", "qy"):
        if out[name] is not None and (name == "pressure" or inp.condition != "frictionless"):
            fine = prolong(coarse[name], inp.shape, inp.periodic)
            diff = max(diff, float(np.abs(out[name] - fine).max()))
    return RICHARDSON * diff / peak


def _resolution_warning(inp, contact: np.ndarray) -> None:
    if not contact.any():
        return
    labels, n = ndimage.label(contact)
    largest = int(np.bincount(labels.ravel())[1:].max())
    across = largest if contact.ndim == 1 else 2.0 * math.sqrt(largest / math.pi)
    if across < MIN_NODES_ACROSS:
        h = min(inp.spacing)
        warnings.warn(f"spacing: the largest contact patch spans only {across:.1f} nodes at {h:g} m; a spacing of "
                      f"{h * across / MIN_NODES_ACROSS:.3g} m or finer resolves it to {MIN_NODES_ACROSS} nodes "
                      "(see error_estimate)", AccuracyWarning, stacklevel=3)


def _edge_warning(inp, contact: np.ndarray) -> None:
    """An isolated contact must lie inside the grid (the traction is zero outside it): warn when it
    reaches the outermost ring of nodes, naming a grid twice as wide."""
    if inp.periodic or not contact.any():
        return
    edge = contact.copy()
    edge[tuple(slice(1, -1) for _ in contact.shape)] = False
    if edge.any():
        nodes = int(np.count_nonzero(edge))
        bigger = " x ".join(str(2 * n) for n in reversed(contact.shape))
        warnings.warn(f"gap: the isolated contact reaches the grid's edge ({nodes} contact nodes on the outermost "
                      f"ring), so the grid is too small and the traction beyond it is missing; solve on a grid of "
                      f"{bigger} nodes (x first) at this spacing, or a coarser spacing", AccuracyWarning, stacklevel=3)


def _package(inp, comp, skin, out: dict, coarse: dict | None, estimated: bool = True) -> ContactSolution:
    parts = {"solver": _solver_error(comp, skin, out) + out["tangential_residual"],
             "discretisation": _discretisation_error(inp, out, coarse) if estimated else math.nan}
    _resolution_warning(inp, out["contact"])
    _edge_warning(inp, out["contact"])
    if not out["converged"]:
        warnings.warn(f"max_iter: the solver stopped after {out['iterations']} iterations short of tol (gap residual "
                      f"{out['residual']:.3g} m; or the tangential solve, or the normal-tangential coupling, did "
                      "not settle); raise max_iter or tol", AccuracyWarning, stacklevel=3)
    force = float(out["pressure"].sum()) * math.prod(inp.spacing)
    return ContactSolution(pressure=out["pressure"], qx=out["qx"], qy=out["qy"], contact=out["contact"],
                           stick=out["stick"], slip=out["slip"], gap=out["gap"], spacing=inp.spacing,
                           periodic=inp.periodic, normal_force=force, approach=out["approach"],
                           iterations=out["iterations"], converged=out["converged"],
                           error_estimate=parts["solver"] + parts["discretisation"], error_parts=parts,
                           coupling=out["coupling"], method=getattr(_method(inp.method), "__name__", "custom"),
                           condition=inp.condition, friction=inp.friction,
                           _coarse_pressure=None if coarse is None else coarse["pressure"])


def _empty(inp) -> ContactSolution:
    zeros = np.zeros(inp.shape)
    none = np.zeros(inp.shape, dtype=bool)
    return ContactSolution(pressure=zeros, qx=zeros.copy(), qy=zeros.copy() if zeros.ndim == 2 else None,
                           contact=none, stick=none.copy(), slip=none.copy(), gap=inp.gap - inp.approach,
                           spacing=inp.spacing, periodic=inp.periodic, normal_force=0.0, approach=inp.approach,
                           iterations=0, converged=True, error_estimate=0.0,
                           error_parts={"solver": 0.0, "discretisation": 0.0}, coupling={"force": 0.0, "area": 0.0},
                           method=str(inp.method), condition=inp.condition, friction=inp.friction)

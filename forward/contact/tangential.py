"""Partial slip and stuck contact: the tangential traction under a given pressure.

:func:`solve_tangential` finds the tangential traction ``q`` on the skin (Pa) for a given normal
solution (pressure ``p`` and contact mask), a Coulomb coefficient ``mu`` and a total tangential
force ``Q`` (N in 3-D, N/m in plane strain), on the grid of a
:class:`~tactilab.forward.contact.ContactCompliance` (periodic or isolated, ``(ny, nx)`` or ``(nx,)``).

Sign convention (that of :func:`~tactilab.forward.contact.interfacial_traction`): ``q`` acts on the
skin. The rigid surface is displaced tangentially by the rigid shift ``s`` (m) relative to the
skin's far field; the skin's surface moves by ``u_t`` (m). The slip of the skin relative to the
surface is ``u_t - s`` and friction drags the skin along the surface's motion:

- stick zone: ``u_t = s`` (no slip) and ``|q| < mu p``;
- slip zone: ``|q| = mu p`` and ``q = mu p (s - u_t) / |s - u_t|`` (``q`` opposes the skin's slip);
- ``q = 0`` outside the contact, and ``sum(q) dA = Q``.

A surface sliding along +x over the skin gives ``qx = +mu p``, as ``interfacial_traction`` says.
The slip is counted from the unloaded state (one loading step): exact for a monotonic tangential
load, as in Cattaneo--Mindlin and Ciavarella--Jaeger. ``"stuck"`` (``mu = inf``) has no slip zone:
``u_t = s`` over the whole contact (Mindlin's no-slip solution).

Algorithm: these conditions are the optimality conditions of the convex problem::

    min_q  1/2 q.C q + q.u_p    subject to  |q_i| <= mu p_i  and  sum_i q_i dA = Q

with ``C`` the tangential surface compliance, ``u_p`` the tangential displacement produced by the
pressure (0 at nu = 1/2) and ``s`` the Lagrange multiplier of the force. We solve it with an
accelerated projected gradient (FISTA, Beck and Teboulle 2009, with O'Donoghue and Candes' adaptive
restart), whose projection is exact: a node's traction is clipped to its friction disc after a
common shift ``lambda`` found by a damped semismooth Newton iteration, so that every iterate
satisfies Coulomb and carries exactly ``Q``. Why this and not an active-set (Polonsky--Keer-like)
method: the friction constraint is a disc per node in 3-D, not a one-sided bound, and the slip
direction is itself unknown; projection onto discs is exact and cheap, the method converges for
any convex data (no stick/slip set heuristics), costs one compliance product per iteration
(``C`` at the extrapolated point is a combination of two stored products), and its iteration
count grows like the square root of the contact's width in nodes. The step is ``1 / L`` with
``L`` the largest eigenvalue of ``C`` on the contact (power iteration). ``"stuck"`` is a linear
problem (no bound): conjugate gradients on the contact nodes with the force held fixed.

Normal-tangential coupling (nu < 1/2): pass the tangential displacement produced by the pressure
(``pressure_displacement``, :meth:`ContactCompliance.tangential_from_normal`); the result
carries the normal displacement produced by ``q`` (``normal_displacement``,
:meth:`ContactCompliance.normal_from_tangential`) for the normal solve's gap. The caller
alternates the two solves until the pressure stops changing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .hertz import _check_friction

#: relative margin below the friction bound under which a contact node counts as stuck
STICK_MARGIN = 1e-6


@dataclass(frozen=True)
class TangentialSolution:
    """The tangential traction of a partial-slip or stuck contact (see the module docstring).

    Attributes
    ----------
    qx, qy : ndarray, grid shape
        Tangential traction on the skin along +x, +y in Pa; ``qy`` is None in plane strain.
    stick, slip : ndarray of bool, grid shape
        Contact nodes with ``|q| < mu p (1 - STICK_MARGIN)``, and the others (``|q| = mu p``).
    shift : ndarray, shape (1,) or (2,)
        Rigid tangential shift ``s`` of the surface relative to the skin's far field, m (x, y);
        defined up to the compliance's rigid-body constant (periodic: the mean displacement).
    displacement : ndarray, shape (1 or 2,) + grid shape
        Tangential surface displacement ``u_t`` in m, including the pressure's part.
    normal_displacement : ndarray, grid shape
        Normal surface displacement (m, into the skin) produced by ``q``: 0 at nu = 1/2.
    iterations : int
        Compliance products of the iteration (the power iteration's not counted).
    converged : bool
        Whether ``residual <= tol``.
    residual : float
        Optimality residual: the largest change of one projected gradient step, over ``mu max(p)``
        (partial), or the largest slip in the contact over the largest displacement (stuck).
    """

    qx: np.ndarray
    qy: np.ndarray | None
    stick: np.ndarray
    slip: np.ndarray
    shift: np.ndarray
    displacement: np.ndarray
    normal_displacement: np.ndarray
    iterations: int
    converged: bool
    residual: float


def solve_tangential(compliance, pressure, contact, friction, tangential_force, *, stuck: bool = False,
                     pressure_displacement=None, tol: float = 1e-8, max_iter: int | None = None,
                     initial=None) -> TangentialSolution:
    """Tangential traction for a partial-slip (``stuck=False``) or stuck contact under a given pressure.

    Parameters
    ----------
    compliance : ContactCompliance
        The grid's surface compliance (shape ``(nx,)`` or ``(ny, nx)``, spacing, periodic or not).
    pressure : ndarray, grid shape
        Contact pressure ``p >= 0`` in Pa (the normal solution).
    contact : ndarray of bool, grid shape
        The contact nodes (where the tangential traction may be non-zero).
    friction : float
        Coulomb coefficient ``mu >= 0``; ``inf`` only with ``stuck=True`` (then ignored).
    tangential_force : float or sequence of float
        Total tangential force on the skin: ``Qx`` in N/m (plane strain) or ``(Qx, Qy)`` in N (3-D).
        Partial slip needs ``|Q| <= mu P`` with ``P = sum(p) dA``; ``|Q| = mu P`` is full sliding.
    stuck : bool
        True: no slip anywhere in the contact (Mindlin's no-slip solution).
    pressure_displacement : ndarray, shape (1 or 2,) + grid shape, optional
        Tangential surface displacement (m) produced by the pressure, for nu < 1/2; None: zero.
    tol : float
        Stop when ``residual <= tol`` (see :class:`TangentialSolution`).
    max_iter : int, optional
        Most compliance products (default 5000).
    initial : ndarray, shape (1 or 2,) + grid shape, optional
        A traction (Pa) to start from (a warm start); made admissible before use.

    Returns
    -------
    TangentialSolution

    Raises
    ------
    ValueError
        For a bad shape, a NaN or negative pressure, ``mu < 0`` or NaN, ``mu = inf`` without ``stuck``,
        a force that is not finite or (partial slip) above ``mu P``, or ``tol`` / ``max_iter`` out of range.
    """
    shape, dims = tuple(compliance.shape), compliance.ndim
    p = _grid(pressure, "pressure", shape)
    if np.any(p < 0):
        raise ValueError(f"pressure: must be >= 0 Pa (it pushes into the skin), min {p.min():g} Pa; "
                         f"pass the normal solution's pressure")
    mask = np.asarray(contact)
    if mask.shape != shape or mask.dtype != bool:
        raise ValueError(f"contact: expected a bool mask of the grid's shape {shape}, got "
                         f"{mask.dtype} {mask.shape}; pass the normal solution's contact mask")
    mu = math.inf if stuck else _check_friction(friction)
    if math.isinf(mu) and not stuck:
        raise ValueError("friction: partial slip needs a finite friction coefficient, got inf; "
                         "use condition='stuck' for mu -> infinity")
    Q = _force(tangential_force, dims)
    if not (tol > 0 and math.isfinite(tol)):
        raise ValueError(f"tol: must be finite and > 0, got {tol!r}; the default is 1e-8")
    max_iter = 5000 if max_iter is None else int(max_iter)
    if max_iter < 1:
        raise ValueError(f"max_iter: must be >= 1, got {max_iter}; None picks 5000")
    d = 1 if dims == 1 else 2
    offset = np.zeros((d,) + shape) if pressure_displacement is None else \
        _grid(pressure_displacement, "pressure_displacement", (d,) + shape)
    start = None if initial is None else _grid(initial, "initial", (d,) + shape)
    area = float(np.prod(compliance.spacing))
    nodes = np.nonzero(mask)
    bound = mu * p[nodes]
    total = float(p[nodes].sum()) * area
    if not stuck and np.linalg.norm(Q) > mu * total * (1 + 1e-12):
        raise ValueError(f"tangential_force: |Q| = {np.linalg.norm(Q):g} exceeds the friction limit mu P = "
                         f"{mu * total:g} (mu = {mu:g}, P = {total:g}); the contact slides: use "
                         f"condition='sliding', or lower the force / raise the friction")
    if stuck and not nodes[0].size and np.any(Q != 0):
        raise ValueError("contact: a stuck contact with a tangential force needs at least one contact node")

    def apply(q_nodes: np.ndarray) -> np.ndarray:  # (n, d) nodal traction -> (n, d) displacement
        grids = [np.zeros(shape) for _ in range(d)]
        for j in range(d):
            grids[j][nodes] = q_nodes[:, j]
        u = compliance.tangential(*grids)
        return np.stack([u[j][nodes] for j in range(d)], axis=1)

    u_p = np.stack([offset[j][nodes] for j in range(d)], axis=1)
    q0 = None if start is None else np.stack([start[j][nodes] for j in range(d)], axis=1)
    if not nodes[0].size or (not stuck and not np.any(bound)):  # no traction possible (Q = 0 checked)
        q, s, its, res = np.zeros((nodes[0].size, d)), np.zeros(d), 0, 0.0
    elif stuck:
        q, s, its, res = _stuck(apply, area, Q, u_p, q0, tol, max_iter)
    elif np.any(Q) and np.linalg.norm(Q) >= mu * total * (1 - 1e-12):  # full sliding: the only admissible q
        q, s, its, res = bound[:, None] * (Q / np.linalg.norm(Q))[None, :], np.zeros(d), 0, 0.0
    else:
        q, s, its, res = _partial(apply, bound, area, Q, u_p, q0, tol, max_iter)
    q_grid = np.zeros((d,) + shape)
    for j in range(d):
        q_grid[j][nodes] = q[:, j]
    u = np.stack(compliance.tangential(*q_grid), axis=0) if d == 2 else compliance.tangential(q_grid[0])[0][None]
    uz = compliance.normal_from_tangential(*q_grid) if d == 2 else compliance.normal_from_tangential(q_grid[0])
    stick = np.zeros(shape, dtype=bool)
    stick[nodes] = np.hypot.reduce(q, axis=1) < bound * (1 - STICK_MARGIN) if d == 2 else \
        np.abs(q[:, 0]) < bound * (1 - STICK_MARGIN)
    return TangentialSolution(qx=q_grid[0], qy=q_grid[1] if d == 2 else None, stick=stick, slip=mask & ~stick,
                              shift=s, displacement=u + offset, normal_displacement=uz, iterations=its,
                              converged=bool(res <= tol), residual=float(res))


def _grid(value, name: str, shape: tuple) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"{name}: expected shape {shape} (the grid), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: must be finite, got {int(np.sum(~np.isfinite(arr)))} NaN or inf value(s); "
                         f"check the normal solution or the input")
    return arr


def _force(value, dims: int) -> np.ndarray:
    unit, want = ("N/m", "a number Qx") if dims == 1 else ("N", "a pair (Qx, Qy)")
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    if arr.shape != (1 if dims == 1 else 2,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"tangential_force: expected {want} of finite forces in {unit} on this "
                         f"{'plane-strain' if dims == 1 else '3-D'} grid, got {value!r}")
    return arr


def _project(z: np.ndarray, bound: np.ndarray, area: float, Q: np.ndarray, lam: np.ndarray):
    """Euclidean projection of ``z`` (n, d) onto {|q_i| <= bound_i} and {sum q area = Q}.

    The projection is ``q_i = clip_i(z_i + lam)`` with the shift ``lam`` (d,) the root of
    ``F(lam) = area sum clip_i(z_i + lam) - Q``, the gradient of the convex function
    ``phi(lam) = area sum (|x|^2 - dist(x, disc_i)^2) / 2 - Q.lam`` (``x = z_i + lam``): damped
    semismooth Newton on ``phi`` from the previous ``lam``. Returns ``(q, lam)``.
    """
    d = z.shape[1]
    scale = area * float(bound.sum())
    lam = lam.copy()

    def state(lam):
        x = z + lam
        norm = np.abs(x[:, 0]) if d == 1 else np.hypot(x[:, 0], x[:, 1])
        out = norm > bound
        ratio = np.where(out, bound / np.where(out, norm, 1.0), 1.0)
        q = x * ratio[:, None]
        excess = np.where(out, norm - bound, 0.0)
        phi = area * 0.5 * float(np.sum(x * x) - np.sum(excess * excess)) - float(Q @ lam)
        return x, norm, out, ratio, q, area * q.sum(axis=0) - Q, phi

    x, norm, out, ratio, q, F, phi = state(lam)
    for _ in range(100):
        if np.max(np.abs(F)) <= 1e-13 * scale:
            break
        # generalised Jacobian of F: identity inside a disc, (b/|x|)(I - n n^T) outside
        J = np.eye(d) * area * (np.sum(~out) + (np.sum(ratio[out]) if d == 2 else 0.0))
        if d == 2 and out.any():
            n = x[out] / norm[out, None]
            J -= area * np.einsum("i,ij,ik->jk", ratio[out], n, n)
        J += np.eye(d) * 1e-12 * area * len(bound)  # keeps J invertible when every node is clipped
        step = -np.linalg.solve(J, F)
        t, size = 1.0, float(np.max(np.abs(F)))
        for _ in range(40):  # a smaller residual, or Armijo's decrease of the convex merit phi
            trial = state(lam + t * step)
            if float(np.max(np.abs(trial[-2]))) < size or trial[-1] <= phi + 1e-4 * t * float(F @ step):
                break
            t *= 0.5
        else:
            break  # no progress at round-off level: lam is as good as it gets
        lam = lam + t * step
        x, norm, out, ratio, q, F, phi = trial
    return q, lam


def _partial(apply, bound, area, Q, u_p, q0, tol, max_iter):
    """FISTA with adaptive restart on min 1/2 q.C q + q.u_p over the friction discs and the force."""
    n, d = u_p.shape
    v = np.repeat(bound[:, None], d, axis=1)  # smooth, positive: close to the top eigenvector
    L, products = 0.0, 0
    for _ in range(30):  # power iteration for the largest eigenvalue of C on the contact
        w = apply(v / np.linalg.norm(v))
        products += 1
        L_new = float(np.sum(w * v) / np.linalg.norm(v))
        v = w
        if abs(L_new - L) <= 1e-3 * L_new:
            break
        L = L_new
    L = 1.05 * max(L_new, L)
    lam = np.zeros(d)
    q, lam = _project(np.zeros((n, d)) if q0 is None else q0, bound, area, Q, lam)
    u = apply(q) + u_p
    y, u_y, t, res, its = q, u, 1.0, math.inf, 0
    top = float(bound.max())
    while its < max_iter:
        q_new, lam = _project(y - u_y / L, bound, area, Q, lam)
        u_new = apply(q_new) + u_p
        its += 1
        res = float(np.max(np.abs(q_new - y))) / top
        if float(np.sum((y - q_new) * (q_new - q))) > 0:  # the momentum points uphill: restart
            t = 1.0
        t_new = 0.5 * (1.0 + math.sqrt(1.0 + 4.0 * t * t))
        beta = (t - 1.0) / t_new
        y, u_y = q_new + beta * (q_new - q), u_new + beta * (u_new - u)  # C is linear: no product for y
        q, u, t = q_new, u_new, t_new
        if res <= tol:
            break
    return q, lam * L, its, res


def _stuck(apply, area, Q, u_p, q0, tol, max_iter):
    """Conjugate gradients for C q + u_p = s on the contact nodes with sum(q) area = Q."""
    n, d = u_p.shape
    q = np.repeat((Q / (area * n))[None, :], n, axis=0)
    if q0 is not None:
        q = q0 + (Q - area * q0.sum(axis=0))[None, :] / (area * n)
    u = apply(q) + u_p
    r = u.mean(axis=0) - u  # minus the zero-mean part of the gradient: the slip, reversed
    scale = max(float(np.max(np.abs(u))), 1e-300)
    direction, rr, its = r.copy(), float(np.sum(r * r)), 0
    res = float(np.max(np.abs(r))) / scale
    while res > tol and its < max_iter:
        w = apply(direction)
        its += 1
        u += (alpha := rr / float(np.sum(direction * w))) * w
        q += alpha * direction
        r -= alpha * (w - w.mean(axis=0))
        rr_new = float(np.sum(r * r))
        direction = r + (rr_new / rr) * direction
        rr = rr_new
        res = float(np.max(np.abs(r))) / scale
    return q, u.mean(axis=0), its, res

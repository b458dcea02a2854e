"""The quadratic program of Coulomb friction on a grid: projection, accelerated gradient, Newton.

:func:`~tactilab.forward.contact.tangential.solve_tangential` reduces partial slip to::

    min_q  1/2 q.C q + q.u_p    subject to  |q_i| <= b_i  and  sum_i q_i dA = Q

over the contact nodes (``q`` of shape (n, d), d = 1 in plane strain, 2 in 3-D; ``b = mu p``;
``C`` the tangential compliance as a function ``apply(q) -> C q``). Its optimality conditions are
the stick / slip conditions with the rigid shift ``s`` as the force's multiplier. The solver here
runs in two phases:

1. FISTA (Beck and Teboulle 2009) with O'Donoghue and Candes' gradient restart and the exact
   projection of :func:`project`, until the optimality residual is below ``switch``: every
   iterate obeys Coulomb and carries ``Q`` exactly, and the stick and slip sets settle within a
   few tens of products, but its linear rate then costs hundreds more.
2. Semismooth Newton on the settled sets: the stick tractions and the slip directions (one angle
   per slip node) move together, the force held by a projection; the Newton system is solved by
   conjugate gradients, its matrix ``C`` on the free variables plus ``|slip| / b`` on each slip
   node's angle (the friction disc's curvature). A step that does not halve the residual is
   rejected and FISTA resumes with a tighter switch, so the method cannot do worse than FISTA.

Measured on a Hertz contact (radius a quarter of the grid) at Q/(mu P) = 0.5, tol 1e-8: 73 / 96 /
101 compliance products at 64^2 / 128^2 / 256^2 (FISTA alone: 113 / 347 / 962; without the Jacobi
preconditioner of the Newton system: 78 / 127 / 201).

The residual is ``max |q - P(q - (u - s) / L)| / max |q|``: the change of one projected gradient
step of length ``1 / L`` (``L`` the largest eigenvalue of ``C`` on the contact), relative to the
largest traction (so that a small force is solved as accurately as a large one); 0 exactly at
the solution.
"""

from __future__ import annotations

import math

import numpy as np


def project(z: np.ndarray, bound: np.ndarray, area: float, Q: np.ndarray, lam: np.ndarray):
    """Euclidean projection of ``z`` (n, d) onto {|q_i| <= bound_i} and {sum q area = Q}.

    The projection is ``q_i = clip_i(z_i + lam)`` with the shift ``lam`` (d,) the root of
    ``F(lam) = area sum clip_i(z_i + lam) - Q``, the gradient of the convex function
    ``phi(lam) = area sum (|x|^2 - dist(x, disc_i)^2) / 2 - Q.lam`` (``x = z_i + lam``): semismooth
    Newton from ``lam``, with Armijo backtracking on ``phi`` when a full step does not shrink ``F``.
    Returns ``(q, lam)``.
    """
    d = z.shape[1]
    small = 1e-13 * area * float(bound.sum())

    def clip(lam):
        x = z + lam
        norm = np.abs(x[:, 0]) if d == 1 else np.sqrt(x[:, 0] * x[:, 0] + x[:, 1] * x[:, 1])
        ratio = np.minimum(1.0, bound / np.maximum(norm, 1e-300))
        q = x * ratio[:, None]
        return x, norm, ratio, q, area * q.sum(axis=0) - Q

    def phi(x, norm):
        excess = np.maximum(norm - bound, 0.0)
        return area * 0.5 * float(np.sum(x * x) - np.sum(excess * excess)) - float(Q @ (x[0] - z[0]))

    x, norm, ratio, q, F = clip(lam)
    for _ in range(100):
        size = float(np.max(np.abs(F)))
        if size <= small:
            break
        # generalised Jacobian of F: identity inside a disc, (b/|x|)(I - n n^T) outside
        if d == 1:
            J = np.array([[area * float(np.sum(ratio >= 1.0))]])
        else:
            out = ratio < 1.0
            w = ratio[out] / np.maximum(norm[out] * norm[out], 1e-300)
            xo, yo = x[out, 0], x[out, 1]
            inside = float(np.sum(~out))
            J = area * np.array([[inside + float(np.sum(w * yo * yo)), -float(np.sum(w * xo * yo))],
                                 [-float(np.sum(w * xo * yo)), inside + float(np.sum(w * xo * xo))]])
        J += np.eye(d) * 1e-12 * area * len(bound)  # invertible even when every node is clipped
        step = -np.linalg.solve(J, F)
        trial = clip(lam + step)
        if float(np.max(np.abs(trial[-1]))) >= size:  # backtrack on the convex merit phi
            base, slope, t = phi(x, norm), float(F @ step), 1.0
            for _ in range(40):
                if phi(trial[0], trial[1]) <= base + 1e-4 * t * slope:
                    break
                t *= 0.5
                trial = clip(lam + t * step)
            else:
                break  # no progress at round-off level: lam is as good as it gets
            step = t * step
        lam = lam + step
        x, norm, ratio, q, F = trial
    return q, lam


def largest_eigenvalue(apply, start: np.ndarray) -> tuple[float, int]:
    """Power iteration for the largest eigenvalue of ``C`` (to 1e-3, times 1.05): ``(L, products)``."""
    v, L, products = start, 0.0, 0
    for _ in range(30):
        w = apply(v / np.linalg.norm(v))
        products += 1
        L_new = float(np.sum(w * v) / np.linalg.norm(v))
        v = w
        if abs(L_new - L) <= 1e-3 * L_new:
            break
        L = L_new
    return 1.05 * max(L_new, L), products


def residual(q, u, bound, area, Q, L) -> tuple[float, np.ndarray]:
    """Optimality residual at ``q`` (``u = C q + u_p``) and the shift ``s`` (module docstring)."""
    step, lam = project(q - u / L, bound, area, Q, np.zeros(q.shape[1]))
    return float(np.max(np.abs(step - q))) / _size(q), lam * L


def _size(q: np.ndarray) -> float:
    """The largest traction component, the residual's unit (1e-300 for q = 0: a zero step stays 0)."""
    return max(float(np.max(np.abs(q))), 1e-300)


def solve_partial(apply, bound, area, Q, u_p, q0, tol, max_products):
    """Minimise over the friction discs and the force (module docstring): ``(q, s, products, residual)``."""
    n, d = u_p.shape
    L, products = largest_eigenvalue(apply, np.repeat(bound[:, None], d, axis=1))
    unit = np.zeros((n, d))
    unit[0, 0] = 1.0
    diagonal = float(apply(unit)[0, 0])  # the same at every node: the operator is translation invariant
    products += 1
    q, _ = project(np.zeros((n, d)) if q0 is None else q0, bound, area, Q, np.zeros(d))
    u = apply(q) + u_p
    products += 1
    res, s = residual(q, u, bound, area, Q, L)
    switch = 1e-4
    while res > tol and products < max_products:
        q, u, used = _fista(apply, bound, area, Q, u_p, q, u, L, max(tol, switch), max_products - products)
        products += used
        res, s = residual(q, u, bound, area, Q, L)
        while tol < res and products < max_products:
            step = _newton_step(apply, bound, area, Q, q, u - s, diagonal, max_products - products)
            if step is None:  # no free variable to move (every node slips, in plane strain): FISTA to the end
                switch = 0.0
                break
            q_new, used = step
            u_new = apply(q_new) + u_p
            products += used + 1
            res_new, s_new = residual(q_new, u_new, bound, area, Q, L)
            if res_new > 0.5 * res:  # not a Newton step's progress: back to FISTA, tighter
                switch = min(switch, res) * 0.1
                break
            q, u, res, s = q_new, u_new, res_new, s_new
    return q, s, products, res


def _fista(apply, bound, area, Q, u_p, q, u, L, tol, max_products):
    """FISTA with adaptive restart from ``(q, u)`` until one step changes q by <= tol max |q|."""
    lam = np.zeros(q.shape[1])
    y, u_y, t, products = q, u, 1.0, 0
    while products < max_products:
        q_new, lam = project(y - u_y / L, bound, area, Q, lam)
        u_new = apply(q_new) + u_p
        products += 1
        change = float(np.max(np.abs(q_new - y))) / _size(q_new)
        if float(np.sum((y - q_new) * (q_new - q))) > 0:  # the momentum points uphill: restart
            t = 1.0
        t_new = 0.5 * (1.0 + math.sqrt(1.0 + 4.0 * t * t))
        beta = (t - 1.0) / t_new
        y, u_y = q_new + beta * (q_new - q), u_new + beta * (u_new - u)  # C is linear: no product for y
        q, u, t = q_new, u_new, t_new
        if change <= tol:
            break
    return q, u, products


def _newton_step(apply, bound, area, Q, q, slip, diagonal, max_products):
    """One semismooth Newton step on the current stick / slip sets; ``slip = u - s`` at ``q``.

    Variables: the full traction change on stick nodes, a tangential amplitude ``eta`` on slip nodes
    (``dq = eta t``, ``t`` the unit tangent of the disc). Conjugate gradients on the subspace where
    the force is unchanged, Jacobi-preconditioned (``diagonal``: the compliance at zero offset), to a
    relative residual of 1e-3. Returns ``(q_new, products)`` or None.
    """
    n, d = q.shape
    norm = np.sqrt(np.sum(q * q, axis=1))
    at_bound = norm >= bound * (1 - 1e-12)
    normal = np.zeros_like(q)
    normal[at_bound] = q[at_bound] / norm[at_bound, None]
    radial = np.sum(slip * normal, axis=1)
    B = at_bound & (radial < 0)  # slipping against q: stays on its disc
    S = ~B
    tangent = np.stack([-normal[:, 1], normal[:, 0]], axis=1) if d == 2 else np.zeros_like(q)
    curvature = np.where(B, -radial / np.maximum(bound, 1e-300), 0.0)
    ring = d == 2 and bool(B.any())

    def expand(x):  # variables -> traction change
        dq = np.where(S[:, None], x, 0.0)
        if ring:
            dq[B] = x[B, :1] * tangent[B]
        return dq

    def reduce(v):  # the adjoint of expand
        out = np.where(S[:, None], v, 0.0)
        if ring:
            out[B, 0] = np.sum(v[B] * tangent[B], axis=1)
        return out

    gram = np.eye(d) * float(S.sum()) + (tangent[B].T @ tangent[B] if ring else 0.0)
    if np.linalg.det(gram) <= 0:
        return None

    def keep_force(x):  # orthogonal projection onto {sum(expand(x)) = 0}
        c = np.linalg.solve(gram, expand(x).sum(axis=0))
        return x - reduce(np.broadcast_to(c, (n, d)))

    def hessian(x):
        y = reduce(apply(expand(x)))
        if ring:
            y[B, 0] += curvature[B] * x[B, 0]
        return keep_force(y)

    # Jacobi preconditioner: the compliance's diagonal, plus the curvature on a slip node's angle
    scale = np.full((n, d), diagonal)
    if ring:
        scale[B, 0] += curvature[B]

    def precondition(v):
        return keep_force(v / scale)

    r = -keep_force(reduce(slip))
    z = precondition(r)
    x, direction, rz, products = np.zeros_like(q), z.copy(), float(np.sum(r * z)), 0
    target = 1e-6 * rz
    while rz > target and products < max_products:
        w = hessian(direction)
        products += 1
        curv = float(np.sum(direction * w))
        if curv <= 0:
            break
        alpha = rz / curv
        x += alpha * direction
        r -= alpha * w
        z = precondition(r)
        rz_new = float(np.sum(r * z))
        direction = z + (rz_new / rz) * direction
        rz = rz_new
    dq = expand(x)
    q_new = q + np.where(S[:, None], dq, 0.0)
    if ring:  # rotate on the disc
        z = q[B] + dq[B]
        q_new[B] = z * (bound[B] / np.sqrt(np.sum(z * z, axis=1)))[:, None]
    return project(q_new, bound, area, Q, np.zeros(d))[0], products


def solve_stuck(apply, area, Q, u_p, q0, tol, max_products):
    """Conjugate gradients for C q + u_p = s on the contact nodes with sum(q) area = Q.

    Returns ``(q, s, products, residual)``, the residual the largest slip over the largest displacement.
    """
    n, d = u_p.shape
    q = np.repeat((Q / (area * n))[None, :], n, axis=0)
    if q0 is not None:
        q = q0 + (Q - area * q0.sum(axis=0))[None, :] / (area * n)
    u = apply(q) + u_p
    r = u.mean(axis=0) - u  # minus the zero-mean part of the gradient: the slip, reversed
    scale = max(float(np.max(np.abs(u))), 1e-300)
    direction, rr, products = r.copy(), float(np.sum(r * r)), 1
    res = float(np.max(np.abs(r))) / scale
    while res > tol and products < max_products:
        w = apply(direction)
        products += 1
        u += (alpha := rr / float(np.sum(direction * w))) * w
        q += alpha * direction
        r -= alpha * (w - w.mean(axis=0))
        rr_new = float(np.sum(r * r))
        direction = r + (rr_new / rr) * direction
        rr = rr_new
        res = float(np.max(np.abs(r))) / scale
    return q, u.mean(axis=0), products, res

"""Normal contact: the constrained conjugate-gradient solver of Polonsky and Keer (1999).

Unknown: the nodal pressure ``p >= 0`` (Pa, pushes into the skin). The gap
``g = g0 + uz(p) - delta`` (m) must satisfy ``g >= 0`` with ``p g = 0`` at every node; the
rigid approach ``delta`` is given (approach control) or is the Lagrange multiplier of the total
force (force control, ``sum(p) = total``). Conjugate gradients run on the current contact set
``I = {p > 0}``: the search direction is the gap on ``I`` (minus its mean under force control),
the step is exact for the quadratic energy, pressures that would turn negative are set to 0, and
nodes outside ``I`` that penetrate (``g < 0``) re-enter with a gradient step, which restarts the
conjugacy (Polonsky and Keer, Wear 231, 1999, the algorithm of section 3).

Products: the product ``A t`` of the search direction gives the step length, and ``uz`` is
updated as ``s (uz - tau A t)`` whenever the step leaves the contact set unchanged (no clipping,
no re-entry; ``s`` the force rescaling), so an iteration that keeps the set costs one compliance
product; one that changes it recomputes ``uz = A p`` (a second product), and so does every 32nd,
to stop round-off drift. On a rough surface at 10 % contact the set changes in most iterations
(about 1.85 products per iteration). :mod:`.preconditioned` is the default method; this one is
kept as the reference (``method="polonsky_keer"``).

Convergence: the gap residual ``max(|g| on I, max(-g) off I) <= tol * (max g0 - min g0)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: iterations between exact recomputations of uz (the incremental update drifts by round-off)
REFRESH = 32


@dataclass(frozen=True)
class NormalResult:
    """Raw output of a normal solve: pressure (Pa), approach (m), gap (m) and the iteration record."""

    pressure: np.ndarray
    approach: float
    gap: np.ndarray
    iterations: int
    converged: bool
    residual: float  # final gap residual, m
    products: int  # compliance products computed


def polonsky_keer(compliance, g0: np.ndarray, *, total: float | None, approach: float | None, tol: float,
                  max_iter: int, p0: np.ndarray, extra_gap: np.ndarray | None = None) -> NormalResult:
    """Solve the frictionless normal contact on one grid (arguments checked by the caller).

    Parameters
    ----------
    compliance : ContactCompliance
        The skin on the grid (its ``normal`` operator is used).
    g0 : ndarray
        Initial gap in m (grid shape).
    total, approach : float or None
        Exactly one: the target sum of nodal pressures (Pa; force / cell area), or the approach (m).
    tol : float
        Relative gap residual to reach.
    max_iter : int
        Iteration limit.
    p0 : ndarray
        Starting pressure, Pa (>= 0; rescaled to ``total`` under force control).
    extra_gap : ndarray, optional
        A fixed displacement (m) added to the gap (the normal displacement of given tangential
        tractions, for the coupled problem at nu < 1/2).
    """
    A = compliance.normal
    g0 = g0 if extra_gap is None else g0 + extra_gap
    scale = float(g0.max() - g0.min()) or float(np.abs(g0).max()) or 1.0
    target = tol * scale
    p = np.array(p0, dtype=float, order="C")
    force = total is not None
    if force:
        s = p.sum()
        p = p * (total / s) if s > 0 else np.full(p.shape, total / p.size)
    u = A(p)
    products = 1
    t = np.zeros_like(p)
    G_old, conjugate, residual, delta = 1.0, False, np.inf, approach
    it = 0
    for it in range(max_iter + 1):
        g = g0 + u
        inside = p > 0
        n_in = int(np.count_nonzero(inside))
        if force:
            delta = float(g[inside].mean()) if n_in else float(g.min())
        g -= delta
        g_in = np.where(inside, g, 0.0)
        residual = max(float(np.abs(g_in).max()), float(-np.where(inside, 0.0, g).min()))
        if residual <= target or it == max_iter:
            break
        G = _dot(g_in, g_in)
        if n_in == 0:  # approach control with no contact yet: penetrating nodes enter below
            t.fill(0.0)
        elif conjugate:
            t *= G / G_old
            t += g_in
            t *= inside
        else:
            t = g_in.copy()
        G_old = G if G > 0 else 1.0
        r_raw = A(t)
        products += 1
        r = r_raw - float(r_raw[inside].mean()) if (force and n_in) else r_raw
        denom = _dot(r, t)
        tau = _dot(g_in, t) / denom if denom > 0 else 0.0
        p_new = p - tau * t
        clipped = bool((p_new < 0).any())
        np.maximum(p_new, 0.0, out=p_new)
        entering = (~inside) & (g < 0)
        conjugate = not entering.any()
        if not conjugate:
            p_new[entering] -= tau * g[entering] if tau > 0 else g[entering] / compliance_self(compliance)
        factor = 1.0
        if force:
            s = p_new.sum()
            factor = total / s if s > 0 else 1.0
            p_new *= factor
        if clipped or not conjugate or (it + 1) % REFRESH == 0:
            u = A(p_new)
            products += 1
        else:
            u = factor * (u - tau * r_raw)
        p = p_new
    return NormalResult(p, float(delta), g, it, residual <= target, residual, products)


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """Sum of the products, in one pass (einsum's own loop: BLAS's thread pool is slow on a busy machine)."""
    return float(np.einsum(_SUBSCRIPTS[a.ndim], a, b))


#: einsum subscripts of a full contraction by number of dimensions
_SUBSCRIPTS = {1: "i,i->", 2: "ij,ij->"}


def compliance_self(compliance) -> float:
    """The displacement of a node per unit pressure on it (m/Pa): a Jacobi step for entering nodes."""
    return compliance.self_compliance[0]

"""Block conjugate gradients for right-hand sides that share one contact set.

A frame's sensor outputs give several right-hand sides on the same restricted operator (the
Jacobian of a scan). Block CG searches, for each group of ``s`` of them, the span of all their
preconditioned residuals at once: the Krylov space grows by ``s`` directions per product, so each
right-hand side needs fewer iterations than alone (O'Leary 1980). The search directions are
A-orthonormalised per group by the eigendecomposition of their ``s x s`` Gram matrix, directions
of a negligible eigenvalue dropped (set to zero): right-hand sides that become dependent on the
set (the fields of nearby sensors) then cause no breakdown. One batched operator product per
iteration, the same count of columns as independent CG; the extra cost is eight ``s x s x n``
matrix products per group and iteration (BLAS: on a shared machine limit its threads, e.g. by
threadpoolctl, or they spin against the other jobs).

Measured on the surface inversion's Jacobian (docs/inversion.md, "Cost"): a frame's 18 outputs
as one block took 4.4 iterations each instead of 5.6 at the tolerance 1e-4 (8.6 instead of 12.0
at 1e-8), but the dense products cost as much as the saved FFTs there: no faster.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["block_pcg"]

#: relative eigenvalue below which a direction counts as dependent on the others (dropped)
DROP = 1e-12


def block_pcg(apply: Callable[[np.ndarray], np.ndarray], precondition: Callable[[np.ndarray], np.ndarray],
              b: np.ndarray, x0: np.ndarray | None, *, tol: float, max_iter: int) -> tuple[np.ndarray, int, int]:
    """Solve ``A X = B`` per group by preconditioned block CG.

    Parameters
    ----------
    apply, precondition : callable ``(v, groups) -> ndarray``
        ``A`` and the preconditioner ``M`` (both symmetric, ``A`` positive definite on the fields
        the arguments live on, ``M`` positive definite there) on a stack ``v`` of shape
        ``(len(groups), s, *grid)``, ``groups`` the indices of the groups it holds.
    b : ndarray, shape ``(g, s, *grid)``
        ``g`` groups of ``s`` right-hand sides; the groups are solved independently.
    x0 : ndarray, the shape of ``b``, optional
        Starting solutions.
    tol : float
        Relative residual (2-norm) every right-hand side must reach; a group iterates until all
        of its columns do.
    max_iter : int
        Iteration limit.

    Returns
    -------
    x : ndarray, the shape of ``b``
    iterations : int
        Iterations of the slowest group.
    unconverged : int
        Right-hand sides above ``tol`` at the limit.
    """
    g, s = b.shape[:2]
    grid = b.shape[2:]
    flat = (g, s, -1)
    norm0 = np.linalg.norm(b.reshape(flat), axis=-1)
    goal = tol * norm0
    if x0 is None:
        x = np.zeros_like(b)
        r = b.reshape(flat).copy()
    else:
        x = x0.copy()
        r = (b - apply(x0, np.arange(g))).reshape(flat)
    x = x.reshape(flat)
    live = np.flatnonzero((np.linalg.norm(r, axis=-1) > goal).any(axis=1))
    p = None
    it = 0
    for it in range(1, max_iter + 1):
        if live.size == 0:
            it -= 1
            break
        rl = r[live]
        n = live.size
        z = precondition(rl.reshape(n, s, *grid), live).reshape(n, s, -1)
        if p is not None:  # A-conjugate to the previous directions: P = Z - P (AP)^T Z
            z -= np.matmul(np.matmul(q, z.transpose(0, 2, 1)).transpose(0, 2, 1), p)
        p = z
        q = apply(p.reshape(n, s, *grid), live).reshape(n, s, -1)
        gram = np.matmul(p, q.transpose(0, 2, 1))
        gram = 0.5 * (gram + gram.transpose(0, 2, 1))
        lam, vec = np.linalg.eigh(gram)
        keep = lam > DROP * np.maximum(lam[:, -1:], np.finfo(float).tiny)
        scale = np.where(keep, 1.0 / np.sqrt(np.where(keep, lam, 1.0)), 0.0)
        w = vec * scale[:, None, :]  # (n, s, s): P <- W^T P, so P A P^T = I on the kept directions
        wt = w.transpose(0, 2, 1)
        p, q = np.matmul(wt, p), np.matmul(wt, q)
        alpha_t = np.matmul(rl, p.transpose(0, 2, 1))  # (n, j, k): column j's step along direction k
        x[live] += np.matmul(alpha_t, p)
        rl -= np.matmul(alpha_t, q)
        r[live] = rl
        active = (np.linalg.norm(rl, axis=-1) > goal[live]).any(axis=1)
        if not active.all():
            live, p, q = live[active], p[active], q[active]
    unconverged = int((np.linalg.norm(r, axis=-1) > goal).sum())
    return x.reshape(b.shape), it, unconverged

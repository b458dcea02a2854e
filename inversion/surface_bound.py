"""The untouched nodes: the prior conditioned on the touched nodes and on the bound the skin sets.

Where no frame's contact reached a node, the data say only that the surface stayed below the
skin there: in every frame, at every node of the contact grid that was not in contact, the
surface height read by that node (an interpolation ``a . h`` of the profile) lies below the
deformed skin, ``s = (heights read) + (final gap)`` at the MAP. Rows that involve only touched
nodes are dropped (the Laplace posterior of those nodes already holds what the data say); rows
with the same coefficients are merged (the smallest bound wins).

The skin moves with the touched heights: each bound is shifted by the mean change of the touched
block from the MAP (exact for the uniform shift, which the data cannot see and which moves the skin
as much; first order otherwise).

Given the touched heights ``h_T``, the untouched block ``h_U`` follows the prior's conditional
``N(m_U + C_UT C_TT^-1 (h_T - m_T), C_UU - C_UT C_TT^-1 C_TU)`` truncated to ``A h <= b``. Each
draw tries that Gaussian up to ``tries`` times (exact: rejection); if none is feasible it runs
``sweeps`` Gibbs sweeps from a feasible start, each node drawn from its univariate truncated
conditional (exact inverse-CDF in log space, so far tails stay finite).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.linalg import cho_factor, cho_solve
from scipy.special import log_ndtr, ndtri_exp

__all__ = ["BoundRows", "TruncatedConditional", "bound_rows"]

#: relative jitter on the conditional covariance (smooth priors make it nearly singular)
JITTER = 1e-10


class BoundRows:
    """Linear upper bounds ``A h <= b`` on the profile (``A``: sparse, non-negative weights)."""

    def __init__(self, matrix: sparse.csr_matrix, bound: np.ndarray):
        self.matrix = matrix.tocsr()
        self.bound = np.asarray(bound, dtype=float)

    @property
    def n_rows(self) -> int:
        return self.bound.size

    def node_bound(self, heights: np.ndarray, nodes: np.ndarray) -> np.ndarray:
        """The tightest bound on each node with the other nodes at ``heights`` (m; inf where none)."""
        h = heights.reshape(-1)
        A = self.matrix.tocsc()
        slack = self.bound - A @ h
        out = np.full(nodes.size, np.inf)
        for i, j in enumerate(nodes):
            lo, hi = A.indptr[j], A.indptr[j + 1]
            rows, a = A.indices[lo:hi], A.data[lo:hi]
            keep = a > 1e-12
            if keep.any():
                out[i] = h[j] + float(np.min(slack[rows[keep]] / a[keep]))
        return out


def bound_rows(scan, state, touched: np.ndarray) -> BoundRows:
    """The bounds the solved scan ``state`` puts on the untouched nodes (see the module docstring)."""
    idx, w = scan.interpolation
    H, gap = state.node_heights, scan.final_gap(state)
    if scan.profile.y is None and len(scan.grid_shape) == 2:
        top = H[:, 0, :] + gap.min(axis=1)  # ridges along y: the lowest skin over each column binds
    else:
        top = (H + gap).reshape(scan.n_frames, -1)
    idx = idx.reshape(-1, idx.shape[-1])
    w = w.reshape(-1, w.shape[-1])
    b = top.reshape(-1)
    untouched = ~touched.reshape(-1)
    keep = (untouched[idx] & (w > 1e-12)).any(axis=1)
    idx, w, b = idx[keep], w[keep], b[keep]
    n = scan.profile.size
    if b.size == 0:
        return BoundRows(sparse.csr_matrix((0, n)), np.zeros(0))
    key = np.concatenate([idx.astype(float), np.round(w, 12)], axis=1)
    uniq, inverse = np.unique(key, axis=0, return_inverse=True)
    bound = np.full(uniq.shape[0], np.inf)
    np.minimum.at(bound, inverse.reshape(-1), b)
    first = np.zeros(uniq.shape[0], dtype=int)
    first[inverse.reshape(-1)[::-1]] = np.arange(b.size)[::-1]
    rows = np.repeat(np.arange(uniq.shape[0]), idx.shape[1])
    A = sparse.csr_matrix((w[first].reshape(-1), (rows, idx[first].reshape(-1))), shape=(uniq.shape[0], n))
    A.sum_duplicates()
    A.data[A.data < 1e-12] = 0.0
    A.eliminate_zeros()  # a node the row does not read is not in it (no division by a zero weight)
    return BoundRows(A, bound)


class TruncatedConditional:
    """Draws of the untouched heights given the touched ones, under the skin's bound.

    Parameters
    ----------
    covariance : ndarray, shape (n, n)
        The prior covariance of the profile, m^2.
    mean : float
        The prior mean, m.
    touched : ndarray of bool, shape (n,)
    rows : BoundRows
        The bounds at the MAP.
    reference : ndarray, shape (n,), optional
        The MAP heights, m: a draw whose touched block is shifted from them by ``c`` on average moves
        the skin, and so every bound, by ``c``.
    tries, sweeps : int
        Rejection tries per draw, then Gibbs sweeps from a feasible start.
    """

    def __init__(self, covariance, mean, touched, rows: BoundRows, reference=None, *, tries: int = 20,
                 sweeps: int = 30):
        self.t = np.flatnonzero(touched)
        self.u = np.flatnonzero(~touched)
        self.mean = float(mean)
        self.rows = rows
        ref = np.zeros(touched.size) if reference is None else np.asarray(reference, dtype=float).reshape(-1)
        self.reference = ref[self.t]
        self.tries, self.sweeps = int(tries), int(sweeps)
        self.gibbs_draws = 0
        C = np.asarray(covariance, dtype=float)
        scale = float(np.mean(np.diag(C)))
        if self.u.size == 0:
            return
        if self.t.size:
            ctt = cho_factor(C[np.ix_(self.t, self.t)] + JITTER * scale * np.eye(self.t.size))
            self.gain = cho_solve(ctt, C[np.ix_(self.t, self.u)]).T  # C_UT C_TT^-1, (n_U, n_T)
            cond = C[np.ix_(self.u, self.u)] - self.gain @ C[np.ix_(self.t, self.u)]
        else:
            self.gain = np.zeros((self.u.size, 0))
            cond = C[np.ix_(self.u, self.u)]
        cond = 0.5 * (cond + cond.T) + JITTER * scale * np.eye(self.u.size)
        self.chol = np.linalg.cholesky(cond)
        self.precision = np.linalg.inv(cond)
        A = rows.matrix.tocsc()
        self.A_u = A[:, self.u].tocsc()
        self.A_t = A[:, self.t].tocsr()

    def draw(self, heights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Replace the untouched block of each row of ``heights`` (n_draws, n) by a constrained draw."""
        out = np.array(heights, dtype=float)
        if self.u.size == 0:
            return out
        k = out.shape[0]
        mu = self.conditional_mean_rows(out[:, self.t])  # (k, n_U)
        # the skin moves with the touched block: rigidly with its mean shift from the MAP (exact for the
        # unidentifiable uniform shift, which moves the skin by as much; first order otherwise)
        lift = (out[:, self.t] - self.reference).mean(axis=1) if self.t.size else np.zeros(k)
        limit = self.rows.bound[None, :] + lift[:, None] - (self.A_t @ out[:, self.t].T).T  # (k, n_rows)
        todo = np.ones(k, dtype=bool)
        for _ in range(self.tries):  # rejection: exact draws of the truncated Gaussian
            idx = np.flatnonzero(todo)
            if idx.size == 0:
                break
            cand = mu[idx] + rng.standard_normal((idx.size, self.u.size)) @ self.chol.T
            ok = np.all((self.A_u @ cand.T).T <= limit[idx], axis=1)
            out[idx[ok][:, None], self.u[None, :]] = cand[ok]
            todo[idx[ok]] = False
        idx = np.flatnonzero(todo)
        if idx.size:
            out[idx[:, None], self.u[None, :]] = self._gibbs(mu[idx], limit[idx], rng)
            self.gibbs_draws += int(idx.size)
        return out

    def conditional_mean_rows(self, h_touched: np.ndarray) -> np.ndarray:
        return self.mean + (h_touched - self.mean) @ self.gain.T

    def _feasible_start(self, mu, limit):
        """Each node at most the smallest of its rows' limits over the rows' untouched weight sums."""
        A = self.A_u
        total = np.asarray(A.sum(axis=1)).reshape(-1)
        ratio = np.where(total > 0, limit / np.where(total > 0, total, 1.0), np.inf)  # (k, n_rows)
        start = mu.copy()
        for i in range(self.u.size):
            lo, hi = A.indptr[i], A.indptr[i + 1]
            if hi > lo:
                cap = ratio[:, A.indices[lo:hi]].min(axis=1)
                start[:, i] = np.minimum(start[:, i], cap - 1e-12 * np.abs(cap))
        return start

    def _gibbs(self, mu, limit, rng):
        """``sweeps`` Gibbs sweeps for every draw at once (draws along the first axis)."""
        x = self._feasible_start(mu, limit)
        A, Q = self.A_u, self.precision
        ax = (A @ x.T).T  # (k, n_rows)
        for _ in range(self.sweeps):
            for i in range(self.u.size):
                q = Q[i, i]
                m = mu[:, i] - ((x - mu) @ Q[i] - q * (x[:, i] - mu[:, i])) / q
                s = 1.0 / np.sqrt(q)
                lo, hi = A.indptr[i], A.indptr[i + 1]
                upper = np.full(x.shape[0], np.inf)
                if hi > lo:
                    rows, a = A.indices[lo:hi], A.data[lo:hi]
                    upper = np.min(x[:, i, None] + (limit[:, rows] - ax[:, rows]) / a, axis=1)
                beta = (upper - m) / s
                log_u = log_ndtr(beta) + np.log(rng.random(x.shape[0]))
                new = np.minimum(m + s * ndtri_exp(log_u), upper)
                if hi > lo:
                    ax[:, rows] += (new - x[:, i])[:, None] * a
                x[:, i] = new
        return x

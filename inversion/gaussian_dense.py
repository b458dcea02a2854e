"""The dense path of :func:`tactilab.inversion.gaussian_posterior`: the exact linear-Gaussian
posterior in square-root form, without subtraction, at any signal-to-noise.

Prior ``m ~ N(m0, C)`` with ``C`` circulant (eigenvalues ``lambda``, the prior spectrum), data
``d = A m + e``, ``e ~ N(0, sigma^2 I)``. In the prior's real Fourier eigenbasis ``Q``
(``C = Q diag(lambda) Q^T``) the posterior precision is ``diag(1/lambda) + X^T X`` with
``X = A Q / sigma``; a Householder QR of the stacked matrix ``[X; diag(lambda^-1/2)] = Q_M R`` gives
it as ``R^T R`` without forming it.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

__all__: list[str] = []


def _real_fourier_basis(lam_full: np.ndarray, dims) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal real eigenbasis of the circulant prior and its eigenvalues, shapes (n, n), (n,).

    Columns ``sqrt(2/n) cos(k.x)`` and ``sqrt(2/n) sin(k.x)`` for each pair of modes ``(k, -k)``
    (eigenvalue ``(lambda_k + lambda_-k) / 2``), ``cos(k.x) / sqrt(n)`` for self-conjugate modes.
    """
    dims = tuple(int(v) for v in dims)
    grid = np.indices(dims).reshape(len(dims), -1)  # (d, n) node indices
    n = grid.shape[1]
    shape = np.array(dims)
    cols, lams, seen = [], [], set()
    for f in map(tuple, grid.T):
        neg = tuple(int(v) for v in (-np.array(f)) % shape)
        if f in seen:
            continue
        seen.update((f, neg))
        phase = 2 * np.pi * sum(f[i] * grid[i] / dims[i] for i in range(len(dims)))
        lam = 0.5 * (lam_full[f] + lam_full[neg])
        if f == neg:
            cols.append(np.cos(phase) / np.sqrt(n))
            lams.append(lam)
        else:
            cols += [np.sqrt(2.0 / n) * np.cos(phase), np.sqrt(2.0 / n) * np.sin(phase)]
            lams += [lam, lam]
    return np.column_stack(cols), np.array(lams)


def _dense_posterior(a, d, lam_full, m0, sigma, dims):
    """Square-root form without subtraction: QR of the stacked system in the prior's eigenbasis.

    With ``C = Q diag(lambda) Q^T`` (real Fourier basis), ``X = A Q / sigma`` and
    ``[X; diag(lambda^-1/2)] = Q_M R``: the posterior precision in that basis is ``R^T R``, so
    ``mean = m0 + Q R^-1 Q_M^T [r / sigma; 0]`` and ``cov = L L^T`` with ``L = Q R^-1``. Householder
    QR errs column by column relative to each column's norm, i.e. relative to each mode's own
    precision, so mean and pointwise std keep their accuracy at any signal-to-noise and any prior
    grading (the data-space form ``C - C A^T K^-1 A C`` loses ``(prior sd / posterior sd)^2`` of
    it, and its Cholesky of ``K`` fails once ``sigma^2`` drops below the rounding of ``A C A^T``).
    """
    if not np.all(np.isfinite(lam_full)):
        raise ValueError("prior: the dense path needs a proper prior (finite spectrum); use the fft path "
                         "for flat modes")
    n, m_data = a.shape[1], a.shape[0]
    basis, lam = _real_fourier_basis(lam_full, dims)
    x = (a @ basis) / sigma
    q_m, r_fac = np.linalg.qr(np.vstack([x, np.diag(1.0 / np.sqrt(lam))]))
    resid = d - a @ np.full(n, m0)
    rhs = np.concatenate([resid / sigma, np.zeros(n)])
    y = sla.solve_triangular(r_fac, q_m.T @ rhs, lower=False)
    r_inv = sla.solve_triangular(r_fac, np.eye(n), lower=False)
    root = basis @ r_inv  # posterior covariance root, (n, n)
    mean = m0 + basis @ y
    cov = root @ root.T
    # log evidence: the minimum of the stacked least squares is r^T K^-1 r; log det K from R
    fit = x @ y - resid / sigma
    quad = float(fit @ fit + np.sum(y * y / lam))
    logdet = m_data * np.log(sigma**2) + float(np.sum(np.log(lam))) + 2 * float(np.sum(np.log(np.abs(np.diag(r_fac)))))
    log_ev = float(-0.5 * (quad + logdet + m_data * np.log(2 * np.pi)))
    resolution = root @ (r_inv.T @ (x.T @ (a / sigma)))  # Sigma A^T A / sigma^2 = C A^T K^-1 A
    aux = {"cov": cov, "cov_root": root, "resolution": resolution, "prior_full": lam_full,
           "prior_pointwise_var": float(np.mean(lam_full)), "gain": float(np.linalg.norm(a, 2))}
    std = np.sqrt(np.einsum("ij,ij->i", root, root)).reshape(dims)
    return mean.reshape(dims), std, log_ev, aux, "exact (dense, QR of the stacked system in the prior's eigenbasis)"

"""The dense Gaussian posterior at any signal-to-noise: mean and pointwise std against an exact
rational-arithmetic reference (``fractions.Fraction``: the data-space formula
``C - C A^T (A C A^T + s^2 I)^-1 A C`` evaluated without rounding) to 1e-10 relative, for prior sd /
noise sd from 1 to 1e12, under- and over-determined."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from tactilab.inversion import StationaryPrior, gaussian_posterior
from tactilab.inversion.gaussian import _circulant

N = 10


def _solve(mat: list[list[Fraction]], rhs: list[list[Fraction]]) -> list[list[Fraction]]:
    """Exact Gauss-Jordan elimination: mat^-1 rhs (mat symmetric positive definite)."""
    n = len(mat)
    aug = [row[:] + rhs_row[:] for row, rhs_row in zip(mat, rhs)]
    for col in range(n):
        piv = next(i for i in range(col, n) if aug[i][col] != 0)
        aug[col], aug[piv] = aug[piv], aug[col]
        inv = 1 / aug[col][col]
        aug[col] = [v * inv for v in aug[col]]
        for i in range(n):
            if i != col and aug[i][col] != 0:
                f = aug[i][col]
                aug[i] = [vi - f * vc for vi, vc in zip(aug[i], aug[col])]
    return [row[n:] for row in aug]


def _exact_posterior(a: np.ndarray, d: np.ndarray, c: np.ndarray, sigma: float):
    """Mean and pointwise variance (as floats) computed exactly from the given float inputs."""
    fa = [[Fraction(float(v)) for v in row] for row in a]
    # the prior covariance made exactly symmetric (a float product is symmetric only to rounding,
    # and the posterior variance is ~1e-16 of the prior's at the highest ratios)
    fc = [[(Fraction(float(c[i][j])) + Fraction(float(c[j][i]))) / 2 for j in range(len(c))] for i in range(len(c))]
    fd = [Fraction(float(v)) for v in d]
    s2 = Fraction(float(sigma)) ** 2
    m, n = len(fa), len(fc)
    ca_t = [[sum(fc[i][k] * fa[j][k] for k in range(n)) for j in range(m)] for i in range(n)]  # C A^T (n, m)
    kmat = [[sum(fa[i][k] * ca_t[k][j] for k in range(n)) + (s2 if i == j else 0) for j in range(m)]
            for i in range(m)]
    rhs = [[fd[i]] + [ca_t[r][i] for r in range(n)] for i in range(m)]  # [d, (C A^T)^T]
    sol = _solve(kmat, rhs)  # K^-1 [d, A C]
    mean = [sum(ca_t[i][j] * sol[j][0] for j in range(m)) for i in range(n)]
    var = [fc[i][i] - sum(ca_t[i][j] * sol[j][1 + i] for j in range(m)) for i in range(n)]
    return np.array([float(v) for v in mean]), np.array([float(v) for v in var])


@pytest.mark.parametrize("n_data", [6, 16])
@pytest.mark.parametrize("ratio", [1.0, 1e3, 1e6, 1e9, 1e12])
def test_dense_posterior_matches_exact_reference(n_data, ratio):
    rng = np.random.default_rng(12 + n_data)
    prior = StationaryPrior(variance=1e10, correlation_length=3e-4, kind="matern32")  # prior sd 100 kPa
    spacing = 1e-4
    a = rng.standard_normal((n_data, N))
    sigma = 1e5 / ratio
    truth = rng.standard_normal(N) * 1e5
    d = a @ truth + sigma * rng.standard_normal(n_data)
    post = gaussian_posterior(a, d, prior, sigma, spacing=spacing)
    assert post.method == "dense"
    c = _circulant(prior.spectrum((N,), spacing), (N,))
    mean, var = _exact_posterior(a, d, c, sigma)
    np.testing.assert_allclose(post.std, np.sqrt(var), rtol=1e-10)
    np.testing.assert_allclose(post.mean, mean, rtol=1e-10, atol=1e-10 * np.abs(mean).max())


def test_tiny_noise_against_a_large_signal_does_not_fail():
    """1e-6 Pa noise against an 800 Pa signal, a smooth prior (squared exponential): the data-space
    Cholesky of A C A^T + s^2 I fails; the square-root form matches the exact reference."""
    rng = np.random.default_rng(4)
    prior = StationaryPrior(variance=800.0**2, correlation_length=2e-4, kind="squared_exponential")
    a = rng.standard_normal((N, N)) / N
    c = _circulant(prior.spectrum((N,), 1e-4), (N,))
    truth = np.linalg.cholesky(c + 1e-9 * 800**2 * np.eye(N)) @ rng.standard_normal(N)
    d = a @ truth + 1e-6 * rng.standard_normal(N)
    post = gaussian_posterior(a, d, prior, 1e-6, spacing=1e-4)
    mean, var = _exact_posterior(a, d, c, 1e-6)
    np.testing.assert_allclose(post.std, np.sqrt(var), rtol=1e-10)
    np.testing.assert_allclose(post.mean, mean, rtol=1e-10, atol=1e-10 * np.abs(mean).max())
    assert np.abs(post.mean - truth).max() < 1e-3 * 800
    assert np.isfinite(post.log_evidence)

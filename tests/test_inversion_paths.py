"""One path chooser for every linear entry point: invert_linear, invert_tv and gaussian_posterior
take the same path for the same operator, and a circulant forward operator takes the fft path in
all three with the answers of the dense path (to solver tolerance)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.linalg import LinearOperator, aslinearoperator

from tactilab.forward import HalfSpace
from tactilab.inversion import gaussian_posterior, invert_linear, tikhonov_prior_spectrum
from tactilab.inversion.linear_common import DENSE_MAX
from tactilab.inversion.operators import FourierDiagonal, halfspace_fourier_operator
from tactilab.inversion.paths import choose_path
from tactilab.inversion.tv import invert_tv

DX = 1e-4
N = 48


def _circulant_problem(rng, n=N):
    op = HalfSpace(1e6, 0.45).operator((n,), DX, depth=2e-4, components=("zz",), loads=("p",), periodic=True)
    truth = np.exp(-((np.arange(n) - n / 2) / 5.0) ** 2) * 1e3
    return op, op @ truth + rng.normal(0, 5.0, n)


def test_choose_path_is_the_same_for_every_entry_point(rng):
    op, d = _circulant_problem(rng)
    fd, path = choose_path(op)
    assert path == "fft" and isinstance(fd, FourierDiagonal)
    lam = 1e-3
    noise = 5.0
    linear = invert_linear(op, d, penalty="identity", lam=lam)
    tv = invert_tv(op, d, lam=1.0, max_iter=50)
    prior = tikhonov_prior_spectrum(lam, "identity", noise, (N,), DX)
    post = gaussian_posterior(op, d, prior, noise)
    assert linear.method == tv.method == post.method == path  # gaussian_posterior took "dense" before
    # the posterior mean under the Tikhonov prior is the Tikhonov solution
    np.testing.assert_allclose(post.mean, linear.model, rtol=1e-10, atol=1e-10 * np.abs(linear.model).max())
    # and both agree with the dense path (today's gaussian_posterior answer for this operator)
    matrix = op @ np.eye(N)
    dense = gaussian_posterior(matrix, d, prior, noise, spacing=DX)
    assert dense.method == "dense"
    np.testing.assert_allclose(post.mean, dense.mean, rtol=1e-8, atol=1e-8 * np.abs(dense.mean).max())
    np.testing.assert_allclose(post.std, dense.std, rtol=1e-8)
    assert post.log_evidence == pytest.approx(dense.log_evidence, rel=1e-10)
    forced = gaussian_posterior(op, d, prior, noise, method="dense")
    np.testing.assert_allclose(forced.mean, dense.mean, rtol=1e-12, atol=1e-12 * np.abs(dense.mean).max())


def _plain(op):
    """The same map as a plain LinearOperator (no FourierDiagonal form)."""
    return LinearOperator(op.shape, matvec=op.matvec, rmatvec=op.rmatvec, dtype=float)


@pytest.mark.parametrize("kind", ["matrix", "small operator", "large operator", "fourier"])
def test_auto_paths(kind):
    fd = halfspace_fourier_operator((16,), DX, 2e-4)
    big = halfspace_fourier_operator((DENSE_MAX + 2,), DX, 2e-4)
    operator, want = {"matrix": (fd.todense(), "dense"), "small operator": (aslinearoperator(fd.todense()), "dense"),
                      "large operator": (_plain(big), "iterative"), "fourier": (fd, "fft")}[kind]
    out, path = choose_path(operator)
    assert path == want and out is operator


def test_forced_paths_and_their_errors():
    fd = halfspace_fourier_operator((16,), DX, 2e-4)
    for method in ("fft", "dense", "iterative"):
        assert choose_path(fd, method)[1] == method
    with pytest.raises(ValueError, match="method: unknown path 'qr'; use 'auto' or one of fft, dense, iterative"):
        choose_path(fd, "qr")
    with pytest.raises(ValueError, match="method: 'fft' needs a FourierDiagonal operator"):
        choose_path(fd.todense(), "fft")
    with pytest.raises(ValueError, match="method: 'fft' needs a FourierDiagonal operator"):
        invert_tv(fd.todense(), np.zeros(16), lam=1.0, method="fft")
    with pytest.raises(ValueError, match="method: unknown path"):
        invert_tv(fd, np.zeros(16), lam=1.0, method="qr")


@pytest.mark.filterwarnings("ignore:regularisation criteria disagree")
@pytest.mark.parametrize("method", ["fft", "dense", "iterative"])
def test_invert_linear_returns_its_factorisation_for_reuse(rng, method):
    """factorisation.solve(lam) re-solves without refactorising: at the chosen lam it is the
    result's model, at another lam it is what invert_linear(lam=...) computes from scratch."""
    fd = halfspace_fourier_operator((N,), DX, 2e-4)
    operator = fd if method == "fft" else fd.todense() if method == "dense" else _plain(fd)
    truth = np.exp(-((np.arange(N) - N / 2) / 5.0) ** 2) * 1e3
    d = fd @ truth + rng.normal(0, 5.0, N)
    # lam chosen by the criteria on the direct paths; given on the iterative one (its criteria cost seconds)
    res = invert_linear(operator, d, penalty="gradient", method=method, tol=1e-12,
                        lam=None if method != "iterative" else 3e-2)
    kept = res.factorisation
    assert kept.path == res.method == method and kept.model_shape == (N,)
    rtol = 0 if method != "iterative" else 1e-7
    np.testing.assert_allclose(kept.solve(res.lam), res.model, rtol=rtol, atol=rtol * np.abs(res.model).max())
    other = 3.7 * res.lam
    fresh = invert_linear(operator, d, penalty="gradient", lam=other, method=method, tol=1e-12)
    np.testing.assert_allclose(kept.solve(other), fresh.model, rtol=1e-7, atol=1e-7 * np.abs(fresh.model).max())
    assert "parts" not in repr(kept)  # the arrays stay out of the repr
    with pytest.raises(ValueError, match="lam: regularisation strength must be finite and > 0, got -1.0"):
        kept.solve(-1.0)
    assert invert_linear(fd, d, penalty="tv", lam=1.0, max_iter=20).factorisation is None

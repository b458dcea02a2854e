"""Exact linear-Gaussian posterior: fft path against dense linear algebra (1e-10), evidence
against scipy's multivariate normal, coverage at the nominal rate, resolvable band and kernel."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.linalg import aslinearoperator
from scipy.stats import multivariate_normal

from tactilab.inversion.gaussian import StationaryPrior, gaussian_posterior, tikhonov_prior_spectrum
from tactilab.inversion.operators import FourierDiagonal, normal_pressure_to_szz_multiplier

DX = 0.1e-3
DEPTH = 0.5e-3


def setup(n=96, noise=10.0, rng=None, prior=None):
    op = FourierDiagonal(normal_pressure_to_szz_multiplier(n, DX, DEPTH), DX)
    prior = prior or StationaryPrior(variance=1e6, correlation_length=0.5e-3, mean=100.0)
    lam = prior.spectrum((n,), DX)
    cov = np.fft.ifft(np.fft.fft(np.eye(n), axis=0) * lam[:, None], axis=0).real
    # exact draw from the circulant prior: C^(1/2) w by FFT (C^(1/2) has eigenvalues sqrt(lambda))
    truth = prior.mean + np.fft.irfft(np.sqrt(lam[: n // 2 + 1]) * np.fft.rfft(rng.standard_normal(n)), n)
    data = op.matvec(truth) + rng.normal(0, noise, n)
    return op, prior, cov, truth, data


def test_fft_equals_dense_to_1e10(rng):
    op, prior, cov, truth, data = setup(rng=rng)
    pf = gaussian_posterior(op, data, prior, 10.0)
    pd = gaussian_posterior(op.todense(), data, prior, 10.0, spacing=DX)
    assert pf.method == "fft" and pd.method == "dense"
    scale = np.abs(pd.mean).max()
    np.testing.assert_allclose(pf.mean, pd.mean, atol=1e-10 * scale)
    np.testing.assert_allclose(pf.std, pd.std, rtol=1e-10)
    np.testing.assert_allclose(pf.covariance(), pd.covariance(), atol=1e-10 * pd.covariance().max())
    assert pf.log_evidence == pytest.approx(pd.log_evidence, rel=1e-10)
    np.testing.assert_allclose(pf.resolution_kernel(7), pd.resolution_kernel(7), atol=1e-10)
    kf, rf = pf.variance_ratio()
    kd, rd = pd.variance_ratio()
    np.testing.assert_allclose(rd[: kf.size], rf, rtol=1e-8)  # fftfreq order: the first n//2+1 agree
    bf, bd = pf.resolvable_band(depth=DEPTH), pd.resolvable_band(depth=DEPTH)
    assert bf["k_max"] == pytest.approx(bd["k_max"])


def test_evidence_equals_multivariate_normal_logpdf(rng):
    op, prior, cov, truth, data = setup(n=64, rng=rng)
    a = op.todense()
    post = gaussian_posterior(op, data, prior, 10.0)
    direct = multivariate_normal(a @ np.full(64, prior.mean), a @ cov @ a.T + 100.0 * np.eye(64)).logpdf(data)
    assert post.log_evidence == pytest.approx(direct, rel=1e-10)


def test_iterative_path_agrees(rng):
    op, prior, cov, truth, data = setup(n=64, rng=rng)
    exact = gaussian_posterior(op, data, prior, 10.0)
    it = gaussian_posterior(aslinearoperator(op.todense()), data, prior, 10.0, method="iterative", spacing=DX,
                            rng=rng, n_samples=400)
    assert it.method == "iterative" and "Monte Carlo" in it.note
    np.testing.assert_allclose(it.mean, exact.mean, atol=1e-6 * np.abs(exact.mean).max())
    # Monte Carlo std: relative error ~ 1/sqrt(2 * 399) = 0.035 per point
    assert np.abs(it.std / exact.std - 1).mean() < 0.06
    draws = it.sample(3, rng)
    assert draws.shape == (3, 64)


def test_samples_have_posterior_moments(rng):
    op, prior, cov, truth, data = setup(n=64, rng=rng)
    post = gaussian_posterior(op, data, prior, 10.0)
    draws = post.sample(4000, rng)
    assert np.abs(draws.mean(axis=0) - post.mean).max() < 5 * post.std.max() / np.sqrt(4000)
    assert np.abs(draws.std(axis=0) / post.std - 1).max() < 0.08
    dense = gaussian_posterior(op.todense(), data, prior, 10.0, spacing=DX)
    d2 = dense.sample(4000, rng)
    assert np.abs(d2.std(axis=0) / post.std - 1).max() < 0.08


def test_coverage_at_nominal_rate(seed):
    """95% pointwise credible intervals contain the truth 95% of the time (truth drawn from the prior)."""
    rng = np.random.default_rng(seed)
    hits, total = 0, 0
    for _ in range(200):
        op, prior, cov, truth, data = setup(n=64, rng=rng)
        post = gaussian_posterior(op, data, prior, 10.0)
        hits += int(np.sum(np.abs(truth - post.mean) <= 1.959964 * post.std))
        total += truth.size
    rate = hits / total
    # points within one draw are correlated; 200 independent draws keep the sd of the rate below ~0.01
    assert abs(rate - 0.95) < 0.03


def test_resolvable_band_follows_depth_and_snr(rng):
    """k_max tracks k_c ~ ln(SNR)/Z: it falls with depth and grows with the SNR."""
    n = 1024
    prior = StationaryPrior(variance=1e6, correlation_length=0.1e-3, kind="white")
    out = {}
    for depth in (0.3e-3, 1e-3):
        for noise in (1.0, 100.0):
            op = FourierDiagonal(normal_pressure_to_szz_multiplier(n, DX, depth), DX)
            post = gaussian_posterior(op, np.zeros(n), prior, noise)
            out[depth, noise] = post.resolvable_band(depth=depth)
    assert out[0.3e-3, 1.0]["k_max"] > out[1e-3, 1.0]["k_max"] > out[1e-3, 100.0]["k_max"]
    dk = 2 * np.pi / (n * DX)
    for (depth, noise), band in out.items():
        # rough rule of the issue: within a factor 2
        assert 0.5 < band["k_max"] / band["k_c_estimate"] < 2.0
        # exact edge for a white prior: (1 + kZ) exp(-kZ) = noise / prior std, to one grid step
        snr = 1e3 / noise
        k = band["k_max"]
        assert k * depth - np.log1p(k * depth) <= np.log(snr) < (k + dk) * depth - np.log1p((k + dk) * depth)


def test_resolution_kernel_narrows_with_snr(rng):
    n = 256
    op = FourierDiagonal(normal_pressure_to_szz_multiplier(n, DX, DEPTH), DX)
    prior = StationaryPrior(variance=1e6, kind="white")
    widths = []
    for noise in (100.0, 0.01):
        kern = gaussian_posterior(op, np.zeros(n), prior, noise).resolution_kernel(n // 2)
        assert np.argmax(kern) == n // 2
        widths.append(np.sum(kern > 0.5 * kern.max()))
    assert widths[1] < widths[0]


def test_tikhonov_prior_with_flat_mode(rng):
    op, prior, cov, truth, data = setup(n=64, rng=rng)
    spec = tikhonov_prior_spectrum(1e-9, "gradient", 10.0, (64,), DX)
    assert np.isinf(spec[0])
    post = gaussian_posterior(op, data, spec, 10.0)
    assert np.isnan(post.log_evidence) and np.all(np.isfinite(post.std))
    from tactilab.inversion.linear import invert_linear

    tik = invert_linear(op, data, penalty="gradient", lam=1e-9)
    np.testing.assert_allclose(post.mean, tik.model, atol=1e-9 * np.abs(tik.model).max())


def test_extremes_noise(rng):
    op, prior, cov, truth, data = setup(n=64, rng=rng, noise=1e-12)
    tiny = gaussian_posterior(op, data, prior, 1e-12)
    assert np.all(np.isfinite(tiny.mean)) and np.isfinite(tiny.log_evidence)
    huge = gaussian_posterior(op, data + rng.normal(0, 1e12, 64), prior, 1e12)
    np.testing.assert_allclose(huge.mean, prior.mean, atol=1e-3)
    np.testing.assert_allclose(huge.std, np.sqrt(prior.variance), rtol=1e-6)


def test_validation(rng):
    op, prior, cov, truth, data = setup(n=32, rng=rng)
    with pytest.raises(ValueError, match="variance: must be finite and > 0 model units squared"):
        StationaryPrior(variance=0.0)
    with pytest.raises(ValueError, match="correlation_length"):
        StationaryPrior(variance=1.0, correlation_length=-1.0)
    with pytest.raises(ValueError, match="kind: unknown"):
        StationaryPrior(variance=1.0, kind="cauchy")
    with pytest.raises(ValueError, match="mean: prior mean"):
        StationaryPrior(variance=1.0, mean=np.nan)
    with pytest.raises(ValueError, match="noise_std"):
        gaussian_posterior(op, data, prior, 0.0)
    with pytest.raises(ValueError, match="method: unknown"):
        gaussian_posterior(op, data, prior, 1.0, method="x")
    with pytest.raises(ValueError, match="method: 'fft' needs"):
        gaussian_posterior(op.todense(), data, prior, 1.0, method="fft")
    with pytest.raises(ValueError, match="rng: the iterative path"):
        gaussian_posterior(op, data, prior, 1.0, method="iterative")
    with pytest.raises(ValueError, match="spectrum shape"):
        gaussian_posterior(op, data, np.ones(5), 1.0)
    with pytest.raises(ValueError, match="eigenvalues must be > 0"):
        gaussian_posterior(op, data, -np.ones(32), 1.0)
    bad = data.copy()
    bad[0] = np.nan
    with pytest.raises(ValueError, match="must be finite"):
        gaussian_posterior(op, bad, prior, 1.0)
    spec = tikhonov_prior_spectrum(1.0, "gradient", 1.0, (32,), DX)
    with pytest.raises(ValueError, match="dense path needs a proper prior"):
        gaussian_posterior(op.todense(), data, spec, 1.0, spacing=DX)
    with pytest.raises(ValueError, match="iterative path needs a proper prior"):
        gaussian_posterior(op, data, spec, 1.0, method="iterative", rng=rng)
    zero_mean_op = FourierDiagonal(np.r_[0.0, np.ones(31)], DX)
    with pytest.raises(ValueError, match="not seen by the operator"):
        gaussian_posterior(zero_mean_op, data, spec, 1.0)
    post = gaussian_posterior(op, data, prior, 1.0)
    with pytest.raises(ValueError, match="n_samples"):
        post.sample(0, rng)
    with pytest.raises(ValueError, match="threshold"):
        post.resolvable_band(threshold=1.5)
    it = gaussian_posterior(op, data, prior, 1.0, method="iterative", rng=rng, n_samples=4)
    with pytest.raises(ValueError, match="covariance: a dense covariance"):
        it.covariance()
    with pytest.raises(ValueError, match="variance_ratio"):
        it.variance_ratio()
    with pytest.raises(ValueError, match="resolution_kernel"):
        it.resolution_kernel(0)


def test_iterative_reports_cg_failure(rng):
    op, prior, cov, truth, data = setup(n=32, rng=rng)
    with pytest.raises(ValueError, match="max_iter: CG did not converge"):
        gaussian_posterior(op, data, prior, 1e-3, method="iterative", rng=rng, max_iter=1)


def test_two_dimensional_fft_equals_dense(rng):
    """2-D grid (ny, nx) with the forward model's exact multiplier: fft path = dense path."""
    from tactilab.inversion.operators import halfspace_fourier_operator

    op = halfspace_fourier_operator((12, 16), DX, DEPTH, load="p", component="zz")
    prior = StationaryPrior(variance=1e6, correlation_length=0.4e-3, mean=50.0)
    data = rng.normal(0, 100.0, 12 * 16)
    pf = gaussian_posterior(op, data, prior, 10.0)
    pd = gaussian_posterior(op, data, prior, 10.0, method="dense")
    assert pf.mean.shape == (12, 16)
    np.testing.assert_allclose(pf.mean, pd.mean, atol=1e-10 * np.abs(pd.mean).max())
    np.testing.assert_allclose(pf.std, pd.std, rtol=1e-10)
    assert pf.log_evidence == pytest.approx(pd.log_evidence, rel=1e-10)
    np.testing.assert_allclose(pf.resolution_kernel((3, 4)), pd.resolution_kernel((3, 4)), atol=1e-10)
    draws = pf.sample(2, rng)
    assert draws.shape == (2, 12, 16)


@pytest.mark.slow
def test_irregular_sensors_with_forward_operator(rng):
    """Matrix-free path on the forward model's LoadToSensor (20 irregular sensors, 64 load nodes):
    iterative Gaussian mean = dense mean, Monte Carlo std close; discrepancy lam by CG = closed form."""
    import warnings

    from tactilab.forward.halfspace.facade import HalfSpace
    from tactilab.inversion.linear import invert_linear

    sensors = np.sort(rng.uniform(-2e-3, 2e-3, 20))
    op = HalfSpace(1e6, 0.5).operator((64,), 1e-4, sensors=sensors, depth=5e-4)
    prior = StationaryPrior(1e6, 0.5e-3)
    data = rng.normal(0, 100.0, op.shape[0])
    dense = gaussian_posterior(op, data, prior, 10.0, method="dense")
    it = gaussian_posterior(op, data, prior, 10.0, method="iterative", rng=rng, n_samples=100)
    assert dense.mean.shape == tuple(op.dims)
    np.testing.assert_allclose(it.mean, dense.mean, atol=1e-8 * np.abs(dense.mean).max())
    assert np.abs(it.std / dense.std - 1).mean() < 0.1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        lam_dense = invert_linear(op, data, penalty="gradient", noise_std=10.0, criterion="discrepancy",
                                  method="dense").lam
        # pure-noise data: the four criteria disagree on both paths (warned), discrepancy is defined
        lam_it = invert_linear(op, data, penalty="gradient", noise_std=10.0, criterion="discrepancy",
                               method="iterative", rng=rng).lam
    assert lam_it == pytest.approx(lam_dense, rel=0.05)

"""Linear inversion: operators, penalties, paths of invert_linear, criteria, TV.

Oracles: dense normal-equation solves, agreement between the fft and dense paths,
a closed-form sinusoid response (docs/theory.md section 3), and dot tests for every operator.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.sparse.linalg import aslinearoperator

from tactilab.inversion.criteria import SpectralForm, choose_lambda, plot_criteria
from tactilab.inversion.linear import invert_linear, dense_form, fft_form
from tactilab.inversion.operators import (
    FourierDiagonal, angular_wavenumbers, dottest, normal_pressure_to_szz_multiplier,
)
from tactilab.inversion.penalties import penalty_matrix, penalty_symbol

DX = 0.1e-3
DEPTH = 0.5e-3


def problem(n=128, depth=DEPTH, noise=5.0, rng=None):
    op = FourierDiagonal(normal_pressure_to_szz_multiplier(n, DX, depth), DX)
    x = (np.arange(n) - n // 2) * DX
    truth = 1e3 * np.exp(-x**2 / (2 * (1e-3) ** 2))
    data = op.matvec(truth) + (rng.normal(0, noise, n) if noise else 0)
    return op, truth, data


def test_multiplier_matches_closed_form_sinusoid():
    """p = P cos kx gives sigma_zz = -P (1 + kZ) e^{-kZ} cos kx (docs/theory.md section 3)."""
    n = 64
    op = FourierDiagonal(normal_pressure_to_szz_multiplier(n, DX, DEPTH), DX)
    x = (np.arange(n) - n // 2) * DX
    k = 2 * np.pi * 5 / (n * DX)
    out = op.matvec(1e3 * np.cos(k * x))
    expected = -1e3 * (1 + k * DEPTH) * np.exp(-k * DEPTH) * np.cos(k * x)
    np.testing.assert_allclose(out, expected, atol=1e-9)


def test_dot_tests(rng):
    op1 = FourierDiagonal(normal_pressure_to_szz_multiplier(100, DX, DEPTH), DX)
    assert dottest(op1, rng) < 1e-12
    xi, eta = angular_wavenumbers((16, 20), DX)
    rho = np.sqrt(xi**2 + eta**2)
    h2 = -(1 + rho * DEPTH) * np.exp(-rho * DEPTH) + 1j * 0.3 * np.sin(xi * DX)  # Hermitian, complex
    op2 = FourierDiagonal(h2, DX)
    assert dottest(op2, rng) < 1e-12
    assert dottest(op2.H, rng) < 1e-12
    np.testing.assert_allclose(op2.todense().T, op2.H.todense(), atol=1e-14)


def test_dottest_reports_a_wrong_adjoint(rng):
    bad = aslinearoperator(np.eye(3))
    bad.rmatvec = lambda y: 2 * y
    with pytest.raises(ValueError, match="adjoint mismatch"):
        dottest(bad, rng)


def test_operator_validation():
    with pytest.raises(ValueError, match="Hermitian"):
        FourierDiagonal(np.array([1.0, 1j, 2.0, 0.5]))
    with pytest.raises(ValueError, match="finite"):
        FourierDiagonal(np.array([1.0, np.nan, np.nan]))
    with pytest.raises(ValueError, match="1-D"):
        FourierDiagonal(np.ones((2, 2, 2)))
    with pytest.raises(ValueError, match="depth"):
        normal_pressure_to_szz_multiplier(8, DX, -1.0)
    with pytest.raises(ValueError, match="dx"):
        normal_pressure_to_szz_multiplier(8, 0.0, DEPTH)
    with pytest.raises(ValueError, match="shape"):
        angular_wavenumbers((2, 2, 2), DX)


@pytest.mark.parametrize("penalty", ["identity", "gradient", "curvature"])
@pytest.mark.parametrize("shape", [(24,), (6, 8)])
def test_periodic_penalty_matrix_matches_symbol(penalty, shape):
    spacing = (DX, 2 * DX) if len(shape) == 2 else DX
    lmat = penalty_matrix(penalty, shape, spacing, periodic=True).toarray()
    ltl = lmat.T @ lmat
    sym = penalty_symbol(penalty, shape, spacing)
    n = int(np.prod(shape))
    eye = np.eye(n).reshape(n, *shape)
    axes = tuple(range(1, len(shape) + 1))
    circ = np.fft.ifftn(np.fft.fftn(eye, axes=axes) * sym, axes=axes).real.reshape(n, n)
    np.testing.assert_allclose(ltl, circ, atol=1e-8 * np.abs(circ).max())


def test_penalty_validation():
    with pytest.raises(ValueError, match="unknown penalty"):
        penalty_symbol("l1", (4,), DX)


@pytest.mark.parametrize("penalty", ["identity", "gradient", "curvature"])
def test_fft_path_equals_normal_equations(penalty, rng):
    op, truth, data = problem(rng=rng)
    lam = {"identity": 1e-3, "gradient": 1e-9, "curvature": 1e-16}[penalty]
    a = op.todense()
    lmat = penalty_matrix(penalty, op.dims, DX, periodic=True).toarray()
    expected = np.linalg.solve(a.T @ a + lam * lmat.T @ lmat, a.T @ data)
    res = invert_linear(op, data, penalty=penalty, lam=lam)
    assert res.method == "fft" and res.lam_source == "given"
    np.testing.assert_allclose(res.model, expected, atol=1e-9 * np.abs(expected).max())


@pytest.mark.parametrize("penalty", ["identity", "gradient"])
def test_dense_and_iterative_paths_agree_with_normal_equations(penalty, rng):
    op, truth, data = problem(n=96, rng=rng)
    lam = {"identity": 1e-3, "gradient": 1e-9}[penalty]
    a = op.todense()
    lmat = penalty_matrix(penalty, op.dims, DX, periodic=False).toarray()
    expected = np.linalg.solve(a.T @ a + lam * lmat.T @ lmat, a.T @ data)
    dense = invert_linear(a, data, penalty=penalty, lam=lam, spacing=DX)
    assert dense.method == "dense"
    np.testing.assert_allclose(dense.model, expected, atol=1e-6 * np.abs(expected).max())
    it = invert_linear(aslinearoperator(a), data, penalty=penalty, lam=lam, method="iterative", spacing=DX,
                       tol=1e-12, max_iter=5000, rng=rng)
    assert it.method == "iterative" and it.converged and it.iterations > 0
    np.testing.assert_allclose(it.model, expected, atol=1e-5 * np.abs(expected).max())


def test_criteria_fft_equal_dense_on_periodic_problem(rng):
    """The closed-form criteria over the Fourier spectrum equal those of the dense SVD form."""
    op, truth, data = problem(n=64, rng=rng)
    f_fft, *_ = fft_form(op, data, "identity")
    f_dense, _ = dense_form(op.todense(), data, np.eye(64))
    for lam in [1e-4, 1e-2, 1.0]:
        assert f_fft.gcv(lam) == pytest.approx(f_dense.gcv(lam), rel=1e-9)
        assert f_fft.residual2(lam) == pytest.approx(f_dense.residual2(lam), rel=1e-9)
        assert f_fft.seminorm2(lam) == pytest.approx(f_dense.seminorm2(lam), rel=1e-7)
        assert f_fft.log_evidence(lam, 5.0)[0] == pytest.approx(f_dense.log_evidence(lam, 5.0)[0], rel=1e-9)


def test_evidence_equals_multivariate_normal(rng):
    """Evidence criterion = log N(d; 0, sigma^2 (I + A A^T / lam)) for the identity penalty."""
    from scipy.stats import multivariate_normal

    op, truth, data = problem(n=48, rng=rng)
    form, *_ = fft_form(op, data, "identity")
    a = op.todense()
    sigma, lam = 5.0, 1e-3
    cov = sigma**2 * (np.eye(48) + a @ a.T / lam)
    assert form.log_evidence(lam, sigma)[0] == pytest.approx(multivariate_normal(np.zeros(48), cov).logpdf(data),
                                                             rel=1e-10)


def test_all_criteria_reported_and_reasonable(rng, tmp_path):
    op, truth, data = problem(n=256, rng=rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        res = invert_linear(op, data, penalty="curvature", noise_std=5.0, criterion="evidence")
    assert set(res.criteria.lam) == {"gcv", "lcurve", "discrepancy", "evidence"}
    assert res.lam == res.criteria.lam["evidence"]
    err = np.linalg.norm(res.model - truth) / np.linalg.norm(truth)
    assert err < 0.05
    # the discrepancy choice meets its target
    n = data.size
    form, *_ = fft_form(op, data, "curvature")
    assert form.residual2(res.criteria.lam["discrepancy"]) == pytest.approx(n * 25.0, rel=1e-3)
    plot_criteria(res.criteria, tmp_path / "crit.png")
    assert (tmp_path / "crit.png").stat().st_size > 1000


def test_disagreement_warns():
    form = SpectralForm(ratio=np.geomspace(1e-8, 1, 200), coef2=np.geomspace(1e-8, 1, 200) + 1e-3,
                        weights=np.ones(200), n_data=200)
    with pytest.warns(UserWarning, match="disagree by a factor"):
        choose_lambda(form, noise_std=1e-6)


def test_criteria_validation():
    form = SpectralForm(ratio=np.ones(4), coef2=np.ones(4), weights=np.ones(4), n_data=4)
    with pytest.raises(ValueError, match="criteria: unknown"):
        choose_lambda(form, criteria=("aic",))
    with pytest.raises(ValueError, match="noise_std"):
        choose_lambda(form, noise_std=-1.0)


def test_noise_estimated_when_not_given(rng):
    op, truth, data = problem(n=512, noise=5.0, rng=rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        res = invert_linear(op, data, penalty="curvature")
    assert res.criteria.noise_std == pytest.approx(5.0, rel=0.15)
    assert "estimated" in res.criteria.notes["discrepancy"]


def test_invert_linear_validation(rng):
    op, truth, data = problem(n=32, rng=rng)
    with pytest.raises(ValueError, match="penalty: unknown"):
        invert_linear(op, data, penalty="l2")
    with pytest.raises(ValueError, match="criterion: unknown"):
        invert_linear(op, data, criterion="aic")
    with pytest.raises(ValueError, match="lam: regularisation"):
        invert_linear(op, data, lam=-1.0)
    with pytest.raises(ValueError, match="method: unknown"):
        invert_linear(op, data, method="magic")
    with pytest.raises(ValueError, match="method: 'fft' needs"):
        invert_linear(op.todense(), data, method="fft")
    with pytest.raises(ValueError, match="n_probes: need an integer >= 2"):
        invert_linear(aslinearoperator(op.todense()), data, method="iterative", n_probes=1)
    with pytest.raises(ValueError, match="noise_std: must be finite"):
        invert_linear(aslinearoperator(op.todense()), data, method="iterative", criterion="discrepancy",
                      noise_std=-1.0)
    bad = data.copy()
    bad[3] = np.nan
    with pytest.raises(ValueError, match="must be finite, found nan at flat index 3"):
        invert_linear(op, bad, lam=1.0)
    bad[3] = np.inf
    with pytest.raises(ValueError, match="must be finite, found inf"):
        invert_linear(op, bad, lam=1.0)
    with pytest.raises(ValueError, match="size mismatch"):
        invert_linear(op, data[:-1], lam=1.0)
    with pytest.raises(ValueError, match="real numbers"):
        invert_linear(op, data.astype(complex), lam=1.0)


def test_noise_extremes(rng):
    """Noise near zero recovers the resolvable truth; enormous noise shrinks to the prior (zero)."""
    op, truth, clean = problem(n=128, depth=0.2e-3, noise=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        tiny = invert_linear(op, clean + rng.normal(0, 1e-9, 128), penalty="gradient", criterion="gcv")
        huge = invert_linear(op, clean + rng.normal(0, 1e9, 128), penalty="identity", noise_std=1e9,
                             criterion="discrepancy")
    assert np.all(np.isfinite(tiny.model)) and np.all(np.isfinite(huge.model))
    assert np.linalg.norm(tiny.model - truth) / np.linalg.norm(truth) < 1e-3
    # shrunk to ~0 relative to what the data would suggest (1e9 Pa), and the reason is reported
    assert np.abs(huge.model).max() < 1e-3 * 1e9
    assert "no signal above noise" in huge.criteria.notes["discrepancy"]


def test_sensors_far_deeper_than_resolved_wavelength(rng):
    """At Z = 200 periods every mode but the mean underflows (exp(-kZ) = 0): finite, flat result."""
    op, truth, data = problem(n=128, depth=200 * 128 * DX, noise=1.0, rng=rng)
    assert np.sum(np.abs(op.half_multiplier) > 0) == 1  # only the mean survives
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        res = invert_linear(op, data, penalty="gradient", noise_std=1.0)
    assert np.all(np.isfinite(res.model))
    assert np.ptp(res.model) < 1e-6 * np.abs(res.model).max() + 1e-9


def test_single_sensor_and_all_sensors_at_one_point(rng):
    """One sensor, or many identical rows: the dense path stays finite and fits the data."""
    op, truth, data = problem(n=32, rng=rng)
    a = op.todense()
    one = invert_linear(a[10:11], data[10:11], penalty="gradient", lam=1e-9, spacing=DX)
    assert np.all(np.isfinite(one.model)) and one.residual_norm < abs(data[10])
    with pytest.warns(UserWarning, match="disagree"):  # one informative direction: criteria cannot agree
        same = invert_linear(np.repeat(a[10:11], 8, axis=0), np.full(8, data[10]) + rng.normal(0, 1, 8),
                             penalty="identity", spacing=DX)
    assert np.all(np.isfinite(same.model))
    assert same.criteria is not None


def test_tv_recovers_edges_better_than_tikhonov(rng):
    n = 128
    op = FourierDiagonal(normal_pressure_to_szz_multiplier(n, DX, 0.3e-3), DX)
    x = (np.arange(n) - n // 2) * DX
    truth = np.where(np.abs(x) < 2e-3, 1e3, 0.0)
    data = op.matvec(truth) + rng.normal(0, 10, n)
    tv = invert_linear(op, data, penalty="tv", noise_std=10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        tik = invert_linear(op, data, penalty="gradient", noise_std=10.0, criterion="discrepancy")
    assert tv.converged and tv.method == "fft" and "ADMM" in tv.message
    assert tv.residual_norm == pytest.approx(np.sqrt(n) * 10.0, rel=0.05)
    e_tv = np.linalg.norm(tv.model - truth)
    e_tik = np.linalg.norm(tik.model - truth)
    assert e_tv < 0.5 * e_tik


def test_tv_dense_path_and_validation(rng):
    n = 48
    op = FourierDiagonal(normal_pressure_to_szz_multiplier(n, DX, 0.3e-3), DX)
    truth = np.where(np.abs(np.arange(n) - n // 2) < 10, 1e3, 0.0)
    data = op.matvec(truth) + rng.normal(0, 10, n)
    res = invert_linear(op.todense(), data, penalty="tv", lam=1e-2, spacing=DX)
    assert res.method == "dense" and res.converged
    short = invert_linear(op, data, penalty="tv", lam=1e-2, max_iter=2)
    assert not short.converged and "NOT converged" in short.message
    with pytest.raises(ValueError, match="noise_std: TV with lam=None"):
        invert_linear(op, data, penalty="tv")
    with pytest.raises(ValueError, match="lam: TV strength"):
        invert_linear(op, data, penalty="tv", lam=0.0)
    with pytest.raises(ValueError, match="tol: ADMM"):
        invert_linear(op, data, penalty="tv", lam=1.0, tol=2.0)
    with pytest.raises(ValueError, match="method: unknown"):
        invert_linear(op, data, penalty="tv", lam=1.0, method="x")
    with pytest.raises(ValueError, match="method: 'fft' needs"):
        invert_linear(op.todense(), data, penalty="tv", lam=1.0, method="fft")


def test_lead_transfer_and_halfspace_operator(rng):
    """The forward model's exact multiplier equals the closed form; its LinearOperator inverts on
    the iterative path like the fft path on the same periodic problem."""
    from tactilab.forward.halfspace.facade import HalfSpace
    from tactilab.inversion.operators import halfspace_fourier_operator

    n = 64
    op = halfspace_fourier_operator((n,), DX, DEPTH)
    np.testing.assert_allclose(op.multiplier.real, normal_pressure_to_szz_multiplier(n, DX, DEPTH), atol=1e-14)
    shear = halfspace_fourier_operator((n,), DX, DEPTH, load="qx", component="zz")
    assert dottest(shear, rng) < 1e-12
    op2 = halfspace_fourier_operator((8, 10), DX, DEPTH, load="qy", component="yz")
    assert dottest(op2, rng) < 1e-12
    lead = HalfSpace(1e6, 0.5).operator((n,), DX, depth=DEPTH, periodic=True)
    truth = 1e3 * np.exp(-((np.arange(n) - n // 2) * DX) ** 2 / (2 * (0.5e-3) ** 2))
    np.testing.assert_allclose(lead.matvec(truth), op.matvec(truth), atol=1e-6 * 1e3)
    data = op.matvec(truth) + rng.normal(0, 1.0, n)
    fft = invert_linear(op, data, penalty="identity", lam=1e-2)
    it = invert_linear(lead, data, penalty="identity", lam=1e-2, method="iterative", tol=1e-12, rng=rng)
    np.testing.assert_allclose(it.model.ravel(), fft.model, atol=1e-6 * np.abs(fft.model).max())


def test_iterative_discrepancy_matches_closed_form(rng):
    """Discrepancy lam on the iterative path (brentq over CG solves) agrees with the closed-form (dense) choice."""
    op, truth, data = problem(n=64, rng=rng)
    a = op.todense()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        dense = invert_linear(a, data, penalty="identity", noise_std=5.0, criterion="discrepancy", spacing=DX)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        it = invert_linear(aslinearoperator(a), data, penalty="identity", noise_std=5.0, criterion="discrepancy",
                           method="iterative", spacing=DX, rng=rng, tol=1e-12)
    assert it.lam_source == "discrepancy" and "CG norms" in it.criteria.estimator
    assert it.lam == pytest.approx(dense.lam, rel=0.05)
    assert it.residual_norm == pytest.approx(np.sqrt(64) * 5.0, rel=0.01)


def test_matrix_operator_on_iterative_paths(rng):
    """A plain ndarray operator works on the iterative Tikhonov and TV paths."""
    op, truth, data = problem(n=48, rng=rng)
    a = op.todense()
    it = invert_linear(a, data, penalty="identity", lam=1e-2, method="iterative", spacing=DX, tol=1e-12, rng=rng)
    dense = invert_linear(a, data, penalty="identity", lam=1e-2, spacing=DX)
    np.testing.assert_allclose(it.model, dense.model, atol=1e-6 * np.abs(dense.model).max())
    tv = invert_linear(a, data, penalty="tv", lam=1e-2, method="iterative", spacing=DX, max_iter=50)
    assert tv.method == "iterative" and np.all(np.isfinite(tv.model))


@pytest.mark.parametrize("penalty", ["identity", "gradient", "curvature"])
def test_two_dimensional_fft_path_equals_normal_equations(penalty, rng):
    from tactilab.inversion.operators import halfspace_fourier_operator

    shape = (10, 12)
    op = halfspace_fourier_operator(shape, (DX, 2 * DX), DEPTH)
    data = rng.normal(0, 100.0, 120)
    lam = {"identity": 1e-3, "gradient": 1e-9, "curvature": 1e-16}[penalty]
    a = op.todense()
    lmat = penalty_matrix(penalty, shape, (DX, 2 * DX), periodic=True).toarray()
    expected = np.linalg.solve(a.T @ a + lam * lmat.T @ lmat, a.T @ data).reshape(shape)
    res = invert_linear(op, data, penalty=penalty, lam=lam)
    assert res.model.shape == shape
    np.testing.assert_allclose(res.model, expected, atol=1e-8 * np.abs(expected).max())


def test_rigid_surface_height_operator_closed_form(rng):
    """A height sinusoid H0 cos(kx) gives sigma_zz = -(1 + kZ) e^{-kZ} E k H0 / (2 (1 - nu^2)) cos(kx)."""
    from tactilab.inversion.operators import rigid_surface_height_operator

    n, dx, depth, e, nu = 256, 50e-6, 1e-3, 1e6, 0.5
    op = rigid_surface_height_operator(n, dx, depth, e, nu)
    x = np.arange(n) * dx
    k = 2 * np.pi * 8 / (n * dx)
    h0 = 10e-6
    expected = -(1 + k * depth) * np.exp(-k * depth) * e * k * h0 / (2 * (1 - nu**2)) * np.cos(k * x)
    np.testing.assert_allclose(op.matvec(h0 * np.cos(k * x)), expected, atol=1e-10 * np.abs(expected).max())
    assert abs(op.matvec(np.ones(n))).max() < 1e-9  # a uniform height loads nothing
    assert dottest(op, rng) < 1e-10
    with pytest.raises(ValueError, match="depth: every depth must be finite and > 0 m"):
        rigid_surface_height_operator(n, dx, -1.0, e, nu)
    with pytest.raises(ValueError, match=r"poisson_ratio: Poisson's ratio must lie in \(-1, 0.5\]"):
        rigid_surface_height_operator(n, dx, depth, e, 0.7)

"""GCV, L-curve, discrepancy and evidence on the matrix-free path against the dense closed forms.

Oracles: the dense path's generalised-SVD sums (:class:`SpectralForm`) on the same matrix, wrapped
as a LinearOperator so that only matvecs reach the iterative estimators; a direct
``numpy.linalg.slogdet`` for stochastic Lanczos quadrature. Seeds are fixed; the stochastic
estimates must agree with the exact values within 3 of their own standard errors.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.sparse.linalg import aslinearoperator

from tactilab.inversion.criteria import plot_criteria
from tactilab.inversion.iterative_criteria import (
    IterativeCriteria, NormalSolver, choose_lambda_iterative, slq_log1p_trace,
)
from tactilab.inversion.linear import dense_form, invert_linear
from tactilab.inversion.operators import FourierDiagonal, normal_pressure_to_szz_multiplier
from tactilab.inversion.penalties import penalty_matrix

DX = 0.1e-3
N = 96
NOISE = 5.0


def problem(seed=1):
    rng = np.random.default_rng(seed)
    a = FourierDiagonal(normal_pressure_to_szz_multiplier(N, DX, 0.5e-3), DX).todense()
    x = (np.arange(N) - N // 2) * DX
    truth = 1e3 * np.exp(-x**2 / (2 * (1e-3) ** 2))
    return a, a @ truth + rng.normal(0, NOISE, N)


@pytest.mark.parametrize("penalty", ["identity", "gradient"])
def test_estimates_agree_with_dense_closed_forms(penalty):
    a, data = problem()
    form, _ = dense_form(a, data, penalty_matrix(penalty, (N,), DX, periodic=False).toarray())
    solver = NormalSolver(aslinearoperator(a), penalty, (N,), DX, np.random.default_rng(0), 1e-12, 5000)
    crit = IterativeCriteria(solver, data, np.random.default_rng(5), n_probes=8)
    lam0 = {"identity": 1e-3, "gradient": 1e-9}[penalty]
    for lam in [lam0 * 0.1, lam0, lam0 * 10]:
        h = crit.norms(lam)
        # deterministic quantities: exact to the CG tolerance
        assert h["rho"] == pytest.approx(form.residual2(lam), rel=1e-8)
        assert h["eta"] == pytest.approx(form.seminorm2(lam), rel=1e-7)
        assert crit.curvature(lam) == pytest.approx(form.lcurve_curvature(lam), rel=1e-6, abs=1e-9)
        # stochastic ones: within 3 standard errors, and the error is informative (< 25% of dof with 8 probes)
        dof, dof_se = crit.dof(lam)
        assert abs(dof - form.dof(lam)) < 3 * dof_se and dof_se < 0.25 * form.dof(lam)
        gcv, gcv_se = crit.gcv(lam)
        assert abs(gcv - form.gcv(lam)) < 3 * gcv_se
        ev, ev_se, _ = crit.log_evidence(lam, NOISE)
        assert abs(ev - form.log_evidence(lam, NOISE)[0]) < 3 * ev_se


def test_slq_matches_slogdet(rng):
    """tr log(I + S) = log det(I + S) for a PSD S with a wide spectrum."""
    q, _ = np.linalg.qr(rng.normal(size=(80, 80)))
    spd = (q * np.logspace(-8, 6, 80)) @ q.T
    z = np.random.default_rng(2).choice([-1.0, 1.0], size=(80, 30))
    est = slq_log1p_trace(lambda v: spd @ v, z)
    exact = np.linalg.slogdet(np.eye(80) + spd)[1]
    se = est.std(ddof=1) / np.sqrt(est.size)
    assert abs(est.mean() - exact) < 3 * se and se < 0.1 * exact


@pytest.mark.slow
@pytest.mark.parametrize("penalty", ["identity", "gradient"])
def test_chosen_lambdas_agree_with_dense_path(penalty, tmp_path):
    """Each criterion's lam within a factor 2 of the dense path's (discrepancy: 1%), 10x warning kept."""
    a, data = problem()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        dense = invert_linear(a, data, penalty=penalty, noise_std=NOISE, spacing=DX)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        it = invert_linear(aslinearoperator(a), data, penalty=penalty, noise_std=NOISE, spacing=DX,
                           method="iterative", tol=1e-10, rng=np.random.default_rng(3), criterion="evidence")
    assert it.method == "iterative" and it.lam_source == "evidence"
    assert set(it.criteria.lam) == {"gcv", "lcurve", "discrepancy", "evidence"}
    for name, lam in dense.criteria.lam.items():
        factor = 1.01 if name == "discrepancy" else 2.0
        assert 1 / factor < it.criteria.lam[name] / lam < factor, name
    assert "Hutchinson" in it.criteria.estimator and "Lanczos" in it.criteria.estimator
    assert "Hutchinson" in it.message
    assert set(it.criteria.errors) == {"gcv", "dof", "log_evidence", "gcv_lam_range", "evidence_lam_range"}
    # the stated uncertainty (lam within 2 s.e. of the optimum) holds the dense choice, to one grid step
    step = it.criteria.grid[0] / it.criteria.grid[1]
    for name in ("gcv", "evidence"):
        lo, hi = it.criteria.errors[f"{name}_lam_range"]
        assert lo / step <= dense.criteria.lam[name] <= hi * step, name
    assert (it.criteria.spread > 10) == any("disagree by a factor" in str(w.message) for w in caught)
    plot_criteria(it.criteria, tmp_path / "criteria.png")
    assert (tmp_path / "criteria.png").stat().st_size > 10_000


def test_noise_profiled_and_validation():
    a, data = problem()
    solver = NormalSolver(aslinearoperator(a), "identity", (N,), DX, np.random.default_rng(0), 1e-10, 5000)
    crit = IterativeCriteria(solver, data, np.random.default_rng(5), n_probes=4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        res = choose_lambda_iterative(crit, noise_std=None, criteria=("evidence", "discrepancy"))
    assert res.noise_std == pytest.approx(NOISE, rel=0.3)
    assert "estimated by the evidence" in res.notes["discrepancy"]
    with pytest.raises(ValueError, match="criteria: unknown or empty"):
        choose_lambda_iterative(crit, criteria=("aic",))
    with pytest.raises(ValueError, match="noise_std: must be finite and > 0"):
        choose_lambda_iterative(crit, noise_std=float("nan"))


def test_grid_stops_where_cg_fails():
    """An iteration limit too small for the small lam ends the grid there, with a note (no silent values)."""
    a, data = problem()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        it = invert_linear(aslinearoperator(a), data, penalty="gradient", noise_std=NOISE, spacing=DX,
                           method="iterative", tol=1e-12, max_iter=4, rng=np.random.default_rng(3))
    assert "CG did not converge" in it.criteria.notes["grid"]
    assert all(np.isfinite(v) and v > 0 for v in it.criteria.lam.values())

"""Regularisation choice at the extremes: data and noise at 1e-300 or 1e200, lam above 1e160, a
single-node grid, and data whose shape does not match the operator. Each gives the correct answer
(oracle: the lam choices do not depend on the data's unit; single-node closed forms) or one clear
error."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.sparse.linalg import aslinearoperator

from tactilab.inversion import FourierDiagonal, invert_linear
from tactilab.inversion.criteria import SpectralForm, choose_lambda
from tactilab.inversion.operators import normal_pressure_to_szz_multiplier

DX = 1e-4


def problem(rng, n=64):
    op = FourierDiagonal(normal_pressure_to_szz_multiplier(n, DX, 3e-4), DX)
    truth = 1e3 * np.sin(2 * np.pi * 3 * np.arange(n) / n) + 300 * np.cos(2 * np.pi * 7 * np.arange(n) / n)
    return op, op.matvec(truth) + rng.normal(0, 20.0, n)


def quiet(fun, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the criteria may disagree: reported, not the subject
        return fun(*args, **kwargs)


@pytest.mark.parametrize("unit,path", [(1e200, "fft"), (1e-300, "fft"), (1e200, "dense"), (1e-300, "dense"),
                                       (1e200, "iterative")])
def test_lam_choices_do_not_depend_on_the_data_unit(rng, unit, path):
    op, data = problem(rng, n=64 if path != "iterative" else 24)
    operator = {"fft": op, "dense": op.todense(), "iterative": aslinearoperator(op.todense())}[path]
    kw = dict(method=path, penalty="gradient", spacing=DX)
    for noise in (20.0, None) if path != "iterative" else (20.0,):  # the iterative path is slow: one case
        ref = quiet(invert_linear, operator, data, noise_std=noise, rng=np.random.default_rng(1), **kw)
        big = quiet(invert_linear, operator, data * unit, noise_std=None if noise is None else noise * unit,
                    rng=np.random.default_rng(1), **kw)
        for name, lam in ref.criteria.lam.items():
            assert big.criteria.lam[name] == pytest.approx(lam, rel=1e-6), (name, path, unit)
        np.testing.assert_allclose(big.model / unit, ref.model, rtol=1e-6, atol=1e-9 * np.abs(ref.model).max())
        assert big.residual_norm / unit == pytest.approx(ref.residual_norm, rel=1e-6)
        assert big.criteria.noise_std / unit == pytest.approx(ref.criteria.noise_std, rel=1e-6)
        ev_shift = ref.criteria.curves["log_evidence"] - big.criteria.curves["log_evidence"]
        if path != "iterative":  # same grid; the density of d * unit is that of d over unit^n_eff
            # restricted likelihood: the fft path leaves the gradient penalty's null mode (the mean) out,
            # the dense path keeps it under its very wide eps prior
            n_eff = data.size - 1 if path == "fft" else data.size
            np.testing.assert_allclose(ev_shift, n_eff * np.log(unit), rtol=1e-9)


@pytest.mark.parametrize("lam", [1e170, 1e300])
@pytest.mark.parametrize("path", ["fft", "dense"])
def test_huge_lam_gives_the_zero_model_and_the_data_norm(rng, lam, path):
    op, data = problem(rng)
    res = invert_linear(op if path == "fft" else op.todense(), data, penalty="identity", lam=lam, method=path)
    assert np.all(np.isfinite(res.model)) and np.abs(res.model).max() < 1e-100
    assert res.residual_norm == pytest.approx(np.linalg.norm(data), rel=1e-12)


def test_single_node_grid_closed_forms():
    """One datum d = a m + e: the evidence is max where sigma^2 (1 + a^2 / lam) = d^2, i.e.
    lam = a^2 sigma^2 / (d^2 - sigma^2); the discrepancy residual lam / (a^2 + lam) |d| = sigma gives
    lam = a^2 sigma / (|d| - sigma); the model is a d / (a^2 + lam)."""
    a, d, sigma = 2.0, 3.0, 1.0
    for op in (np.array([[a]]), FourierDiagonal(np.array([a]), DX)):
        for crit, expected in (("evidence", a * a * sigma**2 / (d * d - sigma**2)),
                               ("discrepancy", a * a * sigma / (abs(d) - sigma))):
            res = quiet(invert_linear, op, np.array([d]), penalty="identity", noise_std=sigma, criterion=crit)
            assert res.lam == pytest.approx(expected, rel=2e-3)
            assert res.model[0] == pytest.approx(a * d / (a * a + res.lam), rel=1e-6)
        # GCV is flat for one datum and the L-curve has no corner: one clear error each
        for crit, why in (("gcv", "GCV is flat"), ("lcurve", "no corner")):
            with pytest.raises(ValueError, match=f"criterion: '{crit}' cannot choose lam .*{why}"):
                quiet(invert_linear, op, np.array([d]), penalty="identity", noise_std=sigma, criterion=crit)
        with pytest.raises(ValueError, match=r"penalty: 'gradient' penalises nothing on a model grid of shape \(1,\)"):
            invert_linear(op, np.array([d]), penalty="gradient", noise_std=sigma)


def test_noise_below_rounding_is_one_clear_error(rng):
    op, data = problem(rng)
    for operator, method in ((op, "fft"), (op.todense(), "dense"), (aslinearoperator(op.todense()), "iterative")):
        with pytest.raises(ValueError, match="noise_std: 1e-300 is .* far below the float rounding of the data"):
            invert_linear(operator, data, noise_std=1e-300, method=method, spacing=DX)


def test_data_shape_must_match_the_operator(rng):
    op, data = problem(rng)
    with pytest.raises(ValueError, match=r"data: shape \(8, 8\) does not match the operator's data shape \(64,\)"):
        invert_linear(op.todense(), data.reshape(8, 8), lam=1.0)
    with pytest.raises(ValueError, match=r"data: shape \(64, 1\) does not match the operator's data shape \(64,\)"):
        invert_linear(op, data.reshape(64, 1), lam=1.0)
    from tactilab.inversion import gaussian_posterior

    with pytest.raises(ValueError, match=r"data: shape \(8, 8\) does not match"):
        gaussian_posterior(op.todense(), data.reshape(8, 8), np.ones(64), 1.0)
    # a 2-D grid operator takes its own (ny, nx) data shape, or the flat vector
    grid = FourierDiagonal(np.ones((4, 8)), DX)
    field = rng.standard_normal((4, 8))
    np.testing.assert_allclose(invert_linear(grid, field, penalty="identity", lam=1e-9).model, field, rtol=1e-6)
    np.testing.assert_allclose(invert_linear(grid, field.ravel(), penalty="identity", lam=1e-9).model, field,
                               rtol=1e-6)


def test_spectral_form_in_scaled_units():
    """A form of data 1e200 carried with data_scale: evidence and residual norm finite; curves in
    data units overflow to inf only where the true value exceeds the float range."""
    r = np.geomspace(1e-3, 1e3, 16)
    form = SpectralForm(ratio=r, coef2=np.ones(16), weights=np.ones(16), n_data=16, data_scale=1e200)
    ref = SpectralForm(ratio=r, coef2=np.ones(16), weights=np.ones(16), n_data=16)
    assert form.residual_norm(1.0) == pytest.approx(1e200 * ref.residual_norm(1.0), rel=1e-12)
    assert np.isinf(form.residual2(1.0))
    ll, sig = form.log_evidence(1.0, 1e200)
    assert ll == pytest.approx(ref.log_evidence(1.0, 1.0)[0] - 16 * np.log(1e200), rel=1e-12)
    assert sig == 1e200
    got, want = choose_lambda(form, noise_std=1e200).lam, choose_lambda(ref, noise_std=1.0).lam
    for name, lam in want.items():
        assert got[name] == pytest.approx(lam, rel=1e-9, nan_ok=True)
    with pytest.raises(ValueError, match="data_scale: must be finite and > 0"):
        SpectralForm(ratio=r, coef2=np.ones(16), weights=np.ones(16), n_data=16, data_scale=0.0)

"""Psychometric fits: sigmoid definitions, parameter recovery, interval coverage, bad input.

Oracles: each sigmoid's defining properties (F(threshold) = pc, F = alpha and 1 - alpha one
width apart, weibull = gumbel on log levels), recovery of known parameters from simulated
binomial data, 95 % interval coverage over 200 seeded repeats, a second sampler (emcee) on the
same posterior, and a finer grid as the reference for the interval ends.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

from tactilab.experiments import fit_psychometric
from tactilab.experiments.modelling.psychometric import SIGMOID_ALIASES, SIGMOIDS, ParamSummary, sigmoid_core

C_NORM = norm.ppf(0.95) - norm.ppf(0.05)


def _psi(x, t, w, lapse, guess=0.5):
    return guess + (1 - guess - lapse) * norm.cdf(C_NORM * (x - t) / w)


def _counts(seed, x, n, t=2.0, w=1.2, lapse=0.02, guess=0.5):
    return np.random.default_rng(seed).binomial(n, _psi(x, t, w, lapse, guess))


@pytest.mark.parametrize("name", sorted(SIGMOIDS))
def test_sigmoid_threshold_and_width_definitions(name):
    """psi at the MAP: F(threshold) = threshold_pc and F = alpha, 1 - alpha exactly one width apart."""
    x = np.array([1.0, 1.5, 2.0, 2.5, 3.0])
    fit = fit_psychometric(x, n_correct=[5, 8, 13, 18, 19], n_trials=[20] * 5, sigmoid=name,
                           threshold_pc=0.6, width_alpha=0.1, fixed={"lapse": 0.0}, rng=0)
    th, w = fit.params["threshold"].map, fit.params["width"].map
    assert fit.p_correct(th) == pytest.approx(0.5 + 0.5 * 0.6, abs=1e-12)
    lo, hi = fit.threshold_at(0.5 + 0.5 * 0.1), fit.threshold_at(0.5 + 0.5 * 0.9)
    if SIGMOIDS[name].log_levels:
        assert math.log(hi) - math.log(lo) == pytest.approx(w, rel=1e-10)
    else:
        assert hi - lo == pytest.approx(w, rel=1e-10)
    # slope: a central difference of p_correct
    h = 1e-6
    assert fit.slope_at(2.2) == pytest.approx((fit.p_correct(2.2 + h) - fit.p_correct(2.2 - h)) / (2 * h), rel=1e-6)
    core = SIGMOIDS[name]
    z = np.linspace(-3, 3, 13)
    np.testing.assert_allclose(core.ppf(core.cdf(z)), z, atol=1e-9)


def test_aliases_name_the_same_cores():
    assert sigmoid_core("normal_cdf") is SIGMOIDS["norm"]
    assert set(SIGMOID_ALIASES.values()) <= set(SIGMOIDS)


def test_weibull_is_gumbel_on_log_levels():
    x = np.array([0.5, 1.0, 2.0, 4.0, 8.0])
    k, n = [11, 12, 15, 19, 20], [20] * 5
    wb = fit_psychometric(x, n_correct=k, n_trials=n, sigmoid="weibull", rng=1)
    gu = fit_psychometric(np.log(x), n_correct=k, n_trials=n, sigmoid="gumbel", rng=1)
    assert wb.params["threshold"].map == pytest.approx(math.exp(gu.params["threshold"].map), rel=1e-6)
    assert wb.params["width"].map == pytest.approx(gu.params["width"].map, rel=1e-6)
    assert wb.params["threshold"].ci95[0] == pytest.approx(math.exp(gu.params["threshold"].ci95[0]), rel=1e-9)


def test_recovery_with_many_trials():
    x = np.linspace(1.0, 3.0, 8)
    n = np.full(8, 400)
    fit = fit_psychometric(x, n_correct=_counts(7, x, n), n_trials=n, rng=7)
    th, w = fit.params["threshold"], fit.params["width"]
    assert th.ci95[0] < 2.0 < th.ci95[1] and abs(th.map - 2.0) < 0.05
    assert w.ci95[0] < 1.2 < w.ci95[1] and abs(w.map - 1.2) < 0.15
    assert th.ci68[0] > th.ci95[0] and th.ci68[1] < th.ci95[1] and th.ci68[0] < th.median < th.ci68[1]
    assert fit.params["guess"] == ParamSummary(0.5, 0.5, 0.5, (0.5, 0.5), (0.5, 0.5))
    assert 0.05 < fit.gof_p < 1.0  # the true model fits: no evidence against it


@pytest.mark.slow
def test_interval_coverage_over_200_seeded_repeats():
    """The 95 % intervals of threshold and width cover the truth in 90 % to 98 % of 200 repeats."""
    x = np.linspace(1.0, 3.0, 6)
    n = np.full(6, 50)
    hits = {"threshold": 0, "width": 0}
    for seed in range(200):
        fit = fit_psychometric(x, n_correct=_counts(seed, x, n), n_trials=n, rng=seed)
        for name, truth in (("threshold", 2.0), ("width", 1.2)):
            lo, hi = fit.params[name].ci95
            hits[name] += lo <= truth <= hi
    for name, h in hits.items():
        assert 0.90 <= h / 200 <= 0.98, (name, h)


def test_per_trial_input_pools_to_counts():
    x = np.array([1.0, 2.0, 3.0])
    correct = [[1, 0, 1, 0, 0], [1, 1, 0, 1, 0], [1, 1, 1, 1, 0]]
    levels = np.repeat(x, 5)
    a = fit_psychometric(levels, np.concatenate(correct), rng=3)
    b = fit_psychometric(x, n_correct=[2, 3, 4], n_trials=[5, 5, 5], rng=3)
    assert a.params["threshold"] == b.params["threshold"]
    np.testing.assert_array_equal(a.tree["observed_data"]["n_correct"].values, [2, 3, 4])


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_emcee_agrees_with_the_grid():
    x = np.linspace(1.0, 3.0, 6)
    n = np.full(6, 60)
    k = _counts(11, x, n)
    g = fit_psychometric(x, n_correct=k, n_trials=n, rng=11)
    e = fit_psychometric(x, n_correct=k, n_trials=n, method="emcee", rng=11)
    for name in ("threshold", "width"):
        spread = g.params[name].ci95[1] - g.params[name].ci95[0]
        assert abs(e.params[name].mean - g.params[name].mean) < 0.05 * spread
        assert abs(e.params[name].ci95[0] - g.params[name].ci95[0]) < 0.1 * spread
        assert abs(e.params[name].ci95[1] - g.params[name].ci95[1]) < 0.1 * spread
    assert e.tree["posterior"]["threshold"].shape[1] > 10000


def test_emcee_runs_on_the_projects_one_sampler(monkeypatch):
    """method="emcee" samples through tactilab.inversion.sample_posterior (the one MCMC engine)."""
    import tactilab.inversion as inv

    calls = []
    real = inv.sample_posterior

    def spy(model, rng, **options):  # a short run: too short to converge, so the fit warns
        calls.append(tuple(model.param_names))
        return real(model, rng, **{**options, "max_steps": 100, "check_every": 100})

    monkeypatch.setattr(inv, "sample_posterior", spy)
    x = np.linspace(1.0, 3.0, 6)
    with pytest.warns(UserWarning, match="emcee: did NOT converge after 100 steps"):
        fit_psychometric(x, n_correct=_counts(4, x, np.full(6, 40)), n_trials=np.full(6, 40), method="emcee", rng=4)
    assert calls == [("lapse", "threshold", "width")]
    with pytest.raises(ValueError, match="method: 'emcee' needs at least one free parameter"):
        fit_psychometric(x, n_correct=_counts(4, x, np.full(6, 40)), n_trials=np.full(6, 40), method="emcee",
                         fixed={"threshold": 2.0, "width": 1.0, "lapse": 0.02}, rng=4)


def test_interval_ends_match_a_finer_grid(monkeypatch):
    from tactilab.experiments.modelling import _psychometric_grid as grid

    x = np.linspace(0.5, 3.5, 7)
    n = np.full(7, 40)
    k = _counts(1, x, n, t=2.0, w=1.0)
    coarse = fit_psychometric(x, n_correct=k, n_trials=n, rng=0)
    monkeypatch.setitem(grid._FINE, "nafc", dict(threshold=200, width=200, lapse=60, guess=1, eta=20))
    fine = fit_psychometric(x, n_correct=k, n_trials=n, rng=0)
    for name in ("threshold", "width"):
        spread = fine.params[name].ci95[1] - fine.params[name].ci95[0]
        for end in (0, 1):
            assert abs(coarse.params[name].ci95[end] - fine.params[name].ci95[end]) < 0.02 * spread
        assert coarse.params[name].mean == pytest.approx(fine.params[name].mean, rel=0.01)


@pytest.mark.parametrize("experiment, guess", [("yes_no", None), ("equal_asymptote", None), ("nafc:4", 0.25)])
def test_experiment_types(experiment, guess):
    x = np.linspace(1.0, 3.0, 6)
    n = np.full(6, 200)
    true_guess = 0.05 if experiment == "yes_no" else (0.03 if experiment == "equal_asymptote" else 0.25)
    lapse = 0.03 if experiment == "equal_asymptote" else 0.02
    k = np.random.default_rng(5).binomial(n, _psi(x, 2.0, 1.2, lapse, true_guess))
    fit = fit_psychometric(x, n_correct=k, n_trials=n, experiment=experiment, overdispersion=False, rng=5)
    th = fit.params["threshold"]
    assert th.ci95[0] < 2.0 < th.ci95[1]
    if guess is not None:
        assert fit.params["guess"].map == guess
    elif experiment == "equal_asymptote":
        assert fit.params["guess"] == fit.params["lapse"]
    else:
        assert fit.params["guess"].ci95[0] < 0.05 < fit.params["guess"].ci95[1]


def test_overdispersion_widens_the_threshold_interval():
    x = np.linspace(0.5, 3.5, 7)
    n = np.full(7, 40)
    k = _counts(1, x, n, t=2.0, w=1.0)
    plain = fit_psychometric(x, n_correct=k, n_trials=n, rng=0)
    over = fit_psychometric(x, n_correct=k, n_trials=n, overdispersion=True, rng=0)
    assert "eta" in over.params and "eta" not in plain.params
    width = (lambda s: s.ci95[1] - s.ci95[0])
    assert width(over.params["threshold"]) > width(plain.params["threshold"])


def test_deviance_closed_form_and_plot(tmp_path):
    x = np.array([1.0, 2.0, 3.0, 4.0])
    k, n = np.array([10, 14, 25, 29]), np.array([30, 30, 30, 30])
    fit = fit_psychometric(x, n_correct=k, n_trials=n, rng=2)
    p = fit.p_correct(x)
    dev = 2 * np.sum(k * np.log(k / (n * p)) + (n - k) * np.log((n - k) / (n * (1 - p))))
    assert fit.deviance == pytest.approx(dev, rel=1e-10)
    assert set(fit.tree.children) == {"posterior", "observed_data"}
    path = tmp_path / "fit.png"
    fit.plot(path, xlabel="amplitude (µm)")
    assert path.stat().st_size > 10_000


@pytest.mark.parametrize("kwargs, match", [
    (dict(levels=[1, 2, 3]), "correct: missing"),
    (dict(levels=[1, 2, 3], correct=[1, 0]), "correct: must have one entry per level"),
    (dict(levels=[1, 2, 3], correct=[1, 0, 2]), "correct: must hold 0/1"),
    (dict(levels=[1, 2, 3], correct=[1, 0, 1], n_correct=[1, 0, 1]), "not both"),
    (dict(levels=[1, np.nan, 3], correct=[1, 0, 1]), "levels: must be finite"),
    (dict(levels=[1, 2], n_correct=[1, 2], n_trials=[1, 2, 3]), "n_correct, n_trials: must match"),
    (dict(levels=[1, 2], n_correct=[3, 1], n_trials=[2, 2]), "n_correct: must be whole numbers"),
    (dict(levels=[1, 2], n_correct=[1, np.nan], n_trials=[2, 2]), "must be finite"),
    (dict(levels=[1, 1], n_correct=[1, 1], n_trials=[2, 2]), ">= 2 distinct levels"),
    (dict(levels=[0, 1], n_correct=[1, 1], n_trials=[2, 2], sigmoid="weibull"), "every level must be > 0"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], sigmoid="probit"), "sigmoid: must be one of"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], experiment="3afc"), "experiment: must be one of"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], experiment="nafc:1"), "integer N >= 2"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], threshold_pc=1.0), "threshold_pc: must lie"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], width_alpha=0.5), "width_alpha: must lie"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], method="mcmc"), "method: must be"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], fixed={"slope": 1}), "fixed: unknown parameter"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], fixed={"lapse": np.nan}), "finite number"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], fixed={"lapse": 1.0}), r"lapse must lie in \[0, 1\)"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], fixed={"width": -1.0}), "width must be > 0"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], fixed={"guess": 0.1}), "fix it only for 'yes_no'"),
    (dict(levels=[1, 2], n_correct=[1, 1], n_trials=[2, 2], priors="flat"), "priors: must be 'psignifit'"),
])
def test_bad_input(kwargs, match):
    levels = kwargs.pop("levels")
    with pytest.raises(ValueError, match=match):
        fit_psychometric(levels, **kwargs)


def test_threshold_at_outside_the_range():
    fit = fit_psychometric([1, 2, 3], n_correct=[6, 8, 10], n_trials=[10, 10, 10], rng=0)
    with pytest.raises(ValueError, match="pc: must lie strictly between the guess rate"):
        fit.threshold_at(0.4)

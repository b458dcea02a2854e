"""Transduction models: statistics (closed forms), the link, the observer, power; no sampling here.

Oracles: docs/theory.md 4a's sliding-sinusoid strain at nu = 1/2 (eps_xx = -eps_zz = K sin,
eps_zx = K cos, tensor shear, K = k^2 A Z exp(-k Z)), a brute-force fine sampling for peaks,
the signal-detection link written out, the simulated observer's response frequencies, and the
per-condition likelihood against the per-trial one.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from tactilab.data_schemas.experiment import Protocol, Stimulus
from tactilab.experiments.modelling.models import TransductionModel, power_analysis
from tactilab.experiments.modelling._transduction_data import TransductionLikelihood, conditions, default_priors, p_correct_table
from tactilab.experiments.session.responses import SimulatedObserver
from tactilab.experiments.procedures.tasks import TrialPlan, blank

GRATING = Stimulus(amplitude_m=1e-6, pitch_m=4e-3, speed_m_per_s=0.02, duration_s=0.1)


def _k(stim, depth):
    k = 2 * math.pi / stim.pitch_m
    return k * k * stim.amplitude_m * depth * math.exp(-k * depth)


@pytest.mark.parametrize("hypothesis, factor", [
    ("xx@1mm", 1.0), ("zz@1mm", 1.0), ("zx@1mm", 1.0), ("zx@1mm:engineering", 2.0), ("max_shear@1mm", 1.0),
    ("von_mises@1mm", math.sqrt(4 / 3)), ("deviatoric_norm@1mm", math.sqrt(2)), ("yy@1mm", 0.0),
    ("volumetric@1mm", 0.0),
])
def test_sinusoid_statistics_closed_form(hypothesis, factor):
    """A sinusoid at nu = 1/2: every linear in-plane readout has amplitude K, so peak = K and rms = K / sqrt 2
    for xx, zz, zx; the invariants are constant in x (peak = rms)."""
    K = _k(GRATING, 1e-3)
    peak = TransductionModel(hypothesis).statistic_of(GRATING)
    rms = TransductionModel(hypothesis, statistic="rms").statistic_of(GRATING)
    assert peak == pytest.approx(factor * K, rel=1e-9, abs=1e-18)
    constant = hypothesis.split("@")[0] in ("max_shear", "von_mises", "deviatoric_norm")
    assert rms == pytest.approx(factor * K / (1 if constant else math.sqrt(2)), rel=1e-9, abs=1e-18)


def test_square_peak_matches_brute_force_sampling():
    """The refined peak of a square surface (odd harmonics) equals a 2^18-point brute-force maximum."""
    square = GRATING.model_copy(update={"surface": "square"})
    for hyp in ("xx@0.7mm", "zx@0.7mm", "max_shear@0.7mm"):
        model = TransductionModel(hyp)
        x = np.linspace(0, square.pitch_m, 2 ** 18, endpoint=False)
        brute = float(np.abs(model._readouts(square, x)).max())
        assert model.statistic_of(square) == pytest.approx(brute, rel=1e-8)
    # gratings tell xx from zx apart only through harmonics: equal for a sinusoid, not for a square
    xx, zx = TransductionModel("xx@0.7mm"), TransductionModel("zx@0.7mm")
    assert xx.statistic_of(GRATING) == pytest.approx(zx.statistic_of(GRATING), rel=1e-12)
    assert abs(xx.statistic_of(square) / zx.statistic_of(square) - 1) > 0.05


def test_blank_cache_and_depths():
    model = TransductionModel("zx@1mm,2mm")
    assert model.statistic_of(blank(GRATING)) == 0.0
    assert model.statistic_of(GRATING) == pytest.approx(max(_k(GRATING, 1e-3), _k(GRATING, 2e-3)), rel=1e-9)
    assert GRATING in model._cache and model.name == "zx@1mm,2mm"


def test_link_closed_forms():
    model = TransductionModel("zx@1mm")
    s = model.statistic_of(GRATING)
    t, b, lam = 0.5 * s, 1.3, 0.03
    d = (s / t) ** b
    from scipy.stats import norm

    p = model.p_correct([(GRATING, blank(GRATING))], "2ifc", t, b, lam)
    assert p[0] == pytest.approx(0.5 + (0.5 - lam) * (2 * norm.cdf(d / math.sqrt(2)) - 1), rel=1e-12)
    p = model.p_correct([GRATING, blank(GRATING)], "yes_no", t, b, lam, false_alarm=0.2)
    yes = lam + (1 - 2 * lam) * norm.cdf(d + norm.ppf(0.2))
    np.testing.assert_allclose(p, [yes, 1 - (lam + (1 - 2 * lam) * 0.2)], rtol=1e-12)


def _protocol(kind="2ifc"):
    return Protocol.model_validate(dict(
        name="amp", seed=1, task=dict(kind=kind),
        stimulus=dict(amplitude_m="1um", pitch_m="4mm", speed_m_per_s="20mm/s", duration_s="100ms"),
        procedure=dict(method="constant_stimuli", parameter="amplitude_m", levels=["1um"])))


def test_observer_from_model_follows_the_link():
    """The observer's frequency of correct 2IFC answers matches the model's P(correct) (binomial 4 sd)."""
    model = TransductionModel("zx@1mm")
    s = model.statistic_of(GRATING)
    obs = SimulatedObserver.from_model(_protocol(), model, threshold_strain=s, exponent=2.0, lapse=0.05, seed=3)
    n = 4000
    hits = 0
    for i in range(n):
        plan = TrialPlan(i, 0, 0, "amplitude_m", 1e-6, (blank(GRATING), GRATING), "2", 0.5)
        obs.arm(plan, 0)
        hits += obs.collect(plan).label == "2"
    p = model.p_correct([(GRATING, blank(GRATING))], "2ifc", s, 2.0, 0.05)[0]
    assert abs(hits / n - p) < 4 * math.sqrt(p * (1 - p) / n)
    assert obs.config["lapse"] == 0.05 and obs.strain_source == "custom"


def _frame(model, n_per, amps, rng, t=2e-4, b=1.0, lam=0.02, pitches=(2e-3, 6e-3)):
    rows = []
    for p in pitches:
        for a in amps:
            stim = GRATING.model_copy(update={"amplitude_m": a, "pitch_m": p})
            prob = model.p_correct([(stim, blank(stim))], "2ifc", t, b, lam)[0]
            for ok in rng.random(n_per) < prob:
                first = rng.random() < 0.5
                rows.append({"stimuli": [stim, blank(stim)] if first else [blank(stim), stim],
                             "target": "1" if first else "2", "correct": bool(ok)})
    return pd.DataFrame(rows)


def test_per_trial_terms_sum_to_the_condition_total():
    model = TransductionModel("zx@1mm")
    frame = _frame(model, 30, [0.5e-6, 1e-6, 2e-6], np.random.default_rng(0))
    data = conditions(model, frame)
    assert data["s1"].size == 6 and data["n"].sum() == len(frame)
    lik = TransductionLikelihood(data, default_priors(data, None))
    theta = np.array([[2e-4, 1.0, 0.02], [3e-4, 1.5, 0.1]])
    np.testing.assert_allclose(lik.log_likelihood(theta).sum(axis=1), lik.total_log_likelihood(theta), rtol=1e-12)
    assert lik.log_likelihood(theta[0]).shape == (len(frame),)
    np.testing.assert_allclose(np.exp(lik._table(theta)[0]), p_correct_table("2ifc", data["s1"], data["s2"], theta),
                               rtol=1e-12)
    assert np.all(np.isfinite(lik.log_prior(lik.initial(np.random.default_rng(1), 50))))


def test_yes_no_likelihood_matches_the_link():
    """Yes/no trials (signal and catch): the likelihood's table equals the model's P(correct)."""
    model = TransductionModel("zx@1mm")
    stims = [GRATING.model_copy(update={"amplitude_m": a}) for a in (0.3e-6, 1e-6)] + [blank(GRATING)]
    rows = [{"stimuli": [s], "target": "yes" if s.amplitude_m > 0 else "no", "correct": bool(i % 2)}
            for i, s in enumerate(stims * 4)]
    data = conditions(model, pd.DataFrame(rows))
    assert data["kind"] == "yes_no" and data["s1"].size == 3
    lik = TransductionLikelihood(data, default_priors(data, None))
    theta = np.array([1e-4, 1.2, 0.03, 0.2])
    lp, _ = lik._table(theta)
    expected = model.p_correct([s for s in stims], "yes_no", 1e-4, 1.2, 0.03, false_alarm=0.2)
    order = [list(zip(data["s1"], data["s2"])).index((model.statistic_of(s), float(s.amplitude_m > 0))) for s in stims]
    np.testing.assert_allclose(np.exp(lp[0, order]), expected, rtol=1e-12)
    np.testing.assert_allclose(lik.log_likelihood(theta[None]).sum(), lik.total_log_likelihood(theta[None])[0],
                               rtol=1e-12)


def test_power_identical_predictions_and_a_distinguishable_pair():
    """xx and zx at one depth read the same peak of every sinusoidal grating: mu = 0, infinite trials.
    One depth against another over two pitches: mu > 0 and N = (z sigma / mu)^2."""
    design = [(GRATING.model_copy(update={"amplitude_m": a, "pitch_m": p}), 40)
              for a in (0.5e-6, 1e-6, 2e-6) for p in (2e-3, 6e-3)]
    truth = dict(threshold_strain=2e-4, exponent=1.0, lapse=0.02)
    tie = power_analysis(TransductionModel("zx@1mm"), truth, TransductionModel("xx@1mm"), design)
    assert abs(tie.mu) < 1e-12 and tie.trials_for() == math.inf
    assert tie.rival_params["threshold_strain"] == pytest.approx(2e-4, rel=1e-5)
    same = power_analysis(TransductionModel("zx@1mm"), truth, TransductionModel("zx@1mm:engineering"), design)
    assert abs(same.mu) < 1e-12 and same.rival_params["threshold_strain"] == pytest.approx(4e-4, rel=1e-5)
    pair = power_analysis(TransductionModel("zx@1mm"), truth, TransductionModel("zx@2mm"), design)
    assert pair.mu > 1e-3 and pair.trials_for(4.0) == pytest.approx((4 * pair.sigma / pair.mu) ** 2)
    assert pair.p_select(int(pair.trials_for(4.0))) == pytest.approx(0.5, abs=1e-3)


@pytest.mark.slow
def test_power_simulated_agrees_with_asymptotic():
    design = [(GRATING.model_copy(update={"amplitude_m": a, "pitch_m": p}), 40)
              for a in (0.5e-6, 1e-6, 2e-6) for p in (2e-3, 6e-3)]
    truth = dict(threshold_strain=2e-4, exponent=1.0, lapse=0.02)
    args = (TransductionModel("zx@1mm"), truth, TransductionModel("zx@2mm"), design)
    asym = power_analysis(*args)
    sim = power_analysis(*args, method="simulate", n_repeats=60, rng=4)
    n = int(asym.trials_for(2.0))
    assert abs(sim.p_select(n, z=2.0) - asym.p_select(n, z=2.0)) < 0.2


@pytest.mark.parametrize("kwargs, match", [
    (dict(statistic="max"), "statistic: must be one of"),
    (dict(source="finger"), "source: must be one of"),
    (dict(source="display"), "display: source='display' needs a SimulatedDisplay"),
])
def test_bad_model(kwargs, match):
    with pytest.raises(ValueError, match=match):
        TransductionModel("zx@1mm", **kwargs)


def test_bad_component_and_inputs():
    with pytest.raises(ValueError, match="qq"):
        TransductionModel("qq@1mm")
    model = TransductionModel("zx@1mm")
    with pytest.raises(ValueError, match="stimulus: expected a data_schemas Stimulus"):
        model.statistic_of({"amplitude_m": 1e-6})
    with pytest.raises(ValueError, match="false_alarm: a yes/no model needs"):
        model.p_correct([GRATING], "yes_no", 1e-4, 1.0, 0.0)
    with pytest.raises(ValueError, match="task: must be '2ifc' or 'yes_no'"):
        model.p_correct([GRATING], "2afc", 1e-4, 1.0, 0.0)
    with pytest.raises(ValueError, match="lapse: must lie in"):
        SimulatedObserver.from_model(_protocol(), model, 1e-4, lapse=0.5)
    with pytest.raises(ValueError, match="model: expected a TransductionModel"):
        SimulatedObserver.from_model(_protocol(), object(), 1e-4)


def test_bad_trials():
    model = TransductionModel("zx@1mm")
    frame = _frame(model, 3, [1e-6], np.random.default_rng(0))
    with pytest.raises(ValueError, match="no 'correct' column"):
        conditions(model, frame.drop(columns="correct"))
    mixed = pd.concat([frame, pd.DataFrame([{"stimuli": [GRATING], "target": "yes", "correct": True}])])
    with pytest.raises(ValueError, match="mixed tasks in one fit"):
        conditions(model, mixed)
    with pytest.raises(ValueError, match="mixed tasks in one fit"):
        conditions(model, frame, task="yes_no")
    with pytest.raises(ValueError, match="no session file at"):
        conditions(model, "/nonexistent/s.sqlite")
    with pytest.raises(ValueError, match="trials: expected session"):
        conditions(model, 42)
    with pytest.raises(ValueError, match="every stimulus has statistic 0"):
        data = conditions(TransductionModel("yy@1mm"), frame)
        default_priors(data, None)
    with pytest.raises(ValueError, match="priors: 'slope' must be one of"):
        default_priors(conditions(model, frame), {"slope": None})


def test_bad_power_inputs():
    m = TransductionModel("zx@1mm")
    good = dict(threshold_strain=2e-4, exponent=1.0, lapse=0.02)
    design = [(GRATING, 10)]
    for kwargs, match in ((dict(task="2afc"), "task: must be"), (dict(method="exact"), "method: must be")):
        with pytest.raises(ValueError, match=match):
            power_analysis(m, good, m, design, **kwargs)
    with pytest.raises(ValueError, match="true_params: need exactly"):
        power_analysis(m, {"threshold_strain": 1e-4}, m, design)
    with pytest.raises(ValueError, match="true_params: need threshold_strain > 0"):
        power_analysis(m, {**good, "lapse": 0.7}, m, design)
    with pytest.raises(ValueError, match="design: give a non-empty list"):
        power_analysis(m, good, m, [(GRATING, 0)])
    with pytest.raises(ValueError, match="rival: every design stimulus has statistic 0"):
        power_analysis(m, good, TransductionModel("yy@1mm"), design)
    with pytest.raises(ValueError, match="n: must be a positive whole number"):
        power_analysis(m, good, TransductionModel("zx@2mm"), design).p_select(0)

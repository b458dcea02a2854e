"""Procedures and tasks: staircase rules and convergence (Levitt 1971), psi as exact Bayes with
expected-entropy minimisation (Kontsevich & Tyler 1999), parameter recovery, constant stimuli."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from tactilab.data_schemas.experiment import (
    ConstantStimuliConfig, Protocol, PsiConfig, StaircaseConfig)
from tactilab.experiments.procedures.build import make_procedure
from tactilab.experiments.procedures import ConstantStimuli, PlannedLevel, Staircase, replay
from tactilab.experiments.procedures.psi import Psi, psychometric, resolve_likelihood
from tactilab.experiments.procedures.registry import UnregisteredError, register_likelihood, register_procedure
from tactilab.experiments.procedures.tasks import outcome_of, plan_trial, score


def staircase(**track) -> Staircase:
    base = {"start": 10.0, "step_sizes": [2.0, 1.0], "step_scale": "linear", "min_level": 5.0,
            "max_level": 20.0, "max_trials": 100}
    base.update(track)
    return Staircase(StaircaseConfig(method="staircase", parameter="amplitude_m", tracks=[base]))


def run(procedure, outcomes, rng=None):
    rng = rng or np.random.default_rng(0)
    levels = []
    for i, outcome in enumerate(outcomes):
        planned = procedure.next_trial(i, rng)
        levels.append(planned.level)
        procedure.update(planned, outcome)
    return levels


def test_one_up_two_down_rule_by_hand():
    """Two positives in a row step down, one negative steps up; reversals shrink the step."""
    proc = staircase()
    levels = run(proc, [True, True, False, True, True, True, True, False])
    # 10,10 -> down 2 -> 8; F -> up (reversal at 8, step 1) -> 9; T,T -> down (reversal at 9) -> 8;
    # T,T -> down (no reversal) -> 7; F -> up (reversal at 7) -> 8
    assert levels == [10, 10, 8, 9, 9, 8, 8, 7]
    assert proc.state()["reversals"] == [[8.0, 9.0, 7.0]] and proc.state()["levels"] == [8.0]
    assert proc.estimate()["threshold"] == pytest.approx(8.0)


def test_staircase_clamps_and_log_steps():
    proc = staircase(start=6.0, min_level=5.0, down=1)
    assert run(proc, [True, True, True]) == [6.0, 5.0, 5.0]
    proc = staircase(step_scale="log", step_sizes=[math.log10(2)], start=8.0, max_level=20.0, up=1, down=1)
    assert run(proc, [False, False, True]) == pytest.approx([8.0, 16.0, 20.0])
    assert proc.estimate()["threshold"] == pytest.approx(20.0)  # geometric mean of the single reversal


def test_interleaved_tracks_finish_on_trials_or_reversals():
    config = StaircaseConfig(method="staircase", parameter="amplitude_m", tracks=[
        {"start": 10.0, "step_sizes": [1.0], "step_scale": "linear", "min_level": 1.0, "max_level": 20.0, "max_trials": 6},
        {"start": 4.0, "step_sizes": [1.0], "step_scale": "linear", "min_level": 1.0, "max_level": 20.0,
         "max_trials": 50, "max_reversals": 2, "down": 1}])
    proc = Staircase(config)
    rng = np.random.default_rng(3)
    tracks = []
    while (planned := proc.next_trial(proc.n_done, rng)) is not None:
        tracks.append(planned.track)
        proc.update(planned, planned.track == 0 or proc.n_done % 2 == 0)
    assert tracks.count(0) == 6 and len(proc.state()["reversals"][1]) == 2
    assert set(tracks[:6]) == {0, 1}  # interleaved, not one after the other
    assert proc.n_planned == 56 and proc.finished


@pytest.mark.parametrize("down,target", [(2, 2 ** -0.5), (3, 2 ** (-1 / 3))])
def test_transformed_staircase_converges_to_levitt_target(down, target):
    """1-up-2-down tracks p = 0.707, 1-up-3-down p = 0.794 of a known psychometric function."""
    f = psychometric("weibull", 0.5)
    truth = dict(threshold=4e-6, slope=3.0, lapse=0.0)
    x_target = brentq(lambda x: f(x, **truth) - target, 1e-7, 1e-4)
    config = StaircaseConfig(method="staircase", parameter="amplitude_m", tracks=[
        {"start": 2e-5, "down": down, "step_sizes": [0.1, 0.03], "min_level": 1e-7, "max_level": 1e-4,
         "max_trials": 3000, "estimate_reversals": 150}])
    proc = Staircase(config)
    rng = np.random.default_rng(11)
    while (planned := proc.next_trial(proc.n_done, rng)) is not None:
        proc.update(planned, bool(rng.random() < f(planned.level, **truth)))
    assert proc.estimate()["threshold"] == pytest.approx(x_target, rel=0.06)


def psi_config(**changes) -> PsiConfig:
    data = dict(method="psi", parameter="amplitude_m", levels=list(np.geomspace(0.5e-6, 20e-6, 25)),
                parameters={"threshold": list(np.geomspace(1e-6, 12e-6, 25)), "slope": [1.5, 2.5, 4.0],
                            "lapse": [0.0, 0.03]}, n_trials=120)
    data.update(changes)
    return PsiConfig(**data)


def test_psi_is_exact_bayes_and_minimises_expected_entropy():
    """Independent brute force: posterior = normalised product of likelihoods; the chosen level
    minimises the expected posterior entropy computed level by level."""
    config = psi_config(levels=[1e-6, 3e-6, 9e-6], parameters={"threshold": [2e-6, 4e-6, 8e-6], "slope": [2.0],
                                                               "lapse": [0.0]}, n_trials=5)
    proc = Psi(config, guess_rate=0.5)
    f = psychometric("weibull", 0.5)
    thetas = [2e-6, 4e-6, 8e-6]
    history = []
    rng = np.random.default_rng(1)
    for i in range(4):
        post = np.ones(3)
        for x, o in history:
            post *= [f(x, t, 2.0, 0.0) if o else 1 - f(x, t, 2.0, 0.0) for t in thetas]
        post /= post.sum()
        np.testing.assert_allclose(proc.posterior(), post, rtol=1e-12)

        def expected_entropy(x):
            total = 0.0
            for o in (True, False):
                like = np.array([f(x, t, 2.0, 0.0) if o else 1 - f(x, t, 2.0, 0.0) for t in thetas])
                p_o = like @ post
                new = like * post / p_o
                total += p_o * -np.sum(new * np.log(new))
            return total

        best = min(config.levels, key=expected_entropy)
        planned = proc.next_trial(i, rng)
        assert planned.level == best
        outcome = bool(i % 2)
        proc.update(planned, outcome)
        history.append((planned.level, outcome))


def test_psi_recovers_the_parameters_of_a_simulated_observer():
    truth = dict(threshold=4e-6, slope=2.5, lapse=0.0)
    f = psychometric("weibull", 0.5)
    proc = Psi(psi_config(), guess_rate=0.5)
    rng = np.random.default_rng(5)
    first_sd = None
    while (planned := proc.next_trial(proc.n_done, rng)) is not None:
        proc.update(planned, bool(rng.random() < f(planned.level, **truth)))
        if proc.n_done == 10:
            first_sd = proc.estimate()["threshold_sd"]
    est = proc.estimate()
    assert abs(est["threshold"] - truth["threshold"]) < 2.5 * est["threshold_sd"]
    assert est["threshold"] == pytest.approx(truth["threshold"], rel=0.2)
    assert est["threshold_sd"] < 0.5 * first_sd
    assert proc.record_state()["n_trials"] == 120 and proc.record_state()["entropy_nats"] > 0


def strain_likelihood(level, gain, exponent):
    """A transduction-model likelihood (any callable): 2IFC with d' = (gain * level)^exponent."""
    from scipy.special import ndtr

    return 0.5 + 0.5 * (2 * ndtr(np.power(gain * level, exponent) / math.sqrt(2)) - 1)


def test_psi_accepts_any_likelihood_callable_and_registered_name():
    register_likelihood("test_strain_likelihood", strain_likelihood, replace=True)
    grid = {"gain": list(np.geomspace(5e4, 1e6, 30)), "exponent": [1.0, 2.0]}
    config = psi_config(likelihood="test_strain_likelihood", parameters=grid, n_trials=150)
    truth = dict(gain=2.5e5, exponent=2.0)
    for proc in (Psi(config, likelihood=strain_likelihood), make_procedure(config, 0.5)):  # callable, then name
        rng = np.random.default_rng(2)
        while (planned := proc.next_trial(proc.n_done, rng)) is not None:
            proc.update(planned, bool(rng.random() < strain_likelihood(planned.level, **truth)))
        assert proc.estimate()["gain"] == pytest.approx(truth["gain"], rel=0.25)
        assert proc.estimate()["exponent"] == pytest.approx(2.0, abs=0.3)


@pytest.mark.parametrize("likelihood,match", [
    (lambda level, threshold, slope, lapse: np.ones(3), "must return p\\(positive\\) of shape"),
    (lambda level, threshold, slope, lapse: 2.0 + 0 * level * threshold, "outside \\[0, 1\\] or NaN"),
    (lambda level, threshold, slope, lapse: np.nan + 0 * level * threshold, "outside \\[0, 1\\] or NaN"),
    ("not callable", "must be callable"),
])
def test_bad_likelihoods_are_refused(likelihood, match):
    with pytest.raises(ValueError, match=match):
        Psi(psi_config(), likelihood=likelihood)


def test_likelihood_names_are_looked_up_never_imported():
    with pytest.raises(UnregisteredError, match="'nopkg_xyz' is not registered in this process; register it"):
        resolve_likelihood("nopkg_xyz")
    with pytest.raises(ValueError, match="never holds an import path"):
        resolve_likelihood("math:pi")
    with pytest.raises(ValueError, match="family: must be one of"):
        psychometric("cubic", 0.5)


@pytest.mark.parametrize("args,match", [
    (("weibull", strain_likelihood), "'weibull' is a built-in psychometric family"),
    (("Bad Name", strain_likelihood), "name: must be the name of a registered likelihood"),
    (("fine_name", 3.0), "f: must be callable"),
])
def test_register_likelihood_validates(args, match):
    with pytest.raises(ValueError, match=match):
        register_likelihood(*args)


def test_register_likelihood_refuses_to_replace_silently():
    register_likelihood("test_once", strain_likelihood, replace=True)
    register_likelihood("test_once", strain_likelihood)  # the same function again is fine
    with pytest.raises(ValueError, match="already registered; pass replace=True"):
        register_likelihood("test_once", lambda level, **p: level)


def test_a_new_procedure_plugs_in_without_touching_the_runner():
    """register_procedure: a protocol names the new method, the runner builds and runs it."""
    from typing import Literal

    from tactilab.data_schemas.experiment_procedures import ProcedureConfigBase

    class FixedConfig(ProcedureConfigBase):
        method: Literal["fixed_levels"]
        levels: list[float]

    class Fixed(ConstantStimuli.__mro__[1]):  # the Procedure base
        def __init__(self, config):
            super().__init__(config)

        n_planned = property(lambda self: len(self.config.levels))
        finished = property(lambda self: self.n_done >= len(self.config.levels))

        def _next(self, rng):
            return PlannedLevel(self.config.levels[self.n_done])

        def _update(self, planned, outcome):
            pass

        def estimate(self):
            return {"threshold": None}

    register_procedure("fixed_levels", FixedConfig, lambda config, *, guess_rate: Fixed(config), replace=True)
    fixed = Protocol.model_validate({
        "name": "t", "seed": 1, "task": {"kind": "2ifc"},
        "stimulus": {"amplitude_m": "5um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s"},
        "procedure": {"method": "fixed_levels", "parameter": "amplitude_m", "levels": [1e-6, 2e-6]}})
    assert isinstance(fixed.procedure, FixedConfig)
    assert Protocol.model_validate_json(fixed.to_json()).procedure == fixed.procedure
    proc = make_procedure(fixed.procedure, 0.5)
    assert [proc.next_trial(0, np.random.default_rng(0)).level] == [1e-6]
    with pytest.raises(ValueError, match="procedure 'fixed_levels' is already registered"):
        register_procedure("fixed_levels", FixedConfig, lambda config, *, guess_rate: None)
    register_procedure("fixed_levels", FixedConfig, lambda config, *, guess_rate: object(), replace=True)
    with pytest.raises(TypeError, match="returned object, not a tactilab.experiments.procedures.Procedure"):
        make_procedure(fixed.procedure, 0.5)
    with pytest.raises(ValueError, match="factory: must be callable"):
        register_procedure("other_levels", FixedConfig, "nope")
    with pytest.raises(ValueError, match="config_cls: must be a subclass"):
        register_procedure("other_levels", dict, lambda config, *, guess_rate: None)


@pytest.mark.parametrize("family,core", [
    ("weibull", lambda x, t, b: 1 - math.exp(-((x / t) ** b))),
    ("gumbel", lambda x, t, b: 1 - math.exp(-(10 ** (b * math.log10(x / t))))),
    ("logistic", lambda x, t, b: 1 / (1 + math.exp(-b * (x - t) / t))),
    ("normal_cdf", lambda x, t, b: 0.5 * math.erfc(-b * (x - t) / t / math.sqrt(2))),
])
def test_psychometric_families_match_their_textbook_forms(family, core):
    f = psychometric(family, 0.5)
    for x in (0.3e-6, 3e-6, 7e-6, 40e-6):
        assert f(x, threshold=3e-6, slope=2.0, lapse=0.1) == pytest.approx(0.5 + 0.4 * core(x, 3e-6, 2.0), rel=1e-12)


def test_constant_stimuli_blocks_are_balanced_shuffled_and_reproducible():
    config = ConstantStimuliConfig(method="constant_stimuli", parameter="amplitude_m", levels=[1e-6, 2e-6, 3e-6],
                                   repeats_per_block=4, n_blocks=3)

    def sequence(seed):
        proc = ConstantStimuli(config)
        out = []
        while (p := proc.next_trial(proc.n_done, np.random.default_rng([seed, proc.n_done]))) is not None:
            out.append((p.block, p.level))
            proc.update(p, None)
        return out

    seq = sequence(1)
    assert len(seq) == 36 and seq == sequence(1) and seq != sequence(2)
    for block in range(3):
        levels = [lv for b, lv in seq if b == block]
        assert sorted(levels) == sorted([1e-6, 2e-6, 3e-6] * 4)
    assert [lv for b, lv in seq if b == 0] != [lv for b, lv in seq if b == 1]


def test_constant_stimuli_estimate_interpolates_the_midpoint():
    config = ConstantStimuliConfig(method="constant_stimuli", parameter="amplitude_m", levels=[1.0, 2.0, 3.0],
                                   repeats_per_block=2, n_blocks=1)
    proc = ConstantStimuli(config, guess_rate=0.5)
    assert proc.estimate() == {"threshold": None}
    rng = np.random.default_rng(0)
    outcomes = {1.0: [False, True], 2.0: [True, True], 3.0: [True, True]}  # p = 0.5, 1, 1
    while (p := proc.next_trial(proc.n_done, rng)) is not None:
        proc.update(p, outcomes[p.level].pop())
    assert proc.proportions() == {1.0: (1, 2), 2.0: (2, 2), 3.0: (2, 2)}
    assert proc.estimate()["threshold"] == pytest.approx(1.5)  # 0.75 halfway between 0.5 and 1


def test_procedure_guards():
    proc = staircase()
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="trials run in order; expected 0, got 3"):
        proc.next_trial(3, rng)
    with pytest.raises(ValueError, match="update\\(\\) must follow next_trial\\(\\)"):
        proc.update(PlannedLevel(10.0), True)
    planned = proc.next_trial(0, rng)
    with pytest.raises(ValueError, match="outcome: must be True, False or None"):
        proc.update(planned, "yes")
    with pytest.raises(ValueError, match="procedure None is not registered"):
        make_procedure(object())
    proc.update(planned, True)
    with pytest.raises(ValueError, match="replay needs a fresh procedure"):
        replay(proc, [], lambda i: rng)
    with pytest.raises(ValueError, match="history: trial 0 recorded level 12.0"):
        replay(staircase(), [{"trial_index": 0, "track": 0, "level": 12.0, "outcome": True}], lambda i: rng)


def test_none_outcomes_leave_adaptive_state_unchanged():
    proc = staircase()
    run(proc, [None, None, True])
    assert proc.state()["levels"] == [10.0] and proc.state()["run_positive"] == [1]
    psi = Psi(psi_config(n_trials=2), guess_rate=0.5)
    before = psi.posterior()
    run(psi, [None, None])
    np.testing.assert_array_equal(psi.posterior(), before)
    assert not psi.finished


# ----- tasks -------------------------------------------------------------------------------
def protocol(task, **extra) -> Protocol:
    return Protocol.model_validate({
        "name": "t", "seed": 1, "task": task, **extra,
        "stimulus": {"amplitude_m": "5um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s"},
        "procedure": {"method": "constant_stimuli", "parameter": "amplitude_m", "levels": ["3um"]}})


def test_task_plans_draw_targets_from_the_trial_generator():
    p = protocol({"kind": "2ifc"})
    plans = [plan_trial(p, i, PlannedLevel(3e-6), np.random.default_rng([1, i])) for i in range(400)]
    firsts = sum(plan.target == "1" for plan in plans)
    assert 160 < firsts < 240  # binomial(400, 0.5): +-4 sd
    for plan in plans:
        test, blank = plan.stimuli if plan.target == "1" else plan.stimuli[::-1]
        assert test.amplitude_m == 3e-6 and blank.amplitude_m == 0.0
    again = plan_trial(p, 7, PlannedLevel(3e-6), np.random.default_rng([1, 7]))
    assert again == plans[7]


def test_yes_no_same_different_and_2afc_plans():
    yn = protocol({"kind": "yes_no", "catch_rate": 0.25})
    targets = [plan_trial(yn, i, PlannedLevel(3e-6), np.random.default_rng(i)).target for i in range(400)]
    assert 60 < targets.count("no") < 140
    ref = {"amplitude_m": "5um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s"}
    sd = protocol({"kind": "same_different"}, reference=ref)
    plan = next(plan_trial(sd, i, PlannedLevel(3e-6), np.random.default_rng(i)) for i in range(50)
                if plan_trial(sd, i, PlannedLevel(3e-6), np.random.default_rng(i)).target == "same")
    assert plan.stimuli[0] == plan.stimuli[1] == sd.reference
    afc = protocol({"kind": "2afc", "alternatives": {"left": {"speed_m_per_s": "-40mm/s"},
                                                     "right": {"speed_m_per_s": "40mm/s"}}})
    plan = plan_trial(afc, 0, PlannedLevel(3e-6), np.random.default_rng(0))
    (shown,) = plan.stimuli
    assert math.copysign(1, shown.speed_m_per_s) == (1 if plan.target == "right" else -1)
    assert shown.amplitude_m == 3e-6
    me = protocol({"kind": "magnitude_estimation"})
    plan = plan_trial(me, 0, PlannedLevel(3e-6), np.random.default_rng(0))
    assert plan.target is None and score(me, plan, "7") == (None, None)


@pytest.mark.parametrize("kind,target,response,expected", [
    ("2ifc", "1", "1", True), ("2ifc", "1", "2", False), ("2afc", "left", "right", False),
    ("yes_no", "yes", "yes", True), ("yes_no", "yes", "no", False), ("yes_no", "no", "yes", None),
    ("same_different", "different", "different", True), ("same_different", "same", "different", None),
    ("magnitude_estimation", None, "5", None),
])
def test_outcome_counted_by_adaptive_procedures(kind, target, response, expected):
    assert outcome_of(kind, target, response) is expected


def test_score_refuses_unknown_responses():
    p = protocol({"kind": "2ifc"})
    plan = plan_trial(p, 0, PlannedLevel(3e-6), np.random.default_rng(0))
    with pytest.raises(ValueError, match="response: must be one of \\['1', '2'\\], got 'x'"):
        score(p, plan, "x")

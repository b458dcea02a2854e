"""ModelDiscrimination: exact information gain, order invariance, recovery, metameres, errors."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from tactilab.data_schemas.experiment import Stimulus
from tactilab.experiments import ModelDiscrimination
from tactilab.experiments.modelling._transduction_data import p_correct_table
from tactilab.experiments.modelling.design import information_gain, metameric_groups


def _sines(amps=(3e-6, 8e-6, 2e-5, 5e-5), pitches=(1.5e-3, 3e-3, 6e-3)):
    return [Stimulus(amplitude_m=a, pitch_m=p, speed_m_per_s=0.02) for a in amps for p in pitches]


def _brute(table, w, utility):
    """I(Y; m), I(Y; theta | m), I(Y; m, theta), and the expected change of the generating model's
    log posterior odds ("odds"), by enumerating every (y, m, g) and applying Bayes' rule."""
    n_c, n_m, n_g = table.shape
    out = []
    for c in range(n_c):
        joint = {}  # (y, m, g) -> probability
        for y, m, g in itertools.product((0, 1), range(n_m), range(n_g)):
            p = table[c, m, g] if y else 1 - table[c, m, g]
            joint[y, m, g] = w[m, g] * p

        def marg(keep):
            d = {}
            for k, v in joint.items():
                key = tuple(k[i] for i in keep)
                d[key] = d.get(key, 0.0) + v
            return d

        py, pm, pym, pmg = marg([0]), marg([1]), marg([0, 1]), marg([1, 2])
        i_model = sum(v * math.log(v / (py[(y,)] * pm[(m,)])) for (y, m), v in pym.items() if v > 0)
        i_both = sum(v * math.log(v / (py[(y,)] * pmg[(m, g)])) for (y, m, g), v in joint.items() if v > 0)
        # "odds": E over (m, g, y) of log-odds of m after y (by Bayes' rule) minus log-odds of m before
        odds = sum(v * (math.log(pym[(y, m)] / (py[(y,)] - pym[(y, m)])) - math.log(pm[(m,)] / (1 - pm[(m,)])))
                   for (y, m, g), v in joint.items() if v > 0)
        out.append({"model": i_model, "parameters": i_both - i_model, "both": i_both, "odds": odds}[utility])
    return np.array(out)


@pytest.mark.parametrize("utility", ["odds", "model", "parameters", "both"])
def test_information_gain_matches_brute_force_enumeration(utility):
    rng = np.random.default_rng(4)
    table = rng.uniform(0.02, 0.98, (5, 3, 4))
    w = rng.random((3, 4))
    w /= w.sum()
    np.testing.assert_allclose(information_gain(table, w, utility), _brute(table, w, utility), rtol=1e-9, atol=1e-12)
    if utility in ("model", "odds"):  # about metameric groups: models 0 and 1 merged into one model
        merged_w = np.concatenate([w[:2].reshape(1, -1), np.pad(w[2:], ((0, 0), (0, 4)))])
        merged_t = np.concatenate([table[:, :2].reshape(5, 1, -1), np.pad(table[:, 2:], ((0, 0), (0, 0), (0, 4)),
                                                                           constant_values=0.5)], axis=1)
        np.testing.assert_allclose(information_gain(table, w, utility, groups=np.array([0, 0, 1])),
                                   _brute(merged_t, merged_w, utility), rtol=1e-9, atol=1e-12)
    if utility == "odds":  # every model in one group: no odds to gain
        np.testing.assert_array_equal(information_gain(table, w, "odds", groups=np.array([0, 0, 0])), 0.0)


def test_choice_is_invariant_to_candidate_order():
    cands = _sines()
    a = ModelDiscrimination(["zx@1mm", "zx@2mm"], cands, rng=0)
    b = ModelDiscrimination(["zx@1mm", "zx@2mm"], cands[::-1], rng=1)
    for step in range(6):
        ia, ib = a.choose(), b.choose()
        assert a.candidates[ia] == b.candidates[ib]
        np.testing.assert_array_equal(a.utilities(), b.utilities())
        a.observe(ia, step % 3 != 0)
        b.observe(ib, step % 3 != 0)
    assert a.probabilities == b.probabilities and len(a.probabilities) == 6


def _simulate(design, truth_index, theta, rng):
    s = design.stats[truth_index]
    p = p_correct_table(design.task, s[:, 0], s[:, 1], np.array([theta]))[0]
    while not design.finished:
        i = design.choose()
        design.observe(i, bool(rng.random() < p[i]))
    return design


@pytest.mark.parametrize("truth", [0, 1])
def test_observer_reading_one_hypothesis_ends_with_it_most_probable(truth):
    models = ["zx@1mm", "zx@2mm"]
    for seed in range(5):
        d = ModelDiscrimination(models, _sines(), rng=seed, max_trials=300)
        ref = np.median(d.stats[truth][:, 0])
        _simulate(d, truth, [ref, 1.3, 0.02], np.random.default_rng(seed))
        probs = d.model_probabilities()
        assert max(probs, key=probs.get) == models[truth], (seed, probs)
        assert d.winner == models[truth] and d.verdict == f"winner: {models[truth]}"
        assert len(d.probabilities) == d.n_done or len(d.probabilities) <= 300


def test_identical_hypotheses_are_reported_at_start_and_never_win():
    # engineering shear doubles zx: the statistics are proportional over every candidate
    with pytest.warns(UserWarning, match="metameric over every candidate"):
        d = ModelDiscrimination(["zx@1mm", "zx@1mm:engineering"], _sines(), rng=0)
    assert d.metameric_groups == [("zx@1mm", "zx@1mm:engineering")]
    assert d.finished and d.winner is None and d.verdict.startswith("nothing to learn")
    assert np.all(d.utilities() < 1e-12)
    with pytest.warns(UserWarning, match="metameric"):
        d = ModelDiscrimination(["zx@1mm", "zx@1mm:engineering", "zx@2mm"], _sines(), rng=0, max_trials=200)
    _simulate(d, 0, [np.median(d.stats[0][:, 0]), 1.0, 0.02], np.random.default_rng(0))
    for probs in d.probabilities:  # never a winner inside the metameric pair
        assert max(probs["zx@1mm"], probs["zx@1mm:engineering"]) < 0.99
    assert d.winner is None and d.verdict == "metameric: zx@1mm, zx@1mm:engineering"


def test_metameric_groups_power_law_and_single_stimulus():
    s = np.array([[[1.0, 0], [2.0, 0], [4.0, 0]], [[3.0, 0], [12.0, 0], [48.0, 0]], [[1.0, 0], [3.0, 0], [4.0, 0]]])
    assert metameric_groups(s, ["a", "b", "c"]) == [("a", "b"), ("c",)]  # b = 3 a^2
    assert metameric_groups(s[:, :1], ["a", "b", "c"]) == [("a", "b", "c")]  # one stimulus: rate zero


def test_square_gratings_chosen_when_hypotheses_differ_only_in_the_component():
    sines = [Stimulus(amplitude_m=a, pitch_m=p, speed_m_per_s=0.02) for a in (5e-6, 2e-5) for p in (2e-3, 4e-3)]
    squares = [Stimulus(surface="square", amplitude_m=a, pitch_m=4e-3, speed_m_per_s=0.02) for a in (5e-6, 2e-5)]
    with pytest.warns(UserWarning, match="metameric"):  # sinusoids alone cannot separate xx from zx
        ModelDiscrimination(["xx@1mm", "zx@1mm"], sines)
    d = ModelDiscrimination(["xx@1mm", "zx@1mm"], sines + squares, rng=0)
    assert d.metameric_groups == [("xx@1mm",), ("zx@1mm",)]
    u = d.utilities()
    square = np.array([c.surface == "square" for c in d.candidates])
    assert d.candidates[d.choose()].surface == "square"
    assert u[square].min() > 0 and u[~square].max() < u[square].max()


def test_runner_interface_plans_the_parameter_and_records_probabilities():
    d = ModelDiscrimination(["zx@1mm", "zx@2mm"], _sines(), rng=0, max_trials=3)
    rng = np.random.default_rng(0)
    while not d.finished:
        planned = d.next_trial(d.n_done, rng)
        assert planned.level == d.candidates[planned.track].amplitude_m
        d.update(planned, True)
    assert d.n_done == 3 and set(d.estimate()) == {"threshold", "p_zx@1mm", "p_zx@2mm", "verdict"}
    assert sum(d.record_state()["model_probabilities"].values()) == pytest.approx(1.0)


@pytest.mark.parametrize("kwargs, match", [
    (dict(models=["qq@1mm", "zx@2mm"]), r"models\[0\]: unknown model 'qq@1mm'"),
    (dict(models=["zx@1mm"]), "models: give at least two hypotheses"),
    (dict(models=["zx@1mm", "zx@1mm"]), "models: names must be distinct"),
    (dict(models=["yy@1mm", "zx@1mm"]), "'yy@1mm' reads 0 strain for every candidate"),
    (dict(candidates=[]), "candidates: the candidate set is empty"),
    (dict(candidates=None), "candidates: the candidate set is empty"),
    (dict(candidates=["3mm"]), r"candidates\[0\]: expected a Stimulus"),
    (dict(candidates=_sines()[:2] * 2), "candidates: contains repeated stimuli"),
    (dict(utility="entropy"), "utility: must be one of"),
    (dict(task="yes_no"), "task: only '2ifc' is supported"),
    (dict(stop_probability=1.0), r"stop_probability: must lie in \(0.5, 1\)"),
    (dict(max_trials=0), "max_trials: must be a whole number >= 1"),
    (dict(n_grid=1), "n_grid: need whole numbers >= 2"),
    (dict(n_grid=(25, float("nan"))), "n_grid: need whole numbers >= 2"),
    (dict(max_trials=float("nan")), "max_trials: must be a whole number >= 1"),
    (dict(stop_probability=float("nan")), r"stop_probability: must lie in \(0.5, 1\)"),
    (dict(priors={"slope": None}), r"priors: unknown keys \['slope'\]"),
    (dict(priors={"model": [1.0]}), "priors: 'model' needs 2 positive probabilities"),
])
def test_bad_inputs(kwargs, match):
    args = dict(models=["zx@1mm", "zx@2mm"], candidates=_sines()[:3]) | kwargs
    with pytest.raises(ValueError, match=match):
        ModelDiscrimination(args.pop("models"), args.pop("candidates"), **args)


def test_prior_with_zero_density_on_the_grid_is_refused():
    class Zero:
        def logpdf(self, x):
            return np.full(np.shape(x), -np.inf)

    with pytest.raises(ValueError, match="priors: a prior has zero density at a grid point"):
        ModelDiscrimination(["zx@1mm", "zx@2mm"], _sines()[:3], priors={"lapse": Zero()})


def test_pairs_and_single_stimulus_designs():
    sines = _sines()
    pairs = [(sines[i], sines[0]) for i in range(1, 6)]
    d = ModelDiscrimination(["zx@1mm", "zx@2mm"], pairs, rng=0)
    assert d.stats.shape == (2, 5, 2) and np.all(d.stats[:, :, 1] > 0)
    assert d.utilities().max() > 0
    # one stimulus: a free threshold fits any rival exactly (a rate of zero), reported up front
    with pytest.warns(UserWarning, match="metameric"):
        one = ModelDiscrimination(["zx@1mm", "zx@2mm"], sines[:1], rng=0)
    assert one.finished and one.winner is None and one.verdict.startswith("nothing to learn")


def test_no_winner_while_the_shown_stimuli_cannot_separate_the_models():
    d = ModelDiscrimination(["zx@1mm", "zx@2mm"], _sines(), rng=0, stop_probability=0.51)
    i = int(np.argmax(d.utilities()))
    for _ in range(40):  # one stimulus shown again and again: the rival fits it exactly
        d.observe(i, True)
    assert max(d.model_probabilities().values()) >= 0.51
    assert d.winner is None and not d.finished and d.verdict == "undecided"


def test_max_trials_stops_an_undecided_design():
    d = ModelDiscrimination(["zx@1mm", "zx@2mm"], _sines(), rng=0, max_trials=4)
    for _ in range(4):
        assert not d.finished
        d.observe(d.choose(), True)
    assert d.finished and len(d.probabilities) == 4


def test_each_statistic_is_computed_once_per_model_and_candidate():
    from tactilab.experiments import TransductionModel

    class Counting(TransductionModel):
        calls = 0

        def _surface_statistic(self, stimulus):
            Counting.calls += 1
            return super()._surface_statistic(stimulus)

    models = [Counting("zx@1mm"), Counting("zx@2mm")]
    d = ModelDiscrimination(models, _sines(), rng=0)
    for _ in range(5):
        d.observe(d.choose(), True)
    ModelDiscrimination(models, _sines()[::-1], rng=0)  # a second design reuses the models' caches
    assert Counting.calls == 2 * len(_sines())

"""Model comparison a lab can report: deterministic, identifiability first, no verdict for a failed fit.

Oracles: the emcee sampler (the reference) against the quadrature on three designs; a design
that cannot separate two models by construction (one sinusoid pitch: a receptor depth only
rescales the statistic, so the threshold absorbs it) against one that can (two pitches); the
quadrature's exact leave-one-out elpd against PSIS-LOO of its deterministic draws.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pandas as pd
import pytest

from tactilab.experiments.modelling import (
    VERDICTS, TransductionModel, compare_models, fit_transduction, separation)
from tactilab.experiments.modelling.analysis import compare_sessions

from test_models import _frame
from test_models_fit import FAST, _session

DEPTHS = ["zx@1mm", "zx@2mm", "zx@3mm"]
AMPS = [0.15e-6, 0.3e-6, 0.6e-6, 1.2e-6, 2.4e-6]


@pytest.fixture(scope="module")
def one_pitch(tmp_path_factory):
    return [_session(tmp_path_factory.mktemp("one") / "s.sqlite", 2, 1, TransductionModel("zx@1mm"))]


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_the_table_is_the_same_for_every_seed(one_pitch):
    """The grid path draws no random number: seeds 0..9 give the same table, bit for bit."""
    first, _ = compare_sessions(one_pitch, ["zx@1mm", "zx@3mm"], rng=0)
    for seed in range(1, 10):
        table, _ = compare_sessions(one_pitch, ["zx@1mm", "zx@3mm"], rng=seed)
        pd.testing.assert_frame_equal(table, first, check_exact=True)


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_one_pitch_never_separates_depths_two_pitches_do(one_pitch, tmp_path):
    """One pitch: every pair of depth hypotheses is 'not identifiable on this design' (the runner's
    session, and simulated sessions of five response seeds); the reason names the pitch. Two
    pitches (2 and 8 mm) of the same observer: zx@1mm is best and zx@3mm worse."""
    table, fits = compare_sessions(one_pitch, DEPTHS)
    assert set(table["verdict"]) == {"not identifiable on this design"}
    assert "pitch 2 mm" in table["reason"].iloc[1] and not table["identifiable"].any()
    for a, b in itertools.permutations(DEPTHS, 2):
        assert not separation(fits[a].tree, fits[b].tree).identifiable
    for seed in range(5):
        frame = _frame(TransductionModel("zx@1mm"), 40, AMPS, np.random.default_rng(seed), t=1e-4, pitches=(2e-3,))
        fits = {h: fit_transduction(TransductionModel(h), frame) for h in DEPTHS}
        assert set(compare_models(fits)["verdict"]) == {"not identifiable on this design"}, seed
    two = [one_pitch[0], _session(tmp_path / "s8.sqlite", 8, 2, TransductionModel("zx@1mm"))]
    table, _ = compare_sessions(two, ["zx@1mm", "zx@3mm"])
    assert list(table.index) == ["zx@1mm", "zx@3mm"] and table["verdict"].iloc[0] == "best"
    assert table["verdict"].iloc[1] in ("worse", "weakly worse") and table["separation"].iloc[1] >= 2


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_a_fit_that_did_not_converge_never_gets_a_verdict(one_pitch, tmp_path):
    """Whatever its elpd, a non-converged fit gets 'no verdict: fit not converged' and what to do;
    the leader is the best converged fit; a leader without a converged rival gets no verdict."""
    two = [one_pitch[0], _session(tmp_path / "s8.sqlite", 8, 2, TransductionModel("zx@1mm"))]
    _, fits = compare_sessions(two, ["zx@1mm", "zx@3mm", "xx@2mm"])
    broken = dataclasses.replace(fits["zx@1mm"], converged=False)  # the true model, highest elpd
    table = compare_models({**fits, "zx@1mm": broken})
    assert table.loc["zx@1mm", "verdict"] == "no verdict: fit not converged" and table.index[-1] == "zx@1mm"
    assert "method='emcee'" in table.loc["zx@1mm", "reason"]
    assert table.index[0] != "zx@1mm" and table["elpd_diff"].iloc[0] == 0.0
    tree = fits["zx@3mm"].tree.copy()
    tree.attrs["converged"] = 0  # a fit read back from a file
    table = compare_models({"zx@1mm": broken, "zx@3mm": tree})
    assert set(table["verdict"]) == {"no verdict: fit not converged"}
    table = compare_models({"zx@1mm": fits["zx@1mm"], "zx@3mm": tree})
    assert list(table["verdict"]) == ["no verdict: no converged rival", "no verdict: fit not converged"]
    assert set(table["verdict"]) <= set(VERDICTS)


def test_quadrature_loo_agrees_with_psis_of_its_draws():
    """The grid's exact LOO and PSIS-LOO of its deterministic draws agree to 0.1 nats; the draws'
    Pareto k are small (the grid posterior is smooth)."""
    frame = _frame(TransductionModel("zx@1mm"), 50, AMPS, np.random.default_rng(3))
    fits = {h: fit_transduction(TransductionModel(h), frame) for h in ("zx@1mm", "zx@3mm")}
    table = compare_models(fits)
    assert (table["mcse"] < 0.1).all() and (table["pareto_k_max"] < 0.7).all()


def test_separation_needs_the_per_trial_statistics():
    frame = _frame(TransductionModel("zx@1mm"), 10, AMPS, np.random.default_rng(0))
    fit = fit_transduction(TransductionModel("zx@1mm"), frame)
    bare = fit.tree.copy()
    del bare["constant_data"]
    with pytest.raises(ValueError, match="fits: 'b' has no per-trial statistics"):
        compare_models({"a": fit, "b": bare})
    short = _frame(TransductionModel("zx@1mm"), 5, AMPS, np.random.default_rng(0))
    with pytest.raises(ValueError, match="fitted to different trials"):
        separation(fit.tree, fit_transduction(TransductionModel("zx@1mm"), short).tree)


DESIGNS = {  # (truth, rival, amplitudes, pitches, trials per stimulus)
    "two pitches": ("zx@1mm", "zx@3mm", AMPS, (2e-3, 6e-3), 40),
    "four pitches, xx vs zx@2mm": ("xx@1mm", "zx@2mm", AMPS[1:], (1.5e-3, 3e-3, 6e-3, 10e-3), 20),
    "one pitch, few trials": ("zx@1mm", "zx@2mm", AMPS, (4e-3,), 12),
}


@pytest.mark.slow
@pytest.mark.parametrize("design", list(DESIGNS))
def test_grid_elpd_agrees_with_the_emcee_reference(design):
    """On three designs, each model's elpd by quadrature lies within 4 Monte Carlo standard errors
    of emcee's (plus the grid's own numerical error), and the parameters' medians agree within
    a tenth of the 95 % interval's width."""
    truth, rival, amps, pitches, n = DESIGNS[design]
    frame = _frame(TransductionModel(truth), n, amps, np.random.default_rng(7), t=1e-4, pitches=pitches)
    for h in (truth, rival):
        grid = fit_transduction(TransductionModel(h), frame)
        ref = fit_transduction(TransductionModel(h), frame, rng=11, method="emcee", sampler_options=FAST)
        table = compare_models({"grid": grid, "emcee": ref})
        assert ref.converged and grid.converged
        tol = 4 * float(table["mcse_diff"].max()) + 0.05
        assert abs(table.loc["grid", "elpd"] - table.loc["emcee", "elpd"]) < tol, (design, h)
        for name, s in grid.params.items():
            r = ref.params[name]
            assert abs(s.median - r.median) < 0.1 * (r.ci95[1] - r.ci95[0]) + 1e-3 * abs(r.median), (design, h, name)


def test_compare_sessions_refuses_sampler_options_for_the_grid(one_pitch):
    with pytest.raises(ValueError, match="sampler_options: only for method='emcee'"):
        compare_sessions(one_pitch, ["zx@1mm", "zx@3mm"], sampler_options=FAST)

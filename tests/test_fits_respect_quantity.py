"""Fits that respect the quantity: positive quantities on log levels, no impossible interval ends.

Property (hypothesis): over random 2AFC sessions of an amplitude (levels, trials per level and a
true threshold drawn at random, responses from a Weibull observer), the default fit of a
positive quantity never gives an interval end at or below 0, and its curve is drawn on a log axis.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tactilab.experiments.modelling import fit_psychometric
from tactilab.experiments.modelling.analysis import POSITIVE, sigmoid_for


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n_levels=st.integers(2, 6), per_level=st.integers(1, 12), lowest=st.floats(0.05, 2.0),
       ratio=st.floats(1.2, 3.0), threshold=st.floats(0.01, 20.0), seed=st.integers(0, 2**31 - 1))
def test_amplitude_intervals_never_reach_below_zero(n_levels, per_level, lowest, ratio, threshold, seed):
    rng = np.random.default_rng(seed)
    levels = np.repeat(lowest * ratio ** np.arange(n_levels), per_level)  # um
    p = 0.5 + 0.48 * (1 - np.exp(-(levels / threshold) ** 2))
    correct = rng.random(levels.size) < p
    fit = fit_psychometric(levels, correct, sigmoid=sigmoid_for("amplitude_m"), rng=0)
    th = fit.params["threshold"]
    assert 0 < th.ci95[0] <= th.median <= th.ci95[1] and 0 < th.ci68[0] and th.map > 0


def test_the_sigmoid_follows_the_quantity(tmp_path):
    assert [sigmoid_for(p) for p in POSITIVE] == ["weibull"] * 3 and sigmoid_for("speed_m_per_s") == "norm"
    assert sigmoid_for("amplitude_m", "lognorm") == "lognorm" and sigmoid_for("speed_m_per_s", "logistic") == "logistic"
    with pytest.raises(ValueError, match="sigmoid: 'norm' fits amplitude_m on linear levels, where its interval can "
                                         "reach below 0"):
        sigmoid_for("amplitude_m", "norm")
    fit = fit_psychometric([1.0, 2.0, 4.0], n_correct=[6, 8, 10], n_trials=[10, 10, 10], sigmoid="lognorm", rng=0)
    assert fit.params["threshold"].ci95[0] > 0
    fit.plot(tmp_path / "fit.png")
    assert (tmp_path / "fit.png").stat().st_size > 5_000


def test_a_session_summary_fits_amplitude_on_log_levels_without_the_first_crossing(tmp_path):
    from tactilab.experiments.modelling import TransductionModel, session_summary, summary_lines
    from tactilab.experiments.modelling.analysis import fit_conditions

    from test_models_fit import _session

    path = _session(tmp_path / "s.sqlite", 2, 1, TransductionModel("zx@1mm"))
    (cond,) = fit_conditions([path])
    assert cond.fit.sigmoid == "weibull" and cond.fit.params["threshold"].ci95[0] > 0
    text = "\n".join(summary_lines(session_summary(path)))
    assert "fitted threshold" in text and "procedure's" not in text

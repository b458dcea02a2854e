"""A design with few distinct stimuli may be fitted exactly by the rival: its rate is zero, reported as such."""

from __future__ import annotations

import math

import numpy as np

from tactilab.data_schemas.experiment import Stimulus
from tactilab.experiments.modelling.models import TransductionModel, power_analysis

TRUE = {"threshold_strain": 3e-4, "exponent": 1.2, "lapse": 0.02}


def _stim(a, p):
    return Stimulus(amplitude_m=a, pitch_m=p, speed_m_per_s=0.02)


def test_one_stimulus_or_one_pitch_gives_rate_zero_not_a_huge_number():
    true, rival = TransductionModel("zx@1mm"), TransductionModel("zx@2mm")
    # an observer at neither chance nor ceiling: threshold near the design's statistics
    TRUE["threshold_strain"] = true.statistic_of(_stim(1e-5, 3e-3))
    for design in ([(_stim(1e-5, 3e-3), 100)], [(_stim(1e-5, 3e-3), 50), (_stim(2e-5, 3e-3), 50)]):
        res = power_analysis(true, TRUE, rival, design)
        assert res.exact_fit and res.rate == 0.0 and math.isinf(res.trials_for(4.0)), (len(design), res.mu)


def test_many_pitches_give_a_positive_rate():
    true, rival = TransductionModel("zx@1mm"), TransductionModel("zx@2mm")
    design = [(_stim(a, p), 20) for a in (5e-6, 2e-5) for p in np.geomspace(1e-3, 8e-3, 6)]
    threshold = float(np.median([true.statistic_of(s) for s, _ in design]))  # neither chance nor ceiling
    res = power_analysis(true, {**TRUE, "threshold_strain": threshold}, rival, design)
    assert not res.exact_fit and res.rate > 0 and res.rate == res.mu / res.sigma
    assert math.isfinite(res.trials_for(4.0)) and res.trials_for(4.0) == (4.0 / res.rate) ** 2

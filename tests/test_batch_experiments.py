"""Batch sweeps of tactilab.experiments.batch: power over (seed, N) and the design table, serial.

Oracles: each sweep point equals the direct, in-process call with the same per-key generator
(power) or the direct design table; a rerun resumes; bad input fails at the entry point. The
worker-count independence of the generic layer is tested in tests/test_batch.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import ndtr

from tactilab.core import task_rng
from tactilab.data_schemas import Stimulus
from tactilab.experiments.batch import design_sweep, power_sweep
from tactilab.experiments.models import TransductionModel, power_analysis
from tactilab.forward import design_table

GRATING = Stimulus(amplitude_m=1e-6, pitch_m=4e-3, speed_m_per_s=0.02, duration_s=0.1)
DESIGN = [(GRATING.model_copy(update={"amplitude_m": a, "pitch_m": p}), 40) for a in (0.5e-6, 2e-6) for p in (2e-3, 6e-3)]
TRUTH = dict(threshold_strain=2e-4, exponent=1.0, lapse=0.02)


def test_power_sweep_points_equal_direct_calls_and_resume(tmp_path):
    args = (TransductionModel("zx@1mm"), TRUTH, TransductionModel("zx@2mm"), DESIGN)
    out = power_sweep(*args, [20, 200], n_seeds=1, seed=9, out_dir=tmp_path, n_repeats=4, z=2.0, workers=0,
                      progress=False)
    assert out["p_select"].shape == (1, 2) and out.attrs["n_run"] == 2 and out.attrs["n_failed"] == 0
    direct = power_analysis(*args, method="simulate", n_repeats=4, rng=task_rng(9, "seed-0000/n-200"))
    assert float(out["p_select"].sel(seed=0, n_trials=200)) == direct.p_select(200, z=2.0)
    assert out.attrs["mu_nats"] == direct.mu and out.attrs["sigma_nats"] == direct.sigma
    n = np.array([20, 200])  # asymptotic power Phi(sqrt(n) mu / sigma - z)
    expected = ndtr(np.sqrt(n) * direct.mu / direct.sigma - 2.0)
    np.testing.assert_allclose(out["p_asymptotic"].values, expected, rtol=1e-12)
    again = power_sweep(*args, [20, 200], n_seeds=1, seed=9, out_dir=tmp_path, n_repeats=4, z=2.0, workers=0,
                        progress=False)
    assert (again.attrs["n_run"], again.attrs["n_skipped"]) == (0, 2) and again["p_select"].equals(out["p_select"])
    with pytest.raises(ValueError, match="n_trials: need whole numbers >= 1"):
        power_sweep(*args, [0], n_seeds=1, seed=0, out_dir=tmp_path, workers=0)
    with pytest.raises(ValueError, match="n_seeds: need whole numbers >= 1"):
        power_sweep(*args, [10], n_seeds=0, seed=0, out_dir=tmp_path, workers=0)


def test_design_sweep_equals_design_table(tmp_path):
    depths, widths, pairs = [1e-3, 2e-3], [4e-3], [1, 3]
    out = design_sweep(depths, widths, pairs, out_dir=tmp_path, workers=0, progress=False)
    table = design_table(depths, widths, pairs)
    assert out.attrs["n_run"] == 4
    for _, row in table.iterrows():
        point = out.sel(depth=row["depth_m"], width=row["width_m"], pairs=int(row["pairs"]))
        for name in ("d_m", "pitch_m", "objective_per_m", "n_minima"):
            assert float(point[name]) == float(row[name])
    assert design_sweep(depths, widths, pairs, out_dir=tmp_path, workers=0, progress=False).attrs["n_skipped"] == 4
    with pytest.raises(ValueError, match=r"depths: need finite values > 0 in m, got \[-0.001\]"):
        design_sweep([-1e-3], widths, pairs, out_dir=tmp_path, workers=0)
    with pytest.raises(ValueError, match="pairs_list: need whole numbers >= 1"):
        design_sweep(depths, widths, [0], out_dir=tmp_path, workers=0)

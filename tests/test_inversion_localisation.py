"""Localisation study: Cramer-Rao bound behaves (more sensors, more components -> tighter) and
matches the emcee posterior width at high SNR."""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.inversion.localisation import (
    DEFAULT_SCENE, cramer_rao, localisation_study, plot_localisation, square_sensors,
)
from tactilab.inversion.scene_params import DefectScanModel


def test_crb_tightens_with_sensors_and_components(tmp_path):
    table = localisation_study(n_sides=(1, 2, 3), n_times=21)
    for comps, grp in table.groupby("components"):
        assert np.all(np.diff(grp["crb_sd_x0_um"].values) < 0)
        assert np.all(np.diff(grp["crb_sd_y0_um"].values) < 0)
    zz = table[table.components == "zz"].reset_index()
    both = table[table.components == "zx+zz"].reset_index()
    assert np.all(both["crb_sd_x0_um"] <= zz["crb_sd_x0_um"])
    plot_localisation(table, tmp_path / "loc.png")
    assert (tmp_path / "loc.png").stat().st_size > 1000


@pytest.mark.slow
def test_crb_scales_with_noise_and_matches_posterior(rng):
    model = DefectScanModel(np.linspace(-6e-3, 6e-3, 21), square_sensors(2), ("zz",))
    a = cramer_rao(model, DEFAULT_SCENE, 5e-8, 10.0)
    b = cramer_rao(model, DEFAULT_SCENE, 5e-8, 20.0)
    assert b["sd_x0"] == pytest.approx(2 * a["sd_x0"], rel=1e-6)
    assert cramer_rao(model, DEFAULT_SCENE, 5e-8, 10.0, step=5e-8)["sd_x0"] == pytest.approx(a["sd_x0"], rel=1e-4)
    table = localisation_study(n_sides=(2,), components_sets=(("zz",),), n_times=21, mcmc=True, rng=rng,
                               sampler_options=dict(n_walkers=12, check_every=150, max_steps=3000, min_ess=150,
                                                    tau_factor=15, n_start=128))
    row = table.iloc[0]
    assert row["converged"]
    # high SNR, flat priors: the posterior sd is close to the bound
    assert 0.7 < row["post_sd_x0_um"] / row["crb_sd_x0_um"] < 1.4
    assert 0.7 < row["post_sd_y0_um"] / row["crb_sd_y0_um"] < 1.4


def test_validation(rng):
    model = DefectScanModel([0.0], [[0.0, 0.0]])
    with pytest.raises(ValueError, match="noise_std"):
        cramer_rao(model, DEFAULT_SCENE, 5e-8, 0.0)
    with pytest.raises(ValueError, match="area"):
        cramer_rao(model, DEFAULT_SCENE, 0.0, 1.0)
    with pytest.raises(ValueError, match="params: missing"):
        cramer_rao(model, {"x0": 0.0}, 5e-8, 1.0)
    with pytest.raises(ValueError, match="n_side"):
        square_sensors(0)
    with pytest.raises(ValueError, match="rng: the posterior widths"):
        localisation_study(mcmc=True)

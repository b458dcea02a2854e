"""Recording + scene -> defect position and load profile; CLI ``tactilab invert``; mismatches fail loudly."""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.data_schemas.files import load_example
from tactilab.data_schemas.recording import Recording
from tactilab.data_schemas.scene import Scan
from tactilab.data_schemas.sensors import SensorArray
from tactilab.inversion.scene_inversion import (
    defect_problem, defect_profile, invert_defect_position,
)
from tactilab.inversion.scene_params import DefectScanModel, defect_footprint


def small_scene():
    base = load_example("fingertip_defect")
    sensors = SensorArray(positions_m=np.array([[0.0, 0.0], [1e-3, 0.0], [-1e-3, 1e-3]]), depth_m=2e-3,
                          components=("zz",), noise_std=20.0)
    scan = Scan(speed_m_per_s=0.02, duration_s=0.4, sampling_rate_hz=75.0, start_position_m=-4e-3)
    return base.model_copy(update={"sensors": sensors, "scan": scan})


def synthetic_recording(scene, rng, baseline=-5e3):
    c = scene.contact
    model = DefectScanModel(scene.scan.positions_m, scene.sensors.positions_m, ("zz",),
                            finger_radius=c.finger_radius_m, poisson_ratio=scene.material.poisson_ratio,
                            footprint=defect_footprint(scene.surface))  # the scene's 0.5 mm bump
    truth = dict(x0=0.0, y0=0.0, friction=c.friction_coefficient, depth=scene.sensors.depth_m,
                 young_modulus=scene.material.young_modulus_pa, normal_force=c.normal_force_n)
    clean = model.simulate(truth, 5e-8)
    values = clean + baseline + rng.normal(0, scene.sensors.noise_std, clean.shape)
    return Recording.from_sensors(scene.sensors, values, scene.scan.sampling_rate_hz), clean


def test_defect_problem_removes_baseline_and_keeps_order(rng):
    scene = small_scene()
    rec, clean = synthetic_recording(scene, rng)
    model, data, info = defect_problem(scene, rec)
    assert model.n_data == data.size == clean.size
    # after the median removal the data follow the model signal up to its own (small) median
    expected = (clean - np.median(clean, axis=0)).ravel()
    assert np.abs(data - expected).max() < 6 * scene.sensors.noise_std
    assert info["noise_std"] == 20.0 and info["truth"] == (0.0, 0.0)


@pytest.mark.slow
def test_position_and_profile_recovered(rng, tmp_path):
    scene = small_scene()
    rec, _ = synthetic_recording(scene, rng)
    res, info = invert_defect_position(scene, rec, rng, n_walkers=12, check_every=150, max_steps=3000,
                                       min_ess=150, tau_factor=15, n_start=128)
    assert res.converged, res.message
    post = res.tree["posterior"]
    for name in ("x0", "y0"):
        lo, hi = np.quantile(post[name].values, [0.001, 0.999])
        assert lo <= 0.0 <= hi
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the criteria may disagree; that is reported
        prof, crit, x = defect_profile(scene, rec, n_grid=80)
    assert set(crit.lam) == {"gcv", "lcurve", "discrepancy", "evidence"}
    assert abs(x[int(np.argmax(prof.mean))]) < 0.5e-3  # the profile peaks at the defect
    assert np.all(prof.std > 0)


def test_mismatched_recordings_fail(rng, tmp_path):
    scene = small_scene()
    rec, clean = synthetic_recording(scene, rng)
    other = Recording(values=rec.values, sampling_rate_hz=rec.sampling_rate_hz, sensor_ids=("a", "b", "c"),
                      components=rec.components)
    with pytest.raises(ValueError, match="sensor_ids .* does not match"):
        defect_problem(scene, other)
    short = Recording.from_sensors(scene.sensors, rec.values[:-1], rec.sampling_rate_hz)
    with pytest.raises(ValueError, match="samples, but the scene's scan has"):
        defect_problem(scene, short)
    broken = Recording.model_construct(**{**dict(rec), "values": np.where(np.arange(clean.size).reshape(clean.shape) == 4,
                                                                        np.nan, rec.values)})
    with pytest.raises(ValueError, match="recording.values: must be finite, found nan"):
        defect_problem(scene, broken)
    odd = Recording.model_construct(**{**dict(rec), "quantity": "displacement"})  # bypasses the schema
    scene_odd = scene.model_copy(update={"sensors": scene.sensors.model_copy(update={"quantity": "displacement"})})
    with pytest.raises(ValueError, match="recording.quantity: the defect model predicts stress .* or tensor strain"):
        defect_problem(scene_odd, odd)
    quiet = scene.model_copy(update={"sensors": scene.sensors.model_copy(update={"noise_std": 0.0})})
    with pytest.raises(ValueError, match="noise_std"):
        defect_problem(quiet, rec)
    grating = load_example("sliding_grating")
    with pytest.raises(ValueError, match="isolated defect"):
        defect_problem(grating.model_copy(update={"sensors": scene.sensors, "scan": scene.scan}), rec)
    no_contact = scene.model_copy(update={"contact": None})
    with pytest.raises(ValueError, match="scene.contact"):
        defect_problem(no_contact, rec)


def test_a_prepared_problem_is_used_as_given(rng):
    scene = small_scene()
    rec, _ = synthetic_recording(scene, rng)
    problem = defect_problem(scene, rec)
    post, crit, x = defect_profile(scene, rec, problem=problem)
    again, _, _ = defect_profile(scene, rec)
    np.testing.assert_array_equal(post.mean, again.mean)
    with pytest.raises(ValueError, match=r"problem: expected the \(model, data, info\) that defect_problem returns"):
        defect_profile(scene, rec, problem=problem[:2])
    with pytest.raises(ValueError, match="problem: data holds 3 values but the model predicts"):
        invert_defect_position(scene, rec, rng, problem=(problem[0], problem[1][:3], problem[2]))


@pytest.mark.slow
def test_cli_invert_end_to_end(rng, tmp_path, capsys, monkeypatch):
    import tactilab.inversion.scene_inversion as scene_inversion
    from tactilab.cli.main import main

    prepared = []
    real_problem = scene_inversion.defect_problem

    def counting_problem(*args, **kwargs):
        prepared.append(1)
        return real_problem(*args, **kwargs)

    monkeypatch.setattr(scene_inversion, "defect_problem", counting_problem)
    scene = small_scene()
    rec, _ = synthetic_recording(scene, rng)
    rec_path = rec.save(tmp_path / "rec.json")
    scene_path = scene.save(tmp_path / "scene.json")
    out = tmp_path / "inv"
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        status = main(["invert", str(rec_path), "--scene", str(scene_path), "--out", str(out), "--max-steps", "400",
                       "--quiet", "--sample", "friction"])
    assert status == 0
    assert len(prepared) == 1  # the defect problem is prepared once, for the position and the profile
    for name in ("posterior.nc", "corner.png", "profile.png", "criteria.png"):
        assert (out / name).stat().st_size > 1000
    text = capsys.readouterr().out
    assert "R-hat" in text and "lam by evidence" in text
    assert main(["invert", str(rec_path), "--scene", str(scene_path), "--max-steps", "0"]) == 2
    assert "--max-steps: must be >= 1" in capsys.readouterr().err
    assert main(["invert", str(rec_path), "--scene", str(scene_path), "--max-data", "3"]) == 2
    assert "--max-data" in capsys.readouterr().err


@pytest.mark.slow
def test_extra_parameters_sampled_and_validated(rng):
    scene = small_scene()
    rec, _ = synthetic_recording(scene, rng)
    res, _ = invert_defect_position(scene, rec, rng, sample=("friction", "depth"), n_walkers=16, check_every=150,
                                    max_steps=300, min_ess=10, tau_factor=1, n_start=64)
    assert set(res.tree["posterior"].data_vars) == {"x0", "y0", "friction", "depth", "amplitude"}
    depth = res.tree["posterior"]["depth"].values
    assert np.all(depth > 0)
    with pytest.raises(ValueError, match="sample: unknown parameter"):
        invert_defect_position(scene, rec, rng, sample=("speed",))

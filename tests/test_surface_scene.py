"""invert_surface on a scene and its recording, and ``tactilab invert --target surface``.

The recording is the scene engine's own (``scene_signals`` with the exact interface model): the
inversion's forward map must reproduce it (a second code path: its weights, friction folding and
windowed readout are the engine's), and the posterior must hold the true grating.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.cli.main import main
from tactilab.data_schemas import load_scene
from tactilab.data_schemas.recording import Recording
from tactilab.forward.scene_models import scene_signals
from tactilab.inversion import LogNormal, StationaryPrior, invert_surface, scene_scan

SCENE = """
name = "surface_small"
description = "a small finger over a grating, for the surface inversion"
[material]
young_modulus = "1MPa"
poisson_ratio = 0.5
[surface]
kind = "sinusoidal_grating"
period = "0.6mm"
amplitude = "2um"
[contact]
normal_force = "0.02N"
finger_radius = "10mm"
friction_coefficient = 0.4
model = "exact"
[sensors]
quantity = "stress"
components = ["zz"]
depth = "0.3mm"
noise_std = 10.0
[sensors.grid]
nx = 2
ny = 1
spacing_x = "0.3mm"
[scan]
speed = "40mm/s"
duration = "5ms"
sampling_rate = "1kHz"
start_position = "-0.1mm"
"""


@pytest.fixture(scope="module")
def scene_and_recording(tmp_path_factory):
    folder = tmp_path_factory.mktemp("surface")
    path = folder / "scene.toml"
    path.write_text(SCENE)
    scene = load_scene(path)
    values, _ = scene_signals(scene, "exact")
    noisy = values + 10.0 * np.random.default_rng(7).standard_normal(values.shape)
    rec = Recording.from_sensors(scene.sensors, noisy, scene.scan.sampling_rate_hz)
    return scene, rec, values, path, folder


def test_the_forward_map_reproduces_the_scene_engine(scene_and_recording):
    scene, rec, values, _, _ = scene_and_recording
    scan = scene_scan(scene, rec)
    x = scan.profile.x
    truth = scene.surface.height_at(x, np.zeros_like(x))
    out = scan.solve(truth).outputs
    assert np.abs(out - values.reshape(out.shape)).max() < 1e-3 * np.abs(values).max()


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_invert_surface_holds_the_grating(scene_and_recording, rng):
    scene, rec, _, _, _ = scene_and_recording
    prior = StationaryPrior(variance=(2e-6) ** 2, correlation_length=0.15e-3, kind="matern52")
    scan = scene_scan(scene, rec)
    x = scan.profile.x
    truth = scene.surface.height_at(x, np.zeros_like(x))
    post = invert_surface(scene, rec, prior=prior, context={"normal_force": LogNormal(0.02, 0.2)}, rng=rng,
                          truth=truth)
    t = post.touched
    z = (post.mean[t] - truth[t]) / post.std[t]
    assert t.sum() > 5 and np.mean(np.abs(z) < 2.58) > 0.9
    assert abs(post.context["normal_force"]["mean"] - 0.02) < 4 * post.context["normal_force"]["sd"]


def test_invert_surface_refuses_a_mismatched_recording(scene_and_recording, rng):
    scene, rec, values, _, _ = scene_and_recording
    prior = StationaryPrior(variance=1e-12, correlation_length=0.15e-3)
    other = Recording(values=values, sampling_rate_hz=rec.sampling_rate_hz, sensor_ids=("a", "b"),
                      components=rec.components, quantity=rec.quantity)
    with pytest.raises(ValueError, match="recording sensor_ids"):
        invert_surface(scene, other, prior=prior, rng=rng)
    slower = Recording.from_sensors(scene.sensors, values, 2 * rec.sampling_rate_hz)
    with pytest.raises(ValueError, match="recording.sampling_rate_hz: 2000.0 Hz, but the scene samples at"):
        invert_surface(scene, slower, prior=prior, rng=rng)
    short = Recording.from_sensors(scene.sensors, values[:3], rec.sampling_rate_hz)
    with pytest.raises(ValueError, match="recording: 3 samples, but the scene's scan has 5"):
        invert_surface(scene, short, prior=prior, rng=rng)
    with pytest.raises(ValueError, match="geometry: must be one of"):
        invert_surface(scene, rec, geometry="disc", prior=prior, rng=rng)
    with pytest.raises(ValueError, match="spacing: the profile's spacing must be at least the contact grid's"):
        invert_surface(scene, rec, spacing=1e-6, prior=prior, rng=rng)
    with pytest.raises(ValueError, match="context: unknown parameter 'depth'"):
        invert_surface(scene, rec, prior=prior, context={"depth": LogNormal(3e-4, 0.1)}, rng=rng)


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_cli_invert_target_surface(scene_and_recording, capsys):
    scene, rec, _, scene_path, folder = scene_and_recording
    rec_path = rec.save(folder / "rec.json")
    out = folder / "inv"
    status = main(["invert", str(rec_path), "--scene", str(scene_path), "--target", "surface", "--sample",
                   "normal_force", "--prior-rms", "2um", "--prior-length", "0.15mm", "--out", str(out)])
    assert status == 0
    assert (out / "surface.nc").stat().st_size > 1000 and (out / "surface.png").stat().st_size > 1000
    text = capsys.readouterr().out
    assert "touched fraction" in text and "resolved wavelengths >=" in text and "normal_force =" in text
    assert main(["invert", str(rec_path), "--scene", str(scene_path), "--target", "surface", "--sample", "depth",
                 "--out", str(folder / "inv2")]) == 2
    assert "--sample: 'depth' is not a context parameter" in capsys.readouterr().err

"""``tactilab simulate``: scene file -> recording file and plots; user mistakes -> one line, exit 2."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
import xarray as xr

from tactilab.cli.main import main
from tactilab.core import COMPONENTS

ROOT = pathlib.Path(__file__).resolve().parents[1]

SCENE = """
name = "tiny"
description = "small finger scan for the CLI test"
[material]
young_modulus = "2MPa"
[surface]
kind = "defect"
shape = "bump"
size = "0.6mm"
height = "20um"
position = ["0mm", "0.5mm"]
[contact]
normal_force = "0.8N"
finger_radius = "100mm"
friction_coefficient = 0.5
model = "modulation"
[sensors]
quantity = "{quantity}"
components = ["zz", "zx"]
depth = "3mm"
noise_std = {noise}
[sensors.grid]
nx = 3
ny = 2
spacing_x = "1mm"
[scan]
speed = "{speed}"
duration = "0.1s"
sampling_rate = "500Hz"
start_position = "-2mm"
"""


def _scene(tmp_path, speed="20mm/s", quantity="stress", noise="1.0", defect_x="0mm"):
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.format(speed=speed, quantity=quantity, noise=noise).replace(
        'position = ["0mm"', f'position = ["{defect_x}"'))
    return path


def test_simulate_writes_netcdf_and_plots(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(_scene(tmp_path)), "--out", str(out), "--quiet", "--seed", "3"]) == 0
    text = capsys.readouterr().out
    assert "Hertz contact a = 2.82 mm" in text and "recording.nc" in text
    ds = xr.open_dataset(out / "recording.nc", engine="h5netcdf")
    assert ds["values"].shape == (50, 6, 2) and ds.attrs["unit"] == "Pa"
    assert np.all(np.isfinite(ds["values"].values))
    np.testing.assert_allclose(np.diff(ds["contact_x"].values), 20e-3 / 500)
    ds.close()
    for name in ("field_maps.png", "receptive_fields.png", "time_series.png"):
        assert (out / name).stat().st_size > 10_000


def test_simulate_parquet_strain(tmp_path):
    """pyarrow is in the test extra (pyproject), so this runs everywhere the suite is meant to run."""
    import pandas as pd

    out = tmp_path / "pq"
    scene = _scene(tmp_path, quantity="strain", noise="0.0")
    assert main(["simulate", str(scene), "--out", str(out), "--quiet", "--format", "parquet", "--no-plots",
                 "--grid-spacing", "100um"]) == 0
    df = pd.read_parquet(out / "recording.parquet")
    assert len(df) == 50 * 6 * 2 and set(df["component"]) == {"zz", "zx"}
    assert df["value"].abs().max() < 0.1  # strain, dimensionless


def test_example_scene_runs(tmp_path):
    out = tmp_path / "ex"
    assert main(["simulate", str(ROOT / "examples" / "biomimetic_finger_defect.toml"), "--out", str(out),
                 "--quiet", "--no-plots", "--grid-spacing", "0.2mm"]) == 0
    assert (out / "recording.nc").exists()


def test_simulate_user_mistakes_exit_2(tmp_path, capsys):
    assert main(["simulate", str(_scene(tmp_path, speed="0mm/s")), "--out", str(tmp_path / "a"), "--quiet"]) == 2
    assert "speed: a scan time series needs a finger speed > 0" in capsys.readouterr().err
    assert main(["simulate", str(_scene(tmp_path, defect_x="40mm")), "--out", str(tmp_path / "b"), "--quiet"]) == 2
    assert "outside the surface" in capsys.readouterr().err
    assert main(["simulate", str(_scene(tmp_path)), "--grid-spacing=-1mm", "--quiet"]) == 2
    assert "--grid-spacing: must be > 0" in capsys.readouterr().err
    assert main(["simulate", str(_scene(tmp_path)), "--grid-spacing", "1kPa", "--quiet"]) == 2
    assert "--grid-spacing" in capsys.readouterr().err
    assert main(["simulate", str(_scene(tmp_path)), "--grid-spacing", "1e-12mm", "--quiet"]) == 2  # was MemoryError
    assert "contact-grid nodes per axis" in capsys.readouterr().err
    (tmp_path / "a_file").write_text("")
    assert main(["simulate", str(_scene(tmp_path)), "--out", str(tmp_path / "a_file" / "x"), "--quiet"]) == 2
    assert "--out: cannot create the output folder" in capsys.readouterr().err  # before simulating, in one line
    display = (ROOT / "data_schemas" / "examples" / "tractor_display.toml").read_text()
    strong = tmp_path / "strong.toml"
    strong.write_text(display.replace('amplitude = "10um"', 'amplitude = "100um"'))
    assert main(["simulate", str(strong), "--out", str(tmp_path / "c"), "--quiet", "--no-plots"]) == 2
    assert "exceeds the display's traction_limit" in capsys.readouterr().err
    fine = tmp_path / "fine.toml"
    fine.write_text(display.replace('pitch_x = "1.2mm"', 'pitch_x = "0.2mm"').replace(
        'tractor_width = "0.6mm"', 'tractor_width = "0.1mm"'))
    assert main(["simulate", str(fine), "--out", str(tmp_path / "d"), "--quiet", "--no-plots"]) == 2
    assert "is not positive, so no drive renders a grating" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "missing.toml"), "--quiet"]) == 2


def test_write_recording_rejects_unknown_format(tmp_path):
    from tactilab.data_schemas.recording import Recording
    from tactilab.data_schemas.recording_io import write_recording
    from tactilab.forward.scene_simulation import simulate_scene

    rec = Recording(values=np.zeros((2, 1, 1)), sampling_rate_hz=10.0, sensor_ids=("s0",), components=("zz",))
    with pytest.raises(ValueError, match="format: must be one of"):
        write_recording(rec, tmp_path, "csv")
    from tactilab.data_schemas.files import load_scene

    with pytest.raises(ValueError, match="format: must be one of"):
        simulate_scene(load_scene(_scene(tmp_path)), tmp_path, fmt="xlsx")


def test_simulate_display_scene_matches_tractor_display_module(tmp_path, capsys):
    """Display scenes: the recording equals the strain of tractor_display.render_virtual_surface
    (an independent path: display_row_strain) for the same drive; the CLI reports the match
    with the real sliding grating (standing wave: correlation ~ 1/sqrt(2))."""
    from tactilab.data_schemas.files import load_scene
    from tactilab.forward.display_scene import display_gain, display_scene_outputs
    from tactilab.forward.tractor_display import render_virtual_surface

    path = ROOT / "data_schemas" / "examples" / "tractor_display.toml"
    scene = load_scene(path)
    values, loads, info = display_scene_outputs(scene)
    s, sens = scene.scan, scene.sensors
    gain, _ = display_gain(scene.display, sens.depth_m, scene.material.young_modulus_pa)
    q, strain = render_virtual_surface(scene.display, scene.surface.height_at, s.speed_m_per_s, s.times_s,
                                       sens.positions_m[:, 0], sens.depth_m, gain, scene.material.young_modulus_pa,
                                       lead=s.start_position_m + scene.surface.period_m / 4)
    np.testing.assert_allclose(loads, q)
    idx = [COMPONENTS.index(c) for c in sens.components]
    np.testing.assert_allclose(values, strain[..., idx], atol=1e-9 * np.abs(strain).max())
    with pytest.raises(ValueError, match="scene.display: the scene has no display"):
        display_scene_outputs(scene.model_copy(update={"display": None}))
    with pytest.raises(ValueError, match="speed: a rendered scan needs a speed > 0"):
        display_scene_outputs(scene.model_copy(update={"scan": s.model_copy(update={"speed_m_per_s": 0.0})}))
    out = tmp_path / "disp"
    assert main(["simulate", str(path), "--out", str(out), "--quiet", "--no-plots"]) == 0
    text = capsys.readouterr().out
    corr = float(text.split("xx: normalised correlation ")[1].split(",")[0])
    assert 0.6 < corr < 0.72
    assert xr.open_dataset(out / "recording.nc", engine="h5netcdf")["values"].shape == (values.shape)

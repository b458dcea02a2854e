"""``tactilab invert`` refuses a scene that did not produce the recording, in one line naming what
differs; ``--allow-scene-mismatch`` inverts anyway with a (counted) warning. Before, a recording of
another contact radius inverted with exit 0 and a profile peak 7x too large, 1.15 mm off."""

from __future__ import annotations

import json
import re

import pytest

from tactilab.cli.main import main
from tactilab.data_schemas.files import load_scene
from tactilab.forward.scene_simulation import simulate_scene

SCENE = """
name = "small_defect"
[material]
young_modulus = "{E}"
poisson_ratio = 0.5
[surface]
kind = "defect"
shape = "bump"
size = "0.3mm"
height = "30um"
position = ["0mm", "0mm"]
[contact]
normal_force = "0.8N"
finger_radius = "{R}"
friction_coefficient = 0.5
[sensors]
quantity = "stress"
components = ["zz", "zx"]
depth = "{Z}"
noise_std = "5Pa"
[sensors.grid]
nx = 2
ny = 2
spacing_x = "{S}"
spacing_y = "0.6mm"
[scan]
speed = "20mm/s"
duration = "{T}"
sampling_rate = "100Hz"
start_position = "-4mm"
"""
SAME = dict(E="2MPa", R="100mm", Z="3mm", S="0.6mm", T="0.4s")


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rec")
    (folder / "scene.toml").write_text(SCENE.format(**SAME))
    list(simulate_scene(load_scene(folder / "scene.toml"), folder / "sim", plots=False))
    return folder / "sim" / "recording.nc"


def _scene(tmp_path, **change):
    path = tmp_path / "other.toml"
    path.write_text(SCENE.format(**{**SAME, **change}))
    return path


@pytest.mark.parametrize("change, named", [
    (dict(R="50mm"), r"contact radius: scene 2\.24\d* mm, recording 2\.82\d* mm"),
    (dict(S="1.2mm"), r"sensor positions: scene -?\d\.\d+ mm, recording -?\d\.\d+ mm"),
    (dict(Z="2mm"), r"sensor depth: scene 2 mm, recording 3 mm"),
    (dict(E="1MPa"), r"Young's modulus: scene 1000 kPa, recording 2000 kPa"),
    (dict(T="0.3s"), r"contact path: scene has 30 values, recording 40"),
])
def test_a_scene_that_did_not_produce_the_recording_is_refused(recording, tmp_path, capsys, change, named):
    code = main(["invert", str(recording), "--scene", str(_scene(tmp_path, **change)), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "--scene: the scene did not produce the recording" in err and "--allow-scene-mismatch" in err
    assert re.search(named, err), err
    assert not (tmp_path / "o").exists()  # refused before any output


def test_sampled_parameters_are_not_compared(recording, tmp_path):
    from tactilab.inversion import check_scene_recording

    assert check_scene_recording(load_scene(_scene(tmp_path)), recording) == []  # the scene that produced it
    scene = load_scene(_scene(tmp_path, Z="2mm"))
    assert check_scene_recording(scene, recording, sample=["depth"]) == []
    with pytest.raises(ValueError, match=r"scene: the scene did not produce the recording .*sensor depth: scene 2 mm"):
        check_scene_recording(scene, recording, sample=["friction"])


def test_allow_scene_mismatch_inverts_with_a_counted_warning(recording, tmp_path, capsys):
    argv = ["invert", str(recording), "--method", "profile", "--max-data", "40", "--json"]
    assert main([*argv, "--scene", str(_scene(tmp_path, R="50mm")), "--out", str(tmp_path / "o"),
                 "--allow-scene-mismatch"]) == 0
    out, err = capsys.readouterr()
    assert "warning: --scene: the scene did not produce the recording" in err and "contact radius" in err
    assert any("contact radius: scene" in w for w in json.loads(out)["warnings"])


def test_a_parquet_recording_carries_what_the_check_compares(tmp_path):
    """The check reads Parquet recordings through the same metadata reader as netCDF ones."""
    from tactilab.data_schemas.recording_metadata import scene_fields
    from tactilab.forward.scene_metadata import scene_mismatches

    pytest.importorskip("pyarrow")
    (tmp_path / "scene.toml").write_text(SCENE.format(**SAME))
    scene = load_scene(tmp_path / "scene.toml")
    list(simulate_scene(scene, tmp_path / "sim", fmt="parquet", plots=False))
    fields = scene_fields(tmp_path / "sim" / "recording.parquet")
    assert fields["depth_m"] == pytest.approx(3e-3) and fields["sensor_positions_m"].shape == (4, 2)
    assert scene_mismatches(scene, fields) == []
    other = load_scene(_scene(tmp_path, Z="2mm"))
    assert any("depth" in m for m in scene_mismatches(other, fields))

"""The file edge: TOML scene files with unit suffixes, JSON records, built-in examples."""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest

from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.files import (
    example_path,
    list_examples,
    load_example,
    load_scene,
    read_json_record,
    read_toml_record,
    record_from_dict,
)
from tactilab.data_schemas.material import SkinMaterial
from tactilab.data_schemas.scene import Scan, Scene
from tactilab.data_schemas.sensors import SensorArray
from tactilab.data_schemas.surface import IsolatedDefect, SinusoidalGrating
from tactilab.data_schemas.unit_keys import convert_units, field_dimension

SCENE = """
name = "t"
[material]
young_modulus = "{E}"
[surface]
kind = "sinusoidal_grating"
period = "2mm"
amplitude = "20um"
[contact]
normal_force = "0.5N"
finger_radius = "8mm"
[sensors]
components = ["zz"]
{sensors}
[scan]
{scan}
"""


def write_scene(tmp_path: pathlib.Path, *, E="1MPa", sensors='depth = "1mm"\npositions_mm = [[0, 0], [1, 0]]',
                scan='speed = "20mm/s"\nduration = "500ms"\nsampling_rate = "2kHz"') -> pathlib.Path:
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.format(E=E, sensors=sensors, scan=scan), encoding="utf-8")
    return path


# ----- built-in examples ----------------------------------------------------------------------
def test_examples_are_listed_and_shipped_inside_the_package():
    assert list_examples() == ["fingertip_defect", "sliding_grating", "tractor_display"]
    path = example_path("fingertip_defect.toml")
    assert path.is_file() and path.parent.name == "examples" and path.parent.parent.name == "data_schemas"
    with pytest.raises(ValueError, match=r"example 'nope' does not exist; use one of \['fingertip_defect'"):
        example_path("nope")


def test_fingertip_example_is_in_si():
    s = load_example("fingertip_defect")
    assert s.material.young_modulus_pa == pytest.approx(1e6, rel=1e-15) and s.material.poisson_ratio == 0.5
    assert s.contact.normal_force_n == 0.8 and s.contact.finger_radius_m == pytest.approx(0.01, rel=1e-15)
    assert isinstance(s.surface, IsolatedDefect)
    assert s.surface.height_m == pytest.approx(50e-6, rel=1e-15) and s.surface.size_m == pytest.approx(0.5e-3)
    assert s.sensors.n_sensors == 100 and s.sensors.depth_m == pytest.approx(3e-3, rel=1e-15)
    assert s.sensors.noise_std == 10.0 and s.sensors.unit == "Pa"
    np.testing.assert_allclose(s.sensors.positions_m.min(axis=0), [-4.5e-3, -4.5e-3], rtol=1e-12)
    assert (s.scan.speed_m_per_s, s.scan.duration_s, s.scan.sampling_rate_hz) == pytest.approx((0.02, 1.0, 1000.0))
    assert s.scan.start_position_m == pytest.approx(-0.01) and s.scan.n_samples == 1000


def test_grating_and_display_examples():
    g = load_example("sliding_grating")
    assert isinstance(g.surface, SinusoidalGrating) and g.contact.friction_coefficient == 0.0
    assert g.sensors.quantity == "strain" and g.sensors.n_sensors == 41 and g.scan.n_samples == 1000
    d = load_example("tractor_display")
    assert d.display == DisplayDescription.stress2()  # the file spells the preset in mm, kPa, kHz
    assert d.surface.period_m == pytest.approx(2 * d.display.pitch_x_m)


@pytest.mark.parametrize("name", ["fingertip_defect", "sliding_grating", "tractor_display"])
def test_examples_round_trip_through_json(name, tmp_path):
    s = load_example(name)
    assert Scene.from_json(s.to_json()) == s
    assert load_scene(s.save(tmp_path / f"{name}.json")) == s
    assert read_json_record(tmp_path / f"{name}.json", Scene) == s


def test_read_one_table_of_a_file():
    d = read_toml_record(example_path("tractor_display"), DisplayDescription, table="display")
    assert d.n_tractors == 60
    with pytest.raises(ValueError, match=r"table \[optics\] is missing"):
        read_toml_record(example_path("tractor_display"), DisplayDescription, table="optics")


# ----- unit spellings --------------------------------------------------------------------------
@pytest.mark.parametrize(
    "depth",
    ['depth = "1.25mm"', "depth_mm = 1.25", "depth_m = 0.00125", 'depth_m = "1.25 mm"',
     "depth_um = 1250", 'depth = "0.125cm"', "depth_MM = 1.25", 'depth = "1.25e-3m"'],
)
def test_every_depth_spelling_gives_the_same_si_value(depth, tmp_path):
    s = load_scene(write_scene(tmp_path, sensors=f"{depth}\npositions = [[\"0mm\", \"0mm\"]]"))
    assert s.sensors.depth_m == pytest.approx(1.25e-3, rel=1e-15)


@pytest.mark.parametrize(
    ("E", "scan", "expected_E", "expected_scan"),
    [
        ("200kPa", 'speed_mm_per_s = 20\nduration_ms = 500\nsampling_rate_khz = 2', 2e5, (0.02, 0.5, 2000.0)),
        ("0.2MPa", 'speed = "2cm/s"\nduration_s = 0.5\nsampling_rate_hz = 2000', 2e5, (0.02, 0.5, 2000.0)),
        ("200000Pa", 'speed_m_per_s = "20mm/s"\nduration = "0.5s"\nsampling_rate = "2000Hz"', 2e5, (0.02, 0.5, 2000.0)),
    ],
)
def test_modulus_and_scan_spellings(E, scan, expected_E, expected_scan, tmp_path):
    s = load_scene(write_scene(tmp_path, E=E, scan=scan))
    assert s.material.young_modulus_pa == pytest.approx(expected_E, rel=1e-15)
    assert (s.scan.speed_m_per_s, s.scan.duration_s, s.scan.sampling_rate_hz) == pytest.approx(expected_scan, rel=1e-15)


def test_a_bare_number_string_is_never_silently_si(tmp_path):
    with pytest.raises(ValueError, match=r"young_modulus: '1\.54' has no unit, and a pressure needs one; "
                                         r"write it with a unit, e\.g\. '1\.54MPa'"):
        load_scene(write_scene(tmp_path, E="1.54", scan='speed_mm_per_s = 20\nduration_ms = 500\nsampling_rate_khz = 2'))


def test_strain_noise_is_dimensionless_and_stress_noise_a_pressure():
    strain = convert_units(SensorArray, {"quantity": "strain", "noise_std": "2e-5"})
    stress = convert_units(SensorArray, {"noise_std": "0.1kPa"})
    assert strain["noise_std"] == pytest.approx(2e-5) and stress["noise_std"] == pytest.approx(100.0)
    with pytest.raises(ValueError, match=r"noise_std_kpa: unknown unit suffix 'kpa' for noise_std \(a dimensionless\)"):
        convert_units(SensorArray, {"quantity": "strain", "noise_std_kpa": 1.0})


def test_field_dimension_parsing():
    assert field_dimension("speed_m_per_s") == ("speed", "speed")
    assert field_dimension("normal_force_n") == ("normal_force", "force")
    assert field_dimension("max_slew_rate_per_s") is None  # a rate in 1/s passes through
    assert field_dimension("poisson_ratio") is None and field_dimension("_m") is None


def test_json_records_may_carry_units(tmp_path):
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"young_modulus": "20kPa", "poisson_ratio": 0.45}))
    assert SkinMaterial.load(path) == SkinMaterial(young_modulus_pa=2e4, poisson_ratio=0.45)
    assert Scan.from_json('{"speed_mm_per_s": 5, "duration": "2s", "sampling_rate_hz": 10}').n_samples == 20


# ----- errors at the edge: one line naming the file, the key, the rule, the value, the fix --------
@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        (dict(sensors='depth = "3furlong"\npositions_m = [[0, 0]]'),
         r"scene.toml: sensors.depth: unknown unit 'furlong'; use one of m, cm, mm"),
        (dict(sensors='depth = "3kPa"\npositions_m = [[0, 0]]'),
         r"sensors.depth: unit 'kPa' measures pressure, but a length is expected"),
        (dict(sensors='depth_furlong = 3\npositions_m = [[0, 0]]'),
         r"sensors.depth_furlong: unknown unit suffix 'furlong' for depth \(a length\); use one of depth_m, depth_cm, depth_mm"),
        (dict(sensors='depth = 3\npositions_m = [[0, 0]]'),
         r"sensors.depth = 3 has no unit \(depth is a quantity in m\); write depth = \"3mm\" with a unit, or use depth_m for SI"),
        (dict(sensors='depth = "3mm"\ndepth_mm = 3\npositions_m = [[0, 0]]'),
         r"sensors.depth_mm: depth_m is given twice \(as depth and depth_mm\); keep one of them"),
        (dict(sensors='depth = "-1mm"\npositions_m = [[0, 0]]'),
         r"scene.toml: sensors.depth_m must be > 0 \(sensors sit inside the skin\), got -0.001"),
        (dict(sensors='depth = "1mm"\npositions = [["0mm", "1 parsec"]]'),
         r"sensors.positions\[0\]\[1\]: unknown unit 'parsec'"),
        (dict(sensors='depth = "1mm"\npositions_m = [[0, 0]]\ncolour = "red"'),
         r"sensors.colour: unknown key \(check its spelling and unit suffix"),
        (dict(sensors='depth = "1mm"'), r"sensors.positions_m: missing; this key is required"),
        (dict(E="nanPa"), r"material.young_modulus: must be finite, got 'nanPa'"),
        (dict(E="-3kPa"), r"material.young_modulus_pa must be > 0 \(a stiffness\), got -3000.0"),
        (dict(sensors='depth = "1mm"\n[sensors.grid]\nnx = 0\nspacing_x = "1mm"'),
         r"sensors.grid: nx must be >= 1 \(sensors along x\), got 0"),
        (dict(sensors='depth = "1mm"\npositions_m = [[0, 0]]\n[sensors.grid]\nnx = 2\nspacing_x = "1mm"'),
         r"sensors.grid: both a grid and positions_m are given; keep one way"),
        (dict(sensors='depth = "1mm"\ngrid = 3'), r"sensors.grid must be a table with nx, ny, spacing_x"),
        (dict(scan='speed = "20mm/s"\nduration = "0.1ms"\nsampling_rate = "1kHz"'),
         r"scan: duration_s \* sampling_rate_hz must give at least 1 sample"),
    ],
)
def test_scene_file_errors_are_one_clear_line(kwargs, pattern, tmp_path):
    with pytest.raises(ValueError, match=pattern) as info:
        load_scene(write_scene(tmp_path, **kwargs))
    assert "\n" not in str(info.value)


def test_file_level_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n")
    with pytest.raises(ValueError, match=r"bad.toml: not valid TOML .*; fix the syntax"):
        load_scene(bad)
    with pytest.raises(ValueError, match=r"a scene file must end in .toml or .json, got '.yaml'"):
        load_scene(tmp_path / "scene.yaml")
    with pytest.raises(FileNotFoundError, match="scene file not found") as info:
        load_scene(tmp_path / "missing.toml")
    assert info.value.filename == str(tmp_path / "missing.toml")
    broken = tmp_path / "broken.json"
    broken.write_text("{")
    with pytest.raises(ValueError, match=r"broken.json: not valid JSON .*; fix the file"):
        Scene.load(broken)
    listed = tmp_path / "list.json"
    listed.write_text("[1, 2]")
    with pytest.raises(ValueError, match=r"list.json: a Scene must be a JSON object, got list"):
        Scene.load(listed)
    with pytest.raises(ValueError, match=r"SkinMaterial: young_modulus: unknown unit 'kpa'"):
        SkinMaterial.from_json('{"young_modulus": "3kpa"}', where="SkinMaterial")
    with pytest.raises(ValueError, match=r"SkinMaterial: poisson_ratio: Poisson's ratio must lie in \(-1, 0.5\]"):
        SkinMaterial.from_json('{"young_modulus_pa": 3, "poisson_ratio": 0.7}')
    with pytest.raises(ValueError, match=r"here: a SkinMaterial must be a table, got list"):
        record_from_dict(SkinMaterial, [1], "here")


def test_base_and_files_import_at_module_level_only():
    """base.py and files.py form no import cycle: neither hides an import inside a function."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "data_schemas"
    for name in ("base.py", "files.py"):
        tree = ast.parse((root / name).read_text())
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                inner = [n for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom))]
                assert not inner, f"data_schemas/{name}: {node.name} imports inside the function"
    base = (root / "base.py").read_text()
    assert "from .files" not in base and "import files" not in base

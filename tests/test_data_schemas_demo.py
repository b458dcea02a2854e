"""The data_schemas demo section writes the scene records and figures it announces."""

from __future__ import annotations

from tactilab.demo.records import run_demo
from tactilab.data_schemas.files import list_examples
from tactilab.data_schemas.scene import Scene


def test_demo_writes_exact_json_and_a_figure_per_scene(tmp_path):
    lines = list(run_demo(tmp_path, progress=False))
    assert lines[0].startswith("[data_schemas] 3 built-in scenes")
    for name in list_examples():
        json_path = tmp_path / "scenes" / f"scene_{name}.json"
        assert Scene.load(json_path).name == name
        assert (tmp_path / "scenes" / f"scene_{name}.png").stat().st_size > 10_000
        assert any(line.strip().startswith(f"{name}:") and "JSON round-trip exact" in line for line in lines)

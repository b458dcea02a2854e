"""The demo section that scans one texture through each interface model (demo/scene_models.py)."""

import pytest

from tactilab.demo import SECTIONS, scene_models, scenes


def test_the_section_follows_the_finger_scan():
    assert SECTIONS.index(scene_models) == SECTIONS.index(scenes) + 1


@pytest.mark.slow
def test_the_section_reports_each_model_and_draws_the_errors(tmp_path):
    lines = list(scene_models.run_demo(tmp_path, progress=False))
    text = "\n".join(lines)
    for name in ("exact", "linear", "modulation"):
        assert f"\n{name}: " in text
    assert "auto at tol 0.01: exact" in text
    assert (tmp_path / "scene_models" / "models.png").stat().st_size > 20_000

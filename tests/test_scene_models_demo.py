"""The demo section that scans one texture through each interface model (demo/scene_models.py)."""

import pytest

from tactilab.demo import SECTIONS, scene_models, scenes


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_the_studies_print_one_line_each_with_their_key_figure():
    """Oracles: the modulation is linear in M = 1 + h / h_ref (h_ref the bump's own height), so its
    gain per um of a 50 um bump against a 20 um one is 20 / 50 and two bumps superpose to rounding;
    the solved contact scales with the height (gain near 1) and two touching bumps interact."""
    import re

    lines = list(scene_models.study_lines())
    assert len(lines) == 5 and [line[:3] for line in lines[1:]] == ["(a)", "(b)", "(c)", "(d)"]
    a, b, c, d = lines[1:]
    assert "modulation gain per um 0.40" in a and 0.9 < float(re.search(r"exact .*?gain per um ([\d.]+)", a)[1]) < 1.1
    exact, modulation = (float(v) for v in re.search(r"exact ([\d.e+-]+), modulation ([\d.e+-]+)", b).groups())
    assert 1 < exact < modulation / 10  # ridges raise v / lambda in the contact, far less than the modulation says
    shallow, deep = (float(v) for v in re.search(r"gain ([\d.]+) at 1 um, ([\d.]+) at 20 um", c).groups())
    assert deep < shallow <= 1.0
    numbers = [float(v) for v in re.findall(r"\d[\d.]*e[+-]\d+|\d+\.\d+", d.split("apart")[1])]
    assert min(numbers[:2]) > 1e-4 and max(numbers[2:]) < 1e-10


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

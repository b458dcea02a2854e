"""benchmarks/bench_scene_studies.py at reduced size: the defect studies through the solved contact.

Oracles: the modulation model is linear in M = 1 + h / h_ref, so two bumps that do not overlap
superpose exactly (error at rounding) and, with h_ref the bump's own height, its response does not
depend on the height at all (gain per um = 20 / 50 = 0.4); the solved contact is not linear, and
two bumps interact more the closer they are.
"""

import importlib.util
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _bench():
    spec = importlib.util.spec_from_file_location("bench_scene_studies", ROOT / "benchmarks" / "bench_scene_studies.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_shape_invariance_rows(capsys):
    rows = _bench().section_a(True, 80e-6)
    assert "(a) shape invariance" in capsys.readouterr().out
    corr, gain = rows[("modulation", "height", 0.5, 50e-6)]
    assert gain == pytest.approx(0.4, rel=1e-9)  # h / h_ref: the modulation cannot see the bump's height
    assert all(c == pytest.approx(1.0, abs=1e-12) for pair in corr for c in pair)
    corr, gain = rows[("exact", "height", 0.5, 50e-6)]
    assert 0.5 < gain < 2 and min(c for pair in corr for c in pair) > 0.95  # the solved contact does
    force_corr, _ = rows[("exact", "force", 0.3, 20e-6)]
    assert min(c for pair in force_corr for c in pair) > 0.9


@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_two_bumps_interact_in_the_solved_contact_only(capsys):
    rows = _bench().section_d(True, 80e-6)
    assert "(d) two bumps" in capsys.readouterr().out
    assert max(rows[("modulation", 20e-6, 1.2e-3)]) < 1e-10  # linear in M: superposition exact
    near, far = rows[("exact", 20e-6, 0.4e-3)], rows[("exact", 20e-6, 1.2e-3)]
    assert near[0] > far[0] > 0 and near[1] > far[1]  # the interaction grows as the bumps approach


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_fingerprint_band_pass_rows(capsys):
    rows = _bench().section_b(True)
    assert "(b) fingerprint band-pass" in capsys.readouterr().out
    peak, ratio, resolution = rows["modulation"]
    assert abs(peak - 200.0) <= resolution and ratio > 100  # the founding paper's band-pass at v / lambda
    _, ratio, _ = rows["exact"]
    assert ratio > 1  # ridges in partial contact still raise v / lambda, far less than the modulation says


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_wiener_kernel_rows(capsys):
    rows = _bench().section_c(True)
    assert "(c) Wiener kernel" in capsys.readouterr().out
    shallow, deep = rows[1e-6], rows[20e-6]
    assert shallow[2] == 0.0  # the linear model at the smallest depth is the reference
    assert shallow[1] < 0.1  # a shallow grating: the solved contact's kernel has the linear kernel's shape
    assert deep[0] > shallow[0] and deep[1] > shallow[1]  # the non-linearity grows with the texture's depth

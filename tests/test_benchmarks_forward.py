"""Smoke test of benchmarks/bench_forward.py: it imports and runs one tiny case (no timing checks).

The benchmark's exact references are themselves checked here, so the script cannot rot into
comparing against a wrong closed form: the plane-wave closed form must agree with the spectral
solver, and the converged-reference helper must report rounding-level differences.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_forward.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_forward", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_spectral_case_runs_and_matches_plane_wave_closed_form(bench, rng):
    row = bench.bench_spectral(32, 3, rng, repeats=1, nu=0.3)
    assert row["method"] == "spectral" and row["n"] == 32 and row["depths"] == 3
    assert row["err"] < 1e-12 and row["err_facade"] < 1e-12
    assert set(row) >= {"time", "floor", "facade"}
    assert all(len(row[k]) == 2 and min(row[k]) > 0 for k in ("time", "floor", "facade"))


def test_dcfft_case_runs_and_agrees_with_direct_sum(bench, rng):
    row = bench.bench_dcfft(32, 1, rng, repeats=1, converged=True)
    assert row["err"] < 1e-12
    assert row["err_conv"] < 1e-9  # Gaussian of 1.6 h at depth 10 h: load and kernel resolved
    assert row["estimate"] > 0


def test_closed_form_plane_wave_is_an_equilibrium_field(bench, rng):
    # independent of the solver: d(sigma_xz)/dx + d(sigma_yz)/dy + d(sigma_zz)/dz = 0
    n, nu, z, h = 32, 0.4, 1e-3, 1e-7
    modes = bench.plane_wave_modes(n, rng)
    pts = rng.uniform(-1e-3, 1e-3, size=(20, 2))
    x, y = pts[:, 0], pts[:, 1]

    def s(dx=0.0, dy=0.0, dz=0.0):
        return bench.plane_wave_stress(n, modes, z + dz, nu, x + dx, y + dy)

    div_z = ((s(dx=h)[4] - s(dx=-h)[4]) + (s(dy=h)[3] - s(dy=-h)[3]) + (s(dz=h)[2] - s(dz=-h)[2])) / (2 * h)
    scale = np.abs(s()[2]).max() / 1e-3
    assert np.abs(div_z).max() < 1e-5 * scale
    # the surface boundary condition sigma_zz(z -> 0) = -p
    load = bench.plane_wave_load(n, modes)
    near = bench.plane_wave_stress(n, modes, 1e-12, nu, load.x[None, :], load.y[:, None])
    assert np.allclose(near[2], -load.p, atol=1e-6 * np.abs(load.p).max())


def test_tamaas_absent_gives_a_skip_line(bench, rng, monkeypatch, tmp_path):
    monkeypatch.setattr(bench, "TAMAAS_VENV", tmp_path / "no-venv")
    res = bench.bench_tamaas(16, rng, repeats=1)
    assert isinstance(res, str) and res.startswith("Tamaas skipped")


def test_memory_and_sensor_helpers_run(bench, rng):
    assert bench.traced_peak(lambda: np.zeros(1000)) > 0
    rows = bench.bench_sensors([5], rng, quick=True)
    assert rows[0]["trig_err"] < 1e-12 and rows[0]["dense_err"] < 1e-12 and rows[0]["fft_err"] < 1e-12


def test_floor_table_runs_and_prints_its_columns(bench, rng, capsys, monkeypatch, tmp_path):
    monkeypatch.setattr(bench, "TAMAAS_VENV", tmp_path / "no-venv")
    rows = bench.bench_floor_table([32], 2, rng, peer=True)
    (row,) = rows
    assert row["n"] == 32 and row["err"] < 1e-12 and row["peer_note"].startswith("Tamaas skipped")
    assert all(row[k] > 0 for k in ("facade_wall_min", "floor_wall_min", "facade_cpu_min", "floor_cpu_min"))
    bench.print_floor_table(rows)
    out = capsys.readouterr().out
    for column in ("size", "facade ms", "floor ms", "ratio", "+data", "Tamaas ms", "speedup"):
        assert column in out
    assert "  32^2" in out and "Tamaas skipped" in out
    assert row["labelled_wall_min"] > 0


def test_phase_table_runs_and_names_every_phase(bench, capsys, kernel_path):
    phases = bench.bench_phases(16, 2)
    assert all(t > 0 for t in phases.values())
    bench.print_phases([16], 2)
    out = capsys.readouterr().out
    passes = "6 compiled multiply-adds" if kernel_path == "compiled" else "30 multiply-add passes"
    for phase in ("facade", "periodic_stress", "3 forward transforms", passes, "6 inverse transforms",
                  "small-strain check", "floor: 3 rfft2", "floor: 6 irfft2"):
        assert phase in out
    expected = "compiled (numba " if kernel_path == "compiled" else "NumPy (TACTILAB_JIT=0)"
    assert bench.kernels_in_use().startswith(expected)

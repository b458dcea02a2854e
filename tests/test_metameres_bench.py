"""Smoke test of benchmarks/bench_metameres.py: it imports and runs tiny cases (no timing checks)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_metameres.py"


def test_benchmark_cases_run():
    spec = importlib.util.spec_from_file_location("bench_metameres", BENCH)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    row = bench.bench_subspace(256, repeats=1)
    assert row["n"] == 256 and row["params"] == 512 and row["time"] > 0 and row["fft"] > 0
    rows = bench.bench_pair(repeats=1, n_receptors=100, n_tractors=12)
    assert [r["case"] for r in rows] == ["unbounded", "bounded |q| <= 2 N/mm"]
    assert abs(rows[1]["max_load"]) <= 2000.0 * (1 + 1e-9) and rows[1]["residual"] >= rows[0]["residual"] - 1e-12

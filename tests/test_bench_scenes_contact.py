"""benchmarks/bench_scenes_contact.py runs (its --quick harness) and prints its table."""

import importlib.util
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_bench_scenes_contact_quick_runs(capsys):
    spec = importlib.util.spec_from_file_location("bench_scenes_contact",
                                                  ROOT / "benchmarks" / "bench_scenes_contact.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert bench.main(["--quick"]) == 0
    out = capsys.readouterr().out
    assert "| exact, warm-started |" in out and "| linear |" in out
    assert "linear model's error against the exact model" in out and "all converged: True" in out

"""benchmarks/bench_skin_speed.py: its table runs, and the numbers docs/viscoelastic.md and docs/theory.md quote."""

import importlib.util
import pathlib

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _bench():
    spec = importlib.util.spec_from_file_location("bench_skin_speed", ROOT / "benchmarks" / "bench_skin_speed.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_speed_table_runs_and_keeps_the_quoted_numbers(capsys):
    bench = _bench()
    rows = bench.table()
    out = capsys.readouterr().out
    assert "grating 1 mm in full contact" in out and out.count(" gain ") == 8
    quoted = {("pulp on bone", 0.75e-3, "stress"): [3.134, 4.427, 5.459, 7.277, 9.483, 9.936, 9.994],
              ("pulp on bone", 2e-3, "strain"): [1.0] * 7,
              ("dermis on pulp", 0.75e-3, "strain"): [1.078, 1.103, 1.116, 1.126, 1.119, 1.112, 1.111],
              ("dermis on pulp", 2e-3, "strain"): [0.664, 0.547, 0.482, 0.435, 0.464, 0.494, 0.499]}
    for key, gains in quoted.items():
        assert np.allclose(np.abs(rows[key]), gains, atol=5e-4), key
    assert np.allclose(-np.degrees(np.angle(rows[("dermis on pulp", 2e-3, "strain")][[0, 4]])), [-11.3, 3.9], atol=0.05)

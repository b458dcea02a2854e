"""benchmarks/bench_surface_coverage.py runs at a tiny size and prints its table."""

import importlib.util
import pathlib

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _bench():
    spec = importlib.util.spec_from_file_location("bench_surface_coverage",
                                                  ROOT / "benchmarks" / "bench_surface_coverage.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_bench_surface_coverage_runs_two_scans(capsys):
    assert _bench().main(["--scans", "2", "--workers", "1"]) == 0
    out = capsys.readouterr().out
    rows = {line[:44].strip(): line[44:].split() for line in out.splitlines()[2:]}
    assert 0 <= float(rows["touched nodes inside their 90 % band"][0]) <= 1
    for name in ("normal_force", "friction"):
        assert rows[f"{name} 90 % interval holds the truth"][1:3] == ["/", "2"]
    assert float(rows["relief error, rms over touched nodes (um)"][0]) > 0
    assert "calibrated range (99 %)" in out and "time:" in out


def test_bench_surface_coverage_height_sd_sets_the_prior(capsys):
    """--height-sd draws and inverts with that prior: a ten times smoother surface (the same seed: the same
    profile scaled by 0.1) leaves a smaller relief error (0.37 of the rough one's at seed 0)."""
    bench = _bench()
    rough, smooth = (bench.one_scan(2, 5, 48, np.random.default_rng([0, 0]), 1,
                                    bench.StationaryPrior(variance=(sd * 1e-6) ** 2, correlation_length=60e-6,
                                                          kind="matern52")) for sd in (0.5, 0.05))
    assert smooth["error"] < 0.5 * rough["error"]
    assert bench.main(["--scans", "1", "--workers", "1", "--height-sd", "0.05"]) == 0
    assert "height sd 0.05 um" in capsys.readouterr().out


def test_calibrated_range_of_a_calibrated_method_holds_the_nominal_rate():
    """Scans whose pseudo-truths are covered at 0.9 each: the pooled range brackets 0.9 and narrows with scans."""
    bench, rng = _bench(), np.random.default_rng(3)
    few = bench.calibrated_range([rng.random(200) < 0.9 for _ in range(5)], rng)
    many = bench.calibrated_range([rng.random(200) < 0.9 for _ in range(100)], rng)
    assert few[0] < many[0] < 0.9 < many[1] < few[1]


def test_bench_surface_coverage_refuses_empty_studies(capsys):
    bench = _bench()
    with pytest.raises(SystemExit):
        bench.main(["--scans", "0"])
    assert "--scans, --frames and --workers must be >= 1, got 0" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bench.main(["--grid", "8"])
    assert "--grid: at least 16 nodes a side" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bench.main(["--height-sd", "0"])
    assert "--height-sd: the prior's sd in um must be > 0, got 0.0" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bench.main(["--height-sd", "nan"])
    assert "--height-sd: the prior's sd in um must be > 0, got nan" in capsys.readouterr().err


def test_prior_sd_matches_the_priors_draws():
    bench, rng = _bench(), np.random.default_rng(4)
    for prior in (bench.FORCE_PRIOR[2], bench.FRICTION_PRIOR):
        assert bench.prior_sd(prior) == pytest.approx(np.std(prior.sample(rng, 400_000)), rel=5e-3)

"""Smoke test of benchmarks/bench_tradeoff.py: a tiny configuration writes the page and the figure
(no timing checks), and its references are checked so the page cannot rot into comparing against a
wrong answer."""

from __future__ import annotations

import importlib.util
import math
import re
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_tradeoff.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_tradeoff", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_tiny_run_writes_table_rows_and_png_with_finite_true_errors(bench, tmp_path):
    forward = bench.forward_rows(per_a=(4,), repeats=1, box=4)
    inversion = bench.inversion_rows(tols=(1e-4,), steps=(20,), repeats=1)
    assert {r["method"] for r in forward} == set(bench.FORWARD_METHODS)
    assert {r["method"] for r in inversion} == set(bench.INVERSION_METHODS)
    for r in forward + inversion:
        assert math.isfinite(r["error"]) and r["error"] >= 0 and r["time_ms"] > 0
    for r in forward:
        assert math.isfinite(r["estimate"]) and r["covers"] == "method+sampling"
    md = bench.write_page(forward, inversion, tmp_path, "python benchmarks/bench_tradeoff.py", "load average 0.0")
    text = md.read_text()
    png = tmp_path / "accuracy.png"
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "![time against true error](accuracy.png)" in text
    for method in bench.FORWARD_METHODS:
        assert re.search(rf"^\| {method} \| a/4 \| \d+\^2 \| ", text, re.M)
    for method in bench.INVERSION_METHODS:
        assert re.search(rf"^\| {method} \| ", text, re.M)
    assert "## Which method for which need" in text and "load average 0.0" in text


def test_exact_routes_match_the_independent_dense_posterior(bench):
    rows = bench.inversion_rows(tols=(1e-10,), steps=(), repeats=1)
    by = {r["method"]: r for r in rows}
    assert by["fft"]["error"] < 1e-10 and by["dense"]["error"] < 1e-10
    assert by["fft"]["std_error"] < 1e-12 and by["dense"]["std_error"] < 1e-12
    assert by["iterative"]["error"] < 1e-6


def test_forward_reference_agrees_with_the_solver_on_a_fine_grid(bench):
    """The sampled contact converges to Hamilton's solution: the page's 'true error' is a real error."""
    coarse, fine = (bench.forward_rows(per_a=(m,), repeats=1, box=4)[1] for m in (4, 16))
    assert coarse["method"] == fine["method"] == "dcfft"
    assert fine["error"] < coarse["error"] / 4 and fine["error"] < 1e-2


def test_mcmc_model_peaks_at_the_exact_posterior_mean(bench):
    prob = bench.profile_problem()
    model = bench.GaussianProfileModel(prob["matrix"], prob["data"], prob["noise"], prob["cov"])

    def gradient(theta, step):
        def target(t):
            return float(model.log_prior(t) + model.log_likelihood(t).sum())
        return np.array([(target(theta + step * e) - target(theta - step * e)) / (2 * step)
                         for e in np.eye(theta.size)])

    step = 1e-3 * np.abs(prob["mean"]).max()
    at_mean = gradient(prob["mean"], step)
    off_mean = gradient(prob["mean"] + 0.1 * prob["std"], step)
    assert np.abs(at_mean).max() < 1e-6 * np.abs(off_mean).max()


def test_mcmc_model_log_density_is_the_exact_gaussian_up_to_a_constant(bench):
    """log_prior + sum(log_likelihood) (the sampler's target, vectorized as the sampler calls it)
    differs from the exact posterior's log density by one constant at random points."""
    prob = bench.profile_problem()
    model = bench.GaussianProfileModel(prob["matrix"], prob["data"], prob["noise"], prob["cov"])
    precision = np.linalg.inv(prob["cov"]) + prob["matrix"].T @ prob["matrix"] / prob["noise"] ** 2
    cov = np.linalg.inv(precision)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), prob["std"], rtol=1e-10)
    rng = np.random.default_rng(3)
    points = rng.multivariate_normal(prob["mean"], 9 * cov, size=20)  # out to ~ 3 posterior sd and beyond
    loglik = model.log_likelihood(points)
    assert loglik.shape == (20, prob["data"].size)  # per observation, as PosteriorModel asks
    target = model.log_prior(points) + loglik.sum(axis=1)
    d = points - prob["mean"]
    exact = -0.5 * np.einsum("ni,ij,nj->n", d, precision, d)
    assert np.ptp(exact) > 50  # the points span a wide range of density
    np.testing.assert_allclose(target - exact, (target - exact)[0], atol=1e-8 * np.ptp(exact))


@pytest.mark.slow
def test_quick_mcmc_run_matches_the_exact_posterior(bench):
    """The --quick configuration's MCMC run (1000 steps, 64 walkers x 4 ensembles, autocorrelation
    time about 70 steps there): posterior mean within 1 % and pointwise std within 10 % (relative
    L2) of the exact posterior. The sampler before its BFGS start and walker-keeping thinning gave 0.15-0.35 and 6-7."""
    rows = bench.inversion_rows(tols=(), steps=(1000,), repeats=1)
    mc = next(r for r in rows if r["method"] == "mcmc")
    assert mc["error"] < 0.01 and mc["std_error"] < 0.10, mc
    assert mc["tau"] > 0 and mc["kept"] == 750

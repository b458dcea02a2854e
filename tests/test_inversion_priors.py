"""One prior family for every sampled model: densities integrate to 1, draws follow them, std is
the draws' sd, scipy.stats' rvs signature works, and bad parameters are refused."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, stats

from tactilab.inversion import Beta1, LogNormal, LogUniform, Normal, Uniform

PRIORS = [Uniform(-1.0, 3.0), Normal(1.0, 2.0), LogNormal(2.0, 0.3), LogUniform(1e-3, 10.0), Beta1(10.0, 0.5),
          Beta1(1.0, 1.0)]
SCIPY = [stats.uniform(-1.0, 4.0), stats.norm(1.0, 2.0), stats.lognorm(0.3, scale=2.0), stats.loguniform(1e-3, 10.0),
         stats.beta(1.0, 10.0, scale=0.5), stats.beta(1.0, 1.0)]


@pytest.mark.parametrize("prior,reference", list(zip(PRIORS, SCIPY)), ids=lambda p: type(p).__name__)
def test_density_std_and_draws_match_scipy(prior, reference, rng):
    x = reference.ppf(np.linspace(0.01, 0.99, 41))
    np.testing.assert_allclose(prior.logpdf(x), reference.logpdf(x), rtol=1e-10, atol=1e-12)
    assert prior.std == pytest.approx(reference.std(), rel=1e-10)
    draws = prior.sample(rng, 20000)
    assert stats.kstest(draws, reference.cdf).pvalue > 1e-3
    lo, hi = reference.ppf([1e-12, 1 - 1e-12])
    area, _ = integrate.quad(lambda v: float(np.exp(prior.logpdf(v))), lo, hi, limit=200)
    assert area == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("prior", PRIORS, ids=lambda p: type(p).__name__)
def test_rvs_is_sample_with_scipys_signature(prior):
    a = prior.rvs(size=5, random_state=np.random.default_rng(3))
    b = prior.sample(np.random.default_rng(3), 5)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(prior.rvs(size=5, random_state=3), b)  # a seed works too


def test_outside_the_support_is_minus_inf_never_nan():
    assert LogUniform(1.0, 2.0).logpdf(0.5) == -np.inf and LogUniform(1.0, 2.0).logpdf(-1.0) == -np.inf
    assert Beta1(10.0, 0.5).logpdf(0.5) == -np.inf and Beta1(10.0, 0.5).logpdf(-0.1) == -np.inf
    assert Uniform(0.0, 1.0).logpdf(2.0) == -np.inf and LogNormal(1.0, 0.5).logpdf(0.0) == -np.inf


@pytest.mark.parametrize("make,match", [
    (lambda: Uniform(1.0, 1.0), "Uniform: need finite low < high"),
    (lambda: Normal(0.0, 0.0), "Normal: need a finite mean and sd > 0"),
    (lambda: LogNormal(0.0, 1.0), "LogNormal: need median > 0 and sigma_log > 0"),
    (lambda: LogUniform(0.0, 1.0), "LogUniform: need finite 0 < low < high"),
    (lambda: LogUniform(2.0, 1.0), "LogUniform: need finite 0 < low < high"),
    (lambda: Beta1(0.0, 1.0), "Beta1: need b > 0 and scale > 0"),
    (lambda: Beta1(1.0, float("nan")), "Beta1: need b > 0 and scale > 0"),
])
def test_bad_parameters_are_refused(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_old_homes_still_work():
    from tactilab.inversion.scene_params import LogNormal as SceneLogNormal

    assert SceneLogNormal is LogNormal

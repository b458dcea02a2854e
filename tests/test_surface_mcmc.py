"""Laplace against MCMC on a small surface problem (slow): emcee on the exact non-linear posterior.

A periodic plane-strain cell in partial contact, three profile nodes, two frames, four outputs each,
2 % noise: the reduced basis (two vectors) spans every direction the data see (the uniform shift,
which they cannot, is the prior's), so the sampler checks the Laplace answer itself. Sized to run
in about 30 s (4 ensembles x 8 walkers x 800 steps of two contact solves each, 1000 kept draws).
"""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.inversion import StationaryPrior
from tactilab.inversion.surface import invert_scan
from tactilab.inversion.surface_scan import ContactScan, ProfileGrid


def _cell(rng):
    n, dx, frames = 12, 25e-6, 2
    x = (np.arange(n) - n // 2) * dx
    weights = rng.standard_normal((n, 4)) * dx
    return ContactScan(young_modulus=1e6, poisson_ratio=0.5, grid_shape=(n,), spacing=dx, shape_gap=np.zeros(n),
                       positions=np.arange(frames) * dx, weights_p=weights, weights_q=np.zeros((n, 4)),
                       profile=ProfileGrid(x=x[0] + 4 * dx * np.arange(3), periodic=True), mean_pressure=8e3,
                       periodic=True, tol=1e-12)


@pytest.mark.slow
def test_laplace_agrees_with_mcmc_on_a_small_problem():
    rng = np.random.default_rng(5)
    scan = _cell(rng)
    prior = StationaryPrior(variance=(1e-6) ** 2, correlation_length=100e-6, kind="matern52")
    truth = np.array([0.5, -0.25, 0.15]) * 1e-6
    clean = scan.solve(truth)
    assert 0.5 < clean.contact.mean() < 1.0  # partial contact: the map is non-linear
    sigma = 0.02 * np.abs(clean.outputs).max()
    data = clean.outputs + sigma * rng.standard_normal(clean.outputs.shape)
    laplace = invert_scan(scan, data, sigma, prior=prior, rng=rng, n_draws=4000)
    mcmc = invert_scan(scan, data, sigma, prior=prior, rng=rng, method="mcmc", n_draws=4000,
                       mcmc_options=dict(n_basis=3, max_steps=800, check_every=200, n_start=2, n_walkers=8,
                                         tau_factor=10, min_ess=300, max_draws=1000))
    assert "MCMC on a 2-vector likelihood-informed basis: converged" in mcmc.message and mcmc.method == "mcmc"
    assert np.abs(mcmc.mean - laplace.mean).max() < 0.1 * laplace.std.min()
    assert np.abs(mcmc.std / laplace.std - 1).max() < 0.1


def test_mcmc_needs_a_prior(rng):
    scan = _cell(rng)
    data = scan.solve(np.zeros(3)).outputs
    with pytest.raises(ValueError, match="prior: method='mcmc' samples a reduced basis"):
        invert_scan(scan, data + 0.01 * rng.standard_normal(data.shape), 0.01, prior=None, method="mcmc", rng=rng)

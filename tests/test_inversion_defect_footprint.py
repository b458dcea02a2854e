"""A defect of finite size: its footprint quadrature, the model against the forward simulation, and
interval coverage on the demo's scene (the example 0.5 mm bump under 3 x 3 sensors at 3 mm).

Oracles: closed-form moments of the footprints; the noise-free forward simulation of the scene
(tactilab.forward, a 20 um contact grid) fitted by the finite model to a small fraction of the
noise with the position right, where the point model is off by a posterior sd; the exact grid
posterior over (x0, y0) covering the truth in seeded noise draws; emcee agreeing with that grid.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from tactilab.data_schemas.files import load_example
from tactilab.data_schemas.recording_io import read_recording
from tactilab.forward.scene_simulation import simulate_scene
from tactilab.demo.inversion import defect_demo_scene
from tactilab.inversion.mcmc import DefectPosterior
from tactilab.inversion.scene_inversion import _fixed, defect_problem, invert_defect_position
from tactilab.inversion.scene_params import DefectScanModel, Normal, defect_footprint

NOISE = 10.0  # Pa, the example's sensors


@pytest.fixture(scope="module")
def scene():
    return defect_demo_scene()


@pytest.fixture(scope="module")
def clean(scene, tmp_path_factory):
    """Noise-free recordings: the forward model's default contact grid (the demo's) and a 20 um one."""
    out = {}
    for name, spacing in (("default", None), ("fine", 20e-6)):
        folder = tmp_path_factory.mktemp(name)
        list(simulate_scene(scene, folder, plots=False, grid_spacing=spacing))
        out[name] = read_recording(folder / "recording.nc")
    return out


def test_footprint_quadrature_has_the_defects_moments():
    dot = load_example("fingertip_defect").surface.model_copy(update={"shape": "dot", "position_m": (1e-3, -2e-3)})
    bump = dot.model_copy(update={"shape": "bump"})
    b = dot.size_m / 2
    for surface in (dot, bump):
        offsets, weights = defect_footprint(surface)
        assert offsets.shape == (96, 2) and weights.shape == (96,) and np.all(weights > 0)
        assert weights.sum() == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(weights @ offsets, 0.0, atol=1e-18)  # centred on the defect
        h = (lambda r: 1.0) if surface.shape == "dot" else (lambda r: 0.5 * (1 + np.cos(np.pi * r / b)))
        r2 = quad(lambda r: h(r) * r**3, 0, b)[0] / quad(lambda r: h(r) * r, 0, b)[0]
        assert weights @ (offsets**2).sum(axis=1) == pytest.approx(r2, rel=1e-6)
    assert r2 < b * b / 2  # the bump's load is more central than the dot's (b^2 / 2)
    assert defect_footprint(dot.model_copy(update={"shape": "edge_step"})) is None


def test_footprint_bad_input():
    surface = load_example("fingertip_defect").surface
    with pytest.raises(ValueError, match="surface: expected an isolated defect"):
        defect_footprint(load_example("fingertip_defect").material)
    with pytest.raises(ValueError, match="n_radial, n_angles: need whole numbers >= 1 and >= 3"):
        defect_footprint(surface, n_angles=2)
    args = (np.zeros(3), np.zeros((1, 2)), ("zz",))
    with pytest.raises(ValueError, match=r"footprint: expected \(offsets of shape \(K, 2\)"):
        DefectScanModel(*args, footprint=np.zeros(4))
    with pytest.raises(ValueError, match=r"footprint: expected finite offsets .* got shapes \(3, 2\) and \(2,\)"):
        DefectScanModel(*args, footprint=(np.zeros((3, 2)), np.full(2, 0.5)))
    with pytest.raises(ValueError, match="footprint: weights must be >= 0 and sum to 1"):
        DefectScanModel(*args, footprint=(np.zeros((2, 2)), np.array([0.5, 0.6])))


def _best_x0(model, data, fixed):
    """Least-squares x0 (y0 = 0, the area fitted) over a 0.25 um grid, and the rms residual."""
    xs = np.linspace(-20e-6, 20e-6, 161)
    g = model.design(dict(fixed, x0=xs, y0=np.zeros_like(xs)))
    area = g @ data / np.einsum("ij,ij->i", g, g)
    rss = np.sum((data[None] - area[:, None] * g) ** 2, axis=1)
    return xs[np.argmin(rss)], float(np.sqrt(rss.min() / data.size))


def test_finite_model_matches_the_forward_simulation_where_a_point_does_not(scene, clean):
    fixed = _fixed(scene)
    finite, data, info = defect_problem(scene, clean["fine"], max_data=400)
    point, _, _ = defect_problem(scene, clean["fine"], max_data=400, footprint=False)
    x_f, rms_f = _best_x0(finite, data, fixed)
    x_p, rms_p = _best_x0(point, data, fixed)
    # posterior sd of x0 at 10 Pa noise is 4.5 um: the finite model's error is a small part of it
    assert abs(x_f) <= 1.5e-6 and rms_f < 0.1 * NOISE
    assert x_p <= -2e-6 and rms_p > 2 * rms_f


def _grid_posterior(model, data, scene):
    """Exact posterior of x0 on a grid (y0 marginalised), the sampler's likelihood, flat local prior."""
    fixed = _fixed(scene)
    post = DefectPosterior(model, data, NOISE, {**fixed, "x0": Normal(0, 1), "y0": Normal(0, 1)},
                           Normal(0.0, 1e-6))
    xs, ys = np.linspace(-30e-6, 30e-6, 81), np.linspace(-80e-6, 80e-6, 27)
    theta = np.array([(x, y) for y in ys for x in xs])
    ll = post.log_marginal_likelihood(theta).reshape(ys.size, xs.size)
    px = np.exp(ll - ll.max()).sum(axis=0)
    px /= px.sum()
    mean = px @ xs
    lo, hi = np.interp([0.025, 0.975], np.cumsum(px), xs)
    return mean, float(np.sqrt(px @ (xs - mean) ** 2)), lo, hi


@pytest.mark.slow
def test_intervals_cover_the_truth_on_the_demo_scene(scene, clean):
    """20 noise draws of the demo's scan (on the 20 um contact grid, whose own error is below 0.5 um):
    the exact 95 % interval of x0 holds the truth in at least 18 and the mean z = (mean - truth) / sd
    is near 0 (benchmarks/bench_defect_coverage.py: 200 draws, docs/inversion.md)."""
    rec = clean["fine"]
    values = np.asarray(rec.values)
    z, covered = [], 0
    for seed in range(20):
        noisy = rec.model_copy(update={"values": values + NOISE * np.random.default_rng(seed).standard_normal(values.shape)})
        model, data, _ = defect_problem(scene, noisy, max_data=400)
        mean, sd, lo, hi = _grid_posterior(model, data, scene)
        z.append(mean / sd)
        covered += lo <= 0.0 <= hi
    assert covered >= 18 and abs(np.mean(z)) < 0.5


@pytest.mark.slow
def test_invert_defect_position_covers_the_truth(scene, clean):
    """emcee (short chains) on two noise draws: the 95 % interval holds the truth and the posterior
    agrees with the exact grid posterior (mean within 0.2 sd, sd within 10 %); the recording is the
    demo's (the forward model's default contact grid)."""
    rec = clean["default"]
    values = np.asarray(rec.values)
    for seed in range(2):
        noisy = rec.model_copy(update={"values": values + NOISE * np.random.default_rng(seed).standard_normal(values.shape)})
        res, info = invert_defect_position(scene, noisy, np.random.default_rng(seed), max_data=400, n_walkers=12,
                                           check_every=150, max_steps=1500, min_ess=150, tau_factor=15, n_start=128)
        assert res.converged, res.message
        x = res.tree["posterior"]["x0"].values.ravel()
        lo, hi = np.quantile(x, [0.025, 0.975])
        assert lo <= info["truth"][0] <= hi
        model, data, _ = defect_problem(scene, noisy, max_data=400)
        mean, sd, _, _ = _grid_posterior(model, data, scene)
        assert abs(x.mean() - mean) < 0.2 * sd and x.std() == pytest.approx(sd, rel=0.1)

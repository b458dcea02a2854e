"""The surface posterior through the solved contact (tactilab.inversion.surface).

Oracles: the exact linear-Gaussian posterior of the full-contact operator built independently
(the periodic surface stiffness E* |k| / 2 by FFT, ``gaussian_posterior`` on the dense path);
noise-free data of the scene engine (``solve_scan`` + ``SensorReadout``, a second code path for
the outputs); scipy's truncated normal for the untouched nodes under a white prior.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.stats import truncnorm

from tactilab.data_schemas.sensors import SensorArray
from tactilab.forward import HalfSpace, SensorReadout, finger_gap, solve_scan
from tactilab.inversion.gaussian import StationaryPrior, gaussian_posterior
from tactilab.inversion.priors import LogNormal, Normal
from tactilab.inversion.surface_jacobian import ScanJacobian
from tactilab.inversion.surface import invert_scan
from tactilab.inversion.surface_laplace import prior_root
from tactilab.inversion.surface_scan import ContactScan, ProfileGrid

E = 1e6


def _periodic_scan(rng, n=32, dx=20e-6, frames=4):
    x = (np.arange(n) - n // 2) * dx
    weights = rng.standard_normal((n, 3)) * dx
    scan = ContactScan(young_modulus=E, poisson_ratio=0.5, grid_shape=(n,), spacing=dx, shape_gap=np.zeros(n),
                       positions=np.arange(frames) * 3 * dx, weights_p=weights, weights_q=np.zeros((n, 3)),
                       profile=ProfileGrid(x=x.copy(), periodic=True), mean_pressure=20e3, periodic=True, tol=1e-13)
    return scan, x, weights


def _full_contact_operator(scan, x, weights):
    """Heights -> outputs of a periodic cell in full contact: p = mean + (E* |k| / 2) h (zero mean), by FFT."""
    n, dx = x.size, scan.spacing
    k = 2 * np.pi * np.fft.rfftfreq(n, dx)
    stiff = E / (1 - 0.25) * k / 2
    rows = []
    for u in scan.positions:
        shift = int(round(u / dx))
        cols = []
        for j in range(n):
            e = np.zeros(n)
            e[(np.arange(n) + shift) % n == j] = 1.0  # frame reads node (i + shift) at its node i
            cols.append(np.fft.irfft(np.fft.rfft(e) * stiff, n))
        rows.append(weights.T @ np.stack(cols, axis=1))
    return np.concatenate(rows)


def test_periodic_full_contact_equals_the_exact_linear_gaussian_posterior(rng):
    scan, x, weights = _periodic_scan(rng)
    prior = StationaryPrior(variance=(0.5e-6) ** 2, correlation_length=100e-6, kind="matern52")
    truth = prior_root(prior, (x.size,), scan.spacing) @ rng.standard_normal(x.size)
    clean = scan.solve(truth)
    assert clean.contact.all()
    sigma = 0.01 * np.abs(clean.outputs).max()
    data = clean.outputs + sigma * rng.standard_normal(clean.outputs.shape)
    post = invert_scan(scan, data, sigma, prior=prior, context={"young_modulus": E}, rng=rng)
    J = _full_contact_operator(scan, x, weights)
    offset = scan.solve(np.zeros(x.size)).outputs.ravel()
    exact = gaussian_posterior(J, data.ravel() - offset, prior, sigma, method="dense", spacing=scan.spacing)
    assert np.abs(post.mean - exact.mean).max() < 1e-8 * np.abs(exact.mean).max()
    assert np.abs(post.std - exact.std).max() < 1e-8 * exact.std.max()
    assert post.touched.all() and post.touched_fraction == 1.0
    draws = post.sample(4000, rng)
    assert np.abs(draws.std(axis=0) / exact.std - 1).max() < 0.1


def _groove_problem(rng):
    """A plane-strain finger over a plateau (0) with a 20 um deep groove: the skin never reaches its floor."""
    n, dx, R, force = 96, 10e-6, 10e-3, 8.0
    skin = HalfSpace(E=E, nu=0.5)
    x = (np.arange(n) - n // 2) * dx
    pos = np.arange(4) * 4 * dx
    px = np.arange(x[0] + pos[0], x[-1] + pos[-1] + 4 * dx, 4 * dx)
    truth = np.where(np.abs(px - 0.1e-3) < 0.09e-3, -20e-6, 0.0)
    sensors = SensorArray(positions_m=np.column_stack([np.linspace(-0.3e-3, 0.3e-3, 16), np.zeros(16)]),
                          depth_m=30e-6, components=("zz", "zx"))
    readout = SensorReadout(skin, (n,), dx, sensors, loads=("p", "qx"))
    gap0 = finger_gap((n,), dx, R)
    scan = ContactScan(young_modulus=E, poisson_ratio=0.5, grid_shape=(n,), spacing=dx, shape_gap=gap0,
                       positions=pos, weights_p=readout.weights[:n], weights_q=readout.weights[n:],
                       profile=ProfileGrid(x=px), normal_force=force, friction=0.3, friction_direction=-1.0,
                       tol=1e-12)
    engine = solve_scan(skin, gap0[None] - scan.node_heights(truth), dx, normal_force=force, friction=0.3,
                        slide_direction=(-1.0, 0.0), tol=1e-12, sensors=sensors)
    return scan, truth, engine.outputs[0].reshape(pos.size, -1)


def test_a_scan_started_from_an_earlier_iterate_equals_a_cold_one(rng):
    """ContactScan.solve(start=...): each frame from the earlier state's same frame (other heights,
    another force) gives the cold scan's pressures to the solver's tolerance and the engine's outputs."""
    scan, truth, data = _groove_problem(rng)
    cold = scan.solve(truth)
    near = scan.solve(truth + 0.3e-6 * rng.standard_normal(truth.shape), {"normal_force": 7.0})
    warm = scan.solve(truth, start=near)
    assert np.abs(warm.pressure - cold.pressure).max() <= 1e-8 * cold.pressure.max()
    assert np.array_equal(warm.contact, cold.contact)
    assert np.abs(warm.outputs - data).max() <= 1e-8 * np.abs(data).max()
    threads = scan.solve(truth, start=near, workers=3)  # three blocks of frames on three threads
    assert np.array_equal(threads.pressure, warm.pressure) and np.array_equal(threads.contact, warm.contact)
    blocks = scan.solve(truth, workers=2)  # without a start: each block's first frame cold
    assert np.abs(blocks.pressure - cold.pressure).max() <= 1e-8 * cold.pressure.max()
    # a flat surface (every frame reads the same heights) is solved once: the same as frame by frame
    # (heights a femtometre apart, which the solver's tolerance does not see, take the frame-by-frame path)
    flat = scan.solve(np.zeros_like(truth))
    each = scan.solve(1e-15 * np.arange(truth.size).reshape(truth.shape))
    assert np.abs(flat.pressure - each.pressure).max() <= 1e-8 * each.pressure.max()
    assert np.array_equal(flat.contact, each.contact)
    assert np.abs(flat.outputs - each.outputs).max() <= 1e-8 * np.abs(each.outputs).max()
    with pytest.raises(ValueError, match="start: expected a ScanState of this scan"):
        scan.solve(truth, start=cold.pressure)
    with pytest.raises(ValueError, match="workers: threads must be a positive integer"):
        scan.solve(truth, workers=0)


def test_noise_free_partial_contact_recovers_the_touched_heights_and_bounds_the_groove(rng):
    scan, truth, data = _groove_problem(rng)
    sd = 2e-6
    with pytest.warns(UserWarning, match="chi2: the MAP leaves chi2"):  # a local optimum at the groove's edge
        post = invert_scan(scan, data, 1e-4 * np.abs(data).max(), prior=StationaryPrior(variance=sd**2, kind="white"),
                           rng=rng, n_draws=1500)
    touched, groove = post.touched, truth < 0
    assert touched.sum() >= 10 and not (touched & groove).any()
    # the absolute level is not identified (a uniform shift leaves the data unchanged): compare shapes
    offset = np.mean(post.mean[touched] - truth[touched])
    # measured 6 nm: a local optimum at the groove's edge (the objective is piecewise quadratic)
    assert np.abs(post.mean[touched] - truth[touched] - offset).max() < 5e-4 * 20e-6
    # untouched nodes: the (white) prior truncated at the skin's bound, far below it or pressed by it
    untouched = ~touched
    bound = post.upper_bound[untouched]
    assert np.all(np.isfinite(bound))
    floor = groove[untouched]  # the skin sags into the groove but stays above its floor
    assert np.all(bound[floor] < offset) and np.all(bound[floor] > truth[untouched][floor] + offset)
    # the skin (and so the bound) moves with the touched block's unidentifiable uniform shift c, whose
    # posterior is N(0, s_c^2): average scipy's truncated normal over it (Gauss-Hermite)
    s_c = float(np.std(post.draws[:, touched].mean(axis=1) - post.map[touched].mean()))
    nodes, weights = np.polynomial.hermite_e.hermegauss(40)
    weights = weights / weights.sum()
    edge = (bound[None, :] + s_c * nodes[:, None]) / sd
    m1 = truncnorm.mean(-np.inf, edge, scale=sd)
    exact_mean = weights @ m1
    exact_std = np.sqrt(weights @ (truncnorm.var(-np.inf, edge, scale=sd) + m1**2) - exact_mean**2)
    assert np.abs(post.mean[untouched] - exact_mean).max() < 4 * sd / np.sqrt(1500)
    assert np.abs(post.std[untouched] / exact_std - 1).max() < 0.1
    far = bound > 2 * sd  # outside the contact the skin curves away: the prior is (almost) kept
    assert far.any() and np.abs(post.mean[untouched][far]).max() < 0.05 * sd + 4 * sd / np.sqrt(1500)
    assert np.abs(post.std[untouched][far] / sd - 1).max() < 0.1
    lower, upper = post.band(0.9)
    assert np.all(upper[untouched] <= post.upper_bound[untouched] + 4 * s_c) and np.all(lower < upper)


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_context_is_marginalised_and_recovered(rng, monkeypatch):
    scan, truth, data = _groove_problem(rng)
    sigma = 0.01 * np.abs(data).max()
    noisy = data + sigma * rng.standard_normal(data.shape)
    post = invert_scan(scan, noisy, sigma, prior=StationaryPrior(variance=(10e-6) ** 2, kind="white"),
                       context={"normal_force": LogNormal(8.0, 0.3), "friction": Normal(0.3, 0.1)},
                       rng=np.random.default_rng(7))
    for name, true in (("normal_force", 8.0), ("friction", 0.3)):
        c = post.context[name]
        assert c["q05"] < c["mean"] < c["q95"] and c["sd"] > 0
        assert abs(c["mean"] - true) < 4 * c["sd"], name
    assert post.context_draws["friction"].shape == (400,)
    # the Jacobian rebuilt every third iteration (the exact gradient between): the same MAP and Hessian
    lagged = invert_scan(scan, noisy, sigma, prior=StationaryPrior(variance=(10e-6) ** 2, kind="white"),
                         context={"normal_force": LogNormal(8.0, 0.3), "friction": Normal(0.3, 0.1)},
                         rng=np.random.default_rng(7), jacobian_every=3)  # the same draws' numbers
    t = post.touched
    assert np.array_equal(lagged.touched, t)
    assert np.abs(lagged.mean[t] - post.mean[t]).max() < 0.1 * post.std[t].min()
    assert np.abs(lagged.std[t] / post.std[t] - 1).max() < 0.02
    for name in ("normal_force", "friction"):
        assert abs(lagged.context[name]["mean"] - post.context[name]["mean"]) < 0.1 * post.context[name]["sd"]
    # the exact gradients solved to 1e-6 only: they steer, the MAP stays the same
    loose = invert_scan(scan, noisy, sigma, prior=StationaryPrior(variance=(10e-6) ** 2, kind="white"),
                        context={"normal_force": LogNormal(8.0, 0.3), "friction": Normal(0.3, 0.1)},
                        rng=np.random.default_rng(7), jacobian_every=3, gradient_tol=1e-6)
    assert np.array_equal(loose.touched, t)
    assert np.abs(loose.mean[t] - lagged.mean[t]).max() < 0.01 * post.std[t].min()
    assert np.abs(loose.std[t] / lagged.std[t] - 1).max() < 1e-3
    # their iterations in float32 (refined to the same tolerances in float64): the same MAP and Hessian;
    # a continuation stage starting where the last ended reuses its gradient's solves (no state twice)
    seen, adjoint = [], ScanJacobian.adjoint
    monkeypatch.setattr(ScanJacobian, "adjoint", lambda self, *a, **k: seen.append(self.state) or adjoint(self, *a, **k))
    single = invert_scan(scan, noisy, sigma, prior=StationaryPrior(variance=(10e-6) ** 2, kind="white"),
                         context={"normal_force": LogNormal(8.0, 0.3), "friction": Normal(0.3, 0.1)},
                         rng=np.random.default_rng(7), jacobian_every=3, gradient_tol=1e-6, solve_dtype=np.float32)
    assert np.array_equal(single.touched, t)
    assert np.abs(single.mean[t] - loose.mean[t]).max() < 0.01 * post.std[t].min()
    assert np.abs(single.std[t] / loose.std[t] - 1).max() < 1e-3
    assert "continuation stages" in single.message and len(seen) == len({id(x) for x in seen}) > 1
    # the search stopped at a decrement of 0.1 nats (here the stall test stops the default first, on a kink):
    # a MAP within sqrt(0.1) sd per node
    early = invert_scan(scan, noisy, sigma, prior=StationaryPrior(variance=(10e-6) ** 2, kind="white"),
                        context={"normal_force": LogNormal(8.0, 0.3), "friction": Normal(0.3, 0.1)},
                        rng=np.random.default_rng(7), jacobian_every=3, gradient_tol=1e-6, solve_dtype=np.float32,
                        map_tol=0.1)
    assert "converged: Gauss-Newton decrement" in early.message, early.message
    dev = np.abs(early.mean[t] - single.mean[t]) / single.std[t]
    assert dev.max() < np.sqrt(0.1)


def test_surface_posterior_files_and_draws(rng, tmp_path):
    import xarray as xr

    scan, x, _ = _periodic_scan(rng, n=16, frames=2)
    data = scan.solve(np.zeros(16)).outputs
    post = invert_scan(scan, data, 1.0, prior=StationaryPrior(variance=1e-12, correlation_length=50e-6), rng=rng,
                       n_draws=50)
    assert post.sample(7, rng).shape == (7, 16)
    path = post.to_netcdf(tmp_path / "surface.nc")
    back = xr.open_datatree(path, engine="h5netcdf")
    assert back["posterior"]["height"].shape == (1, 50, 16)
    assert back["posterior"]["height"].attrs["units"] == "m" and back["profile"]["mean"].attrs["units"] == "m"
    assert back.attrs["method"] == "laplace"
    assert post.plot(tmp_path / "surface.png", truth=np.zeros(16)).stat().st_size > 0
    assert "SurfacePosterior(method='laplace'" in repr(post)
    with pytest.raises(ValueError, match="level: the band's probability must lie in"):
        post.band(1.5)
    with pytest.raises(ValueError, match="n: need a positive whole number of draws"):
        post.sample(0, rng)
    with pytest.raises(ValueError, match="rng: expected a numpy Generator"):
        post.sample(3, 1)


def test_invert_scan_refuses_bad_input(rng):
    scan, x, _ = _periodic_scan(rng, n=16, frames=2)
    data = scan.solve(np.zeros(16)).outputs
    prior = StationaryPrior(variance=1e-12, correlation_length=50e-6)
    with pytest.raises(ValueError, match="context: the scene is a periodic cell loaded by its mean pressure"):
        invert_scan(scan, data, 1.0, prior=prior, context={"normal_force": LogNormal(1.0, 0.2)}, rng=rng)
    with pytest.raises(ValueError, match="context: unknown parameter 'depth'"):
        invert_scan(scan, data, 1.0, prior=prior, context={"depth": 1e-3}, rng=rng)
    with pytest.raises(ValueError, match="context: friction must be a finite float"):
        invert_scan(scan, data, 1.0, prior=prior, context={"friction": -0.1}, rng=rng)
    with pytest.raises(ValueError, match="method: must be one of"):
        invert_scan(scan, data, 1.0, prior=prior, method="vi", rng=rng)
    with pytest.raises(ValueError, match="rng: expected a numpy Generator"):
        invert_scan(scan, data, 1.0, prior=prior, rng=3)
    with pytest.raises(ValueError, match="prior: expected a StationaryPrior"):
        invert_scan(scan, data, 1.0, prior=1e-12, rng=rng)
    with pytest.raises(ValueError, match="jacobian_every: iterations per explicit Jacobian must be >= 1"):
        invert_scan(scan, data, 1.0, prior=prior, rng=rng, jacobian_every=0)
    with pytest.raises(ValueError, match=r"jacobian_tol: the restricted solves' relative residual must lie in"):
        invert_scan(scan, data, 1.0, prior=prior, rng=rng, jacobian_tol=0.0)
    with pytest.raises(ValueError, match=r"gradient_tol: the gradients' relative residual must lie in"):
        invert_scan(scan, data, 1.0, prior=prior, rng=rng, gradient_tol=1.0)
    with pytest.raises(ValueError, match="solve_dtype: expected float32 or float64, got float16"):
        invert_scan(scan, data, 1.0, prior=prior, rng=rng, solve_dtype=np.float16)
    with pytest.raises(ValueError, match="map_tol: the Gauss-Newton decrement at which the search stops must be > 0"):
        invert_scan(scan, data, 1.0, prior=prior, rng=rng, map_tol=float("nan"))
    with pytest.raises(ValueError, match="noise_std: the likelihood needs"):
        invert_scan(scan, data, 0.0, prior=prior, rng=rng)
    with pytest.raises(ValueError, match=r"data: expected finite values of shape \(2, 3\)"):
        invert_scan(scan, data[:1], 1.0, prior=prior, rng=rng)
    # without a prior a grid finer than the data resolve is refused
    with pytest.raises(ValueError, match="spacing: without a prior the data must resolve every node"):
        invert_scan(scan, data + rng.standard_normal(data.shape), 1.0, prior=None, rng=rng)


def test_without_a_prior_the_touched_relief_is_recovered_and_the_rest_only_bounded(rng):
    scan, truth, data = _groove_problem(rng)
    sigma = 1e-3 * np.abs(data).max()
    with warnings.catch_warnings():  # the flat-prior MAP may stop at a groove edge's kink (chi2 1228 / 128 seen)
        warnings.simplefilter("ignore", UserWarning)
        post = invert_scan(scan, data + sigma * rng.standard_normal(data.shape), sigma, prior=None, rng=rng)
    t = post.touched
    relief = truth[t] - truth[t].mean()  # the level is held at 0: the touched heights are a relief
    assert np.all(np.abs(post.mean[t] - relief) < 4 * post.std[t]) and np.all(post.std[t] < 0.5e-6)
    assert np.all(np.isnan(post.mean[~t])) and np.all(np.isnan(post.std[~t]))
    lower, upper = post.band(0.9)
    assert np.all(lower[~t] == -np.inf) and np.all(upper[~t] == post.upper_bound[~t])
    assert "no prior, no posterior (NaN)" in post.message


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_the_relief_is_known_far_better_than_the_level(rng):
    scan, truth, data = _groove_problem(rng)
    sigma = 0.01 * np.abs(data).max()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        post = invert_scan(scan, data + sigma * rng.standard_normal(data.shape), sigma, rng=rng,
                           prior=StationaryPrior(variance=(8e-6) ** 2, correlation_length=60e-6, kind="matern52"))
    sd, lower, upper = post.relief(0.9)
    t = post.touched
    assert np.median(sd[t]) < 0.2 * np.median(post.std[t])  # the level dominates the heights' sd
    assert np.all(lower[t] <= upper[t])
    with pytest.raises(ValueError, match="level: the band's probability must lie in"):
        post.relief(0.0)

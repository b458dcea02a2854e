"""emcee scene posterior: marginal likelihood oracle, closed-form kernels, recovery over seeds,
flat likelihood reported, non-convergence reported, DataTree/netCDF output, validation."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from scipy.stats import multivariate_normal

from tactilab.inversion.mcmc import DefectPosterior, sample_scene_posterior
from tactilab.inversion.scene_params import DefectScanModel, LogNormal, Normal, Uniform, check_prior

TRUTH = dict(x0=0.5e-3, y0=0.3e-3, friction=0.5, depth=2e-3, young_modulus=1e6, normal_force=0.8)
AREA = 4e-8
FAST = dict(n_walkers=12, check_every=150, max_steps=3000, min_ess=150, tau_factor=15, n_start=128)


def small_model(n_times=15, components=("zz",)):
    return DefectScanModel(np.linspace(-4e-3, 4e-3, n_times), np.array([[0.0, 0.0], [1.5e-3, 1e-3]]), components)


def test_design_matches_boussinesq_cerruti_closed_form():
    """sigma_zz = S p [ -3 z^3 / (2 pi R^5) + mu (-3 x z^2 / (2 pi R^5)) ] (docs/theory.md section 3)."""
    model = small_model(n_times=7)
    g = model.design(TRUTH)[0].reshape(model.data_shape)
    from tactilab.forward.contact import HertzContact

    contact = HertzContact(normal_force=0.8, finger_radius=0.01, young_modulus=1e6, poisson_ratio=0.5)
    z = TRUTH["depth"]
    for t, u in enumerate(model.scan_positions):
        xd, yd = TRUTH["x0"] - u, TRUTH["y0"]
        p = contact.pressure(xd, yd)
        for s, (xs, ys) in enumerate(model.sensors):
            x, y = xs - xd, ys - yd
            r5 = (x * x + y * y + z * z) ** 2.5
            expected = p * (-3 * z**3 / (2 * np.pi * r5) + 0.5 * (-3 * x * z * z / (2 * np.pi * r5)))
            assert g[t, s, 0] == pytest.approx(expected, rel=1e-10, abs=1e-12 * np.abs(g).max())


def test_marginal_likelihood_equals_multivariate_normal(rng):
    model = small_model()
    data = model.simulate(TRUTH, AREA).ravel() + rng.normal(0, 5.0, model.n_data)
    amp = Normal(1e-8, 3e-8)
    lp = DefectPosterior(model, data, 5.0, {k: float(v) for k, v in TRUTH.items()}, amp)
    g = model.design(TRUTH)
    ll, cmean, cvar = lp.marginal(g)
    cov = 25.0 * np.eye(model.n_data) + amp.sd**2 * np.outer(g[0], g[0])
    assert ll[0] == pytest.approx(multivariate_normal(amp.mean * g[0], cov).logpdf(data), rel=1e-10)
    # conditional posterior of the amplitude: Gaussian conjugate formula
    prec = g[0] @ g[0] / 25.0 + 1 / amp.sd**2
    assert cvar[0] == pytest.approx(1 / prec)
    assert cmean[0] == pytest.approx((g[0] @ data / 25.0 + amp.mean / amp.sd**2) / prec)


@pytest.mark.slow
def test_recovery_over_seeds_at_nominal_rate(seed):
    """90% central intervals of x0 and y0 contain the truth in about 90% of 8 synthetic data sets."""
    model = small_model()
    clean = model.simulate(TRUTH, AREA).ravel()
    sigma = 0.03 * np.abs(clean).max()
    priors = dict(TRUTH, x0=Uniform(-3e-3, 3e-3), y0=Uniform(-2e-3, 2e-3))
    hits, total = 0, 0
    for i in range(8):
        rng = np.random.default_rng(seed + i)
        data = clean + rng.normal(0, sigma, clean.size)
        res = sample_scene_posterior(model, data, sigma, priors, Normal(0.0, 1e-7), rng=rng, **FAST)
        assert res.converged, res.message
        post = res.tree["posterior"]
        for name in ("x0", "y0"):
            lo, hi = np.quantile(post[name].values, [0.05, 0.95])
            hits += int(lo <= TRUTH[name] <= hi)
            total += 1
    # binomial(16, 0.9): P(hits <= 11) = 0.017
    assert hits >= 12, f"{hits}/{total} intervals cover the truth"


def test_output_tree_netcdf_and_summary(rng, tmp_path):
    model = small_model(components=("zx", "zz"))
    data = model.simulate(TRUTH, AREA).ravel() + rng.normal(0, 20.0, model.n_data)
    priors = dict(TRUTH, x0=Uniform(-3e-3, 3e-3), friction=Uniform(0.0, 1.0))
    res = sample_scene_posterior(model, data, 20.0, priors, Normal(0.0, 1e-7), rng=rng, **FAST)
    tree = res.tree
    assert set(tree.children) >= {"posterior", "log_likelihood", "observed_data", "sample_stats"}
    assert set(tree["posterior"].data_vars) == {"x0", "friction", "amplitude"}
    assert "y0" not in tree["posterior"].data_vars  # fixed parameters are not sampled
    assert tree["posterior"].sizes["chain"] == 4
    # uninformative observations are dropped from the log_likelihood group (for arviz_stats.loo), and listed
    dropped = [d for d in tree.attrs["log_likelihood_dropped"].split(", ") if d]
    assert tree["log_likelihood"]["obs"].shape[-1] + len(dropped) == model.n_data
    assert {"mean", "sd", "ess_bulk", "ess_tail", "r_hat"} <= set(res.summary.columns)
    assert res.summary.loc["x0", "r_hat"] < 1.02
    path = tmp_path / "posterior.nc"
    res.to_netcdf(path)
    back = xr.open_datatree(path, engine="h5netcdf")
    np.testing.assert_allclose(back["posterior"]["x0"].values, tree["posterior"]["x0"].values)
    assert back.attrs["converged"] == int(res.converged)
    assert len(res.map_estimates) == 4


def test_flat_likelihood_is_reported(rng):
    """The contact never reaches the defect's prior region: the data say nothing about x0."""
    model = DefectScanModel(np.linspace(10e-3, 14e-3, 9), np.array([[0.0, 0.0]]))
    data = rng.normal(0, 1.0, model.n_data)
    priors = dict(TRUTH, x0=Uniform(-2e-3, 2e-3))
    res = sample_scene_posterior(model, data, 1.0, priors, Normal(0.0, 1e-7), rng=rng, **FAST)
    assert res.flat_parameters == ["x0"]
    assert "flat likelihood" in res.message and "x0" in res.message


def test_non_convergence_is_reported(rng):
    model = small_model()
    data = model.simulate(TRUTH, AREA).ravel() + rng.normal(0, 5.0, model.n_data)
    priors = dict(TRUTH, x0=Uniform(-3e-3, 3e-3))
    res = sample_scene_posterior(model, data, 5.0, priors, Normal(0.0, 1e-7), rng=rng, n_walkers=8,
                                 check_every=20, max_steps=20, min_ess=1e6)
    assert not res.converged
    assert "did NOT converge" in res.message and "ESS" in res.message
    assert res.tree.attrs["converged"] == 0


def test_validation(rng):
    model = small_model()
    data = np.zeros(model.n_data)
    priors = dict(TRUTH, x0=Uniform(-3e-3, 3e-3))
    amp = Normal(0.0, 1e-7)
    kw = dict(rng=rng, **FAST)
    with pytest.raises(ValueError, match="data: size mismatch"):
        sample_scene_posterior(model, data[:-1], 1.0, priors, amp, **kw)
    bad = data.copy()
    bad[2] = np.inf
    with pytest.raises(ValueError, match="data: must be finite, found inf"):
        sample_scene_posterior(model, bad, 1.0, priors, amp, **kw)
    with pytest.raises(ValueError, match="noise_std"):
        sample_scene_posterior(model, data, 0.0, priors, amp, **kw)
    with pytest.raises(ValueError, match="priors: need exactly"):
        sample_scene_posterior(model, data, 1.0, {"x0": Uniform(0, 1)}, amp, **kw)
    with pytest.raises(ValueError, match="every parameter is fixed"):
        sample_scene_posterior(model, data, 1.0, dict(TRUTH), amp, **kw)
    with pytest.raises(ValueError, match="amplitude_prior"):
        sample_scene_posterior(model, data, 1.0, priors, Uniform(0, 1), **kw)
    with pytest.raises(ValueError, match="n_ensembles"):
        sample_scene_posterior(model, data, 1.0, priors, amp, n_ensembles=2, **kw)
    with pytest.raises(ValueError, match="n_walkers"):
        sample_scene_posterior(model, data, 1.0, dict(priors, y0=Uniform(0, 1e-3), friction=Uniform(0, 1)), amp,
                               rng=rng, n_walkers=4)
    with pytest.raises(ValueError, match="burn_fraction"):
        sample_scene_posterior(model, data, 1.0, priors, amp, burn_fraction=0.95, **kw)
    with pytest.raises(ValueError, match="x0: expected a prior"):
        check_prior("x0", "left")
    with pytest.raises(ValueError, match="Uniform"):
        Uniform(1.0, 0.0)
    with pytest.raises(ValueError, match="Normal"):
        Normal(0.0, -1.0)
    with pytest.raises(ValueError, match="LogNormal"):
        LogNormal(-1.0, 0.1)
    with pytest.raises(ValueError, match="scan_positions"):
        DefectScanModel([], [[0.0, 0.0]])
    with pytest.raises(ValueError, match="sensors: expected"):
        DefectScanModel([0.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="components"):
        DefectScanModel([0.0], [[0.0, 0.0]], components=("zzz",))
    with pytest.raises(ValueError, match="finger_radius"):
        DefectScanModel([0.0], [[0.0, 0.0]], finger_radius=0.0)
    with pytest.raises(ValueError, match="poisson_ratio"):
        DefectScanModel([0.0], [[0.0, 0.0]], poisson_ratio=0.7)


def test_checked_design_is_the_unchecked_one_with_its_checks(rng):
    """design() checks its parameters once and calls _design(), the likelihood's unchecked inner
    loop (one geometry for all Green's functions): the same numbers, bit for bit, as point_green."""
    from tactilab.forward.halfspace import point_green

    model = DefectScanModel(np.linspace(-3e-3, 3e-3, 5), np.array([[0.0, 0.0], [1e-3, 5e-4]]), ("zx", "zz"))
    walkers = {k: np.full(4, v) for k, v in TRUTH.items()}
    walkers["x0"] = rng.uniform(-2e-3, 2e-3, 4)
    g = model.design(walkers)
    np.testing.assert_array_equal(g, model._design(walkers))
    # the Green's functions through the checked public kernel, as before the split
    for w in range(4):
        xd = walkers["x0"][w] - model.scan_positions[:, None]
        dx, dy = model.sensors[None, :, 0] - xd, model.sensors[None, :, 1] - walkers["y0"][w]
        from tactilab.forward.contact import HertzContact

        p = HertzContact(normal_force=0.8, finger_radius=0.01, young_modulus=1e6, poisson_ratio=0.5).pressure(
            xd, walkers["y0"][w])
        for c, comp in enumerate(("zx", "zz")):
            want = p * (point_green(comp, "z", dx, dy, TRUTH["depth"]) + TRUTH["friction"] * point_green(
                comp, "x", dx, dy, TRUTH["depth"]))
            np.testing.assert_allclose(g[w].reshape(model.data_shape)[..., c], want, rtol=1e-12,
                                       atol=1e-12 * np.abs(want).max())
    with pytest.raises(ValueError, match=r"params: missing \['normal_force'\]"):
        model.design({k: v for k, v in TRUTH.items() if k != "normal_force"})
    with pytest.raises(ValueError, match=r"params\['depth'\]: must be a scalar or a 1-D array .*finite and > 0"):
        model.design(dict(TRUTH, depth=-1e-3))
    with pytest.raises(ValueError, match=r"params\['x0'\]: must be a scalar or a 1-D array .*finite, got"):
        model.design(dict(TRUTH, x0=np.nan))
    with pytest.raises(ValueError, match="params: the arrays must have one length"):
        model.design(dict(TRUTH, x0=np.zeros(3), y0=np.zeros(2)))


def test_positive_parameters_need_positive_priors(rng):
    """The inner loop skips the kernels' checks, so a prior that allows depth <= 0 is refused up front."""
    model = small_model()
    data = model.simulate(TRUTH, AREA).ravel()
    priors = dict(TRUTH, x0=Uniform(-4e-3, 4e-3), y0=Uniform(-2e-3, 2e-3))
    for bad in (dict(depth=Normal(2e-3, 1e-4)), dict(depth=Uniform(0.0, 3e-3)), dict(normal_force=-0.8)):
        with pytest.raises(ValueError, match="priors: (depth|normal_force) must be > 0 .*allows values <= 0"):
            sample_scene_posterior(model, data, 1.0, dict(priors, **bad), Normal(0.0, 1e-7), rng=rng)


def test_priors_logpdf_and_moments(rng):
    for prior in (Uniform(-1.0, 3.0), Normal(1.0, 2.0), LogNormal(2.0, 0.3)):
        x = prior.sample(rng, 200_000)
        assert np.std(x) == pytest.approx(prior.std, rel=0.02)
        grid = np.linspace(x.min(), x.max(), 20001)
        assert np.trapezoid(np.exp(prior.logpdf(grid)), grid) == pytest.approx(1.0, abs=2e-3)
    assert LogNormal(1.0, 0.5).logpdf(-1.0) == -np.inf
    assert Uniform(0, 1).logpdf(2.0) == -np.inf


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_separated_modes_caught_across_ensembles():
    """One sensor on the scan line cannot tell +y0 from -y0: ensembles started at their own MAPs land
    in different modes, and the between-ensemble R-hat reports it (not flagged as flat)."""
    rng = np.random.default_rng(7)  # fixed: which mode each ensemble finds is random
    truth = dict(TRUTH, y0=1.0e-3)
    model = DefectScanModel(np.linspace(-4e-3, 4e-3, 15), np.array([[0.0, 0.0]]), ("zz",))
    clean = model.simulate(truth, AREA).ravel()
    sigma = 0.01 * np.abs(clean).max()
    data = clean + rng.normal(0, sigma, clean.size)
    priors = dict(truth, x0=Uniform(-3e-3, 3e-3), y0=Uniform(-2e-3, 2e-3))
    res = sample_scene_posterior(model, data, sigma, priors, Normal(0.0, 1e-7), rng=rng, n_ensembles=8,
                                 n_walkers=12, check_every=200, max_steps=400, min_ess=100, tau_factor=5,
                                 n_start=128)
    signs = {np.sign(m["y0"]) for m in res.map_estimates}
    assert signs == {-1.0, 1.0}
    assert not res.converged and "between ensembles" in res.message
    assert res.diagnostics["rhat_between_max"] > 1.1
    assert "y0" not in res.flat_parameters


@pytest.mark.slow
def test_defect_posterior_works_with_arviz_loo(rng):
    """Sensors the defect's signal never reaches give identical log-likelihood terms in every draw
    ("All tail values are the same" in PSIS): they are dropped and said so; loo then runs."""
    import arviz_stats as azs

    model = small_model(components=("zx", "zz"))
    data = model.simulate(TRUTH, AREA).ravel() + rng.normal(0, 20.0, model.n_data)
    priors = dict(TRUTH, x0=Uniform(-3e-3, 3e-3), friction=Uniform(0.0, 1.0))
    res = sample_scene_posterior(model, data, 20.0, priors, Normal(0.0, 1e-7), rng=rng, **FAST)
    tree = res.tree
    assert "dropped" in tree.attrs["log_likelihood_note"]
    dropped = [int(i) for i in tree.attrs["log_likelihood_dropped"].split(", ")]
    ll = tree["log_likelihood"]["obs"].values
    assert ll.shape[-1] + len(dropped) == model.n_data  # nothing merged here: kept + dropped = all
    # kept terms + the dropped terms' mean sum = the total log-likelihood of every draw (to the
    # dropped terms' spread, < 1e-9 nats each for the uninformative ones)
    post = tree["posterior"]
    theta = np.column_stack([post[q].values.ravel() for q in ("x0", "friction", "amplitude")])
    fixed = {q: float(v) for q, v in TRUTH.items()}
    defect = DefectPosterior(model, data, 20.0, dict(fixed, x0=priors["x0"], friction=priors["friction"]),
                             Normal(0.0, 1e-7))
    total = defect.log_likelihood(theta).sum(axis=1)
    approx = ll.reshape(-1, ll.shape[-1]).sum(axis=1) + tree.attrs["log_likelihood_dropped_total"]
    informative_dropped = np.ptp(defect.log_likelihood(theta)[:, dropped], axis=0).sum()
    assert np.abs(total - approx).max() <= informative_dropped + 1e-6
    loo = azs.loo(tree)
    assert np.isfinite(loo.elpd) and loo.n_data_points == ll.shape[-1]
    off = sample_scene_posterior(model, data, 20.0, priors, Normal(0.0, 1e-7), rng=np.random.default_rng(3),
                                 info_tol=None, **dict(FAST, max_steps=300))
    assert off.tree["log_likelihood"]["obs"].shape[-1] == model.n_data
    with pytest.raises(ValueError, match="All tail values are the same"):
        azs.loo(off.tree)


def test_loo_ready_drops_and_merges():
    from tactilab.inversion.pointwise import loo_ready

    rng = np.random.default_rng(0)
    s = 400
    ll = rng.normal(size=(s, 6))
    ll[:, 1] = -3.0  # uninformative
    ll[:, 3] = -2.0  # each at its minimum in half the draws: tied tails; their sum is not tied
    ll[:200, 3] = -1.0
    ll[:, 4] = -2.0
    ll[-200:, 4] = -2.0 + rng.uniform(0.1, 1.0, 200)
    ll[:, 5] = -2.0  # alone in its group and tied: dropped
    ll[:3, 5] = -0.5
    out, labels, attrs = loo_ready(ll, 1e-9, groups=[0, 0, 1, 1, 1, 2])
    assert list(labels) == ["0", "2", "group 1: 3+4"]
    np.testing.assert_array_equal(out[:, 2], ll[:, 3] + ll[:, 4])
    assert attrs["log_likelihood_dropped"] == "1, 5"
    assert attrs["log_likelihood_dropped_total"] == pytest.approx(np.mean(ll[:, 1] + ll[:, 5]))
    assert "merged within their group" in attrs["log_likelihood_note"]
    _, labels, attrs = loo_ready(ll, 1e-9)
    assert list(labels) == ["0", "2"] and "observation_groups" in attrs["log_likelihood_note"]
    with pytest.raises(ValueError, match=r"model.observation_groups: expected one label per observation, shape \(6,\)"):
        loo_ready(ll, 1e-9, groups=[0, 1])

"""sample_posterior on any PosteriorModel: recovery of a known Gaussian posterior, picklability,
pool and backend (checkpoint, resume), the log_likelihood group, validation."""

from __future__ import annotations

import pickle
import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import emcee
import numpy as np
import pytest

from tactilab.inversion import PosteriorModel, sample_posterior
from tactilab.inversion.mcmc import DefectPosterior
from tactilab.inversion.sampler import _Target, _thin
from tactilab.inversion.scene_params import DefectScanModel, Normal, Uniform

FAST = dict(n_walkers=8, check_every=200, max_steps=3000, min_ess=400, tau_factor=20, n_start=64)


class GaussianToy:
    """y = X theta + N(0, s^2), theta ~ N(0, prior_sd^2 I): the posterior is Gaussian in closed form."""

    param_names = ("a", "b")

    def __init__(self, x, y, noise_std, prior_sd, vectorized=True):
        self.x, self.observed, self.noise_std, self.prior_sd = x, y, noise_std, prior_sd
        self.vectorized = vectorized

    def log_prior(self, theta):
        theta = np.asarray(theta)
        return -0.5 * np.sum(theta**2, axis=-1) / self.prior_sd**2 - np.log(2 * np.pi * self.prior_sd**2)

    def log_likelihood(self, theta):
        pred = np.asarray(theta) @ self.x.T
        return -0.5 * ((self.observed - pred) / self.noise_std) ** 2 - np.log(self.noise_std * np.sqrt(2 * np.pi))

    def initial(self, rng, n):
        return rng.normal(0.0, self.prior_sd, (n, 2))

    def exact(self):
        prec = self.x.T @ self.x / self.noise_std**2 + np.eye(2) / self.prior_sd**2
        cov = np.linalg.inv(prec)
        return cov @ self.x.T @ self.observed / self.noise_std**2, cov


class CountingPool:
    """A pool with ``map`` that counts its calls (serial)."""

    def __init__(self):
        self.calls = 0

    def map(self, func, iterable):
        self.calls += 1
        return list(map(func, iterable))


def toy(rng, vectorized=True, n=30):
    x = np.column_stack([np.ones(n), np.linspace(-1, 1, n)])
    truth = np.array([0.7, -1.2])
    return GaussianToy(x, x @ truth + rng.normal(0, 0.5, n), 0.5, 3.0, vectorized=vectorized)


def draws(tree, names=("a", "b")):
    return np.column_stack([tree["posterior"][q].values.ravel() for q in names])


def test_recovers_a_known_gaussian_posterior(rng):
    model = toy(rng)
    assert isinstance(model, PosteriorModel)
    tree = sample_posterior(model, rng, **FAST)
    assert tree.attrs["converged"] == 1, tree.attrs["message"]
    mean, cov = model.exact()
    sd = np.sqrt(np.diag(cov))
    x = draws(tree)
    ess = tree.attrs["ess_bulk_min"]
    # Monte Carlo error of the mean is sd / sqrt(ESS); of the sd about sd / sqrt(2 ESS)
    np.testing.assert_array_less(np.abs(x.mean(axis=0) - mean), 4 * sd / np.sqrt(ess))
    np.testing.assert_array_less(np.abs(x.std(axis=0) - sd), 4 * sd / np.sqrt(2 * ess) + 0.02 * sd)
    corr = np.corrcoef(x.T)[0, 1]
    assert corr == pytest.approx(cov[0, 1] / (sd[0] * sd[1]), abs=0.08)
    assert tree["posterior"].sizes["chain"] == 4
    assert len(eval(tree.attrs["map_estimates"])) == 4  # noqa: S307 (JSON list of dicts)


def test_log_likelihood_group_sums_to_the_total(rng):
    model = toy(rng)
    tree = sample_posterior(model, rng, **dict(FAST, max_steps=400))
    x = draws(tree)
    ll = tree["log_likelihood"]["obs"].values.reshape(x.shape[0], -1)
    assert ll.shape[1] == model.observed.size
    np.testing.assert_allclose(ll.sum(axis=1), model.log_likelihood(x).sum(axis=1), rtol=1e-12)
    lp = tree["sample_stats"]["lp"].values.ravel()
    np.testing.assert_allclose(lp, model.log_prior(x) + ll.sum(axis=1), rtol=1e-10)
    np.testing.assert_array_equal(tree["observed_data"]["data"].values, model.observed)


def test_vectorised_and_per_walker_targets_give_the_same_chains(seed):
    model_v = toy(np.random.default_rng(seed))
    model_w = toy(np.random.default_rng(seed), vectorized=False)
    opts = dict(FAST, max_steps=200)
    a = sample_posterior(model_v, np.random.default_rng(seed), **opts)
    b = sample_posterior(model_w, np.random.default_rng(seed), **opts)
    np.testing.assert_allclose(draws(a), draws(b), rtol=1e-10)


def test_models_and_target_pickle(rng):
    model = toy(rng)
    back = pickle.loads(pickle.dumps(_Target(model)))
    theta = np.array([0.3, -0.4])
    assert back(theta) == _Target(model)(theta)
    dm = DefectScanModel(np.linspace(-4e-3, 4e-3, 7), np.array([[0.0, 0.0]]))
    priors = dict(x0=Uniform(-3e-3, 3e-3), y0=0.3e-3, friction=0.5, depth=2e-3, young_modulus=1e6, normal_force=0.8)
    defect = DefectPosterior(dm, np.ones(dm.n_data), 1.0, priors, Normal(0.0, 1e-7))
    again = pickle.loads(pickle.dumps(defect))
    full = np.array([[1e-3, 2e-8]])
    np.testing.assert_array_equal(again.log_likelihood(full), defect.log_likelihood(full))


@pytest.mark.slow
def test_pool_is_used_and_gives_the_serial_result(seed):
    model = toy(np.random.default_rng(seed), vectorized=False)
    opts = dict(FAST, max_steps=100, check_every=100)
    pool = CountingPool()
    with_pool = sample_posterior(model, np.random.default_rng(seed), pool=pool, **opts)
    # emcee maps each half-ensemble per step: 2 x 100 steps x 4 ensembles, plus the pointwise pass
    assert pool.calls >= 800
    serial = sample_posterior(model, np.random.default_rng(seed), **opts)
    np.testing.assert_array_equal(draws(with_pool), draws(serial))
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as workers:
        parallel = sample_posterior(model, np.random.default_rng(seed), pool=workers, **dict(opts, max_steps=20,
                                                                                               check_every=20))
    short = sample_posterior(model, np.random.default_rng(seed), **dict(opts, max_steps=20, check_every=20))
    np.testing.assert_array_equal(draws(parallel), draws(short))


@pytest.mark.slow
def test_hdf_backend_checkpoints_and_resumes(rng, tmp_path):
    model = toy(rng)
    path = tmp_path / "chains.h5"
    opts = dict(FAST, check_every=40, min_ess=1e9)  # never converges: runs to max_steps
    first = sample_posterior(model, np.random.default_rng(1), backend=emcee.backends.HDFBackend(path),
                             **dict(opts, max_steps=80))
    assert first.attrs["n_steps"] == 80 and first.attrs["resumed"] == 0
    stored = [emcee.backends.HDFBackend(path, name=f"mcmc_ensemble{i}", read_only=True) for i in range(4)]
    assert [b.iteration for b in stored] == [80] * 4
    head = stored[0].get_chain().copy()
    second = sample_posterior(model, np.random.default_rng(2), backend=emcee.backends.HDFBackend(path),
                              **dict(opts, max_steps=160))
    assert second.attrs["n_steps"] == 160 and second.attrs["resumed"] == 1
    after = emcee.backends.HDFBackend(path, name="mcmc_ensemble0", read_only=True)
    assert after.iteration == 160
    np.testing.assert_array_equal(after.get_chain()[:80], head)
    backends = [emcee.backends.Backend() for _ in range(4)]
    sample_posterior(model, rng, backend=backends, **dict(opts, max_steps=100))
    assert all(b.iteration == 100 for b in backends)


class NoInitial:
    param_names = ("a",)

    def log_prior(self, theta):
        return 0.0 if abs(theta[0]) < 1 else -np.inf

    def log_likelihood(self, theta):
        return np.array([-0.5 * theta[0] ** 2])


class NaNModel(NoInitial):
    def log_likelihood(self, theta):
        return np.array([np.nan])


class BadInitial(NoInitial):
    def initial(self, rng, n):
        return np.full((n, 1), 5.0)


class WrongInitial(NoInitial):
    def initial(self, rng, n):
        return np.zeros((n, 3))


class Unpicklable(NoInitial):
    def __init__(self):
        self.hook = lambda x: x


def test_start_without_initial_hook(rng):
    tree = sample_posterior(NoInitial(), rng, start=[0.1], **dict(FAST, max_steps=400))
    assert abs(float(tree["posterior"]["a"].mean())) < 0.2


def test_validation(rng):
    model = toy(rng)
    kw = dict(FAST, max_steps=10)
    with pytest.raises(ValueError, match="model.param_names: expected a sequence"):
        sample_posterior(type("M", (), {"param_names": "ab"})(), rng)
    with pytest.raises(ValueError, match="model.param_names: need at least one name and no repeats"):
        sample_posterior(type("M", (), {"param_names": ("a", "a")})(), rng)
    with pytest.raises(ValueError, match="model.log_prior: the model must define"):
        sample_posterior(type("M", (), {"param_names": ("a",)})(), rng)
    with pytest.raises(ValueError, match="n_ensembles: need at least 4"):
        sample_posterior(model, rng, n_ensembles=3)
    with pytest.raises(ValueError, match="burn_fraction: must lie in"):
        sample_posterior(model, rng, burn_fraction=0.95)
    with pytest.raises(ValueError, match="max_steps, check_every: need positive"):
        sample_posterior(model, rng, max_steps=0)
    with pytest.raises(ValueError, match="pool: expected an object with a map"):
        sample_posterior(model, rng, pool=object())
    with pytest.raises(ValueError, match="model: must be picklable"):
        sample_posterior(Unpicklable(), rng, pool=CountingPool(), start=[0.0])
    with pytest.raises(ValueError, match="n_walkers: emcee needs at least 2 x n_parameters = 4"):
        sample_posterior(model, rng, n_walkers=2)
    with pytest.raises(ValueError, match=r"start: expected finite values of shape \(2,\)"):
        sample_posterior(model, rng, start=[0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="start: the model has no initial"):
        sample_posterior(NoInitial(), rng)
    with pytest.raises(ValueError, match="start: the log posterior is -inf"):
        sample_posterior(NoInitial(), rng, start=[3.0], **kw)
    with pytest.raises(ValueError, match=r"model.initial: expected shape \(64, 1\)"):
        sample_posterior(WrongInitial(), rng, **kw)
    with pytest.raises(ValueError, match="model.initial: none of 64 candidates"):
        sample_posterior(BadInitial(), rng, **kw)
    with pytest.raises(ValueError, match="model: log posterior is NaN"):
        sample_posterior(NaNModel(), rng, start=[0.0], **kw)
    with pytest.raises(ValueError, match="backend: expected an emcee.backends.HDFBackend"):
        sample_posterior(model, rng, backend=[emcee.backends.Backend()], **kw)


def test_backends_with_different_progress_are_refused(rng):
    model = toy(rng)
    backends = [emcee.backends.Backend() for _ in range(4)]
    sample_posterior(model, rng, backend=backends, **dict(FAST, max_steps=50, check_every=50, min_ess=1e9))
    backends[0] = emcee.backends.Backend()
    with pytest.raises(ValueError, match=r"backend: the ensembles hold different numbers of steps \[0, 50\]"):
        sample_posterior(model, rng, backend=backends, **dict(FAST, max_steps=100))


class CorrelatedGaussian:
    """y = X theta + noise in 10 dimensions, prior sd 30-50 x the posterior sd, strongly correlated
    posterior: the case where a Nelder-Mead-only MAP search stopped tens of posterior sd from the
    mode and the ensembles' pooled draws had several times the true sd."""

    vectorized = True

    def __init__(self, rng, p=10, n=30, prior_sd=1.0, noise_std=0.01):
        t = np.linspace(0, 1, n)[:, None]
        self.x = np.exp(-((t - np.linspace(0, 1, p)[None, :]) ** 2) / 0.02)  # overlapping bumps
        self.prior_sd, self.noise_std = prior_sd, noise_std
        self.observed = self.x @ rng.normal(0, prior_sd, p) + rng.normal(0, noise_std, n)
        self.param_names = tuple(f"t{i}" for i in range(p))

    def log_prior(self, theta):
        return -0.5 * np.sum(np.asarray(theta) ** 2, axis=-1) / self.prior_sd**2

    def log_likelihood(self, theta):
        return -0.5 * ((self.observed - np.asarray(theta) @ self.x.T) / self.noise_std) ** 2

    def initial(self, rng, n):
        return rng.normal(0.0, self.prior_sd, (n, len(self.param_names)))

    def exact(self):
        cov = np.linalg.inv(self.x.T @ self.x / self.noise_std**2 + np.eye(self.x.shape[1]) / self.prior_sd**2)
        return cov @ self.x.T @ self.observed / self.noise_std**2, cov


@pytest.mark.slow
def test_correlated_gaussian_map_start_and_moments(rng):
    model = CorrelatedGaussian(rng)
    mean, cov = model.exact()
    sd, prec = np.sqrt(np.diag(cov)), np.linalg.inv(cov)
    assert sd.max() < 0.05 * model.prior_sd  # the data dominate: the MAP search has far to go
    tree = sample_posterior(model, rng, n_walkers=24, max_steps=2000, check_every=2000, n_start=32,
                            info_tol=None)
    for est in eval(tree.attrs["map_estimates"]):  # noqa: S307 (JSON list of dicts)
        d = np.array([est[q] for q in model.param_names]) - mean
        assert np.sqrt(d @ prec @ d) < 1e-2  # at the mode, in posterior sd (a draw is ~3 away)
    x = draws(tree, model.param_names)
    # Monte Carlo error with the measured autocorrelation time: ESS ~ draws x walkers / tau
    ess = tree.attrs["n_kept"] * 24 * 4 / tree.attrs["tau_max"]
    assert ess > 200, tree.attrs["message"]
    np.testing.assert_array_less(np.abs(x.mean(axis=0) - mean), 5 * sd / np.sqrt(ess))
    np.testing.assert_array_less(np.abs(x.std(axis=0) / sd - 1), 5 / np.sqrt(2 * ess) + 0.05)


def test_thinning_keeps_every_walker(rng):
    """max_draws thins by steps, not by a stride over (step, walker): a stride of 60 over 24 walkers
    kept only walkers 0 and 12 of every ensemble."""
    model = toy(rng)
    backends = [emcee.backends.Backend() for _ in range(4)]
    tree = sample_posterior(model, rng, backend=backends, max_draws=480, info_tol=None,
                            **dict(FAST, n_walkers=24, max_steps=400, check_every=400))
    burn = int(tree.attrs["burn_in"])
    x = draws(tree)
    assert x.shape[0] <= 480
    per_chain = x.reshape(4, -1, 2)
    steps, walkers = _thin(400 - burn, 24, 120)
    assert set(walkers.tolist()) == set(range(24)) and np.unique(steps).size == 5
    assert steps[0] == 0 and steps[-1] == 400 - burn - 1  # spread over the whole kept chain
    for chain, backend in zip(per_chain, backends):
        np.testing.assert_array_equal(chain, backend.get_chain()[burn:][steps, walkers])


def test_thin_with_fewer_draws_than_walkers():
    steps, walkers = _thin(100, 24, 10)
    assert steps.size == walkers.size == 10
    assert np.unique(steps).size == 10 and np.unique(walkers).size == 10
    assert steps[0] == 0 and steps[-1] == 99 and walkers.max() < 24
    s_all, w_all = _thin(5, 4, 1000)  # everything fits: every state, step by step over the walkers
    np.testing.assert_array_equal(s_all, np.repeat(np.arange(5), 4))
    np.testing.assert_array_equal(w_all, np.tile(np.arange(4), 5))


def test_one_emcee_driver_in_the_library():
    """Only the sampler module drives emcee; every other MCMC (defect scenes, transduction and
    psychometric fits) goes through sample_posterior."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    drivers = []
    for part in ("core", "data_schemas", "forward", "inversion", "experiments", "demo", "cli"):
        for path in sorted((root / part).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                    [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
                if any(n == "emcee" or n.startswith("emcee.") for n in names):
                    drivers.append(str(path.relative_to(root)))
    assert drivers == ["inversion/sampler.py"]

"""Posterior sampling of any model object with emcee, convergence judged across ensembles.

:func:`sample_posterior` takes a model that follows :class:`PosteriorModel` (parameter names, a
log prior and a per-observation log-likelihood, picklable) and returns an arviz ``DataTree``.

Sampling: ``n_ensembles`` (>= 4) independent ``emcee.EnsembleSampler`` runs. Each ensemble starts
in a small ball around its OWN MAP estimate (best of the model's ``initial`` candidates drawn with
the ensemble's own rng, polished by BFGS with a finite-difference gradient and then Nelder-Mead,
both in scaled coordinates), so ensembles that find different modes disagree visibly. (Nelder-Mead
alone stopped tens of posterior sd short of the mode in 10-16 dimensions; walkers started there
took thousands of steps to reach the posterior or stayed stuck, inflating the pooled sd.)
Every ``check_every`` steps, on the chains after burn-in:

- rank-normalised split R-hat (arviz_stats) between ensembles (each ensemble's draws, step by
  step over its walkers, pooled as one chain) < ``rhat_target``; the R-hat with every walker as
  a chain is reported too (walkers of one ensemble are not independent chains, so it is not a
  stopping rule);
- bulk and tail ESS (every walker a chain) >= ``min_ess``;
- kept chain length >= ``tau_factor`` x the integrated autocorrelation time (emcee, per ensemble).

Sampling stops when all hold (``converged = 1`` in the tree's attrs) or at ``max_steps``
(``converged = 0``, the failing checks listed in ``attrs["failed"]`` and ``attrs["message"]``).

The log-likelihood group holds the model's per-observation terms at the kept draws, made ready
for ``arviz_stats.loo`` by :func:`tactilab.inversion.pointwise.loo_ready`: observations whose
term spans less than ``info_tol`` nats over all draws carry no information and are dropped;
observations informative in only some draws (tied PSIS tails) are merged into the model's
``observation_groups`` where it names them, else dropped. ``attrs["log_likelihood_note"]`` says
what was done, ``attrs["log_likelihood_dropped"]`` lists what was dropped and
``attrs["log_likelihood_dropped_total"]`` holds the mean of their summed terms.
"""

from __future__ import annotations

import json
import pickle
from typing import Protocol, Sequence, runtime_checkable

import emcee
import numpy as np
from scipy.optimize import minimize

from .chain_memory import check_max_steps, default_walkers
from .pointwise import loo_ready

__all__ = ["PosteriorModel", "sample_posterior", "mcmc_diagnostics"]


@runtime_checkable
class PosteriorModel(Protocol):
    """What :func:`sample_posterior` needs from a model (a ``typing.Protocol``).

    Required
    --------
    param_names : sequence of str
        Names of the P sampled parameters, in the order of ``theta``; unique.
    log_prior(theta) -> float
        ``theta`` shape (P,): log prior density (``-inf`` outside the support, never NaN).
    log_likelihood(theta) -> ndarray, shape (n_obs,)
        Per-observation log-likelihood terms ``log p(d_i | theta)``; the sampler's target is
        ``log_prior(theta) + sum(log_likelihood(theta))`` and the terms fill the tree's
        ``log_likelihood`` group. Never NaN (``-inf`` is allowed).

    The model must pickle (``pickle.dumps(model)``) so that a ``pool`` can send it to workers.

    Optional hooks (looked up with ``getattr``)
    -------------------------------------------
    vectorized : bool
        When True, ``log_prior`` takes ``theta`` shape (W, P) and returns (W,), and
        ``log_likelihood`` takes (W, P) and returns (W, n_obs): one call per ensemble step
        (emcee ``vectorize=True``; ignored when a ``pool`` is given).
    initial(rng, n) -> ndarray, shape (n, P)
        Candidate starting points (e.g. prior draws); each ensemble starts at the best of
        ``n_start`` candidates polished by BFGS and Nelder-Mead (its MAP estimate). Without it, pass
        ``start`` to :func:`sample_posterior`.
    scale : ndarray, shape (P,)
        Typical parameter scale (e.g. prior sd) for the MAP polish and the start ball
        (default: the sd of the ``initial`` candidates, else 1).
    observed : ndarray, shape (n_obs,)
        The data, written to the tree's ``observed_data`` group.
    units : str
        Units of the parameters, written to ``attrs["units"]``.
    variable_attrs : mapping name -> dict
        Attributes of the tree's variables (``units`` in SI, ``long_name``), by name: the
        parameters of the ``posterior`` group and ``data`` of ``observed_data``; they reach
        ``az.summary`` users and the netCDF file (CF). The sampler's own variables (``obs``,
        ``lp``) get theirs here.
    observation_groups : ndarray, shape (n_obs,)
        A group label per observation (e.g. the sensor channel); used to merge observations
        for LOO when some are informative in only some draws (see
        :mod:`tactilab.inversion.pointwise`).
    marginalised_names, log_marginal_likelihood(theta), draw_marginalised(theta, rng)
        For models that integrate some parameters out exactly (a linear amplitude): the target
        is ``log_prior + log_marginal_likelihood(theta)`` (float, or (W,) when vectorized);
        ``draw_marginalised(theta (N, P), rng) -> dict name -> (N,)`` draws them from their
        conditional posterior for every kept draw (they join the ``posterior`` group), and
        ``log_likelihood`` then takes the full vector (sampled parameters followed by
        ``marginalised_names``).
    """

    param_names: Sequence[str]

    def log_prior(self, theta: np.ndarray) -> float: ...

    def log_likelihood(self, theta: np.ndarray) -> np.ndarray: ...


class _Target:
    """Picklable log posterior (target) of a model: one theta (P,) -> float, or (W, P) -> (W,)."""

    def __init__(self, model):
        self.model = model
        self.vectorized = bool(getattr(model, "vectorized", False))
        self.marginal = callable(getattr(model, "log_marginal_likelihood", None))

    def _likelihood(self, theta):
        if self.marginal:
            return self.model.log_marginal_likelihood(theta)
        ll = np.asarray(self.model.log_likelihood(theta), dtype=float)
        return ll.sum(axis=-1)

    def __call__(self, theta):
        theta = np.asarray(theta, dtype=float)
        if theta.ndim == 2:
            return self.many(theta)
        if self.vectorized:
            return float(self.many(theta[None, :])[0])
        lp = float(self.model.log_prior(theta))
        out = lp + float(self._likelihood(theta)) if np.isfinite(lp) else -np.inf
        if np.isnan(out) or np.isnan(lp):
            raise ValueError(f"model: log posterior is NaN at theta={theta.tolist()}; log_prior and "
                             "log_likelihood must return -inf (not NaN) outside the support")
        return out

    def many(self, thetas: np.ndarray) -> np.ndarray:
        if not self.vectorized:
            return np.array([self(t) for t in thetas])
        lp = np.asarray(self.model.log_prior(thetas), dtype=float).reshape(thetas.shape[0])
        out = np.full(thetas.shape[0], -np.inf)
        ok = np.isfinite(lp)
        if ok.any():
            out[ok] = lp[ok] + np.asarray(self._likelihood(thetas[ok]), dtype=float).reshape(-1)
        bad = np.isnan(out) | np.isnan(lp)
        if bad.any():
            raise ValueError(f"model: log posterior is NaN at theta={thetas[np.flatnonzero(bad)[0]].tolist()}; "
                             "log_prior and log_likelihood must return -inf (not NaN) outside the support")
        return out


def _pointwise(model, thetas: np.ndarray, pool) -> np.ndarray:
    """Per-observation log-likelihood, shape (N, n_obs)."""
    if getattr(model, "vectorized", False) and pool is None:
        return np.concatenate([np.asarray(model.log_likelihood(thetas[i:i + 256]), dtype=float)
                               for i in range(0, thetas.shape[0], 256)])
    mapper = pool.map if pool is not None else map
    return np.array([np.asarray(v, dtype=float) for v in mapper(model.log_likelihood, list(thetas))])


def _initial(model, rng, n: int, ndim: int) -> np.ndarray:
    cand = np.asarray(model.initial(rng, n), dtype=float)
    if cand.shape != (n, ndim):
        raise ValueError(f"model.initial: expected shape ({n}, {ndim}) from initial(rng, {n}), got {cand.shape}")
    return cand


def _map_start(target: _Target, model, rng, n_start: int, scale: np.ndarray, start):
    """Best initial candidate (or the given start), polished by BFGS then Nelder-Mead in scaled coordinates."""
    if start is not None:
        best = np.asarray(start, dtype=float)
        if not np.isfinite(target(best)):
            raise ValueError(f"start: the log posterior is -inf at {best.tolist()}; start inside the prior's support")
    else:
        cand = _initial(model, rng, n_start, scale.size)
        vals = target.many(cand)
        if not np.isfinite(vals).any():
            raise ValueError(f"model.initial: none of {n_start} candidates has a finite log posterior; "
                             "draw the candidates from the prior")
        best = cand[int(np.argmax(vals))]
    def neg(z):
        return -float(target(best + z * scale))

    z = np.zeros(best.size)
    # quasi-Newton first (finite-difference gradient): Nelder-Mead alone stalls tens of posterior
    # sd from the mode in more than a few dimensions, and walkers started there need thousands of
    # steps to find the posterior (or stay stuck); a non-finite or worse result is ignored
    with np.errstate(all="ignore"):
        quasi = minimize(neg, z, method="BFGS", options={"maxiter": max(50, 10 * best.size), "gtol": 1e-6})
    if np.all(np.isfinite(quasi.x)) and np.isfinite(quasi.fun) and quasi.fun <= neg(z):
        z = quasi.x
    res = minimize(neg, z, method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-3, "maxfev": 600})
    polished = best + res.x * scale
    return polished if np.isfinite(target(polished)) else best + z * scale


def _thin(n: int, w: int, per_chain: int) -> tuple[np.ndarray, np.ndarray]:
    """Step and walker indices (each shape (D,), D <= max(per_chain, 1)) of the draws kept from a chain
    of ``n`` steps x ``w`` walkers: evenly spaced steps with every walker, or, when fewer than ``w``
    draws fit, one distinct walker per evenly spaced step.

    Thinning with a stride over the flattened (step, walker) array would keep the same few walkers
    whenever the stride shares a factor with ``w`` (2 of 64 walkers for the 16-parameter benchmark in
    benchmarks/bench_tradeoff.py), throwing away most of the ensemble's effective sample size.
    """
    if per_chain >= n * w:
        steps = np.arange(n)
    elif per_chain >= w:
        steps = np.unique(np.round(np.linspace(0, n - 1, per_chain // w)).astype(int))
    else:
        m = min(n, per_chain)
        steps = np.unique(np.round(np.linspace(0, n - 1, m)).astype(int))
        walkers = (np.arange(steps.size) * w) // steps.size
        return steps, walkers
    return np.repeat(steps, w), np.tile(np.arange(w), steps.size)


def mcmc_diagnostics(chains: np.ndarray, tau_factor: float, rhat_target: float, min_ess: float) -> dict:
    """R-hat, ESS and autocorrelation checks of ``chains``, shape (n_ensembles, steps, walkers, P).

    Returns
    -------
    dict
        ``rhat_max`` (every walker a chain), ``rhat_between_max`` (every ensemble a chain),
        ``ess_bulk_min``, ``ess_tail_min``, ``tau_max`` (steps), ``n_kept`` and ``failed`` (list
        of the checks that fail against the thresholds).
    """
    import arviz_stats as azs

    k, n, w, p = chains.shape
    per_walker = chains.transpose(0, 2, 1, 3).reshape(k * w, n, p)
    per_ensemble = chains.reshape(k, n * w, p)
    rhat = np.atleast_1d(azs.rhat(per_walker, chain_axis=0, draw_axis=1))
    rhat_between = np.atleast_1d(azs.rhat(per_ensemble, chain_axis=0, draw_axis=1))
    ess_bulk = np.atleast_1d(azs.ess(per_walker, method="bulk", chain_axis=0, draw_axis=1))
    ess_tail = np.atleast_1d(azs.ess(per_walker, method="tail", prob=(0.05, 0.95), chain_axis=0, draw_axis=1))
    # tol=0: no emcee warning; the length check against tau_factor x tau is ours, below
    tau = max(float(np.max(emcee.autocorr.integrated_time(chains[i], c=5, tol=0))) for i in range(k))
    diag = {"rhat_max": float(np.max(rhat)), "rhat_between_max": float(np.max(rhat_between)),
            "ess_bulk_min": float(np.min(ess_bulk)), "ess_tail_min": float(np.min(ess_tail)),
            "tau_max": tau, "n_kept": n}
    failed = []
    if not diag["rhat_between_max"] < rhat_target:
        failed.append(f"R-hat between ensembles {diag['rhat_between_max']:.4f} >= {rhat_target}")
    if not diag["ess_bulk_min"] >= min_ess:
        failed.append(f"bulk ESS {diag['ess_bulk_min']:.0f} < {min_ess}")
    if not diag["ess_tail_min"] >= min_ess:
        failed.append(f"tail ESS {diag['ess_tail_min']:.0f} < {min_ess}")
    if not n >= tau_factor * tau:
        failed.append(f"kept chain {n} steps < {tau_factor} x autocorrelation time {tau:.1f}")
    diag["failed"] = failed
    return diag


def _check_model(model) -> tuple[str, ...]:
    names = getattr(model, "param_names", None)
    if names is None or isinstance(names, str) or not all(isinstance(q, str) for q in names):
        raise ValueError(f"model.param_names: expected a sequence of parameter names (str), got {names!r}")
    names = tuple(names)
    if not names or len(set(names)) != len(names):
        raise ValueError(f"model.param_names: need at least one name and no repeats, got {names!r}")
    for hook in ("log_prior", "log_likelihood"):
        if not callable(getattr(model, hook, None)):
            raise ValueError(f"model.{hook}: the model must define a callable {hook}(theta); see PosteriorModel")
    return names


def _backends(backend, k: int) -> list:
    if backend is None:
        return [None] * k
    if isinstance(backend, emcee.backends.HDFBackend):  # one HDF5 group per ensemble, same file
        return [emcee.backends.HDFBackend(backend.filename, name=f"{backend.name}_ensemble{i}",
                                          read_only=backend.read_only, dtype=backend.dtype,
                                          compression=backend.compression,
                                          compression_opts=backend.compression_opts) for i in range(k)]
    if isinstance(backend, (list, tuple)) and len(backend) == k and all(
            isinstance(b, emcee.backends.Backend) for b in backend):
        return list(backend)
    raise ValueError(f"backend: expected an emcee.backends.HDFBackend (one group per ensemble) or a list of "
                     f"{k} emcee backends (one per ensemble), got {backend!r}")


def sample_posterior(model: PosteriorModel, rng: np.random.Generator, *, n_ensembles: int = 4,
                     pool=None, backend=None, n_walkers: int | None = None, start=None,
                     max_steps: int = 20000, check_every: int = 500, rhat_target: float = 1.01,
                     min_ess: float = 400.0, tau_factor: float = 50.0, n_start: int = 512,
                     max_draws: int = 4000, burn_fraction: float = 0.25, info_tol: float | None = 1e-9,
                     progress: bool = False):
    """Sample the posterior of a :class:`PosteriorModel` with emcee (see module docstring).

    Parameters
    ----------
    model : PosteriorModel
        Parameter names, log prior, per-observation log-likelihood; picklable.
    rng : numpy.random.Generator
        Source of every random number (MAP candidates, start balls, emcee's proposals).
    n_ensembles : int
        Independent ensembles, >= 4.
    pool : object with ``map(func, iterable)``, optional
        As emcee's ``pool`` (``multiprocessing.Pool``, ``schwimmbad``, a Dask client wrapper):
        the log posterior of each walker is evaluated through ``pool.map`` (the model must pickle).
    backend : emcee.backends.HDFBackend or list of n_ensembles emcee backends, optional
        Where the chains are stored (checkpointing). An ``HDFBackend`` is split into one group
        per ensemble (``<name>_ensemble<i>`` in the same file). A backend that already holds
        steps is resumed: no new MAP search, sampling continues to ``max_steps`` in all.
    n_walkers : int, optional
        Walkers per ensemble (default max(16, 4 P), made even); >= 2 P.
    start : array_like, shape (P,) or (n_ensembles, P), optional
        Starting point(s) for the MAP polish when the model has no ``initial`` hook.
    max_steps, check_every : int
        Step limit per ensemble and the interval between convergence checks.
    rhat_target, min_ess, tau_factor : float
        Convergence thresholds (see module docstring).
    n_start : int
        ``initial`` candidates per ensemble for its MAP search.
    max_draws : int
        Most draws kept in the tree: evenly spaced steps with all their walkers (one distinct walker
        per step when fewer than ``n_walkers`` draws per ensemble fit).
    burn_fraction : float in [0, 0.9]
        Leading share of every chain discarded as burn-in.
    info_tol : float or None
        Observations whose log-likelihood term spans less than this (nats) over all draws are
        dropped from the ``log_likelihood`` group, and tied tails merged or dropped (stated in
        the attrs; see :mod:`tactilab.inversion.pointwise`); None keeps every observation as is.
    progress : bool
        tqdm progress bar over the steps.

    Returns
    -------
    xarray.DataTree
        ``posterior`` (one chain per ensemble; draws step by step over its walkers),
        ``log_likelihood`` (``obs``, shape (chain, draw, n_kept), coordinate ``obs_id`` = the
        observation's index as text, or ``"group <g>: i+j"`` for merged ones), ``observed_data`` (when the model
        has ``observed``),
        ``sample_stats`` (``lp``, the log target); ``observed_data`` holds the full data (``data``,
        dimension ``data_id``). ``attrs``: the diagnostics of
        :func:`mcmc_diagnostics`, ``converged`` (1/0), ``failed``, ``message``, ``n_steps``,
        ``n_walkers``, ``n_ensembles``, ``burn_in``, ``map_estimates`` (JSON list of dicts),
        ``resumed``, ``log_likelihood_dropped``,
        ``log_likelihood_dropped_total``, ``log_likelihood_note``.
    """
    import arviz_base as azb

    names = _check_model(model)
    ndim = len(names)
    if int(n_ensembles) != n_ensembles or n_ensembles < 4:
        raise ValueError(f"n_ensembles: need at least 4 independent ensembles to judge convergence, got {n_ensembles}")
    k = int(n_ensembles)
    if not (0.0 <= burn_fraction <= 0.9):
        raise ValueError(f"burn_fraction: must lie in [0, 0.9], got {burn_fraction!r}")
    if int(max_steps) < 1 or int(check_every) < 1:
        raise ValueError(f"max_steps, check_every: need positive step counts, got {max_steps!r}, {check_every!r}")
    if pool is not None:
        if not callable(getattr(pool, "map", None)):
            raise ValueError(f"pool: expected an object with a map(func, iterable) method, got {pool!r}")
        try:
            pickle.dumps(model)
        except Exception as exc:  # noqa: BLE001 (any pickling failure)
            raise ValueError(f"model: must be picklable to be sent to pool workers, pickling failed with {exc!r}; "
                             "keep only data and module-level functions on the model") from exc
    n_walkers = default_walkers(ndim) if n_walkers is None else int(n_walkers) + int(n_walkers) % 2
    if n_walkers < 2 * ndim:
        raise ValueError(f"n_walkers: emcee needs at least 2 x n_parameters = {2 * ndim} walkers, got {n_walkers}")
    check_max_steps(max_steps, ndim, n_ensembles=k, n_walkers=n_walkers)  # before any chain grows
    has_initial = callable(getattr(model, "initial", None))
    starts_given = None
    if start is not None:
        starts_given = np.asarray(start, dtype=float)
        if starts_given.shape == (ndim,):
            starts_given = np.tile(starts_given, (k, 1))
        if starts_given.shape != (k, ndim) or not np.all(np.isfinite(starts_given)):
            raise ValueError(f"start: expected finite values of shape ({ndim},) or ({k}, {ndim}), got "
                             f"{np.shape(start)}")
    elif not has_initial:
        raise ValueError("start: the model has no initial(rng, n) hook; pass start=theta (shape (P,)) or add "
                         "initial() returning candidate points (e.g. prior draws)")
    target = _Target(model)
    backends = _backends(backend, k)
    subs = rng.spawn(k)
    scale = getattr(model, "scale", None)
    if scale is None:
        scale = np.std(_initial(model, rng.spawn(1)[0], int(n_start), ndim), axis=0) if has_initial \
            else np.ones(ndim)
    scale = np.broadcast_to(np.asarray(scale, dtype=float), (ndim,))
    scale = np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)
    vectorize = target.vectorized and pool is None
    samplers, p0s, maps = [], [], []
    for i, sub in enumerate(subs):
        sampler = emcee.EnsembleSampler(n_walkers, ndim, target, vectorize=vectorize, pool=pool,
                                        backend=backends[i])
        if sampler.iteration == 0:
            best = _map_start(target, model, sub, int(n_start), scale,
                              None if starts_given is None else starts_given[i])
            maps.append(dict(zip(names, best.tolist())))
            p0 = best + 1e-3 * scale * sub.standard_normal((n_walkers, ndim))
            for _ in range(30):  # a MAP on the prior's edge (lapse 0): redraw the walkers outside it
                bad = ~np.isfinite(target.many(p0))
                if not bad.any():
                    break
                p0[bad] = best + 1e-3 * scale * sub.standard_normal((int(bad.sum()), ndim))
            p0[~np.isfinite(target.many(p0))] = best
            # emcee draws its proposals from a legacy RandomState: seed it from this ensemble's rng
            sampler.random_state = np.random.RandomState(int(sub.integers(2**31))).get_state()
        else:
            p0 = None
        samplers.append(sampler)
        p0s.append(p0)
    done = {s.iteration for s in samplers}
    if len(done) != 1:
        raise ValueError(f"backend: the ensembles hold different numbers of steps {sorted(done)}; resume from "
                         "a backend written by one sample_posterior call")
    steps = done.pop()
    resumed = steps > 0
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=int(max_steps), initial=min(steps, int(max_steps)), desc="emcee (all ensembles)",
                   unit="step")
    while True:
        chunk = max(0, min(int(check_every), int(max_steps) - steps))
        for s, p0 in zip(samplers, p0s):
            if chunk:
                s.run_mcmc(p0 if s.iteration == 0 else None, chunk, progress=False)
        steps += chunk
        if bar is not None:
            bar.update(chunk)
        burn = int(steps * burn_fraction)
        chains = np.stack([s.get_chain() for s in samplers])[:, burn:]
        diag = mcmc_diagnostics(chains, tau_factor, rhat_target, min_ess)
        if not diag["failed"] or steps >= max_steps:
            break
    if bar is not None:
        if not diag["failed"] and steps < max_steps:  # stopped early: say so, and end the bar at 100 %
            bar.set_description_str(f"emcee converged at step {steps} of at most {int(max_steps)}")
            bar.total = steps
            bar.refresh()
        bar.close()
    converged = not diag["failed"]
    kept = chains
    lps = np.stack([s.get_log_prob() for s in samplers])[:, burn:]
    _, n, w, _ = kept.shape
    # one DataTree chain per ensemble; its draws run step by step over the walkers
    steps_kept, walkers_kept = _thin(n, w, max(1, int(max_draws) // k))
    kept, lps = kept[:, steps_kept, walkers_kept], lps[:, steps_kept, walkers_kept]
    n = kept.shape[1]
    flat = kept.reshape(k * n, ndim)
    posterior = {q: flat[:, j].reshape(k, n) for j, q in enumerate(names)}
    full = flat
    if target.marginal:
        extra = model.draw_marginalised(flat, rng)
        for q in model.marginalised_names:
            posterior[q] = np.asarray(extra[q], dtype=float).reshape(k, n)
        full = np.column_stack([flat, *(np.asarray(extra[q], dtype=float) for q in model.marginalised_names)])
    pointwise = _pointwise(model, full, pool)
    if info_tol is None:
        ll_kept, labels, ll_attrs = pointwise, np.arange(pointwise.shape[1]).astype(str), {
            "log_likelihood_dropped": "", "log_likelihood_dropped_total": 0.0,
            "log_likelihood_note": "every observation kept (info_tol=None)"}
    else:
        ll_kept, labels, ll_attrs = loo_ready(pointwise, info_tol, getattr(model, "observation_groups", None))
    diag.update(n_steps=steps, n_walkers=n_walkers, n_ensembles=k, burn_in=burn)
    lines = [("converged" if converged else "did NOT converge") + f" after {steps} steps x {w} walkers x {k} ensembles",
             f"R-hat max {diag['rhat_max']:.4f} (walkers), {diag['rhat_between_max']:.4f} (between ensembles); "
             f"ESS bulk {diag['ess_bulk_min']:.0f}, tail {diag['ess_tail_min']:.0f}; tau {diag['tau_max']:.1f} steps"]
    if diag["failed"]:
        lines.append("failing checks: " + "; ".join(diag["failed"]))
    attrs = {key: (float(v) if not isinstance(v, list) else "; ".join(v)) for key, v in diag.items()}
    attrs.update(converged=int(converged), message="\n".join(lines), map_estimates=json.dumps(maps),
                 resumed=int(resumed), parameters=", ".join(names),
                 **ll_attrs)
    if getattr(model, "units", None):
        attrs["units"] = str(model.units)
    groups = {"posterior": posterior, "log_likelihood": {"obs": ll_kept.reshape(k, n, labels.size)},
              "sample_stats": {"lp": lps}}
    dims = {"obs": ["obs_id"]}
    if getattr(model, "observed", None) is not None:
        groups["observed_data"] = {"data": np.asarray(model.observed, dtype=float).ravel()}
        dims["data"] = ["data_id"]
    tree = azb.from_dict(groups, dims=dims, coords={"obs_id": labels}, attrs={"/": attrs})
    label_variables(tree, getattr(model, "variable_attrs", None))
    return tree


#: attributes of the variables every sampled tree has (log densities in nats: dimensionless)
_OWN_ATTRS = {("log_likelihood", "obs"): {"units": "1", "long_name": "pointwise log-likelihood (nats)"},
              ("sample_stats", "lp"): {"units": "1", "long_name": "log posterior density up to a constant (nats)"}}


def label_variables(tree, variable_attrs=None) -> None:
    """Set ``units`` and ``long_name`` on a sampled tree's variables, in place.

    Parameters
    ----------
    tree : xarray.DataTree
        An arviz tree (``posterior``, ``log_likelihood``, ``sample_stats``, ``observed_data``).
    variable_attrs : mapping name -> dict, optional
        Attributes per variable name, applied in every group that holds the name; the log
        densities ``obs`` and ``lp`` are labelled in any case.
    """
    for (group, name), attrs in _OWN_ATTRS.items():
        if group in tree.children and name in tree[group].dataset:
            tree[group].dataset[name].attrs.update(attrs)
    for name, attrs in dict(variable_attrs or {}).items():
        for group in tree.children:
            if name in tree[group].dataset:
                tree[group].dataset[name].attrs.update(attrs)

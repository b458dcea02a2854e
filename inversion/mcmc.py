"""Posterior sampling of scene parameters with emcee, convergence judged across ensembles by arviz.

Model: ``d = S g(theta) + e``, ``e ~ N(0, sigma^2 I)``, with ``theta`` the nonlinear scene
parameters (priors stated in the call, fixed ones not sampled) and ``S`` a linear amplitude
(e.g. the defect area) with a Gaussian prior ``N(m_S, s_S^2)``. ``S`` is integrated out exactly:

    log p(d | theta) = log N(d; m_S g, sigma^2 I + s_S^2 g g^T)      (Sherman-Morrison)

and drawn afterwards from its exact conditional ``p(S | theta, d)`` for every kept sample, so the
output holds joint posterior draws of ``(theta, S)``.

Sampling: ``n_ensembles`` (>= 4) independent ``emcee.EnsembleSampler`` runs with
``vectorize=True``. Each ensemble starts in a small ball around its OWN MAP estimate (best of a
prior multistart with its own rng, polished by Nelder-Mead), so ensembles that find different
modes disagree visibly. Every ``check_every`` steps, on the second half of the chains:

- rank-normalised split R-hat (arviz) between ensembles (each ensemble's draws, step by step
  over its walkers, pooled as one chain) < ``rhat_target``; the R-hat with every walker as a
  chain is reported too (walkers of one ensemble are not independent chains, so it is not a
  stopping rule);
- bulk and tail ESS (arviz, every walker a chain) >= ``min_ess``;
- chain length >= ``tau_factor`` x the integrated autocorrelation time (emcee, per ensemble).
Sampling stops when all hold (``converged=True``) or at ``max_steps`` (``converged=False``, the
failing checks listed in ``message``). Parameters whose posterior sd exceeds
``flat_ratio`` x their prior sd AND whose marginal is close to the prior (two-sample KS statistic
against prior draws < 0.1; a bimodal posterior is wide but not prior-like) are reported as flat.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import emcee
import numpy as np
from scipy.optimize import minimize

from .scene_params import NONLINEAR, Normal, check_prior

__all__ = ["sample_scene_posterior", "MCMCResult"]


@dataclass
class MCMCResult:
    """Output of :func:`sample_scene_posterior`.

    Attributes
    ----------
    tree : xarray.DataTree
        arviz DataTree: ``posterior`` (sampled parameters and ``amplitude``; one chain per
        ensemble, draws step by step over its walkers, thinned to ``max_draws`` in all),
        ``log_likelihood`` (pointwise), ``observed_data``, ``sample_stats`` (``lp``).
        Convergence diagnostics in ``tree.attrs``.
    converged : bool
    diagnostics : dict
        ``rhat_max``, ``rhat_between_max``, ``ess_bulk_min``, ``ess_tail_min``, ``tau_max``,
        ``n_steps``, ``n_walkers``, ``n_ensembles``, ``failed`` (list of failing checks).
    summary : pandas.DataFrame
        ``arviz_stats.summary`` of the posterior.
    flat_parameters : list of str
        Parameters the data do not inform (posterior sd > flat_ratio x prior sd and the marginal
        is prior-like: KS statistic against prior draws < 0.1).
    map_estimates : list of dict
        The MAP each ensemble started from.
    message : str
    """

    tree: object
    converged: bool
    diagnostics: dict
    summary: object
    flat_parameters: list
    map_estimates: list
    message: str
    sampled: tuple = field(default_factory=tuple)

    def to_netcdf(self, path) -> None:
        """Write the DataTree to a netCDF4/HDF5 file (h5netcdf engine)."""
        self.tree.to_netcdf(path, engine="h5netcdf")


class _LogPosterior:
    """Picklable, vectorised log posterior of the sampled parameters (amplitude integrated out)."""

    def __init__(self, model, data, noise_std, priors, amplitude_prior):
        self.model = model
        self.data = data
        self.s2 = noise_std**2
        self.priors = priors
        self.sampled = tuple(k for k in NONLINEAR if not isinstance(priors[k], float))
        self.amp = amplitude_prior

    def params(self, theta):
        theta = np.atleast_2d(theta)
        out = {}
        for k in NONLINEAR:
            if k in self.sampled:
                out[k] = theta[:, self.sampled.index(k)]
            else:
                out[k] = np.full(theta.shape[0], self.priors[k])
        return out

    def marginal(self, g):
        """log N(d; m g, s2 I + v g g^T) per row of g, and the conditional mean/var of S."""
        m, v = self.amp.mean, self.amp.sd**2
        r = self.data[None, :] - m * g
        a = np.einsum("ij,ij->i", g, g)
        b = g @ self.data - m * a  # g . r
        rr = np.einsum("ij,ij->i", r, r)
        den = self.s2 + v * a
        quad = (rr - v * b * b / den) / self.s2
        logdet = self.data.size * np.log(self.s2) + np.log1p(v * a / self.s2)
        ll = -0.5 * (quad + logdet + self.data.size * np.log(2 * np.pi))
        prec = a / self.s2 + 1.0 / v
        cmean = (g @ self.data / self.s2 + m / v) / prec
        return ll, cmean, 1.0 / prec

    def __call__(self, theta):
        theta = np.atleast_2d(theta)
        params = self.params(theta)
        lp = np.zeros(theta.shape[0])
        for k in self.sampled:
            lp = lp + self.priors[k].logpdf(params[k])
        ok = np.isfinite(lp)
        out = np.full(theta.shape[0], -np.inf)
        if ok.any():
            g = self.model.design({k: v[ok] for k, v in params.items()})
            ll, _, _ = self.marginal(g)
            out[ok] = lp[ok] + ll
        return out


def _map_start(logp: _LogPosterior, rng, n_start: int):
    """Best of a prior multistart, polished by Nelder-Mead in prior-scaled coordinates."""
    cand = np.column_stack([logp.priors[k].sample(rng, n_start) for k in logp.sampled])
    vals = logp(cand)
    best = cand[int(np.argmax(vals))]
    scale = np.array([logp.priors[k].std for k in logp.sampled])
    res = minimize(lambda z: -float(logp((best + z * scale)[None, :])[0]), np.zeros(best.size),
                   method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-3, "maxfev": 600})
    polished = best + res.x * scale
    return polished if np.isfinite(logp(polished[None, :])[0]) else best


def _diagnostics(chains: np.ndarray, tau_factor: float, rhat_target: float, min_ess: float) -> dict:
    """chains: (K, steps, W, P) of the kept half."""
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
    diag = {
        "rhat_max": float(np.max(rhat)), "rhat_between_max": float(np.max(rhat_between)),
        "ess_bulk_min": float(np.min(ess_bulk)), "ess_tail_min": float(np.min(ess_tail)),
        "tau_max": tau, "n_kept": n,
    }
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


def sample_scene_posterior(
    model,
    data,
    noise_std: float,
    priors: dict,
    amplitude_prior: Normal,
    *,
    rng: np.random.Generator,
    n_ensembles: int = 4,
    n_walkers: int | None = None,
    max_steps: int = 20000,
    check_every: int = 500,
    rhat_target: float = 1.01,
    min_ess: float = 400.0,
    tau_factor: float = 50.0,
    n_start: int = 512,
    max_draws: int = 4000,
    flat_ratio: float = 0.8,
    burn_fraction: float = 0.25,
    progress: bool = False,
) -> MCMCResult:
    """Sample the posterior of scene parameters with emcee (see module docstring).

    Parameters
    ----------
    model : DefectScanModel or any object with ``design(params) -> (W, n_data)`` and ``n_data``
    data : array_like, n_data values (Pa), finite
    noise_std : float
        Noise standard deviation (Pa), > 0.
    priors : dict
        Every name in ``NONLINEAR`` -> a prior (sampled) or a float (fixed). SI units.
    amplitude_prior : Normal
        Gaussian prior of the linear amplitude (defect area, m^2); integrated out exactly.
    rng : numpy.random.Generator
    n_ensembles : int
        Independent ensembles, >= 4.
    n_walkers : int, optional
        Walkers per ensemble (default max(16, 4 x n_sampled), even).
    max_steps, check_every : int
        Step limit per ensemble and the interval between convergence checks.
    rhat_target, min_ess, tau_factor : float
        Convergence thresholds.
    max_draws : int
        Total draws kept in the DataTree (chains thinned evenly).
    flat_ratio : float
        Posterior/prior sd ratio above which a parameter is reported as flat.
    burn_fraction : float in [0, 0.9]
        Leading share of every chain discarded as burn-in (walkers start at a MAP, so a
        quarter is ample); diagnostics and output use the rest.
    progress : bool
        tqdm progress bar over convergence checks.

    Returns
    -------
    MCMCResult
    """
    import arviz_base as azb
    import arviz_stats as azs

    d = np.asarray(data, dtype=float).ravel()
    if d.size != model.n_data:
        raise ValueError(f"data: size mismatch, got {d.size} values but the model predicts {model.n_data}")
    if not np.all(np.isfinite(d)):
        i = int(np.flatnonzero(~np.isfinite(d))[0])
        raise ValueError(f"data: must be finite, found {d[i]} at flat index {i}; drop or interpolate bad samples")
    if not (np.isfinite(noise_std) and noise_std > 0):
        raise ValueError(f"noise_std: must be finite and > 0 Pa, got {noise_std!r}")
    missing = [k for k in NONLINEAR if k not in priors]
    extra = [k for k in priors if k not in NONLINEAR]
    if missing or extra:
        raise ValueError(f"priors: need exactly the keys {NONLINEAR}; missing {missing}, unknown {extra}")
    priors = {k: check_prior(k, v) for k, v in priors.items()}
    if not isinstance(amplitude_prior, Normal):
        raise ValueError(f"amplitude_prior: must be a Normal prior (integrated out exactly), got {amplitude_prior!r}")
    if not (0.0 <= burn_fraction <= 0.9):
        raise ValueError(f"burn_fraction: must lie in [0, 0.9], got {burn_fraction!r}")
    if int(n_ensembles) < 4:
        raise ValueError(f"n_ensembles: need at least 4 independent ensembles to judge convergence, got {n_ensembles}")
    logp = _LogPosterior(model, d, float(noise_std), priors, amplitude_prior)
    sampled = logp.sampled
    if not sampled:
        raise ValueError("priors: every parameter is fixed; give at least one a prior (e.g. x0=Uniform(-5e-3, 5e-3))")
    ndim = len(sampled)
    n_walkers = int(n_walkers) if n_walkers is not None else max(16, 4 * ndim)
    n_walkers += n_walkers % 2
    if n_walkers < 2 * ndim:
        raise ValueError(f"n_walkers: emcee needs at least 2 x n_parameters = {2 * ndim} walkers, got {n_walkers}")
    seeds = rng.spawn(int(n_ensembles))
    samplers, starts, maps = [], [], []
    scale = np.array([priors[k].std for k in sampled])
    for sub in seeds:
        best = _map_start(logp, sub, n_start)
        maps.append(dict(zip(sampled, best.tolist())))
        p0 = best + 1e-3 * scale * sub.standard_normal((n_walkers, ndim))
        bad = ~np.isfinite(logp(p0))
        p0[bad] = best
        starts.append(p0)
        sampler = emcee.EnsembleSampler(n_walkers, ndim, logp, vectorize=True)
        # emcee draws its proposals from a legacy RandomState: seed it from this ensemble's rng
        sampler.random_state = np.random.RandomState(int(sub.integers(2**31))).get_state()
        samplers.append(sampler)
    n_checks = max(1, math.ceil(max_steps / check_every))
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n_checks * check_every, desc="emcee (all ensembles)", unit="step")
    diag = None
    steps = 0
    for _ in range(n_checks):
        chunk = min(check_every, max_steps - steps)
        for i, s in enumerate(samplers):
            s.run_mcmc(starts[i] if steps == 0 else None, chunk, progress=False)
        steps += chunk
        if bar is not None:
            bar.update(chunk)
        chains = np.stack([s.get_chain() for s in samplers])[:, int(steps * burn_fraction):]
        diag = _diagnostics(chains, tau_factor, rhat_target, min_ess)
        if not diag["failed"] or steps >= max_steps:
            break
    if bar is not None:
        bar.close()
    converged = not diag["failed"]
    diag.update(n_steps=steps, n_walkers=n_walkers, n_ensembles=int(n_ensembles), burn_in=int(steps * burn_fraction))
    burn = int(steps * burn_fraction)
    kept = np.stack([s.get_chain() for s in samplers])[:, burn:]  # (K, n, W, P)
    lps = np.stack([s.get_log_prob() for s in samplers])[:, burn:]
    k, n, w, _ = kept.shape
    # one DataTree chain per ensemble; its draws run step by step over the walkers
    kept, lps = kept.reshape(k, n * w, ndim), lps.reshape(k, n * w)
    stride = max(1, math.ceil(k * n * w / max_draws))
    kept, lps = kept[:, ::stride], lps[:, ::stride]
    n = kept.shape[1]
    flat = kept.reshape(k * n, ndim)
    params = logp.params(flat)
    g = np.concatenate([model.design({q: v[i:i + 256] for q, v in params.items()})
                        for i in range(0, flat.shape[0], 256)])
    _, cmean, cvar = logp.marginal(g)
    amp = cmean + np.sqrt(cvar) * rng.standard_normal(cmean.size)
    resid = d[None, :] - amp[:, None] * g
    pointwise = -0.5 * (resid / noise_std) ** 2 - np.log(noise_std * np.sqrt(2 * np.pi))
    shape = (k, n)
    posterior = {name: flat[:, j].reshape(shape) for j, name in enumerate(sampled)}
    posterior["amplitude"] = amp.reshape(shape)
    attrs = {key: (float(v) if not isinstance(v, list) else "; ".join(v)) for key, v in diag.items()}
    attrs.update(converged=int(converged), fixed=", ".join(f"{q}={priors[q]:.6g}" for q in NONLINEAR if q not in sampled),
                 priors="; ".join(f"{q}={priors[q]!r}" for q in sampled), amplitude_prior=repr(amplitude_prior),
                 noise_std=float(noise_std), units="x0, y0, depth: m; young_modulus: Pa; normal_force: N; amplitude: m^2")
    tree = azb.from_dict(
        {"posterior": posterior,
         "log_likelihood": {"obs": pointwise.reshape(*shape, d.size)},
         "observed_data": {"obs": d},
         "sample_stats": {"lp": lps}},
        dims={"obs": ["obs_id"]}, attrs={"/": attrs})
    summary = azs.summary(tree, round_to="none")
    from scipy.stats import ks_2samp

    def prior_like(q):
        draws = posterior[q].ravel()
        return ks_2samp(draws, priors[q].sample(rng, draws.size)).statistic < 0.1

    flats = [q for q in sampled if posterior[q].std() > flat_ratio * priors[q].std and prior_like(q)]
    lines = [("converged" if converged else "did NOT converge") + f" after {steps} steps x {w} walkers x {k} ensembles",
             f"R-hat max {diag['rhat_max']:.4f} (walkers), {diag['rhat_between_max']:.4f} (between ensembles); "
             f"ESS bulk {diag['ess_bulk_min']:.0f}, tail {diag['ess_tail_min']:.0f}; tau {diag['tau_max']:.1f} steps"]
    if diag["failed"]:
        lines.append("failing checks: " + "; ".join(diag["failed"]))
    if flats:
        lines.append("flat likelihood (posterior ~ prior, data uninformative) in: " + ", ".join(flats))
    return MCMCResult(tree=tree, converged=converged, diagnostics=diag, summary=summary, flat_parameters=flats,
                      map_estimates=maps, message="\n".join(lines), sampled=sampled)

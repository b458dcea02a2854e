"""Posterior of the defect scene parameters: a :class:`~tactilab.inversion.sampler.PosteriorModel`
sampled by :func:`~tactilab.inversion.sampler.sample_posterior`.

Model: ``d = S g(theta) + e``, ``e ~ N(0, sigma^2 I)``, with ``theta`` the nonlinear scene
parameters (priors stated in the call, fixed ones not sampled) and ``S`` a linear amplitude
(e.g. the defect area) with a Gaussian prior ``N(m_S, s_S^2)``. ``S`` is integrated out exactly:

    log p(d | theta) = log N(d; m_S g, sigma^2 I + s_S^2 g g^T)      (Sherman-Morrison)

and drawn afterwards from its exact conditional ``p(S | theta, d)`` for every kept draw, so the
output holds joint posterior draws of ``(theta, S)``; the per-observation log-likelihood
``log N(d_i; S g_i(theta), sigma^2)`` of each joint draw fills the tree's ``log_likelihood`` group.

Sampling, starts at each ensemble's MAP, R-hat / ESS / autocorrelation stopping: see
:mod:`tactilab.inversion.sampler`. Parameters whose posterior sd exceeds ``flat_ratio`` x their
prior sd AND whose marginal is close to the prior (two-sample KS statistic against prior draws
< 0.1; a bimodal posterior is wide but not prior-like) are reported as flat.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import ks_2samp

from tactilab.core import rules

from .sampler import sample_posterior
from .scene_params import NONLINEAR, POSITIVE, Normal, check_prior

__all__ = ["sample_scene_posterior", "MCMCResult", "DefectPosterior"]


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

    def __repr__(self) -> str:
        """Method, convergence and each parameter's mean +- sd with its SI unit; never the draws."""
        units = {"x0": "m", "y0": "m", "depth": "m", "amplitude": "m^2", "young_modulus": "Pa",
                 "normal_force": "N", "friction": ""}
        rows = []
        for name in list(self.summary.index)[:6]:
            mean, sd = self.summary.loc[name, "mean"], self.summary.loc[name, "sd"]
            rows.append(f"{name} = {mean:.4g} +- {sd:.2g} {units.get(name, 'SI')}".rstrip())
        d = self.diagnostics
        draws = dict(self.tree["posterior"].sizes) if "posterior" in self.tree.children else {}
        return (f"MCMCResult(method='emcee', {'converged' if self.converged else 'NOT converged'} after "
                f"{d.get('n_steps', '?')} steps, R-hat max {d.get('rhat_max', float('nan')):.4g}, "
                f"ESS bulk min {d.get('ess_bulk_min', float('nan')):.0f}, draws {draws}:\n  " + "; ".join(rows) + ")")

    def _repr_html_(self) -> str:
        """The short repr for notebooks (escaped, monospace)."""
        import html

        return "<pre>" + html.escape(repr(self)) + "</pre>"

    def to_netcdf(self, path) -> None:
        """Write the DataTree to a netCDF4/HDF5 file (h5netcdf engine; CF attributes, units on every parameter)."""
        from tactilab.core.netcdf import write_netcdf

        write_netcdf(self.tree, path)


#: SI units and long names of the defect model's parameters
_PARAMETER_ATTRS = {
    "x0": {"units": "m", "long_name": "defect position x"},
    "y0": {"units": "m", "long_name": "defect position y"},
    "depth": {"units": "m", "long_name": "receptor depth below the skin surface"},
    "young_modulus": {"units": "Pa", "long_name": "skin Young's modulus"},
    "normal_force": {"units": "N", "long_name": "finger normal force"},
    "friction": {"units": "1", "long_name": "friction coefficient"},
    "amplitude": {"units": "m^2", "long_name": "effective point-defect area (linear amplitude)"},
}


class DefectPosterior:
    """The defect model as a :class:`~tactilab.inversion.sampler.PosteriorModel` (picklable, vectorised).

    Parameters
    ----------
    model : DefectScanModel or any object with ``design(params) -> (W, n_data)`` and ``n_data``
    data : ndarray, shape (n_data,)
        Observations, Pa (stress) or strain, as the model predicts.
    noise_std : float
        Noise standard deviation, data units.
    priors : dict
        Every name in ``NONLINEAR`` -> a prior (sampled) or a float (fixed).
    amplitude_prior : Normal
        Gaussian prior of the linear amplitude ``S`` (m^2), integrated out.
    """

    vectorized = True
    marginalised_names = ("amplitude",)
    units = "x0, y0, depth: m; young_modulus: Pa; normal_force: N; amplitude: m^2"

    def __init__(self, model, data, noise_std, priors, amplitude_prior):
        self.model = model
        self.data = np.asarray(data, dtype=float)
        self.noise_std = float(noise_std)
        self.s2 = self.noise_std**2
        self.priors = priors
        self.sampled = tuple(k for k in NONLINEAR if not isinstance(priors[k], float))
        self.amp = amplitude_prior

    @property
    def param_names(self) -> tuple[str, ...]:
        return self.sampled

    @property
    def variable_attrs(self) -> dict:
        """SI units and long names of the parameters and of the data (for the tree and its file)."""
        quantity = getattr(self.model, "quantity", None)
        return {**_PARAMETER_ATTRS, "data": {
            "units": {"stress": "Pa", "strain": "1"}.get(quantity, "Pa or 1 (the recording's unit)"),
            "long_name": f"observed sensor signal ({quantity or 'stress or strain'}, flattened)"}}

    @property
    def observed(self) -> np.ndarray:
        return self.data

    @property
    def observation_groups(self) -> np.ndarray:
        """Channel (sensor x component) of every datum, data ordered (time, sensor, component)."""
        n_channels = int(np.prod(self.model.data_shape[1:])) if hasattr(self.model, "data_shape") else 1
        return np.tile(np.arange(n_channels), self.data.size // n_channels)

    @property
    def scale(self) -> np.ndarray:
        return np.array([self.priors[k].std for k in self.sampled])

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

    def _design(self, theta):
        params = self.params(theta)
        # the model's unchecked design where it has one: theta lies in the priors' support, checked once
        design = getattr(self.model, "_design", self.model.design)
        return np.concatenate([design({q: v[i:i + 256] for q, v in params.items()})
                               for i in range(0, theta.shape[0], 256)])

    def log_prior(self, theta):
        """Sum of the sampled parameters' log priors, theta shape (W, P) -> (W,)."""
        params = self.params(theta)
        lp = np.zeros(params[NONLINEAR[0]].shape[0])
        for k in self.sampled:
            lp = lp + self.priors[k].logpdf(params[k])
        return lp

    def log_marginal_likelihood(self, theta):
        """``log p(d | theta)`` with the amplitude integrated out, theta (W, P) -> (W,)."""
        return self.marginal(self._design(np.atleast_2d(theta)))[0]

    def initial(self, rng, n):
        """``n`` prior draws, shape (n, P)."""
        return np.column_stack([self.priors[k].sample(rng, n) for k in self.sampled])

    def draw_marginalised(self, theta, rng):
        """The amplitude from its exact conditional given each row of theta (N, P)."""
        _, cmean, cvar = self.marginal(self._design(np.atleast_2d(theta)))
        return {"amplitude": cmean + np.sqrt(cvar) * rng.standard_normal(cmean.size)}

    def log_likelihood(self, theta):
        """Per-observation ``log N(d_i; S g_i, sigma^2)``; theta (W, P + 1), amplitude last -> (W, n_data)."""
        theta = np.atleast_2d(theta)
        g = self._design(theta[:, :-1])
        resid = self.data[None, :] - theta[:, -1:] * g
        return -0.5 * (resid / self.noise_std) ** 2 - np.log(self.noise_std * np.sqrt(2 * np.pi))


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
    pool=None,
    backend=None,
    info_tol: float | None = 1e-9,
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
    pool, backend, info_tol
        Passed to :func:`~tactilab.inversion.sampler.sample_posterior` (a ``pool`` with ``map``,
        an emcee backend for checkpointing, the no-information threshold of the log-likelihood
        group).

    Returns
    -------
    MCMCResult
    """
    import arviz_stats as azs

    d = np.asarray(data, dtype=float).ravel()
    if d.size != model.n_data:
        raise ValueError(f"data: size mismatch, got {d.size} values but the model predicts {model.n_data}")
    if not np.all(np.isfinite(d)):
        i = int(np.flatnonzero(~np.isfinite(d))[0])
        raise ValueError(f"data: must be finite, found {d[i]} at flat index {i}; drop or interpolate bad samples")
    rules.positive(noise_std, "noise_std", "data units (Pa or strain)", "give the sensors' noise standard deviation")
    missing = [k for k in NONLINEAR if k not in priors]
    extra = [k for k in priors if k not in NONLINEAR]
    if missing or extra:
        raise ValueError(f"priors: need exactly the keys {NONLINEAR}; missing {missing}, unknown {extra}")
    priors = {k: check_prior(k, v) for k, v in priors.items()}
    for q in POSITIVE:  # checked once here: the likelihood's inner loop runs the unchecked kernels
        p = priors[q]
        positive = p > 0 if isinstance(p, float) else (p.support[0] >= 0 and p.logpdf(0.0) == -np.inf)
        if not positive:
            raise ValueError(f"priors: {q} must be > 0 (SI units), but {p!r} allows values <= 0; give a positive "
                             "value, or a LogNormal, a LogUniform or a Uniform with low > 0")
    if not isinstance(amplitude_prior, Normal):
        raise ValueError(f"amplitude_prior: must be a Normal prior (integrated out exactly), got {amplitude_prior!r}")
    defect = DefectPosterior(model, d, float(noise_std), priors, amplitude_prior)
    sampled = defect.sampled
    if not sampled:
        raise ValueError("priors: every parameter is fixed; give at least one a prior (e.g. x0=Uniform(-5e-3, 5e-3))")
    tree = sample_posterior(defect, rng, n_ensembles=n_ensembles, n_walkers=n_walkers, max_steps=max_steps,
                            check_every=check_every, rhat_target=rhat_target, min_ess=min_ess,
                            tau_factor=tau_factor, n_start=n_start, max_draws=max_draws,
                            burn_fraction=burn_fraction, info_tol=info_tol, progress=progress, pool=pool,
                            backend=backend)
    attrs = tree.attrs
    converged = bool(attrs["converged"])
    diag = {key: attrs[key] for key in ("rhat_max", "rhat_between_max", "ess_bulk_min", "ess_tail_min", "tau_max",
                                        "n_kept", "n_steps", "n_walkers", "n_ensembles", "burn_in")}
    for key in ("n_kept", "n_steps", "n_walkers", "n_ensembles", "burn_in"):
        diag[key] = int(diag[key])
    diag["failed"] = [f for f in attrs["failed"].split("; ") if f]
    attrs.update(fixed=", ".join(f"{q}={priors[q]:.6g}" for q in NONLINEAR if q not in sampled),
                 priors="; ".join(f"{q}={priors[q]!r}" for q in sampled), amplitude_prior=repr(amplitude_prior),
                 noise_std=float(noise_std))
    summary = azs.summary(tree, round_to="none")
    posterior = tree["posterior"]

    def prior_like(q):
        draws = posterior[q].values.ravel()
        return ks_2samp(draws, priors[q].sample(rng, draws.size)).statistic < 0.1

    flats = [q for q in sampled if posterior[q].values.std() > flat_ratio * priors[q].std and prior_like(q)]
    message = attrs["message"]
    if flats:
        message += "\nflat likelihood (posterior ~ prior, data uninformative) in: " + ", ".join(flats)
    attrs["message"] = message
    return MCMCResult(tree=tree, converged=converged, diagnostics=diag, summary=summary, flat_parameters=flats,
                      map_estimates=json.loads(attrs["map_estimates"]), message=message, sampled=sampled)

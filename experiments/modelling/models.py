"""Transduction models: which strain does touch read? Fit them to responses and compare them.

A :class:`TransductionModel` is a receptor hypothesis (components, depths, shear convention;
``tactilab.forward.ReceptorHypothesis``), a statistic of the strain it reads and a source of that
strain. The statistic of one interval (a data_schemas ``Stimulus``):

- ``peak`` (default): the largest |readout| over one full period in x of the sliding grating
  (which covers every time: the pattern at time t is the pattern at t = 0 shifted) and over all
  of the hypothesis's components and depths; sampled at 64 points per period of the highest
  harmonic, then refined by a bounded scalar search around the best samples;
- ``rms``: the root mean square over the same set (exact on a uniform grid of more than 4x the
  highest harmonic: the squared readout is a trigonometric polynomial).

Sources: ``surface`` (the ideal virtual surface: nu = 1/2 sliding-sinusoid strain, a square
surface as its odd harmonics 4 A / (n pi) up to n = 29) or ``display`` (the strain a simulated
display really renders after the safety limits, at its points and frames, for every depth).
The link is signal detection (see :mod:`tactilab.experiments.modelling._transduction_data`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy.optimize import minimize_scalar

from tactilab.data_schemas.experiment import Stimulus
from tactilab.forward.receptors import ReceptorHypothesis
from tactilab.forward.tractors import sliding_sinusoid_strain

from ._transduction_data import TransductionLikelihood, conditions, default_priors, map_estimate, p_correct_table
from .model_power import PowerResult, power_analysis
from .psychometric import ParamSummary, fit_psychometric

__all__ = ["TransductionModel", "TransductionFit", "fit_transduction", "compare_models", "elpd_mcse", "power_analysis",
           "PowerResult", "ReceptorHypothesis", "fit_psychometric", "ParamSummary"]

STATISTICS = ("peak", "rms")
SOURCES = ("surface", "display")
N_HARMONICS = 15  # odd harmonics 1..29 of a square surface
_PER_PERIOD = 64  # samples per period of the highest harmonic


class TransductionModel:
    """A receptor hypothesis + a statistic of its readouts + a strain source.

    Parameters
    ----------
    hypothesis : ReceptorHypothesis or str
        E.g. ``"zx@1mm"`` (parsed with ``ReceptorHypothesis.parse``).
    statistic : {"peak", "rms"}
    source : {"surface", "display"}
    display : SimulatedDisplay, optional
        Needed for ``source="display"``.
    """

    def __init__(self, hypothesis, *, statistic: str = "peak", source: str = "surface", display=None):
        self.hypothesis = hypothesis if isinstance(hypothesis, ReceptorHypothesis) \
            else ReceptorHypothesis.parse(str(hypothesis))
        if statistic not in STATISTICS:
            raise ValueError(f"statistic: must be one of {STATISTICS}, got {statistic!r}")
        if source not in SOURCES:
            raise ValueError(f"source: must be one of {SOURCES}, got {source!r}")
        if source == "display" and not callable(getattr(display, "steady_drive", None)):
            raise ValueError("display: source='display' needs a SimulatedDisplay (its rendered strain), got "
                             f"{type(display).__name__}; or use source='surface'")
        self.statistic, self.source, self.display = statistic, source, display
        self._cache: dict[Stimulus, float] = {}

    def __repr__(self) -> str:
        return f"TransductionModel({str(self.hypothesis)!r}, statistic={self.statistic!r}, source={self.source!r})"

    @property
    def name(self) -> str:
        """Short label, e.g. ``zx@1mm`` (with ``/rms`` or ``/display`` when not the default)."""
        extra = ("" if self.statistic == "peak" else f"/{self.statistic}") + ("" if self.source == "surface" else "/display")
        return str(self.hypothesis) + extra

    # ----- statistic ------------------------------------------------------------------------
    def _readouts(self, stimulus: Stimulus, x: np.ndarray) -> np.ndarray:
        """Readouts at positions x (m) at t = 0, shape (n_depths * n_components, n_x)."""
        if stimulus.surface == "sinusoid":
            parts = [(stimulus.amplitude_m, stimulus.pitch_m)]
        else:
            parts = [(4 * stimulus.amplitude_m / (n * math.pi), stimulus.pitch_m / n)
                     for n in range(1, 2 * N_HARMONICS, 2)]
        strain = np.stack([sum(sliding_sinusoid_strain(x, z, a, p) for a, p in parts) for z in self.hypothesis.depths])
        r = self.hypothesis.readout(strain)  # (n_depths * n_components * n_x,)
        return r.reshape(-1, x.size)

    def _surface_statistic(self, stimulus: Stimulus) -> float:
        p = stimulus.pitch_m
        top = 1 if stimulus.surface == "sinusoid" else 2 * N_HARMONICS - 1
        x = np.arange(_PER_PERIOD * top) * (p / (_PER_PERIOD * top))
        r = self._readouts(stimulus, x)
        if self.statistic == "rms":
            return float(np.sqrt(np.mean(r * r)))
        peaks = np.abs(r).max(axis=1)
        best = float(peaks.max())
        dx = p / (_PER_PERIOD * top)
        for row in np.flatnonzero(peaks >= 0.99 * best):  # refine every readout near the top
            x0 = x[int(np.argmax(np.abs(r[row])))]
            res = minimize_scalar(lambda v: -abs(self._readouts(stimulus, np.array([v]))[row, 0]),
                                  bounds=(x0 - dx, x0 + dx), method="bounded", options=dict(xatol=dx * 1e-6))
            best = max(best, -float(res.fun))
        return best

    def _display_statistic(self, stimulus: Stimulus) -> float:
        d = self.display
        steady = d.steady_drive(stimulus)
        strain = []
        for z in self.hypothesis.depths:
            exx, exz = d.strain(steady, depth_m=z)
            zero = np.zeros_like(exx)
            strain.append(np.stack([exx, zero, -exx, zero, exz, zero], axis=-1).reshape(exx.shape[0], -1, 6))
        r = self.hypothesis.readout(np.stack(strain))
        return float(np.abs(r).max() if self.statistic == "peak" else np.sqrt(np.mean(r * r)))

    def statistic_of(self, stimulus: Stimulus) -> float:
        """The statistic of one interval, in readout units (strain); 0 for a blank. Cached."""
        if not isinstance(stimulus, Stimulus):
            raise ValueError(f"stimulus: expected a data_schemas Stimulus (one interval), got {type(stimulus).__name__}")
        if stimulus not in self._cache:
            if stimulus.amplitude_m == 0:
                value = 0.0
            elif self.source == "surface":
                value = self._surface_statistic(stimulus)
            else:
                value = self._display_statistic(stimulus)
            self._cache[stimulus] = value
        return self._cache[stimulus]

    # ----- link -----------------------------------------------------------------------------
    def p_correct(self, trial_stimuli, task: str, threshold_strain: float, exponent: float, lapse: float,
                  false_alarm: float | None = None) -> np.ndarray:
        """P(correct) per trial, shape (n_trials,).

        ``trial_stimuli``: for ``2ifc`` a sequence of (target interval, other interval) pairs;
        for ``yes_no`` a sequence of single stimuli (a blank, amplitude 0, is a catch trial),
        and ``false_alarm`` is required.
        """
        if task not in ("2ifc", "yes_no"):
            raise ValueError(f"task: must be '2ifc' or 'yes_no', got {task!r}")
        if task == "yes_no" and false_alarm is None:
            raise ValueError("false_alarm: a yes/no model needs the false-alarm rate, e.g. false_alarm=0.16")
        theta = np.array([[threshold_strain, exponent, lapse] + ([false_alarm] if task == "yes_no" else [])])
        if task == "2ifc":
            s1 = np.array([self.statistic_of(a) for a, _ in trial_stimuli])
            s2 = np.array([self.statistic_of(b) for _, b in trial_stimuli])
        else:
            items = [s[0] if isinstance(s, (tuple, list)) else s for s in trial_stimuli]
            s1 = np.array([self.statistic_of(s) for s in items])
            s2 = (s1 > 0).astype(float)
        return p_correct_table(task, s1, s2, theta)[0]


@dataclass
class TransductionFit:
    """A fitted transduction model (from :func:`fit_transduction`).

    ``tree``: ``posterior`` (threshold_strain, exponent, lapse[, false_alarm]; one chain per
    ensemble), ``log_likelihood`` (``correct`` over dim ``trial``), ``observed_data``
    (``correct``), ``sample_stats`` (``lp``); ``params``: a :class:`ParamSummary` each;
    ``converged`` and ``diagnostics`` from the sampler (R-hat between ensembles, ESS, tau);
    ``conditions``: the per-condition statistics and counts the likelihood used.
    """

    model: TransductionModel
    tree: object
    params: dict
    converged: bool
    diagnostics: dict
    task: str
    conditions: dict


def fit_transduction(model: TransductionModel, trials, *, task: str | None = None, priors: Mapping | None = None,
                     rng, n_ensembles: int = 4, method: str = "emcee",
                     sampler_options: Mapping | None = None) -> TransductionFit:
    """Fit threshold_strain, exponent, lapse (and false_alarm for yes/no) of a model to trials.

    Parameters
    ----------
    model : TransductionModel
    trials : path, list of paths, Session, list of TrialRecord or DataFrame
        Session .sqlite file(s), or trials with ``stimuli`` and ``correct`` (and ``target``).
    task : {"2ifc", "yes_no"}, optional
        Checked against the sessions' task (default: theirs, or inferred from the trials).
    priors : mapping name -> scipy.stats frozen distribution, optional
        Replaces defaults (log-uniform threshold over 1/100 to 100x the data's statistics,
        lognormal exponent with median 1 and log-sd 0.5, Beta(1, 10) lapse on [0, 0.5],
        uniform false-alarm rate).
    rng : numpy.random.Generator or int
    n_ensembles : int
        Independent emcee ensembles (>= 4); convergence is judged by R-hat across them.
    method : {"emcee"}
    sampler_options : mapping, optional
        Passed on to ``tactilab.inversion.sample_posterior`` (e.g. ``max_steps``, ``tau_factor``,
        ``pool``); the defaults keep its convergence rules.
    """
    if method != "emcee":
        raise ValueError(f"method: only 'emcee' is supported, got {method!r}")
    if not isinstance(model, TransductionModel):
        raise ValueError(f"model: expected a TransductionModel, got {type(model).__name__}")
    from tactilab.inversion import sample_posterior

    gen = np.random.default_rng(rng)
    data = conditions(model, trials, task)
    lik = TransductionLikelihood(data, default_priors(data, priors))
    n_trials = data["idx"].size
    # the per-trial log-likelihood is kept in bounded memory: <= 8e6 values (64 MB); below 400 draws
    # (over 20 000 trials) PSIS-LOO's Pareto k (compare_models' pareto_k_max) says whether that suffices
    max_draws = int(np.clip(8_000_000 // n_trials, 100, 4000))
    options = {"max_draws": max_draws, "info_tol": None, **dict(sampler_options or {})}
    raw = sample_posterior(lik, gen, n_ensembles=n_ensembles, **options)
    tree = _rename(raw, lik)
    post = tree["posterior"]
    best = max(_maps(raw), key=lambda v: float(lik.log_prior(v[None])[0] + lik.total_log_likelihood(v[None])[0]))
    best, _ = map_estimate(lik, best)
    params = {}
    for j, name in enumerate(lik.param_names):
        x = post[name].values.ravel()
        q = np.quantile(x, [0.5, 0.025, 0.975, 0.16, 0.84])
        params[name] = ParamSummary(float(best[j]), float(x.mean()), float(q[0]), (float(q[1]), float(q[2])),
                                    (float(q[3]), float(q[4])))
    attrs = dict(raw.attrs)
    return TransductionFit(model, tree, params, bool(attrs.get("converged", 0)), attrs, data["kind"], data)


def _maps(raw):
    import json

    names = raw.attrs["parameters"].split(", ")
    return [np.array([m[n] for n in names]) for m in json.loads(raw.attrs["map_estimates"])]


def _rename(raw, lik):
    """The sampler's tree with the per-trial terms as ``correct`` over dim ``trial``."""
    import arviz_base as azb

    post = {name: raw["posterior"][name].values for name in lik.param_names}
    ll = raw["log_likelihood"]["obs"].values
    attrs = {**raw.attrs, "task": lik.kind}
    return azb.from_dict({"posterior": post, "log_likelihood": {"correct": ll},
                          "observed_data": {"correct": lik.observed},
                          "sample_stats": {"lp": raw["sample_stats"]["lp"].values}},
                         dims={"correct": ["trial"]}, attrs={"/": attrs})


def elpd_mcse(tree, var_name: str = "correct") -> float:
    """Monte Carlo standard error of a fit's PSIS-LOO elpd (nats), from its chains.

    First order (delta method) in the importance ratios r_is = 1 / p(y_i | theta_s):
    elpd_loo = -sum_i log(mean_s r_is), so its Monte Carlo error is that of the posterior mean
    of the scalar g(theta_s) = sum_i r_is / mean_s(r_is): ``sd(g) / sqrt(ESS(g))``, with the
    effective sample size of g over the chains (``arviz_stats.ess``, method "mean"). The sum
    over trials is taken per draw, so errors that every trial shares (a chain's whole
    posterior slightly off) are counted, unlike in ``dse``. ``tree["log_likelihood"][var_name]``
    has shape (chain, draw, trial).
    """
    import arviz_stats as azs

    ll = np.asarray(tree["log_likelihood"][var_name].values, float)
    ll = ll.reshape(ll.shape[0], ll.shape[1], -1)
    log_r = -ll - (-ll).max(axis=(0, 1))  # scaled per trial: r / max r, no overflow
    r = np.exp(log_r)
    g = (r / r.mean(axis=(0, 1))).sum(axis=-1)  # (chain, draw)
    if np.ptp(g) == 0:
        return 0.0
    return float(np.std(g, ddof=1) / np.sqrt(azs.ess(g, method="mean")))


def compare_models(fits: Mapping, *, var_name: str = "correct", reference: str | None = None):
    """PSIS-LOO comparison (arviz_stats), best first, with z, the largest Pareto k and a verdict.

    Returns a pandas DataFrame indexed by model name: arviz's columns (``elpd``, ``elpd_diff``
    (negative for a worse model), ``dse``, ``se``, ``p``, ``weight``, ...) unrounded, plus
    ``mcse`` (Monte Carlo standard error of the model's elpd, :func:`elpd_mcse`), ``mcse_diff``
    (of its elpd_diff: the two fits' errors combined as independent; 0 for the reference row),
    ``z = |elpd_diff| / sqrt(dse**2 + mcse_diff**2)`` (the difference over its standard error,
    data and Monte Carlo; for distinct models the Monte Carlo part is negligible, for two
    models that predict identical responses it is all there is), ``pareto_k_max`` and
    ``verdict``: ``best`` for the first row, then ``worse`` (z > 4), ``weakly worse``
    (2 <= z <= 4) or ``indistinguishable`` (z < 2; also when elpd_diff = 0, e.g. the same
    fit twice).
    """
    import arviz_stats as azs

    if not isinstance(fits, Mapping) or len(fits) < 2:
        raise ValueError("fits: give a mapping of at least two model names to TransductionFit or DataTree")
    trees = {name: (f.tree if isinstance(f, TransductionFit) else f) for name, f in fits.items()}
    sizes = {}
    for name, tree in trees.items():
        if "log_likelihood" not in getattr(tree, "children", {}) or var_name not in tree["log_likelihood"]:
            raise ValueError(f"fits: {name!r} has no log_likelihood variable {var_name!r}; fit it with "
                             "fit_transduction (it stores one term per trial)")
        sizes[name] = tree["log_likelihood"][var_name].shape[-1]
    if len(set(sizes.values())) != 1:
        raise ValueError(f"fits: the models were fitted to different numbers of trials {sizes}; compare fits to "
                         "the same trials")
    if reference is not None and reference not in trees:
        raise ValueError(f"reference: must be one of {sorted(trees)}, got {reference!r}")
    elpds = {name: azs.loo(tree, pointwise=True, var_name=var_name) for name, tree in trees.items()}
    table = azs.compare(elpds, reference=reference, round_to="none")
    mcse = {name: elpd_mcse(tree, var_name) for name, tree in trees.items()}
    table["mcse"] = [mcse[name] for name in table.index]
    ref = reference if reference is not None else table.index[0]  # the model elpd_diff is taken against
    table["mcse_diff"] = [0.0 if name == ref else math.hypot(mcse[ref], mcse[name]) for name in table.index]
    diff = table["elpd_diff"].to_numpy(float)
    sigma = np.hypot(table["dse"].to_numpy(float), table["mcse_diff"].to_numpy(float))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(sigma > 0, np.abs(diff) / sigma, np.where(np.abs(diff) < 1e-9, 0.0, np.inf))
    table["z"] = z
    table["pareto_k_max"] = [float(np.max(elpds[name].pareto_k)) for name in table.index]
    table["verdict"] = ["best" if i == 0 else "worse" if v > 4 else "weakly worse" if v >= 2 else "indistinguishable"
                        for i, v in enumerate(z)]
    return table

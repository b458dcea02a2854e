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
surface as its odd harmonics 4 A / (n pi) up to n = 29), ``display`` (the strain a simulated
display really renders after the safety limits, at its points and frames, for every depth) or
``contact`` (a physical grating pressed by a finger, through the solved contact: the finger's
pressure and friction and the grating's partial contact, :mod:`.contact_stimulus`).
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
from ._transduction_grid import GridFit
from .model_power import PowerResult, power_analysis
from .psychometric import ParamSummary, fit_psychometric

__all__ = ["TransductionModel", "TransductionFit", "fit_transduction", "power_analysis", "PowerResult",
           "ReceptorHypothesis", "fit_psychometric", "ParamSummary", "METHODS"]

STATISTICS = ("peak", "rms")
SOURCES = ("surface", "display", "contact")
N_HARMONICS = 15  # odd harmonics 1..29 of a square surface
_PER_PERIOD = 64  # samples per period of the highest harmonic


class TransductionModel:
    """A receptor hypothesis + a statistic of its readouts + a strain source.

    Parameters
    ----------
    hypothesis : ReceptorHypothesis or str
        E.g. ``"zx@1mm"`` (parsed with ``ReceptorHypothesis.parse``).
    statistic : {"peak", "rms"}
    source : {"surface", "display", "contact"}
    display : SimulatedDisplay, optional
        Needed for ``source="display"``: any object with ``steady_drive(stimulus)`` and
        ``strain(frames, depth_m=...)``, e.g. a session's ``RenderedStimuli`` (the candidate as a
        trial plays it).
    contact : FingerContact, optional
        Needed for ``source="contact"``: the finger (radius, normal force, friction, skin) that
        presses the grating (:class:`~.contact_stimulus.FingerContact`); its receptors are the
        scan line's nodes under the contact, its statistic is over every offset of the grating.
    """

    def __init__(self, hypothesis, *, statistic: str = "peak", source: str = "surface", display=None,
                 contact=None):
        self.hypothesis = hypothesis if isinstance(hypothesis, ReceptorHypothesis) \
            else ReceptorHypothesis.parse(str(hypothesis))
        if statistic not in STATISTICS:
            raise ValueError(f"statistic: must be one of {STATISTICS}, got {statistic!r}")
        if source not in SOURCES:
            raise ValueError(f"source: must be one of {SOURCES}, got {source!r}")
        if source == "display" and not callable(getattr(display, "steady_drive", None)):
            raise ValueError("display: source='display' needs a SimulatedDisplay (its rendered strain), got "
                             f"{type(display).__name__}; or use source='surface'")
        if source == "contact" and not callable(getattr(contact, "strain", None)):
            raise ValueError("contact: source='contact' needs a FingerContact (the finger that presses the grating), "
                             f"got {type(contact).__name__}; e.g. contact=FingerContact(10e-3, 0.5, 0.5)")
        self.statistic, self.source, self.display, self.contact = statistic, source, display, contact
        self._cache: dict[Stimulus, float] = {}

    def __repr__(self) -> str:
        return f"TransductionModel({str(self.hypothesis)!r}, statistic={self.statistic!r}, source={self.source!r})"

    @property
    def name(self) -> str:
        """Short label, e.g. ``zx@1mm`` (with ``/rms`` or ``/display`` when not the default)."""
        extra = ("" if self.statistic == "peak" else f"/{self.statistic}") + ("" if self.source == "surface"
                                                                               else f"/{self.source}")
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

    def _contact_statistic(self, stimulus: Stimulus) -> float:
        r = self.hypothesis.readout(self.contact.strain(stimulus, self.hypothesis.depths))
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
            elif self.source == "contact":
                value = self._contact_statistic(stimulus)
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

    ``tree``: ``posterior`` (threshold_strain, exponent, lapse[, false_alarm]; emcee: one chain
    per ensemble; grid: one chain of deterministic draws), ``log_likelihood`` (``correct`` over
    dim ``trial``), ``observed_data`` (``correct``), ``sample_stats`` (``lp``), ``constant_data``
    (per-trial statistics and target pitch and amplitude); ``params``: a :class:`ParamSummary`
    each (grid: mean and quantiles of the quadrature's marginals); ``converged`` and
    ``diagnostics`` from the sampler (R-hat between ensembles, ESS, tau) or the grid (mass at
    the box's edges, largest cell mass, passes, ``elpd_quadrature``);
    ``conditions``: the per-condition statistics and counts the likelihood used.
    """

    model: TransductionModel
    tree: object
    params: dict
    converged: bool
    diagnostics: dict
    task: str
    conditions: dict


METHODS = ("grid", "emcee")


def fit_transduction(model: TransductionModel, trials, *, task: str | None = None, priors: Mapping | None = None,
                     rng=None, n_ensembles: int = 4, method: str = "grid",
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
    rng : numpy.random.Generator, int or None
        For ``method="emcee"`` (required there); the grid uses no random numbers.
    n_ensembles : int
        emcee only: independent ensembles (>= 4); convergence is judged by R-hat across them.
    method : {"grid", "emcee"}
        ``grid`` (default): quadrature on an adaptive grid (``_transduction_grid``), deterministic
        draws and the same answer for every seed; converged when the grid holds and resolves the
        posterior. ``emcee``: ensembles of ``tactilab.inversion.sample_posterior`` (the reference).
    sampler_options : mapping, optional
        emcee only: passed on to ``sample_posterior`` (e.g. ``max_steps``, ``tau_factor``, ``pool``).
    """
    if method not in METHODS:
        raise ValueError(f"method: must be one of {METHODS}, got {method!r}")
    if not isinstance(model, TransductionModel):
        raise ValueError(f"model: expected a TransductionModel, got {type(model).__name__}")
    if method == "grid" and sampler_options:
        raise ValueError(f"sampler_options: only for method='emcee' (the grid has no sampler), got "
                         f"{dict(sampler_options)}; drop them or pass method='emcee'")
    if method == "emcee" and rng is None:
        raise ValueError("rng: method='emcee' needs a seed or numpy Generator, e.g. rng=0")
    data = conditions(model, trials, task)
    lik = TransductionLikelihood(data, default_priors(data, priors))
    n_trials = data["idx"].size
    # the per-trial log-likelihood is kept in bounded memory: <= 8e6 values (64 MB); below 400 draws
    # (over 20 000 trials) PSIS-LOO's Pareto k (compare_models' pareto_k_max) says whether that suffices
    max_draws = int(np.clip(8_000_000 // n_trials, 100, 4000))
    if method == "grid":
        return _fit_grid(model, lik, data, max_draws)
    from tactilab.inversion import sample_posterior

    options = {"max_draws": max_draws, "info_tol": None, **dict(sampler_options or {})}
    raw = sample_posterior(lik, np.random.default_rng(rng), n_ensembles=n_ensembles, **options)
    best = max(_maps(raw), key=lambda v: float(lik.log_prior(v[None])[0] + lik.total_log_likelihood(v[None])[0]))
    best, _ = map_estimate(lik, best)
    attrs = {**raw.attrs, "method": "emcee"}
    tree = _tree({name: raw["posterior"][name].values for name in lik.param_names},
                 raw["log_likelihood"]["obs"].values, raw["sample_stats"]["lp"].values, lik, data, best, attrs)
    post = tree["posterior"]
    params = {}
    for j, name in enumerate(lik.param_names):
        x = post[name].values.ravel()
        q = np.quantile(x, [0.5, 0.025, 0.975, 0.16, 0.84])
        params[name] = ParamSummary(float(best[j]), float(x.mean()), float(q[0]), (float(q[1]), float(q[2])),
                                    (float(q[3]), float(q[4])))
    return TransductionFit(model, tree, params, bool(attrs.get("converged", 0)), attrs, data["kind"], data)


def _fit_grid(model, lik, data, n_draws):
    grid = GridFit(lik).run()
    start = grid.natural(np.array([x[i] for x, i in zip(grid.grid, np.unravel_index(np.argmax(grid.logp),
                                                                                      grid.mass.shape))]))
    best, _ = map_estimate(lik, start)
    theta = grid.draws(n_draws)
    ll = lik.log_likelihood(theta)
    lp = lik.log_prior(theta) + lik.total_log_likelihood(theta)
    elpd_i, lppd_i = grid.loo_quadrature()
    attrs = {**grid.diagnostics, "method": "grid", "elpd_quadrature": float(elpd_i.sum()),
             "lppd_quadrature": float(lppd_i.sum())}
    tree = _tree({name: theta[None, :, j] for j, name in enumerate(lik.param_names)}, ll[None], lp[None], lik, data,
                 best, attrs, elpd_i)
    params = {}
    for j, name in enumerate(lik.param_names):
        q = grid.quantiles(j, [0.5, 0.025, 0.975, 0.16, 0.84])
        params[name] = ParamSummary(float(best[j]), grid.mean(j), float(q[0]), (float(q[1]), float(q[2])),
                                    (float(q[3]), float(q[4])))
    return TransductionFit(model, tree, params, bool(attrs["converged"]), attrs, data["kind"], data)


def _maps(raw):
    import json

    names = raw.attrs["parameters"].split(", ")
    return [np.array([m[n] for n in names]) for m in json.loads(raw.attrs["map_estimates"])]


def _tree(post, ll, lp, lik, data, best, attrs, elpd_i=None):
    """The fit's DataTree: ``posterior``, ``log_likelihood`` (``correct`` over dim ``trial``),
    ``observed_data``, ``sample_stats`` (``lp``) and ``constant_data`` (per trial: the model's
    statistic of the target and of the other interval, the target's pitch_m and amplitude_m, which
    the identifiability check of :func:`compare_models` reads; for the grid also
    ``elpd_loo_quadrature``, the exact leave-one-out elpd per trial); root attrs: the method's
    diagnostics, ``task`` and ``map_estimate`` (JSON)."""
    import json

    import arviz_base as azb

    idx = data["idx"]
    constant = {"statistic_target": data["s1"][idx], "statistic_other": data["s2"][idx],
                "pitch_m": data["pitch_m"], "amplitude_m": data["amplitude_m"]}
    if elpd_i is not None:
        constant["elpd_loo_quadrature"] = elpd_i
    root = {k: v for k, v in attrs.items() if isinstance(v, (str, int, float, bool, np.integer, np.floating))}
    root = {k: (int(v) if isinstance(v, (bool, np.bool_)) else v) for k, v in root.items()}
    root.update(task=lik.kind, map_estimate=json.dumps(dict(zip(lik.param_names, map(float, best)))))
    tree = azb.from_dict({"posterior": post, "log_likelihood": {"correct": ll},
                          "observed_data": {"correct": lik.observed}, "sample_stats": {"lp": lp},
                          "constant_data": constant},
                         dims={"correct": ["trial"], **{k: ["trial"] for k in constant}}, attrs={"/": root})
    for group, attrs in _TREE_ATTRS.items():  # units (SI; "1" dimensionless) for az.summary users and CF files
        for name, value in attrs.items():
            if group in tree.children and name in tree[group].dataset:
                tree[group].dataset[name].attrs.update(units=value[0], long_name=value[1])
    return tree


#: group -> variable -> (units, long_name) of a fit's tree
_TREE_ATTRS = {
    "posterior": {"threshold_strain": ("1", "strain readout at d' = 1 (tensor strain)"),
                  "exponent": ("1", "transducer exponent"), "lapse": ("1", "lapse rate"),
                  "false_alarm": ("1", "false-alarm rate")},
    "log_likelihood": {"correct": ("1", "pointwise log-likelihood of the response (nats)")},
    "observed_data": {"correct": ("1", "response correct (1) or wrong (0)")},
    "sample_stats": {"lp": ("1", "log posterior density up to a constant (nats)")},
    "constant_data": {"statistic_target": ("1", "the model's statistic of the target interval (strain)"),
                      "statistic_other": ("1", "the model's statistic of the other interval (strain)"),
                      "pitch_m": ("m", "target pitch"), "amplitude_m": ("m", "target amplitude"),
                      "elpd_loo_quadrature": ("1", "exact leave-one-out elpd per trial (nats)")},
}

"""Adaptive design that tells transduction hypotheses apart: :class:`ModelDiscrimination`.

Each trial shows the candidate stimulus whose response is expected to tell most about the model
(receptor hypothesis) the observer uses. The default ``utility="model"`` is the mutual
information between the next response and the model index, I(Y; m) = H(sum_m pi_m p_mc) -
sum_m pi_m H(p_mc) (H the binary entropy; Cavagnaro, Myung, Pitt and Kujala 2010), with

    p_mc = sum_g w_g|m P(correct | c, m, g),

``pi_m`` the posterior model probabilities and ``w_g|m`` the posterior over the parameter grid
g = (threshold_strain, exponent, lapse) within model m. ``utility="odds"`` is the expected
increase of the log posterior odds log(pi_m / (1 - pi_m)) of the model m that generates the
response, m drawn from the posterior (the extrinsic Jensen-Shannon divergence of Naghshvar and
Javidi 2013, "Active sequential hypothesis testing"):

    U(c) = sum_m pi_m KL(p_mc || sum_{j != m} pi_j p_jc / (1 - pi_m)),

KL between Bernoulli laws in nats. The session stops when a model's posterior probability, i.e.
its log-odds, reaches a level, so "odds" aims at what the stopping rule measures; it decides in
fewer trials where a few trials decide (docs/adaptive_design.md, table 1). ``"parameters"`` is
I(Y; theta | m) = sum_m pi_m [H(p_mc) - sum_g w_g|m H(P_cmg)] and ``"both"`` their sum
I(Y; m, theta) (chain rule). Every utility is exact over the binary response.

The state is a joint posterior on a GRID (not particles): the likelihood of a trial is one
row of a precomputed table P[c, m, g], so the update is an exact Bayes step (an addition of
log-probabilities) and the utility of every candidate is two matrix products, well under
10 ms for 200 candidates (benchmarks/bench_design.py); a grid is also exactly reproducible,
which resume needs. Its approximation is the quadrature of each model's marginal likelihood
over one log-spaced threshold grid shared by all models (the same prior, so a candidate that two
models predict alike is worth exactly 0 nats), a log-spaced exponent grid and a few lapse
values (docs/adaptive_design.md gives the accuracy).

Hypotheses whose statistics over every candidate are related by s_i = k s_j^a (a > 0, zeros
matching; a = 1: proportional) predict the same responses for some parameters whatever the
data: they are METAMERIC over the candidates, found before any trial
(:attr:`ModelDiscrimination.metameric_groups`), and no winner is ever declared between them.
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Mapping
from functools import cached_property

import numpy as np

from tactilab.data_schemas.design_config import ModelDiscriminationConfig
from tactilab.data_schemas.experiment import Stimulus
from tactilab.inversion import Beta1, LogNormal

from ..procedures import PlannedStimulus, Procedure, register_procedure
from ._design_math import _entropy, information_gain, metameric_groups
from ._transduction_data import p_correct_table
from .contact_stimulus import FingerContact
from .models import TransductionModel

__all__ = ["ModelDiscrimination", "ModelDiscriminationConfig", "UTILITIES", "information_gain", "metameric_groups",
           "from_config"]

UTILITIES = ("model", "odds", "parameters", "both")
_LAPSES = (0.0, 0.01, 0.03, 0.08)
_RELATIVE_THRESHOLDS = (1e-2, 3.0)  # threshold grid range / the models' largest candidate statistics
_EXPONENTS = (0.4, 3.0)


def _key(candidate) -> str:
    items = candidate if isinstance(candidate, tuple) else (candidate,)
    return json.dumps([s.model_dump() for s in items], sort_keys=True)


class ModelDiscrimination(Procedure):
    """Adaptive stimulus selection that maximises the expected evidence for the true model.

    Parameters
    ----------
    models : sequence of str or TransductionModel, or mapping label -> TransductionModel
        At least two hypotheses, e.g. ``["zx@1mm", "zx@2mm"]`` (strings parsed with
        ``ReceptorHypothesis.parse``; peak statistic of the ideal surface). A mapping names each
        model by its key (a protocol's design labels display-source models by their hypothesis).
    candidates : sequence of Stimulus or (Stimulus, Stimulus)
        The stimuli the design may show: a single stimulus (2IFC against a blank interval; yes/no:
        the signal) or a 2IFC pair (target, other). Their order does not matter.
    priors : mapping, optional
        ``model`` (one probability per model, default uniform), ``exponent``, ``lapse`` (objects
        with ``logpdf``, e.g. scipy.stats frozen; defaults lognormal with median 1 and log-sd 0.5,
        and Beta(1, 10) on [0, 0.5]). The threshold prior is log-uniform over the grid.
    utility : {"model", "odds", "parameters", "both"}
        ``"model"`` (default): I(Y; m); ``"odds"``: the expected increase of the true model's
        log posterior odds (fewer trials to a decision where a few trials decide);
        ``"parameters"``: I(Y; theta | m); ``"both"``: I(Y; m, theta)
        (docs/adaptive_design.md, "The utility").
    n_grid : int or (int, int)
        Threshold grid points (and exponent grid points; default 25 and 9), log-spaced.
    stop_probability : float
        Stop when a model (not metameric with another) reaches this posterior probability.
    max_trials : int
    rng : numpy.random.Generator, int or None
        Breaks exact ties between equally informative candidates in :meth:`choose`.
    task : {"2ifc"}
        Two-interval forced choice (yes/no would need catch trials to learn the false-alarm rate).
    config : ProcedureConfigBase, optional
        Set when built from a protocol (``method = "model_discrimination"``).
    parameter : str, optional
        The stimulus field reported as the trial's level (the runner varies it).

    Raises
    ------
    ValueError
        For an unknown model string, fewer than two models, an empty candidate set, candidates
        a task other than 2IFC, bad priors or settings.
    """

    _STATE_KEYS = ("log_posterior",)

    def __init__(self, models, candidates, *, priors: Mapping | None = None, utility: str = "model",
                 n_grid: int | tuple[int, int] = (25, 9), stop_probability: float = 0.99, max_trials: int = 500,
                 rng=None, task: str = "2ifc", config=None, parameter: str = "amplitude_m") -> None:
        super().__init__(config)
        if utility not in UTILITIES:
            raise ValueError(f"utility: must be one of {UTILITIES}, got {utility!r}")
        if task != "2ifc":
            raise ValueError(f"task: only '2ifc' is supported (yes/no needs catch trials to learn the false-alarm "
                             f"rate, which this design does not schedule), got {task!r}")
        if not 0.5 < stop_probability < 1:
            raise ValueError(f"stop_probability: must lie in (0.5, 1), got {stop_probability!r}")
        def whole(v, least):
            return isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= least

        if not whole(max_trials, 1):
            raise ValueError(f"max_trials: must be a whole number >= 1, got {max_trials!r}")
        n_t, n_b = (n_grid, 9) if np.ndim(n_grid) == 0 else (tuple(n_grid) + (None,))[:2]
        if not (whole(n_t, 2) and whole(n_b, 2)):
            raise ValueError(f"n_grid: need whole numbers >= 2 of threshold (and exponent) points, got {n_grid!r}")
        self.models, self.names = self._models(models)
        self.task, self.utility, self.parameter = task, utility, parameter
        self.stop_probability, self.max_trials = float(stop_probability), int(max_trials)
        self.candidates = self._candidates(candidates)
        self._rng = np.random.default_rng(rng)
        self.stats = np.array([[self._stats_of(model, c) for c in self.candidates] for model in self.models])
        for name, s in zip(self.names, self.stats):
            if not np.any(s[:, 0] > 0):
                raise ValueError(f"models: {name!r} reads 0 strain for every candidate; it predicts chance only "
                                 "(pick candidates it can feel, or drop it)")
        self.metameric_groups = metameric_groups(self.stats, self.names)
        self._groups = np.array([next(k for k, g in enumerate(self.metameric_groups) if n in g) for n in self.names])
        self._build_grid(int(n_t), int(n_b), dict(priors or {}))
        self.probabilities: list[dict[str, float]] = []
        self._shown: set[int] = set()
        shared = [g for g in self.metameric_groups if len(g) > 1]
        if shared:
            warnings.warn(f"ModelDiscrimination: {shared} are metameric over every candidate (identical predictions "
                          "for some parameters): no data on these candidates can tell them apart", stacklevel=2)

    # ----- construction ---------------------------------------------------------------------
    @staticmethod
    def _models(models) -> tuple[list[TransductionModel], list[str]]:
        if isinstance(models, (str, TransductionModel)) or len(models) < 2:
            raise ValueError(f"models: give at least two hypotheses, e.g. ['zx@1mm', 'zx@2mm'], got {models!r}")
        labels = [str(k) for k in models] if isinstance(models, Mapping) else None
        out = []
        for i, m in enumerate(models.values() if labels is not None else models):
            try:
                out.append(m if isinstance(m, TransductionModel) else TransductionModel(str(m)))
            except ValueError as exc:
                raise ValueError(f"models[{i}]: unknown model {m!r} ({exc})") from None
        names = labels if labels is not None else [m.name for m in out]
        if len(set(names)) < len(out):
            raise ValueError(f"models: names must be distinct, got {names}")
        return out, names

    @staticmethod
    def _candidates(candidates) -> list:
        items = list(candidates) if candidates is not None else []
        if not items:
            raise ValueError("candidates: the candidate set is empty; give at least one Stimulus")
        out = []
        for i, c in enumerate(items):
            if isinstance(c, (tuple, list)) and len(c) == 2 and all(isinstance(s, Stimulus) for s in c):
                out.append(tuple(c))
            elif isinstance(c, Stimulus):
                out.append(c)
            else:
                raise ValueError(f"candidates[{i}]: expected a Stimulus or a (target, other) pair, got {c!r}")
        keys = [_key(c) for c in out]
        if len(set(keys)) < len(keys):
            raise ValueError("candidates: contains repeated stimuli; give each candidate once")
        return [out[i] for i in np.argsort(keys, kind="stable")]  # canonical order: choice ignores input order

    def _stats_of(self, model: TransductionModel, candidate) -> tuple[float, float]:
        if isinstance(candidate, tuple):
            return model.statistic_of(candidate[0]), model.statistic_of(candidate[1])
        return model.statistic_of(candidate), 0.0  # against a blank interval

    def _build_grid(self, n_t: int, n_b: int, priors: dict) -> None:
        unknown = set(priors) - {"model", "exponent", "lapse"}
        if unknown:
            raise ValueError(f"priors: unknown keys {sorted(unknown)}; use model, exponent, lapse")
        # one absolute threshold grid for every model (the same prior; a candidate that two models
        # predict alike is then worth exactly 0 nats): n_t points per 300-fold range, from 1/100 of
        # the smallest to 3x the largest of the models' largest statistics
        top = np.array([s.max() for s in self.stats])
        lo, hi = top.min() * _RELATIVE_THRESHOLDS[0], top.max() * _RELATIVE_THRESHOLDS[1]
        n_abs = int(math.ceil((n_t - 1) * math.log(hi / lo) / math.log(np.divide(*_RELATIVE_THRESHOLDS[::-1])))) + 1
        rel = np.geomspace(lo, hi, n_abs)
        expo = np.geomspace(*_EXPONENTS, n_b)
        axes = [rel, expo, np.array(_LAPSES)]
        mesh = np.meshgrid(*axes, indexing="ij")
        grid = np.stack([m.ravel() for m in mesh], axis=1)  # (G, P): threshold_strain, exponent, lapse[, fa]
        dists = {"exponent": priors.get("exponent", LogNormal(1.0, 0.5)),
                 "lapse": priors.get("lapse", Beta1(10.0, 0.5))}
        # log-spaced axes: a density is weighted by x (d x = x d log x); lapse values as point masses
        log_w = np.asarray(dists["exponent"].logpdf(grid[:, 1]), float) + np.log(grid[:, 1])
        log_w = log_w + np.asarray(dists["lapse"].logpdf(grid[:, 2]), float)
        if not np.all(np.isfinite(log_w)):
            raise ValueError("priors: a prior has zero density at a grid point (exponent 0.4-3, lapse 0-0.08); give priors positive there")
        pm = np.full(len(self.models), 1 / len(self.models)) if "model" not in priors else \
            np.asarray(priors["model"], float)
        if pm.shape != (len(self.models),) or np.any(~np.isfinite(pm)) or np.any(pm <= 0):
            raise ValueError(f"priors: 'model' needs {len(self.models)} positive probabilities, got {priors.get('model')!r}")
        self.grid = grid
        table = np.empty((len(self.candidates), len(self.models), grid.shape[0]))
        for m in range(len(self.models)):
            table[:, m, :] = p_correct_table(self.task, self.stats[m, :, 0], self.stats[m, :, 1], grid).T
        self.table = table
        self._log_p = np.log(np.clip(table, 1e-300, 1))
        self._log_q = np.log(np.clip(1 - table, 1e-300, 1))
        self._entropy_table = _entropy(table) if self.utility in ("parameters", "both") else None
        log_w = log_w - np.logaddexp.reduce(log_w)
        self._log_posterior = np.log(pm / pm.sum())[:, None] + log_w[None, :]  # (M, G)

    # ----- posterior --------------------------------------------------------------------------
    def weights(self) -> np.ndarray:
        """Joint posterior probabilities over (model, grid point), shape (n_models, n_grid)."""
        w = np.exp(self._log_posterior - self._log_posterior.max())
        return w / w.sum()

    def model_probabilities(self) -> dict[str, float]:
        """Posterior probability of each model (sum 1)."""
        return dict(zip(self.names, map(float, self.weights().sum(axis=1))))

    def group_probabilities(self) -> dict[tuple[str, ...], float]:
        """Posterior probability of each metameric group (a singleton for a distinguishable model)."""
        p = self.model_probabilities()
        return {g: sum(p[n] for n in g) for g in self.metameric_groups}

    def _shown_metameric(self, name: str) -> bool:
        """True when ``name`` is metameric with a rival over the candidates shown so far: the
        rival's free threshold and exponent fit those trials as well (a rate of zero), so the
        probabilities reflect the prior, not the data."""
        if not self._shown:
            return True
        shown = sorted(self._shown)
        groups = metameric_groups(self.stats[:, shown], self.names)
        return any(name in g and len(g) > 1 for g in groups)

    @property
    def winner(self) -> str | None:
        """The model whose probability reached ``stop_probability``, never one of a metameric group
        (over all candidates, or over the candidates shown so far)."""
        for g, p in self.group_probabilities().items():
            if len(g) == 1 and p >= self.stop_probability and not self._shown_metameric(g[0]):
                return g[0]
        return None

    @property
    def verdict(self) -> str:
        """``winner: NAME``, ``metameric: A, B`` (a group reached the stop level), ``undecided``,
        or ``nothing to learn`` (every model in one metameric group)."""
        if len(self.metameric_groups) == 1:
            return "nothing to learn: every model is metameric over the candidates"
        if self.winner is not None:
            return f"winner: {self.winner}"
        for g, p in self.group_probabilities().items():
            if p >= self.stop_probability and len(g) > 1:
                return "metameric: " + ", ".join(g)
        return "undecided"

    # ----- choice and update ------------------------------------------------------------------
    def utilities(self) -> np.ndarray:
        """The utility (nats) of each candidate (canonical order), shape (n_candidates,)."""
        return information_gain(self.table, self.weights(), self.utility, self._entropy_table, self._groups)

    def choose(self, rng: np.random.Generator | None = None) -> int:
        """Index (into :attr:`candidates`) of the most informative candidate; exact ties by ``rng``.

        When a model has reached ``stop_probability`` but is metameric with a rival over the
        stimuli shown so far (so the prior, not the data, put it there), the most informative
        candidate NOT yet shown is taken instead.
        """
        u = self.utilities()
        blocked = any(len(g) == 1 and p >= self.stop_probability and self._shown_metameric(g[0])
                      for g, p in self.group_probabilities().items())
        if blocked and len(self._shown) < len(u):  # the prior, not the data, decides: show a new stimulus
            u = u.copy()
            u[sorted(self._shown)] = -np.inf
        best = np.flatnonzero(u >= u.max() - 1e-12 * max(abs(u.max()), 1e-300))
        gen = self._rng if rng is None else rng
        return int(best[0] if best.size == 1 else best[int(gen.integers(best.size))])

    def observe(self, index: int, correct: bool) -> None:
        """Bayes update with the response to candidate ``index`` (correct, or yes on a signal)."""
        self._log_posterior = self._log_posterior + (self._log_p if correct else self._log_q)[index]
        self._log_posterior -= self._log_posterior.max()
        self._shown.add(int(index))
        self.probabilities.append(self.model_probabilities())

    # ----- Procedure interface (runner, resume) -------------------------------------------------
    @property
    def n_planned(self) -> int:
        return self.max_trials

    @property
    def finished(self) -> bool:
        if len(self.probabilities) >= self.max_trials or len(self.metameric_groups) == 1:
            return True
        return self.winner is not None or any(p >= self.stop_probability and len(g) > 1
                                              for g, p in self.group_probabilities().items())

    @cached_property
    def stimulus_fields(self) -> tuple[str, ...]:
        """The stimulus fields a planned trial carries besides the level: the fields the
        ideal-surface statistic reads (surface, amplitude, pitch: what is shown is what was
        predicted, even where ``[stimulus]`` says otherwise), plus those a protocol lists under
        ``candidates`` (built from a protocol) or those that differ between candidates."""
        names = ["surface", "amplitude_m", "pitch_m"]
        if isinstance(self.config, ModelDiscriminationConfig):
            names += list(self.config.candidates)
        else:
            first = [c[0] if isinstance(c, tuple) else c for c in self.candidates]
            dumps = [s.model_dump() for s in first]
            names += [k for k in dumps[0] if len({d[k] for d in dumps}) > 1]
        return tuple(dict.fromkeys(k for k in names if k != self.parameter))

    def _next(self, rng):
        index = self.choose(rng)
        c = self.candidates[index]
        stimulus = c[0] if isinstance(c, tuple) else c
        fields = tuple((k, getattr(stimulus, k)) for k in self.stimulus_fields)
        return PlannedStimulus(float(getattr(stimulus, self.parameter)), index, 0, fields)

    def _update(self, planned, outcome):
        if outcome is not None:
            self.observe(planned.track, outcome)

    def estimate(self):
        """Posterior model probabilities (``p_<model>``), the verdict, and ``threshold`` None."""
        return {"threshold": None, **{f"p_{n}": p for n, p in self.model_probabilities().items()},
                "verdict": self.verdict}

    def record_state(self):
        """Compact per-trial state: the model probabilities and the verdict (the grid is replayed)."""
        return {"n_trials": self.n_done, "model_probabilities": self.model_probabilities(), "verdict": self.verdict,
                "metameric_groups": [list(g) for g in self.metameric_groups if len(g) > 1]}


def from_config(config: ModelDiscriminationConfig, *, guess_rate: float = 0.5,
                display=None, finger=None) -> ModelDiscrimination:
    """Build the procedure a protocol's ``[procedure]`` table describes (the registered factory).

    Parameters
    ----------
    config : ModelDiscriminationConfig
    guess_rate : float
        The task's chance rate (must be 0.5).
    display : SimulatedDisplay, optional
        A model of the session's display: every hypothesis then predicts from the strain the
        display renders, its limits included (``TransductionModel(source="display")``), labelled
        by the protocol's hypothesis string. Default: the ideal surface (``source="surface"``).
    finger : FingerConfig, optional
        The finger that presses the protocol's physical gratings (its ``[finger]`` table): every
        hypothesis then predicts from the strain of that finger's solved contact
        (``TransductionModel(source="contact")`` with ``FingerContact.from_config(finger)``, one
        finger shared by the hypotheses, so each candidate's contact is solved once), labelled by
        the protocol's hypothesis string.

    Raises
    ------
    ValueError
        If the protocol's task is not two-interval forced choice (mixed tasks: the design models
        2IFC, chance rate 0.5), or both ``display`` and ``finger`` are given.
    """
    if guess_rate != 0.5:
        raise ValueError(f"task: mixed tasks: the design models 2ifc (chance rate 0.5) but the protocol's task has "
                         f"chance rate {guess_rate}; use task.kind = '2ifc' with method 'model_discrimination'")
    if display is not None and finger is not None:
        raise ValueError("display, finger: a design predicts from one strain source, the display's rendering or the "
                         "finger's solved contact; give one of them")
    with warnings.catch_warnings():  # the metameric groups are in every trial's recorded state
        warnings.simplefilter("ignore")
        if display is not None:
            models = {m: TransductionModel(m, source="display", display=display) for m in config.models}
        elif finger is not None:
            contact = FingerContact.from_config(finger)
            models = {m: TransductionModel(m, source="contact", contact=contact) for m in config.models}
        else:
            models = config.models
        return ModelDiscrimination(models, config.stimuli(), utility=config.utility,
                                   n_grid=(config.n_grid, 9), stop_probability=config.stop_probability,
                                   max_trials=config.max_trials, task=config.task, config=config,
                                   parameter=config.parameter)


register_procedure("model_discrimination", ModelDiscriminationConfig, from_config)

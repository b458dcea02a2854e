"""Psi / QUEST+ with ANY likelihood, and the named psychometric families.

The named families are built by :func:`psychometric`; any other model is a callable
``f(level, **params) -> p(positive)`` (for example a transduction model that predicts detection
from the strain at the receptors), given to :class:`Psi` directly or, for protocol files and
sessions, registered by name with :func:`tactilab.experiments.register_likelihood`. A name is
looked up (:func:`resolve_likelihood`), never imported. Psi registers itself as ``method = "psi"``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr

from tactilab.data_schemas.experiment import PsiConfig

from .base import Likelihood, PlannedLevel, Procedure
from .registry import get_likelihood, register_procedure

def _weibull(x, threshold, slope):
    return -np.expm1(-np.power(np.clip(x, 0, None) / threshold, slope))


def _gumbel(x, threshold, slope):
    with np.errstate(divide="ignore"):
        z = slope * (np.log10(np.clip(x, 0, None)) - np.log10(threshold))
    return -np.expm1(-np.power(10.0, z))


def _logistic(x, threshold, slope):
    return 0.5 * (1 + np.tanh(0.5 * slope * (x - threshold) / threshold))


def _normal_cdf(x, threshold, slope):
    return ndtr(slope * (x - threshold) / threshold)


_CORES = {"weibull": _weibull, "gumbel": _gumbel, "logistic": _logistic, "normal_cdf": _normal_cdf}


def psychometric(family: str, guess_rate: float) -> Likelihood:
    """Return ``f(x, threshold, slope, lapse) = guess + (1 - guess - lapse) F(x)`` for a family.

    ``F`` uses the dimensionless ratio x / threshold, so ``slope`` is dimensionless in any unit:
    weibull ``1 - exp(-(x/t)^b)``, gumbel ``1 - exp(-10^(b log10(x/t)))``,
    logistic ``1 / (1 + exp(-b (x - t)/t))``, normal_cdf ``Phi(b (x - t)/t)``.
    """
    if family not in _CORES:
        raise ValueError(f"family: must be one of {sorted(_CORES)}, got {family!r}")
    core = _CORES[family]

    def likelihood(x, threshold, slope, lapse):
        return guess_rate + (1 - guess_rate - lapse) * core(x, threshold, slope)

    likelihood.__name__ = f"{family}_guess{guess_rate:g}"
    return likelihood


def resolve_likelihood(name: str, guess_rate: float = 0.0) -> Likelihood:
    """The likelihood a protocol names: a built-in family (with ``guess_rate``) or a registered one.

    Raises
    ------
    UnregisteredError
        If ``name`` is neither a family nor registered (the message says how to register it).
    """
    if name in _CORES:
        return psychometric(name, guess_rate)
    return get_likelihood(name)


class Psi(Procedure):
    """Psi / QUEST+ (Kontsevich & Tyler 1999; Watson 2017) with ANY binary likelihood.

    Parameters
    ----------
    config : PsiConfig
        Candidate levels (SI), parameter grids, the likelihood name and ``n_trials``.
    guess_rate : float
        Chance rate for the named families (``config.guess_rate`` overrides it).
    likelihood : callable, optional
        ``f(level, **params) -> p(positive)``, ``level`` of shape (n_levels, 1) and each
        parameter of shape (1, n_theta); overrides ``config.likelihood``. The posterior over the
        parameter grid is updated exactly by Bayes' rule (uniform prior); each trial takes the
        level that minimises the expected posterior entropy.
    """

    _STATE_KEYS = ("log_posterior", "n_informative")

    def __init__(self, config: PsiConfig, guess_rate: float = 0.0, likelihood: Likelihood | None = None):
        super().__init__(config)
        if likelihood is None:
            guess = config.guess_rate if config.guess_rate is not None else guess_rate
            likelihood = resolve_likelihood(config.likelihood, guess)
        if not callable(likelihood):
            raise ValueError(f"likelihood: must be callable f(level, **params), got {likelihood!r}")
        self.names = list(config.parameters)
        mesh = np.meshgrid(*[np.asarray(config.parameters[k], float) for k in self.names], indexing="ij")
        self.theta = {k: m.ravel() for k, m in zip(self.names, mesh)}
        self.levels = np.asarray(config.levels, float)
        with np.errstate(all="ignore"):
            table = np.asarray(likelihood(self.levels[:, None], **{k: v[None, :] for k, v in self.theta.items()}), float)
        expected = (self.levels.size, mesh[0].size)
        if table.shape != expected:
            raise ValueError(
                f"likelihood: must return p(positive) of shape (n_levels, n_theta) = {expected}, got "
                f"{table.shape}; broadcast level (n_levels, 1) against params (1, n_theta)"
            )
        if not np.all(np.isfinite(table)) or np.any((table < 0) | (table > 1)):
            raise ValueError("likelihood: returned values outside [0, 1] or NaN; it must return probabilities")
        eps = 1e-12
        self._log_p1 = np.log(np.clip(table, eps, 1))
        self._log_p0 = np.log(np.clip(1 - table, eps, 1))
        self._log_posterior = np.full(expected[1], -math.log(expected[1]))
        self._n_informative = 0  # trials with an outcome (catch trials do not count)

    @property
    def n_planned(self) -> int:
        return self.config.n_trials

    @property
    def finished(self) -> bool:
        return self._n_informative >= self.config.n_trials

    def posterior(self) -> np.ndarray:
        """Posterior probabilities over the flattened parameter grid, shape (n_theta,)."""
        w = np.exp(self._log_posterior - self._log_posterior.max())
        return w / w.sum()

    def _next(self, rng):
        post = self.posterior()
        p1_theta = np.exp(self._log_p1)  # (n_levels, n_theta)
        p1 = p1_theta @ post  # predictive probability of a positive outcome per level
        entropies = []
        for log_p, p in ((self._log_p1, p1), (self._log_p0, 1 - p1)):
            w = np.exp(log_p) * post
            w = w / np.clip(w.sum(axis=1, keepdims=True), 1e-300, None)
            h = -np.sum(np.where(w > 0, w * np.log(np.clip(w, 1e-300, None)), 0.0), axis=1)
            entropies.append(p * h)
        expected_entropy = entropies[0] + entropies[1]
        return PlannedLevel(float(self.levels[int(np.argmin(expected_entropy))]), 0, 0)

    def _update(self, planned, outcome):
        if outcome is None:
            return
        self._n_informative += 1
        row = int(np.flatnonzero(self.levels == planned.level)[0])
        self._log_posterior = self._log_posterior + (self._log_p1[row] if outcome else self._log_p0[row])
        self._log_posterior -= self._log_posterior.max()

    def estimate(self):
        post = self.posterior()
        out: dict[str, float | None] = {}
        for k in self.names:
            mean = float(post @ self.theta[k])
            out[k] = mean
            out[f"{k}_sd"] = float(np.sqrt(max(post @ (self.theta[k] - mean) ** 2, 0.0)))
        return out

    def record_state(self):
        post = self.posterior()
        entropy = float(-np.sum(post[post > 0] * np.log(post[post > 0])))
        return {"n_trials": self.n_done, "entropy_nats": entropy, "estimate": self.estimate()}


register_procedure("psi", PsiConfig, lambda config, *, guess_rate=0.0: Psi(config, guess_rate))

"""Prior densities of scalar parameters: one family for every sampled model of the project.

The defect-localisation posterior (:mod:`tactilab.inversion.mcmc`) and the transduction
models of :mod:`tactilab.experiments` (fitted by the same sampler,
:func:`~tactilab.inversion.sample_posterior`) draw their priors from here. Every prior is a
frozen dataclass, checked on creation, with

- ``logpdf(x)``: log density at an array of values (``-inf`` outside the support, never NaN);
- ``sample(rng, size)``: draws from a ``numpy.random.Generator``;
- ``rvs(size, random_state)``: the same draws with ``scipy.stats``' signature, so that a frozen
  ``scipy.stats`` distribution and these priors are interchangeable where a model accepts either;
- ``std``: the prior standard deviation (the sampler's scale for its MAP search and start ball);
- ``support``: the interval ``(low, high)`` outside which the density is 0.

Values are in the parameter's own units (SI: m, Pa, N; dimensionless for rates).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Uniform", "Normal", "LogNormal", "LogUniform", "Beta1", "PRIORS"]


class _Draws:
    """``rvs`` in scipy.stats' signature, on top of each prior's ``sample(rng, size)``."""

    def rvs(self, size=None, random_state=None):
        """Draws of ``size`` (scipy.stats signature); ``random_state``: a Generator or a seed."""
        return self.sample(np.random.default_rng(random_state), size)


@dataclass(frozen=True)
class Uniform(_Draws):
    """Uniform prior on ``[low, high]`` (parameter units)."""

    low: float
    high: float

    def __post_init__(self):
        if not (np.isfinite(self.low) and np.isfinite(self.high) and self.high > self.low):
            raise ValueError(f"Uniform: need finite low < high, got low={self.low!r}, high={self.high!r}")

    def logpdf(self, x):
        x = np.asarray(x, dtype=float)
        inside = (x >= self.low) & (x <= self.high)
        return np.where(inside, -np.log(self.high - self.low), -np.inf)

    def sample(self, rng, size):
        return rng.uniform(self.low, self.high, size)

    @property
    def support(self) -> tuple[float, float]:
        return (self.low, self.high)

    @property
    def std(self) -> float:
        return (self.high - self.low) / np.sqrt(12.0)


@dataclass(frozen=True)
class Normal(_Draws):
    """Normal prior ``N(mean, sd^2)`` (parameter units)."""

    mean: float
    sd: float

    def __post_init__(self):
        if not (np.isfinite(self.mean) and np.isfinite(self.sd) and self.sd > 0):
            raise ValueError(f"Normal: need a finite mean and sd > 0, got mean={self.mean!r}, sd={self.sd!r}")

    def logpdf(self, x):
        z = (np.asarray(x, dtype=float) - self.mean) / self.sd
        return -0.5 * z * z - np.log(self.sd * np.sqrt(2 * np.pi))

    def sample(self, rng, size):
        return rng.normal(self.mean, self.sd, size)

    @property
    def support(self) -> tuple[float, float]:
        return (-math.inf, math.inf)

    @property
    def std(self) -> float:
        return self.sd


@dataclass(frozen=True)
class LogNormal(_Draws):
    """Log-normal prior: ``log(x) ~ N(log(median), sigma_log^2)``, for positive parameters."""

    median: float
    sigma_log: float

    def __post_init__(self):
        if not (np.isfinite(self.median) and self.median > 0 and np.isfinite(self.sigma_log) and self.sigma_log > 0):
            raise ValueError(f"LogNormal: need median > 0 and sigma_log > 0, got {self.median!r}, {self.sigma_log!r}")

    def logpdf(self, x):
        x = np.asarray(x, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            lx = np.log(np.where(x > 0, x, 1.0))
            z = (lx - np.log(self.median)) / self.sigma_log
            val = -0.5 * z * z - lx - np.log(self.sigma_log * np.sqrt(2 * np.pi))
        return np.where(x > 0, val, -np.inf)

    def sample(self, rng, size):
        return self.median * np.exp(self.sigma_log * rng.standard_normal(size))

    @property
    def support(self) -> tuple[float, float]:
        return (0.0, math.inf)  # open at 0

    @property
    def std(self) -> float:
        s2 = self.sigma_log**2
        return float(self.median * np.sqrt((np.exp(s2) - 1) * np.exp(s2)))


@dataclass(frozen=True)
class LogUniform(_Draws):
    """Log-uniform prior on ``[low, high]``, ``0 < low < high``: density ``1 / (x ln(high / low))``."""

    low: float
    high: float

    def __post_init__(self):
        if not (np.isfinite(self.low) and np.isfinite(self.high) and 0 < self.low < self.high):
            raise ValueError(f"LogUniform: need finite 0 < low < high, got low={self.low!r}, high={self.high!r}")

    def logpdf(self, x):
        x = np.asarray(x, dtype=float)
        ok = (x >= self.low) & (x <= self.high)
        return np.where(ok, -math.log(math.log(self.high / self.low)) - np.log(np.where(ok, x, 1.0)), -np.inf)

    def sample(self, rng, size):
        return np.exp(rng.uniform(math.log(self.low), math.log(self.high), size))

    @property
    def support(self) -> tuple[float, float]:
        return (self.low, self.high)

    @property
    def std(self) -> float:
        span = math.log(self.high / self.low)
        mean = (self.high - self.low) / span
        return math.sqrt(max((self.high**2 - self.low**2) / (2 * span) - mean * mean, 0.0))


@dataclass(frozen=True)
class Beta1(_Draws):
    """Beta(1, b) prior scaled to ``[0, scale)``: density ``(b / scale) (1 - x / scale)^(b - 1)``.

    ``Beta1(10, 0.5)`` is the transduction models' lapse prior; ``Beta1(1, 1)`` is uniform on [0, 1).
    """

    b: float
    scale: float = 1.0

    def __post_init__(self):
        if not (np.isfinite(self.b) and self.b > 0 and np.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"Beta1: need b > 0 and scale > 0, got b={self.b!r}, scale={self.scale!r}")

    def logpdf(self, x):
        u = np.asarray(x, dtype=float) / self.scale
        ok = (u >= 0) & (u < 1)
        return np.where(ok, math.log(self.b / self.scale) + (self.b - 1) * np.log1p(-np.where(ok, u, 0.0)), -np.inf)

    def sample(self, rng, size):
        return self.scale * (1 - rng.random(size) ** (1 / self.b))

    @property
    def support(self) -> tuple[float, float]:
        return (0.0, self.scale)

    @property
    def std(self) -> float:
        b = self.b
        return self.scale * math.sqrt(b / ((1 + b) ** 2 * (b + 2)))


#: the prior classes (for isinstance checks)
PRIORS = (Uniform, Normal, LogNormal, LogUniform, Beta1)

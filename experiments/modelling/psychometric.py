"""Bayesian psychometric-function fits, parametrised and gridded as psignifit 4 does.

psi(x) = guess + (1 - guess - lapse) F(x; threshold, width), where F is a sigmoid with
F(threshold) = ``threshold_pc`` and ``width`` the distance between F = alpha and F = 1 - alpha
(Schuett, Harmeling, Macke and Wichmann 2016, eq. 1). ``F(x) = cdf(ppf(pc) + C (x - threshold) / width)``
with ``C = ppf(1 - alpha) - ppf(alpha)`` for the standard core of each name in :data:`SIGMOIDS`;
``weibull`` is ``gumbel`` on natural-log levels. The default priors and the two-pass adaptive
grid are psignifit 4's (docs/model_comparison.md lists them); ``method="emcee"`` samples the
same posterior instead, with the project's one MCMC engine (``tactilab.inversion.sample_posterior``).
Levels may be in any unit; every threshold and interval comes back in it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, NamedTuple

import numpy as np
from scipy.special import expit, logit, ndtr, ndtri

from ._psychometric_grid import GridPosterior, ParamSummary, grid_posterior, sample_emcee


class Sigmoid(NamedTuple):
    """A standard sigmoid core: ``cdf``, its inverse ``ppf`` and density ``pdf`` (all vectorised)."""

    cdf: Callable[[np.ndarray], np.ndarray]
    ppf: Callable[[np.ndarray], np.ndarray]
    pdf: Callable[[np.ndarray], np.ndarray]
    log_levels: bool = False


def _exp_neg(z):
    return np.exp(-np.exp(np.clip(z, -700, 700)))


#: one table of sigmoid names, for fits and for protocol likelihoods
SIGMOIDS: dict[str, Sigmoid] = {
    "norm": Sigmoid(ndtr, ndtri, lambda z: np.exp(-0.5 * z * z) / math.sqrt(2 * math.pi)),
    "logistic": Sigmoid(expit, logit, lambda z: expit(z) * expit(-z)),
    "gumbel": Sigmoid(lambda z: -np.expm1(-np.exp(np.clip(z, -700, 700))),
                      lambda p: np.log(-np.log1p(-p)), lambda z: np.exp(z) * _exp_neg(z)),
    "rgumbel": Sigmoid(lambda z: _exp_neg(-z), lambda p: -np.log(-np.log(p)), lambda z: np.exp(-z) * _exp_neg(-z)),
    "tdist": Sigmoid(lambda z: 0.5 + np.arctan(z) / math.pi, lambda p: np.tan(math.pi * (p - 0.5)),
                     lambda z: 1 / (math.pi * (1 + z * z))),
}
SIGMOIDS["weibull"] = SIGMOIDS["gumbel"]._replace(log_levels=True)
SIGMOIDS["lognorm"] = SIGMOIDS["norm"]._replace(log_levels=True)  # a cumulative lognormal: norm on log levels
#: other names accepted for the same cores (protocol files use ``normal_cdf``)
SIGMOID_ALIASES: dict[str, str] = {"normal_cdf": "norm", "gauss": "norm", "student": "tdist",
                                   "heavytail": "tdist"}


def sigmoid_core(name: str) -> Sigmoid:
    """The core of a sigmoid name or alias from :data:`SIGMOIDS` / :data:`SIGMOID_ALIASES`."""
    key = SIGMOID_ALIASES.get(name, name)
    if key not in SIGMOIDS:
        raise ValueError(f"sigmoid: must be one of {sorted(SIGMOIDS)} (aliases {sorted(SIGMOID_ALIASES)}), "
                         f"got {name!r}")
    return SIGMOIDS[key]


_EXPERIMENTS = ("2afc", "2ifc", "yes_no", "equal_asymptote")
_PARAMS = ("threshold", "width", "lapse", "guess", "eta")


def _parse_experiment(experiment: str) -> tuple[str, float | None]:
    """-> (kind, fixed guess rate or None); kind in nafc, yes_no, equal_asymptote."""
    if experiment in ("2afc", "2ifc"):
        return "nafc", 0.5
    if isinstance(experiment, str) and experiment.startswith("nafc:"):
        try:
            n = int(experiment[5:])
        except ValueError:
            n = 0
        if n < 2:
            raise ValueError(f"experiment: 'nafc:N' needs an integer N >= 2, got {experiment!r}; e.g. 'nafc:4'")
        return "nafc", 1.0 / n
    if experiment in ("yes_no", "equal_asymptote"):
        return experiment, None
    raise ValueError(f"experiment: must be one of {list(_EXPERIMENTS)} or 'nafc:N', got {experiment!r}")


def _blocks(levels, correct, n_correct, n_trials):
    x = np.asarray(levels, dtype=float).ravel()
    if correct is not None:
        if n_correct is not None or n_trials is not None:
            raise ValueError("correct: give either per-trial `correct` or `n_correct` with `n_trials`, not both")
        c = np.asarray(correct, dtype=float).ravel()
        if c.shape != x.shape:
            raise ValueError(f"correct: must have one entry per level (shape {x.shape}), got shape {c.shape}")
        if not np.all((c == 0) | (c == 1)):
            raise ValueError("correct: must hold 0/1 (or False/True) per trial; found other values or NaN")
        if not np.all(np.isfinite(x)):
            raise ValueError("levels: must be finite; found NaN or inf")
        ux, inv = np.unique(x, return_inverse=True)
        return ux, np.bincount(inv, weights=c), np.bincount(inv).astype(float)
    if n_correct is None or n_trials is None:
        raise ValueError("correct: missing; give per-trial `correct` (0/1) or both `n_correct` and `n_trials`")
    k = np.asarray(n_correct, dtype=float).ravel()
    n = np.asarray(n_trials, dtype=float).ravel()
    if k.shape != x.shape or n.shape != x.shape:
        raise ValueError(f"n_correct, n_trials: must match levels' shape {x.shape}, got {k.shape} and {n.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(k)) and np.all(np.isfinite(n))):
        raise ValueError("levels, n_correct, n_trials: must be finite; found NaN or inf")
    if np.any(k < 0) or np.any(k > n) or np.any(k != np.round(k)) or np.any(n != np.round(n)):
        raise ValueError("n_correct: must be whole numbers with 0 <= n_correct <= n_trials at every level")
    ux, inv = np.unique(x, return_inverse=True)
    return ux, np.bincount(inv, weights=k), np.bincount(inv, weights=n)


@dataclass
class PsychometricFit:
    """A fitted psychometric function (from :func:`fit_psychometric`).

    Attributes
    ----------
    params : dict[str, ParamSummary]
        ``threshold`` (F = threshold_pc) and ``width`` in the levels' units (for ``weibull``:
        the threshold in the levels' units and the width in natural-log units), ``lapse`` and
        ``guess`` (probabilities); ``eta`` too with ``overdispersion``. Fixed ones are constant.
    tree : xarray.DataTree
        ``posterior`` (draws of every parameter, dims chain, draw), ``observed_data`` (level,
        n_correct, n_trials over dim ``level``) and the settings in its attrs.
    deviance : float
        Binomial deviance at the MAP against the saturated model.
    gof_p : float
        Posterior-predictive p: the share of posterior draws whose replicated data have a
        deviance at least the observed one's.
    """

    params: dict[str, ParamSummary]
    tree: object
    deviance: float
    gof_p: float
    sigmoid: str
    threshold_pc: float
    width_alpha: float
    levels: np.ndarray
    n_correct: np.ndarray
    n_trials: np.ndarray

    def _core(self):
        core = sigmoid_core(self.sigmoid)
        c = float(core.ppf(1 - self.width_alpha) - core.ppf(self.width_alpha))
        return core, c

    def _f_scale(self, x, theta=None):
        """z-argument of the core at x (level units), for the MAP or the given parameters."""
        p = theta or {k: v.map for k, v in self.params.items()}
        core, c = self._core()
        x = np.asarray(x, dtype=float)
        t = math.log(p["threshold"]) if core.log_levels else p["threshold"]
        with np.errstate(divide="ignore"):
            u = np.log(x) if core.log_levels else x
        return core, c, float(core.ppf(self.threshold_pc)) + c * (u - t) / p["width"], p

    def p_correct(self, x) -> np.ndarray:
        """psi(x) at the MAP parameters; x in the levels' units, any shape."""
        core, _, z, p = self._f_scale(x)
        return p["guess"] + (1 - p["guess"] - p["lapse"]) * core.cdf(z)

    def threshold_at(self, pc: float) -> float:
        """Level (levels' units) where psi = ``pc`` at the MAP; ``pc`` must lie in (guess, 1 - lapse)."""
        p = {k: v.map for k, v in self.params.items()}
        lo, hi = p["guess"], 1 - p["lapse"]
        if not (lo < pc < hi):
            raise ValueError(f"pc: must lie strictly between the guess rate {lo:.4g} and 1 - lapse {hi:.4g} "
                             f"(psi scale), got {pc!r}")
        core, c = self._core()
        f = (pc - lo) / (hi - lo)
        t = math.log(p["threshold"]) if core.log_levels else p["threshold"]
        u = t + (float(core.ppf(f)) - float(core.ppf(self.threshold_pc))) * p["width"] / c
        return float(math.exp(u) if core.log_levels else u)

    def slope_at(self, x) -> np.ndarray:
        """d psi / dx at the MAP (per level unit); x in the levels' units."""
        core, c, z, p = self._f_scale(x)
        d = (1 - p["guess"] - p["lapse"]) * core.pdf(z) * c / p["width"]
        return d / np.asarray(x, dtype=float) if core.log_levels else d

    def plot(self, path, *, xlabel: str = "stimulus level", title: str | None = None) -> None:
        """Data (marker area ~ trials), the MAP curve and the threshold's 95 % interval, to ``path``."""
        from matplotlib.figure import Figure

        fig = Figure(figsize=(5.5, 4.0), layout="constrained")
        ax = fig.add_subplot()
        log = sigmoid_core(self.sigmoid).log_levels
        lo, hi = self.levels.min(), self.levels.max()
        if log:
            xs = np.geomspace(lo / 1.5, hi * 1.5, 400)
            ax.set_xscale("log")
        else:
            pad = 0.15 * (hi - lo)
            xs = np.linspace(lo - pad, hi + pad, 400)
        ax.scatter(self.levels, self.n_correct / self.n_trials, s=12 + 60 * self.n_trials / self.n_trials.max(),
                   color="k", alpha=0.7, label="data (area ~ trials)")
        ax.plot(xs, self.p_correct(xs), color="C0", label=f"{self.sigmoid} fit (MAP)")
        th = self.params["threshold"]
        y = float(self.p_correct(th.map))
        ax.plot(th.ci95, [y, y], color="C3", lw=3, alpha=0.6, label="threshold 95 % interval")
        ax.plot([th.map], [y], "o", color="C3")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("proportion correct")
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(title or f"threshold {th.map:.3g} [{th.ci95[0]:.3g}, {th.ci95[1]:.3g}]; "
                     f"gof p = {self.gof_p:.2f}", fontsize=9)
        ax.legend(fontsize=7, loc="lower right")
        fig.savefig(path, dpi=110)


def fit_psychometric(levels, correct=None, *, n_correct=None, n_trials=None, experiment: str = "2afc",
                     sigmoid: str = "norm", priors: str | Mapping[str, Callable] = "psignifit",
                     fixed: Mapping[str, float] | None = None, threshold_pc: float = 0.5,
                     width_alpha: float = 0.05, overdispersion: bool = False, method: str = "grid",
                     rng=None) -> PsychometricFit:
    """Fit psi(x) = guess + (1 - guess - lapse) F(x) to binary responses, Bayesian, psignifit-4 style.

    Parameters
    ----------
    levels : array_like, shape (n,)
        Stimulus level per trial (with ``correct``) or per block (with ``n_correct``, ``n_trials``),
        any unit; > 0 for ``weibull``.
    correct : array_like of 0/1, shape (n,), optional
        Per-trial outcome. Trials at the same level are pooled into one block.
    n_correct, n_trials : array_like, shape (n,), optional
        Counts per block instead of ``correct``.
    experiment : str
        ``"2afc"``/``"2ifc"`` (guess = 1/2), ``"nafc:N"`` (guess = 1/N), ``"yes_no"`` (guess free)
        or ``"equal_asymptote"`` (guess = lapse).
    sigmoid : str
        A name of :data:`SIGMOIDS` or an alias.
    priors : "psignifit" or mapping
        psignifit 4's default priors, or a mapping ``name -> density(values)`` that replaces the
        defaults for those parameters (names threshold, width, lapse, guess, eta).
    fixed : mapping, optional
        Parameters held at a value, e.g. ``{"lapse": 0.0}``.
    threshold_pc, width_alpha : float
        F at the threshold, in (0, 1); the width runs from F = alpha to F = 1 - alpha, alpha in (0, 0.5).
    overdispersion : bool
        Fit psignifit's beta-binomial ``eta`` (default: binomial, eta = 0).
    method : "grid" or "emcee"
        The adaptive grid posterior, or emcee samples of the same posterior.
    rng : numpy Generator, int or None
        For the posterior draws and the posterior-predictive p.
    """
    kind, guess = _parse_experiment(experiment)
    core = sigmoid_core(sigmoid)
    for name, value, lo, hi in (("threshold_pc", threshold_pc, 0.0, 1.0), ("width_alpha", width_alpha, 0.0, 0.5)):
        if not (isinstance(value, (int, float)) and lo < value < hi):
            raise ValueError(f"{name}: must lie strictly between {lo} and {hi}, got {value!r}")
    if method not in ("grid", "emcee"):
        raise ValueError(f"method: must be 'grid' or 'emcee', got {method!r}")
    fixed = dict(fixed or {})
    for key, value in fixed.items():
        if key not in _PARAMS:
            raise ValueError(f"fixed: unknown parameter {key!r}; use names from {list(_PARAMS)}")
        if not (isinstance(value, (int, float)) and math.isfinite(value)):
            raise ValueError(f"fixed: {key} must be a finite number, got {value!r}")
        if key in ("lapse", "guess", "eta") and not 0 <= value < 1:
            raise ValueError(f"fixed: {key} must lie in [0, 1), got {value!r}")
        if key == "width" and value <= 0:
            raise ValueError(f"fixed: width must be > 0, got {value!r}")
    if "guess" in fixed and kind != "yes_no":
        raise ValueError(f"fixed: guess is set by experiment={experiment!r}; fix it only for 'yes_no'")
    if priors != "psignifit" and not (isinstance(priors, Mapping)
                                      and all(k in _PARAMS and callable(v) for k, v in priors.items())):
        raise ValueError(f"priors: must be 'psignifit' or a mapping from {list(_PARAMS)} to density "
                         f"callables, got {priors!r}")
    x, k, n = _blocks(levels, correct, n_correct, n_trials)
    keep = n > 0
    x, k, n = x[keep], k[keep], n[keep]
    if x.size < 2:
        raise ValueError(f"levels: need trials at >= 2 distinct levels to fit a sigmoid, got {x.size}")
    if core.log_levels:
        if np.any(x <= 0):
            raise ValueError("levels: the weibull sigmoid works on log levels, so every level must be > 0")
        if "threshold" in fixed:
            fixed["threshold"] = math.log(fixed["threshold"])
    u = np.log(x) if core.log_levels else x
    if not overdispersion:
        fixed.setdefault("eta", 0.0)
    if guess is not None:
        fixed["guess"] = guess
    gen = np.random.default_rng(rng)
    post: GridPosterior = grid_posterior(u, k, n, core, kind, fixed, None if priors == "psignifit" else priors,
                                         threshold_pc, width_alpha)
    draws = post.draws(4000, gen) if method == "grid" else sample_emcee(post, gen)
    params = post.summaries(draws, method)
    if core.log_levels:  # back to the levels' units: the threshold maps monotonically
        s = params["threshold"]
        params["threshold"] = ParamSummary(math.exp(s.map), float(np.mean(np.exp(draws["threshold"]))),
                                           math.exp(s.median), tuple(map(math.exp, s.ci95)),
                                           tuple(map(math.exp, s.ci68)))
        draws = {**draws, "threshold": np.exp(draws["threshold"])}
    deviance, gof_p = post.goodness(draws if not core.log_levels else {**draws, "threshold": np.log(draws["threshold"])},
                                    gen)
    tree = _tree(draws, x, k, n, dict(sigmoid=sigmoid, experiment=experiment, threshold_pc=threshold_pc,
                                      width_alpha=width_alpha, method=method, deviance=deviance, gof_p=gof_p))
    return PsychometricFit(params, tree, deviance, gof_p, sigmoid, threshold_pc, width_alpha, x, k, n)


def _tree(draws, x, k, n, attrs):
    import xarray as xr

    post = xr.Dataset({name: (("chain", "draw"), np.asarray(v)[None, :]) for name, v in draws.items()})
    obs = xr.Dataset({"n_correct": ("level", k), "n_trials": ("level", n)}, coords={"level": x})
    return xr.DataTree.from_dict({"/": xr.Dataset(attrs={k_: v for k_, v in attrs.items()}),
                                  "posterior": post, "observed_data": obs})

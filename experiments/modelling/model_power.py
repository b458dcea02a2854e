"""How many trials tell two transduction models apart? Asymptotic and simulated power.

Asymptotic: the truth gives P(correct) p_i at each design stimulus i (weight w_i = n_i / N).
The rival's pseudo-true parameters are the KL projection of the truth over the design,
argmax over theta' of sum_i w_i [p_i log q_i(theta') + (1 - p_i) log(1 - q_i(theta'))]. The
log-likelihood ratio of one trial, L = y log(p/q) + (1 - y) log((1 - p)/(1 - q)), has mean
``mu = sum_i w_i KL(p_i || q_i)`` (nats per trial) and standard deviation ``sigma`` over the
design's mix (what a comparison's dse estimates per trial). After N trials the difference is
about N mu with standard error sqrt(N) sigma, so z standard errors need N = (z sigma / mu)^2.

Simulated: draw outcomes from the truth at the design (scaled to n trials), fit both models by
maximum likelihood (per-condition likelihood, from the truth and the projection), and count the repeats where the truth wins
by more than z standard errors of the per-trial log-likelihood difference (a plug-in stand-in for
PSIS-LOO, which it approaches for these 3-4-parameter models at hundreds of trials).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize
from scipy.special import expit, ndtr

from tactilab.core.memory import check_count

from ._transduction_data import p_correct_table

#: mean log-likelihood ratios per trial at or below this (nats) are the optimiser's floor: the
#: rival fits the design exactly (a rate of zero, never "a huge number of trials")
ZERO_RATE_NATS = 1e-9

_NAMES = {"2ifc": ("threshold_strain", "exponent", "lapse"),
          "yes_no": ("threshold_strain", "exponent", "lapse", "false_alarm")}


def _bernoulli_kl(p, q):
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(p > 0, p * np.log(p / q), 0.0)
        b = np.where(p < 1, (1 - p) * np.log((1 - p) / (1 - q)), 0.0)
    return a + b


def _from_free(u, task):
    # clipped: on a design the rival fits exactly, Nelder-Mead may wander far along a flat valley
    out = [math.exp(min(max(u[0], -700.0), 700.0)), math.exp(min(max(u[1], -700.0), 700.0)), 0.5 * float(expit(u[2]))]
    if task == "yes_no":
        out.append(float(expit(u[3])))
    return np.array(out)


def _to_free(theta, task):
    lam = min(max(theta[2], 1e-9), 0.5 - 1e-9)
    u = [math.log(theta[0]), math.log(theta[1]), math.log(lam / (0.5 - lam))]
    return np.array(u + ([math.log(theta[3] / (1 - theta[3]))] if task == "yes_no" else []))


@dataclass
class PowerResult:
    """Power of a comparison between a true model and a rival over a design.

    Attributes
    ----------
    mu : float
        Mean log-likelihood ratio per trial (truth vs the rival at its pseudo-true parameters), nats.
    sigma : float
        Its standard deviation per trial over the design's mix, nats.
    rival_params : dict
        The rival's pseudo-true parameters (KL projection of the truth).
    """

    mu: float
    sigma: float
    rival_params: dict
    method: str
    task: str
    _sim: dict = field(default_factory=dict, repr=False)

    @property
    def exact_fit(self) -> bool:
        """True when the rival fits the truth's P(correct) exactly over the design: the mean
        log-likelihood ratio is at the optimiser's floor (``mu <= ZERO_RATE_NATS`` nats per trial).
        A design with few distinct stimuli (one, two or three: as many as the rival's free
        threshold, exponent and lapse) is typically fitted exactly, whatever the models."""
        return self.mu <= ZERO_RATE_NATS

    @property
    def rate(self) -> float:
        """Evidence rate per trial ``mu / sigma`` (1/sqrt(trial)); exactly 0 when :attr:`exact_fit`."""
        if self.exact_fit or self.sigma <= 0:
            return 0.0
        return self.mu / self.sigma

    def trials_for(self, z: float = 4.0) -> float:
        """Trials needed for the expected difference to reach z standard errors (inf if the rate is 0)."""
        if self.rate == 0.0:
            return math.inf
        return (z / self.rate) ** 2

    def p_select(self, n: int, z: float = 4.0) -> float:
        """P(the truth beats the rival by more than z standard errors after n trials).

        Asymptotic: Phi(sqrt(n) mu / sigma - z). Simulated: the share of ``n_repeats`` simulated
        experiments of n trials (design proportions kept) where it does.
        """
        if int(n) != n or n < 1:
            raise ValueError(f"n: must be a positive whole number of trials, got {n!r}")
        if self.method == "asymptotic":
            if self.sigma == 0:
                return 1.0 if self.mu > 0 else 0.0
            return float(ndtr(math.sqrt(n) * self.mu / self.sigma - z))
        sim = self._sim
        key = int(n)
        if key not in sim["z"]:
            sim["z"][key] = _simulate(sim, key)
        return float(np.mean(sim["z"][key] > z))


#: bytes per simulated experiment of :func:`_simulate`: its z value in a list and in the returned array
REPEAT_BYTES = 64


def _simulate(sim, n):
    """z of the per-trial log-likelihood difference (truth's MAP - rival's MAP) per repeat."""
    w = sim["w"]
    counts = np.floor(w * n).astype(int)
    counts[np.argsort(-(w * n - counts))[: n - counts.sum()]] += 1  # largest remainders
    task, rng, out = sim["task"], sim["rng"], []
    for _ in range(sim["n_repeats"]):
        k = rng.binomial(counts, sim["p"])
        ll = []
        for (s1, s2), start in ((sim["true_s"], sim["true_u"]), (sim["rival_s"], sim["rival_u"])):
            def nll(u, s1=s1, s2=s2):
                q = np.clip(p_correct_table(task, s1, s2, _from_free(u, task)[None])[0], 1e-300, 1 - 1e-16)
                return -float(np.sum(k * np.log(q) + (counts - k) * np.log1p(-q)))

            u = minimize(nll, start, method="Nelder-Mead", options=dict(xatol=1e-6, fatol=1e-8, maxiter=4000)).x
            p = np.clip(p_correct_table(task, s1, s2, _from_free(u, task)[None])[0], 1e-12, 1 - 1e-12)
            ll.append((np.log(p), np.log1p(-p)))
        a = ll[0][0] - ll[1][0]  # per correct trial of each condition
        b = ll[0][1] - ll[1][1]  # per incorrect trial
        total = float(np.sum(k * a + (counts - k) * b))
        mean = total / n
        var = float(np.sum(k * (a - mean) ** 2 + (counts - k) * (b - mean) ** 2)) / max(n - 1, 1)
        out.append(total / math.sqrt(n * var) if var > 0 else (0.0 if total == 0 else math.copysign(math.inf, total)))
    return np.array(out)


def project(task: str, p, rival_s1, rival_s2, w):
    """KL projection of the truth's P(correct) ``p`` (per condition) onto a rival over a design.

    Parameters
    ----------
    task : {"2ifc", "yes_no"}
    p : ndarray, shape (n,)
        The truth's P(correct) per condition.
    rival_s1, rival_s2 : ndarray, shape (n,)
        The rival's statistics per condition (target and other interval; yes/no: 1 for signal).
    w : ndarray, shape (n,)
        Share of the trials per condition (sums to 1).

    Returns
    -------
    (mu, sigma, rival_theta, u)
        Mean and standard deviation of one trial's log-likelihood ratio (nats), the rival's
        pseudo-true parameters (threshold_strain, exponent, lapse[, false_alarm]) and the same in
        the optimiser's free coordinates.
    """
    pos = rival_s1[rival_s1 > 0]
    typical = float(np.median(pos)) if pos.size else 1.0

    def objective(u):
        q = np.clip(p_correct_table(task, rival_s1, rival_s2, _from_free(u, task)[None])[0], 1e-300, 1 - 1e-16)
        return float(np.sum(w * _bernoulli_kl(p, q)))

    best = None
    for scale in (0.3, 1.0, 3.0):
        for b0 in (0.7, 1.5):
            u0 = np.array([math.log(typical * scale), math.log(b0), -3.0] + ([-1.5] if task == "yes_no" else []))
            res = minimize(objective, u0, method="Nelder-Mead", options=dict(xatol=1e-9, fatol=1e-14, maxiter=8000))
            if best is None or res.fun < best.fun:
                best = res
    rival_theta = _from_free(best.x, task)
    q = np.clip(p_correct_table(task, rival_s1, rival_s2, rival_theta[None])[0], 1e-300, 1 - 1e-16)
    kl = _bernoulli_kl(p, q)
    mu = float(np.sum(w * kl))
    with np.errstate(divide="ignore", invalid="ignore"):
        l1 = np.where(p > 0, np.log(p / q), 0.0)
        l0 = np.where(p < 1, np.log((1 - p) / (1 - q)), 0.0)
    second = np.sum(w * (p * l1 ** 2 + (1 - p) * l0 ** 2))
    return mu, float(math.sqrt(max(second - mu ** 2, 0.0))), rival_theta, best.x


def power_analysis(true_model, true_params: dict, rival, design, *, task: str = "2ifc", method: str = "asymptotic",
                   n_repeats: int = 200, rng=None) -> PowerResult:
    """Power of telling ``true_model`` (at ``true_params``) from ``rival`` with a design.

    Parameters
    ----------
    true_model, rival : TransductionModel
    true_params : dict
        ``threshold_strain`` (readout units), ``exponent``, ``lapse`` and, for yes/no, ``false_alarm``.
    design : list of (Stimulus, n_trials)
        2IFC: each stimulus against a blank interval; yes/no: a blank (amplitude 0) is a catch trial.
    task : {"2ifc", "yes_no"}
    method : {"asymptotic", "simulate"}
    n_repeats : int
        Simulated experiments per ``p_select(n)`` (method="simulate").
    rng : numpy Generator, int or None
    """
    if task not in _NAMES:
        raise ValueError(f"task: must be '2ifc' or 'yes_no', got {task!r}")
    if method not in ("asymptotic", "simulate"):
        raise ValueError(f"method: must be 'asymptotic' or 'simulate', got {method!r}")
    if method == "simulate":  # the memory rule: one z value (a Python float in a list) per simulated experiment
        if int(n_repeats) != n_repeats or n_repeats < 1:
            raise ValueError(f"n_repeats: need a whole number >= 1 of simulated experiments, got {n_repeats!r}")
        check_count(int(n_repeats), REPEAT_BYTES, "n_repeats", "simulated experiments (a z value each)")
    names = _NAMES[task]
    if set(true_params) != set(names):
        raise ValueError(f"true_params: need exactly {list(names)} for task {task!r}, got {sorted(true_params)}")
    theta = np.array([float(true_params[k]) for k in names])
    if not (np.all(np.isfinite(theta)) and theta[0] > 0 and theta[1] > 0 and 0 <= theta[2] < 0.5
            and (task == "2ifc" or 0 < theta[3] < 1)):
        raise ValueError(f"true_params: need threshold_strain > 0, exponent > 0, 0 <= lapse < 0.5 (and 0 < "
                         f"false_alarm < 1), got {true_params}")
    if not design or any(len(item) != 2 or int(item[1]) != item[1] or item[1] < 1 for item in design):
        raise ValueError("design: give a non-empty list of (Stimulus, n_trials) with n_trials a whole number >= 1")
    stims = [s for s, _ in design]
    n = np.array([int(c) for _, c in design], dtype=float)
    w = n / n.sum()

    def stats_of(model):
        s1 = np.array([model.statistic_of(s) for s in stims])
        return s1, (np.zeros_like(s1) if task == "2ifc" else (s1 > 0).astype(float))

    true_s, rival_s = stats_of(true_model), stats_of(rival)
    p = p_correct_table(task, *true_s, theta[None])[0]
    if not np.any(rival_s[0] > 0):
        raise ValueError("rival: every design stimulus has statistic 0 under the rival; it predicts chance only")
    mu, sigma, rival_theta, best_u = project(task, p, rival_s[0], rival_s[1], w)
    sim = {}
    if method == "simulate":
        sim = dict(task=task, w=w, p=p, true_s=true_s, rival_s=rival_s, n_repeats=int(n_repeats),
                   true_u=_to_free(theta, task), rival_u=best_u,
                   rng=np.random.default_rng(rng), z={})
    return PowerResult(mu, sigma, dict(zip(names, map(float, rival_theta))), method, task, sim)

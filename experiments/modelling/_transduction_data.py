"""Trials -> per-unique-stimulus conditions, and the picklable likelihood of a transduction model.

The link (signal detection): d = (s / threshold_strain)^exponent with s the model's statistic of
an interval (0 for a blank). 2IFC: P(correct) = 1/2 + (1/2 - lapse)(2 Phi((d_target - d_other) / sqrt 2) - 1).
Yes/no: P(yes) = lapse + (1 - 2 lapse) Phi(d + Phi^-1(false_alarm)), where ``false_alarm`` is the
noise-only rate of an observer that does not lapse (it says yes when d + n > c, n ~ N(0, 1),
false_alarm = Phi(-c)); a correct answer is yes on a signal trial and no on a blank.

The likelihood is computed once per CONDITION (a unique pair of statistics, or a unique
statistic and signal/blank) and gathered to trials only for the per-trial terms.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from scipy.special import ndtr, ndtri

from tactilab.inversion import Beta1, LogNormal, LogUniform

TASKS = ("2ifc", "yes_no")


def _stimulus(value):
    from tactilab.data_schemas.experiment import Stimulus

    return value if isinstance(value, Stimulus) else Stimulus.model_validate(value)


def _records(trials, task):
    """-> (list of (stimuli tuple, target, correct), task kind)."""
    import pandas as pd

    from tactilab.data_schemas.experiment_records import Session

    kinds, rows = set(), []
    if isinstance(trials, (str, Path)):
        trials = [trials]
    if isinstance(trials, Session):
        kinds.add(trials.protocol.task.kind)
        rows = [(tuple(t.stimuli), t.target, t.correct) for t in trials.trials]
    elif isinstance(trials, pd.DataFrame):
        for col in ("stimuli", "correct"):
            if col not in trials.columns:
                raise ValueError(f"trials: the DataFrame has no {col!r} column; it needs 'stimuli' (list of "
                                 "interval stimuli, or their JSON) and 'correct' (bool), as session_dataframe gives")
        targets = trials["target"] if "target" in trials.columns else [None] * len(trials)
        for stim, target, correct in zip(trials["stimuli"], targets, trials["correct"]):
            stim = json.loads(stim) if isinstance(stim, str) else stim
            rows.append((tuple(_stimulus(s) for s in stim), target, None if pd.isna(correct) else bool(correct)))
    elif isinstance(trials, (list, tuple)) and trials and all(isinstance(t, (str, Path)) for t in trials):
        from ..session import SessionLog

        for path in trials:
            if not Path(path).is_file():
                raise ValueError(f"trials: no session file at {str(path)!r}; pass a session .sqlite path")
            log = SessionLog(path)
            try:
                kinds.add(log.meta()["protocol"]["task"]["kind"])
                rows += [(tuple(t.stimuli), t.target, t.correct) for t in log.trials()]
            finally:
                log.close()
    elif isinstance(trials, (list, tuple)) and trials and all(hasattr(t, "stimuli") for t in trials):
        rows = [(tuple(t.stimuli), t.target, t.correct) for t in trials]
    else:
        raise ValueError(f"trials: expected session .sqlite path(s), a Session, a list of TrialRecord or a "
                         f"DataFrame with 'stimuli' and 'correct', got {type(trials).__name__}")
    if not kinds:  # infer from the intervals and labels
        for stim, target, _ in rows:
            kinds.add("2ifc" if len(stim) == 2 and target in ("1", "2", None) else
                      "yes_no" if len(stim) == 1 and target in ("yes", "no") else f"unknown ({len(stim)} intervals, "
                      f"target {target!r})")
    if task is not None:
        kinds = {task} | kinds if kinds != {task} else kinds
    if len(kinds) > 1:
        raise ValueError(f"trials: mixed tasks in one fit {sorted(kinds)}; fit each task separately")
    kind = kinds.pop()
    if kind not in TASKS:
        raise ValueError(f"task: transduction fits support {TASKS} (detection), got {kind!r}")
    rows = [r for r in rows if r[2] is not None]
    if not rows:
        raise ValueError("trials: no trial with a correct/incorrect outcome to fit")
    return rows, kind


def conditions(model, trials, task=None):
    """Group trials by condition. Returns a dict of arrays (statistics computed once per stimulus)."""
    rows, kind = _records(trials, task)
    keys, idx, correct = {}, np.empty(len(rows), dtype=np.int64), np.empty(len(rows), dtype=bool)
    pitch, amplitude = np.empty(len(rows)), np.empty(len(rows))  # of the target interval, m
    for i, (stim, target, ok) in enumerate(rows):
        if kind == "2ifc":
            if len(stim) != 2:
                raise ValueError(f"trials: a 2ifc trial has 2 intervals, trial {i} has {len(stim)}")
            t = int(target) - 1 if target in ("1", "2") else int(np.argmax([s.amplitude_m for s in stim]))
            key = (model.statistic_of(stim[t]), model.statistic_of(stim[1 - t]))
        else:
            t = 0
            key = (model.statistic_of(stim[0]), 1.0 if target == "yes" else 0.0)
        pitch[i], amplitude[i] = stim[t].pitch_m, stim[t].amplitude_m
        idx[i] = keys.setdefault(key, len(keys))
        correct[i] = ok
    table = np.array(list(keys), dtype=float).reshape(-1, 2)
    n = np.bincount(idx, minlength=len(keys)).astype(float)
    k = np.bincount(idx, weights=correct, minlength=len(keys))
    return dict(kind=kind, s1=table[:, 0], s2=table[:, 1], n=n, k=k, idx=idx, correct=correct, pitch_m=pitch,
                amplitude_m=amplitude)


def p_correct_table(kind, s1, s2, theta):
    """P(correct) per condition for parameter rows ``theta`` (W, P) -> (W, n_conditions)."""
    theta = np.atleast_2d(theta)
    t, b, lam = theta[:, :1], theta[:, 1:2], theta[:, 2:3]
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        d1 = np.where(s1 > 0, (s1 / t) ** b, 0.0)
        if kind == "2ifc":
            d2 = np.where(s2 > 0, (s2 / t) ** b, 0.0)
            return 0.5 + (0.5 - lam) * (2 * ndtr((d1 - d2) / math.sqrt(2)) - 1)
        fa = theta[:, 3:4]
        p_yes = lam + (1 - 2 * lam) * ndtr(d1 + ndtri(fa))
        return np.where(s2 > 0, p_yes, 1 - p_yes)


class TransductionLikelihood:
    """A model object for ``tactilab.inversion.sample_posterior`` (picklable, vectorised).

    Parameters ``threshold_strain`` (readout units), ``exponent``, ``lapse`` and, for yes/no,
    ``false_alarm``. ``log_likelihood(theta)`` gives one term per trial, gathered from the
    per-condition table.
    """

    vectorized = True

    def __init__(self, data: dict, priors: dict):
        self.kind = data["kind"]
        self.s1, self.s2, self.n, self.k = data["s1"], data["s2"], data["n"], data["k"]
        self.idx, self.correct = data["idx"], data["correct"]
        with np.errstate(divide="ignore"):
            self._log_s1, self._log_s2 = np.log(self.s1), np.log(self.s2)
        self._signal = self.s2 > 0
        self.param_names = ("threshold_strain", "exponent", "lapse") + (("false_alarm",) if self.kind == "yes_no" else ())
        self.priors = priors
        self.observed = self.correct.astype(float)
        pos = np.concatenate([self.s1, self.s2 if self.kind == "2ifc" else []])
        pos = pos[pos > 0]
        self.typical = float(np.median(pos)) if pos.size else 1.0
        self.scale = np.array([self.typical, 0.3, 0.05, 0.1][:len(self.param_names)])

    def log_prior(self, theta):
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        out = sum(self.priors[name].logpdf(theta[:, j]) for j, name in enumerate(self.param_names))
        ok = (theta[:, 2] >= 0) & (theta[:, 2] < 0.5) & (theta[:, 0] > 0) & (theta[:, 1] > 0)
        if theta.shape[1] > 3:
            ok &= (theta[:, 3] > 0) & (theta[:, 3] < 1)
        return np.where(ok & ~np.isnan(out), out, -np.inf)

    def _table(self, theta):
        """(log P(correct), log P(incorrect)) per condition, each (W, n_conditions); theta valid."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        t, b, lam = theta[:, 0:1], theta[:, 1:2], theta[:, 2:3]
        d1 = np.exp(b * (self._log_s1 - np.log(t)))  # s = 0 -> log s = -inf -> d = 0
        if self.kind == "2ifc":
            x = (d1 - np.exp(b * (self._log_s2 - np.log(t)))) / math.sqrt(2)
            p = lam + (1 - 2 * lam) * ndtr(x)  # = 1/2 + (1/2 - lam)(2 Phi(x) - 1)
            q = lam + (1 - 2 * lam) * ndtr(-x)
        else:
            z = d1 + ndtri(theta[:, 3:4])
            yes, no = lam + (1 - 2 * lam) * ndtr(z), lam + (1 - 2 * lam) * ndtr(-z)
            p, q = np.where(self._signal, yes, no), np.where(self._signal, no, yes)
        return np.log(np.maximum(p, 1e-300)), np.log(np.maximum(q, 1e-300))

    def log_likelihood(self, theta):
        """Per-trial log-likelihood, shape (W, n_trials) (or (n_trials,) for one theta)."""
        one = np.ndim(theta) == 1
        lp, lq = self._table(theta)
        out = np.where(self.correct, lp[:, self.idx], lq[:, self.idx])
        return out[0] if one else out

    def total_log_likelihood(self, theta):
        """Sum over trials computed per condition (W,)."""
        lp, lq = self._table(theta)
        return lp @ self.k + lq @ (self.n - self.k)

    # the sampler's target needs only the total: one term per condition (marginalising nothing)
    marginalised_names: tuple[str, ...] = ()

    def log_marginal_likelihood(self, theta):
        """The total log-likelihood computed per condition, (W,) (the sampler's fast target)."""
        return self.total_log_likelihood(theta)

    def draw_marginalised(self, theta, rng):
        """Nothing is marginalised: no extra posterior variables."""
        return {}

    def initial(self, rng, n):
        cols = [self.priors[name].rvs(size=n, random_state=rng) for name in self.param_names]
        out = np.column_stack(cols)
        out[:, 2] = np.minimum(out[:, 2], 0.49)
        return out


def default_priors(data: dict, overrides: dict | None):
    """Log-uniform threshold over 1/100 to 100x the data's statistics, lognormal exponent
    (median 1, sd of log 0.5), Beta(1, 10) lapse on [0, 0.5], uniform false-alarm rate."""
    pos = np.concatenate([data["s1"], data["s2"] if data["kind"] == "2ifc" else []])
    pos = pos[pos > 0]
    if pos.size == 0:
        raise ValueError("trials: every stimulus has statistic 0 under this model (it reads nothing the stimuli "
                         "change); pick another hypothesis or check the stimuli")
    priors = {"threshold_strain": LogUniform(pos.min() / 100, pos.max() * 100), "exponent": LogNormal(1.0, 0.5),
              "lapse": Beta1(10.0, 0.5), "false_alarm": Beta1(1.0, 1.0)}
    for name, dist in (overrides or {}).items():
        if name not in priors or not callable(getattr(dist, "logpdf", None)):
            raise ValueError(f"priors: {name!r} must be one of {sorted(priors)} mapped to a scipy.stats frozen "
                             f"distribution (with logpdf and rvs), got {dist!r}")
        priors[name] = dist
    return priors


def map_estimate(lik: TransductionLikelihood, start):
    """Polish a start point to the MAP (Nelder-Mead on the per-condition total)."""
    from scipy.optimize import minimize

    def neg(v):
        v = np.asarray(v)[None, :]
        prior = float(lik.log_prior(v)[0])
        if not math.isfinite(prior):  # outside the support: no likelihood (its logs would be of negatives)
            return 1e300
        val = prior + float(lik.total_log_likelihood(v)[0])
        return -val if math.isfinite(val) else 1e300

    res = minimize(neg, np.asarray(start, dtype=float), method="Nelder-Mead",
                   options=dict(xatol=1e-8, fatol=1e-9, maxiter=4000))
    return res.x, -res.fun


"""Can the trials of a session tell two fitted transduction models apart at all?

Before a comparison says "worse", the design must be able to say it. The check is the
asymptotic power projection (:func:`~.model_power.project`) on the session's own trials: take
the leading model at its fitted (MAP) parameters as the truth, project it onto the rival (the
rival's parameters that predict the truth's P(correct) best over these trials, in KL), and read
the mean ``mu`` and standard deviation ``sigma`` of one trial's log-likelihood ratio. After the
session's N trials the expected elpd difference is about ``N mu`` with standard error
``sqrt(N) sigma``: its ratio, the expected separation ``sqrt(N) mu / sigma``, below 2 means the
design cannot separate the two models whatever the responses were (a one-pitch sinusoid session
and two receptor depths: the depth only rescales the threshold, so the rival fits exactly).

The per-trial statistics come from the fits' trees (``constant_data``: each model's statistic of
the target and of the other interval, the target's pitch and amplitude), so the check runs on
fits loaded from files too.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from ._transduction_data import p_correct_table
from .model_power import ZERO_RATE_NATS, project

#: expected separations (standard errors of the elpd difference) below this are "not identifiable"
MIN_SEPARATION = 2.0
#: predictions within this of each other (P(correct)) count as agreeing, in the reason given
AGREE_TOL = 0.01


@dataclass
class Separation:
    """Expected separation of a leader (as the truth) from a rival on a session's trials.

    ``z``: expected |elpd difference| over its standard error after the session's trials,
    ``sqrt(N) mu / sigma`` (0 when the rival fits the leader's predictions exactly);
    ``mu``, ``sigma``: one trial's log-likelihood ratio (nats); ``n_agree`` of ``n_stimuli``
    distinct stimuli get the same P(correct) within :data:`AGREE_TOL`; ``reason``: one sentence.
    """

    z: float
    mu: float
    sigma: float
    n_agree: int
    n_stimuli: int
    reason: str

    @property
    def identifiable(self) -> bool:
        return self.z >= MIN_SEPARATION


def _needs(tree, name):
    if "constant_data" not in getattr(tree, "children", {}) or "map_estimate" not in tree.attrs:
        raise ValueError(f"fits: {name!r} has no per-trial statistics (constant_data) or map_estimate; refit it with "
                         "fit_transduction of this version, which stores them for the identifiability check")
    c = tree["constant_data"]
    return (np.asarray(c["statistic_target"].values, float), np.asarray(c["statistic_other"].values, float),
            np.asarray(c["pitch_m"].values, float), json.loads(tree.attrs["map_estimate"]))


def separation(leader, rival, *, names=("leader", "rival")) -> Separation:
    """:class:`Separation` of two fits' trees (DataTrees of :func:`~.models.fit_transduction`,
    fitted to the same trials in the same order)."""
    a1, a2, pitch, params = _needs(leader, names[0])
    b1, b2, _, _ = _needs(rival, names[1])
    if a1.shape != b1.shape:
        raise ValueError(f"fits: {names[0]!r} and {names[1]!r} were fitted to different trials ({a1.size} and "
                         f"{b1.size}); compare fits to the same trials")
    task = str(leader.attrs.get("task", "2ifc"))
    rows, first, counts = np.unique(np.column_stack([a1, a2, b1, b2]), axis=0, return_index=True, return_counts=True)
    w = counts / counts.sum()
    theta = np.array(list(params.values()), dtype=float)[None]
    p = p_correct_table(task, rows[:, 0], rows[:, 1], theta)[0]
    mu, sigma, rival_theta, _ = project(task, p, rows[:, 2], rows[:, 3], w)
    q = p_correct_table(task, rows[:, 2], rows[:, 3], rival_theta[None])[0]
    n = int(counts.sum())
    z = 0.0 if mu <= ZERO_RATE_NATS or sigma <= 0 else math.sqrt(n) * mu / sigma
    agree = np.abs(p - q) <= AGREE_TOL
    pitches = sorted({round(float(v) * 1e3, 4) for v in pitch[first[agree]]})
    where = ", ".join(f"{v:g}" for v in pitches)
    if z >= MIN_SEPARATION:
        reason = (f"expected separation {z:.3g} standard errors on these {n} trials: the design can tell them apart")
    else:
        same = (f"predicts the same P(correct) within {AGREE_TOL:g} on {int(agree.sum())} of {agree.size} stimuli "
                f"(pitch {where} mm)" if agree.any() else "differs on every stimulus by too little for these trials")
        reason = (f"expected separation {z:.3g} < {MIN_SEPARATION:g} standard errors on these {n} trials: at "
                  f"{names[0]}'s fitted parameters, {names[1]} {same}; add stimuli where they differ "
                  "(see `tactilab experiment power` or the model_discrimination procedure)")
    return Separation(z, mu, sigma, int(agree.sum()), int(agree.size), reason)

"""Per-observation log-likelihood terms made ready for Pareto-smoothed LOO (``arviz_stats.loo``).

PSIS-LOO fits a generalised Pareto tail to the largest ``M = ceil(min(0.2 S, 3 sqrt(S)))`` of the
``S`` importance ratios ``-log p(d_i | theta_s)`` of every observation ``i``; it fails ("All tail
values are the same") when those are tied. Two kinds of observation do that:

- an observation whose term is the same in every draw (a sensor sample the signal never reaches):
  it carries no information about the parameters and is DROPPED; the mean of the dropped terms'
  sum is kept, so ``sum(kept terms) + dropped_total`` is still the total log-likelihood;
- an observation whose term is the same in most draws but not all (the signal reaches it only in
  some draws, e.g. a defect at the contact's edge): it is informative, so where the model names
  observation groups (``observation_groups``, one label per observation, e.g. the sensor channel)
  the tied observations of a group are MERGED into one (terms summed); without groups, or where a
  merged term is still tied, they are dropped and listed.

Every decision is stated in the returned attrs.
"""

from __future__ import annotations

import numpy as np

__all__ = ["loo_ready"]


def _tail_tied(ll: np.ndarray) -> np.ndarray:
    """Per column of ``ll`` (S, n): True where the M smallest terms (largest ratios) are all equal."""
    s = ll.shape[0]
    m = max(2, int(np.ceil(min(0.2 * s, 3 * np.sqrt(s)))))
    tail = np.sort(ll, axis=0)[:m]
    return np.ptp(tail, axis=0) <= 1e-12 * (1.0 + np.abs(tail[0]))


def loo_ready(pointwise: np.ndarray, info_tol: float, groups=None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Drop uninformative observations; merge tail-tied ones per group, or drop them (module docstring).

    Parameters
    ----------
    pointwise : ndarray, shape (n_draws, n_obs)
        Per-observation log-likelihood terms, nats.
    info_tol : float
        An observation whose term spans less than this over all draws is uninformative.
    groups : array_like, shape (n_obs,), optional
        Group label of every observation (the model's ``observation_groups``).

    Returns
    -------
    ll : ndarray, shape (n_draws, n_kept)
        Terms of the kept observations, then one summed term per group of merged observations.
    labels : ndarray of str, shape (n_kept,)
        ``"<index>"`` for a kept observation, ``"group <label>: <i>+<j>+..."`` for a merged one.
    attrs : dict
        ``log_likelihood_dropped`` (indices), ``log_likelihood_dropped_total`` (nats, the mean over
        draws of the dropped terms' sum) and ``log_likelihood_note``.
    """
    n_obs = pointwise.shape[1]
    span = np.ptp(pointwise, axis=0)
    constant = np.isfinite(span) & (span < info_tol)
    tied = _tail_tied(pointwise) & ~constant
    keep = ~constant & ~tied
    columns = [pointwise[:, keep]]
    labels = [str(i) for i in np.flatnonzero(keep)]
    dropped = list(np.flatnonzero(constant))
    notes = []
    if constant.any():
        notes.append(f"{int(constant.sum())} of {n_obs} observations dropped: their term spans < {info_tol:g} nats "
                     "over all draws (no information; the mean of their sum is log_likelihood_dropped_total)")
    if tied.any():
        if groups is not None:
            groups = np.asarray(groups)
            if groups.shape != (n_obs,):
                raise ValueError(f"model.observation_groups: expected one label per observation, shape ({n_obs},), "
                                 f"got {groups.shape}")
            merged_notes, still = [], []
            for g in np.unique(groups[tied]):
                members = np.flatnonzero(tied & (groups == g))
                term = pointwise[:, members].sum(axis=1)
                if members.size > 1 and not _tail_tied(term[:, None])[0]:
                    columns.append(term[:, None])
                    labels.append(f"group {g}: " + "+".join(map(str, members)))
                    merged_notes.append(f"{members.size} in group {g}")
                else:
                    still.extend(members.tolist())
            if merged_notes:
                notes.append("observations informative in only some draws (tied PSIS tails) merged within their "
                             "group, terms summed: " + ", ".join(merged_notes))
            tied_left = np.array(still, dtype=int)
        else:
            tied_left = np.flatnonzero(tied)
        if tied_left.size:
            dropped.extend(tied_left.tolist())
            notes.append(f"{tied_left.size} observations dropped: informative in only some draws, their PSIS tail is "
                         "tied" + ("" if groups is not None else " (name observation_groups on the model to merge "
                                   "them instead)"))
    dropped = np.array(sorted(dropped), dtype=int)
    attrs = {"log_likelihood_dropped": ", ".join(map(str, dropped.tolist())),
             "log_likelihood_dropped_total": float(np.mean(pointwise[:, dropped].sum(axis=1))) if dropped.size else 0.0,
             "log_likelihood_note": "; ".join(notes) if notes else "every observation kept"}
    return np.column_stack(columns), np.array(labels), attrs

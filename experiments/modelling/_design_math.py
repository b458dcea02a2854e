"""The mathematics of :mod:`tactilab.experiments.modelling.design`: the exact expected information of one
binary response (:func:`information_gain`; with ``utility="odds"`` the expected increase of the
true model's log posterior odds) and the up-front metamerism check (:func:`metameric_groups`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["information_gain", "metameric_groups"]


def _entropy(p: np.ndarray) -> np.ndarray:
    """Binary entropy in nats (0 at p = 0 or 1)."""
    p = np.clip(p, 1e-15, 1 - 1e-15)
    return -(p * np.log(p) + (1 - p) * np.log1p(-p))


def _kl(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """KL divergence (nats) between Bernoulli(p) and Bernoulli(q), elementwise (clipped like :func:`_entropy`)."""
    p, q = np.clip(p, 1e-15, 1 - 1e-15), np.clip(q, 1e-15, 1 - 1e-15)
    return p * np.log(p / q) + (1 - p) * np.log((1 - p) / (1 - q))


def _odds_gain(p: np.ndarray, pi: np.ndarray) -> np.ndarray:
    """sum_i pi_i KL(p_i || sum_{j != i} pi_j p_j / (1 - pi_i)): the expected increase of the true
    model's log posterior odds (p: (C, M) predictive P(correct), pi: (M,) model probabilities)."""
    others = (1.0 - np.eye(pi.size)) * pi[None, :]  # row i: pi_j for j != i
    rest = others.sum(axis=1)
    live = (pi > 0) & (rest > 0)  # a model alone (or absent) has no odds to gain
    if not np.any(live):
        return np.zeros(p.shape[0])
    mix = p @ others[live].T / rest[live]  # (C, live models): the rivals' pooled prediction
    return _kl(p[:, live], mix) @ pi[live]


def information_gain(table: np.ndarray, weights: np.ndarray, utility: str = "model",
                     entropy_table: np.ndarray | None = None, groups: np.ndarray | None = None) -> np.ndarray:
    """Expected information (nats) of one binary response per candidate.

    Parameters
    ----------
    table : ndarray, shape (n_candidates, n_models, n_grid)
        P(correct | candidate, model, grid point).
    weights : ndarray, shape (n_models, n_grid)
        Joint posterior probabilities (sum 1).
    utility : {"odds", "model", "parameters", "both"}
        ``"odds"``: the expected increase, after the response, of the log posterior odds
        log(pi_m / (1 - pi_m)) of the model m that generates it, m drawn from the posterior:
        sum_m pi_m KL(p_mc || sum_{j != m} pi_j p_jc / (1 - pi_m)) (the extrinsic Jensen-Shannon
        divergence of Naghshvar and Javidi 2013; the quantity a stop at a posterior probability
        thresholds). ``"model"``, ``"parameters"``, ``"both"``: I(Y; m), I(Y; theta | m), I(Y; m, theta).
    entropy_table : ndarray, optional
        ``H(table)`` (precomputed; needed only for "parameters" and "both").
    groups : ndarray of int, shape (n_models,), optional
        Metameric group of each model: the "model" term is then I(Y; group) (and "odds" the odds
        of the true group), about the question the candidates CAN answer (default: every model
        its own group).

    Returns
    -------
    ndarray, shape (n_candidates,)
    """
    pi = weights.sum(axis=1)  # (M,)
    cond = weights / np.where(pi > 0, pi, 1.0)[:, None]
    p_m = np.einsum("cmg,mg->cm", table, cond)  # predictive P(correct) per model
    h_m = _entropy(p_m)
    out = np.zeros(table.shape[0])
    if utility == "odds":
        if groups is None:
            return np.maximum(_odds_gain(p_m, pi), 0.0)
        onehot = (np.asarray(groups)[:, None] == np.unique(groups)[None, :]).astype(float)  # (M, n_groups)
        pg = onehot.T @ pi
        return np.maximum(_odds_gain((p_m * pi) @ onehot / np.where(pg > 0, pg, 1.0), pg), 0.0)
    if utility in ("model", "both"):
        if groups is None:
            out += _entropy(p_m @ pi) - h_m @ pi
        else:
            onehot = (np.asarray(groups)[:, None] == np.unique(groups)[None, :]).astype(float)  # (M, n_groups)
            pg = onehot.T @ pi
            p_g = (p_m * pi) @ onehot / np.where(pg > 0, pg, 1.0)
            out += _entropy(p_g @ pg) - _entropy(p_g) @ pg
    if utility in ("parameters", "both"):
        h = entropy_table if entropy_table is not None else _entropy(table)
        out += (h_m - np.einsum("cmg,mg->cm", h, cond)) @ pi
    return np.maximum(out, 0.0)


def metameric_groups(stats: np.ndarray, names: Sequence[str], rtol: float = 1e-6) -> list[tuple[str, ...]]:
    """Groups of models whose statistics are related by s_i = k s_j^a (a > 0) over every candidate.

    ``stats``: shape (n_models, n_candidates, n_intervals), readout units. Two models are
    metameric when their zero statistics coincide and log s_i is an increasing affine function
    of log s_j on the rest (within ``rtol``): a free threshold and exponent then make their
    predictions identical, so no data on these candidates can tell them apart. Returns every
    group (singletons included), in model order.
    """
    m = stats.shape[0]
    flat = stats.reshape(m, -1)
    parent = list(range(m))

    def root(i):
        while parent[i] != i:
            i = parent[i]
        return i

    for i in range(m):
        for j in range(i + 1, m):
            zi, zj = flat[i] > 0, flat[j] > 0
            if not np.array_equal(zi, zj):
                continue
            x, y = np.log(flat[j][zj]), np.log(flat[i][zi])
            if np.ptp(x) <= rtol:  # one distinct value: any rival fits it exactly
                same = np.ptp(y) <= rtol
            else:
                a, b = np.polyfit(x, y, 1)
                same = a > 0 and np.max(np.abs(a * x + b - y)) <= rtol * max(1.0, np.max(np.abs(y)))
            if same:
                parent[root(j)] = root(i)
    groups: dict[int, list[str]] = {}
    for i in range(m):
        groups.setdefault(root(i), []).append(names[i])
    return [tuple(g) for g in groups.values()]

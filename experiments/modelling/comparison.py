"""PSIS-LOO comparison of fitted transduction models, with a verdict only where the design supports one.

The verdicts (one vocabulary for :func:`compare_models`, ``compare_many``, the CLI's table and
JSON and ``compare.png``), per row of the table:

- ``best``: the leader (highest elpd among converged fits), identifiable from the runner-up on
  this design and ahead of it by z >= 2;
- ``worse`` (z > 4), ``weakly worse`` (2 <= z <= 4), ``indistinguishable`` (z < 2): a converged
  rival identifiable from the leader on this design, by its z against the leader (the leader
  too is ``indistinguishable`` when the runner-up is);
- ``not identifiable on this design``: the expected separation of the two models on the
  session's own stimuli (:mod:`.identifiability`) is below 2 standard errors, so no data from
  this design could decide between them; the leader gets it too when its runner-up does;
- ``no verdict: fit not converged``: the fit did not converge (its elpd is not trusted);
- ``no verdict: no converged rival``: the leader, when no other fit converged.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from .identifiability import MIN_SEPARATION, separation

BEST, WORSE, WEAK, TIE = "best", "worse", "weakly worse", "indistinguishable"
NOT_IDENTIFIABLE = "not identifiable on this design"
NOT_CONVERGED = "no verdict: fit not converged"
NO_RIVAL = "no verdict: no converged rival"
#: every verdict compare_models gives
VERDICTS = (BEST, WORSE, WEAK, TIE, NOT_IDENTIFIABLE, NOT_CONVERGED, NO_RIVAL)


def elpd_mcse(tree, var_name: str = "correct") -> float:
    """Monte Carlo standard error of a fit's PSIS-LOO elpd (nats), from its chains.

    First order (delta method) in the importance ratios r_is = 1 / p(y_i | theta_s):
    elpd_loo = -sum_i log(mean_s r_is), so its Monte Carlo error is that of the posterior mean
    of the scalar g(theta_s) = sum_i r_is / mean_s(r_is): ``sd(g) / sqrt(ESS(g))``, with the
    effective sample size of g over the chains (``arviz_stats.ess``, method "mean"). The sum
    over trials is taken per draw, so errors that every trial shares (a chain's whole
    posterior slightly off) are counted, unlike in ``dse``. ``tree["log_likelihood"][var_name]``
    has shape (chain, draw, trial).
    """
    import arviz_stats as azs

    ll = np.asarray(tree["log_likelihood"][var_name].values, float)
    ll = ll.reshape(ll.shape[0], ll.shape[1], -1)
    log_r = -ll - (-ll).max(axis=(0, 1))  # scaled per trial: r / max r, no overflow
    r = np.exp(log_r)
    g = (r / r.mean(axis=(0, 1))).sum(axis=-1)  # (chain, draw)
    if np.ptp(g) == 0:
        return 0.0
    return float(np.std(g, ddof=1) / np.sqrt(azs.ess(g, method="mean")))


def _loo(tree, var_name):
    """PSIS-LOO of a fit; for a grid fit, its pointwise elpd replaced by the quadrature's exact one
    (``constant_data.elpd_loo_quadrature``; se and p recomputed from it, as arviz does)."""
    import arviz_stats as azs

    loo = azs.loo(tree, pointwise=True, var_name=var_name)
    if tree.attrs.get("method") != "grid" or "elpd_loo_quadrature" not in tree.get("constant_data", {}):
        return loo
    exact = np.asarray(tree["constant_data"]["elpd_loo_quadrature"].values, float)
    psis = float(loo.elpd)
    loo.elpd_i = loo.elpd_i.copy(data=exact.reshape(loo.elpd_i.shape))
    loo.elpd = float(exact.sum())
    loo.se = float(np.sqrt(exact.size * np.var(exact)))
    loo.p = float(tree.attrs["lppd_quadrature"]) - loo.elpd
    loo.psis_elpd = psis  # kept for the numerical error
    return loo


def _numerical_error(tree, loo, var_name):
    """Grid fits: |PSIS-LOO of the deterministic draws - the quadrature's exact LOO| (a bound on the
    quadrature's error from a second route); emcee: the MCSE."""
    if hasattr(loo, "psis_elpd"):
        return abs(loo.psis_elpd - float(loo.elpd))
    return elpd_mcse(tree, var_name)


def _advice(tree) -> str:
    if tree.attrs.get("method") == "grid":
        return ("the grid posterior leaves its box or sits in one cell (edge mass "
                f"{float(tree.attrs.get('edge_mass', math.nan)):.2g}); check the trials and priors, or refit with "
                "method='emcee' (--method emcee)")
    return "the emcee ensembles did not converge; refit with more steps (--max-steps) or with method='grid'"


def compare_models(fits: Mapping, *, var_name: str = "correct", reference: str | None = None):
    """PSIS-LOO comparison (arviz_stats), leader first, with z, identifiability and a verdict.

    Parameters
    ----------
    fits : mapping name -> TransductionFit or DataTree
        At least two fits of the same trials (from :func:`~.models.fit_transduction`; a DataTree
        needs its ``constant_data`` and root attrs ``map_estimate`` and ``converged``).
    var_name : str
        The per-trial log-likelihood variable.
    reference : str, optional
        The leader (default: the converged fit with the highest elpd).

    Returns
    -------
    pandas.DataFrame
        Indexed by model name, the leader first, then the converged rivals by elpd, then the fits
        that did not converge: arviz's columns (``elpd``, ``elpd_diff`` against the leader
        (negative for a worse model), ``dse``, ``se``, ``p``, ``weight``) unrounded (a grid fit's
        elpd is the quadrature's exact leave-one-out elpd, pointwise), ``rank`` (the row),
        ``mcse`` (the elpd's numerical error: Monte Carlo, :func:`elpd_mcse`, for emcee;
        |PSIS-LOO of the draws - exact quadrature LOO| for the grid), ``mcse_diff`` (0 for the leader), ``z`` =
        |elpd_diff| / sqrt(dse^2 + mcse_diff^2), ``pareto_k_max``, ``converged``, ``separation``
        (expected separation from the leader on this design, in standard errors; the leader's
        is from its runner-up; NaN where not computed), ``identifiable``, ``verdict`` (one of
        :data:`VERDICTS`) and ``reason`` (why, and what to do).
    """
    import arviz_stats as azs

    from .models import TransductionFit

    if not isinstance(fits, Mapping) or len(fits) < 2:
        raise ValueError("fits: give a mapping of at least two model names to TransductionFit or DataTree")
    trees = {name: (f.tree if isinstance(f, TransductionFit) else f) for name, f in fits.items()}
    sizes = {}
    for name, tree in trees.items():
        if "log_likelihood" not in getattr(tree, "children", {}) or var_name not in tree["log_likelihood"]:
            raise ValueError(f"fits: {name!r} has no log_likelihood variable {var_name!r}; fit it with "
                             "fit_transduction (it stores one term per trial)")
        sizes[name] = tree["log_likelihood"][var_name].shape[-1]
    if len(set(sizes.values())) != 1:
        raise ValueError(f"fits: the models were fitted to different numbers of trials {sizes}; compare fits to "
                         "the same trials")
    if reference is not None and reference not in trees:
        raise ValueError(f"reference: must be one of {sorted(trees)}, got {reference!r}")
    converged = {name: (f.converged if isinstance(f, TransductionFit) else bool(trees[name].attrs.get("converged", 1)))
                 for name, f in fits.items()}
    elpds = {name: _loo(tree, var_name) for name, tree in trees.items()}
    by_elpd = sorted(trees, key=lambda n: -float(elpds[n].elpd))
    ok = [n for n in by_elpd if converged[n]]
    leader = reference if reference is not None else (ok[0] if ok else by_elpd[0])
    order = [leader] + [n for n in ok if n != leader] + [n for n in by_elpd if n not in ok and n != leader]
    table = azs.compare(elpds, reference=leader, round_to="none").loc[order]
    table["rank"] = range(len(order))
    mcse = {name: _numerical_error(trees[name], elpds[name], var_name) for name in order}
    table["mcse"] = [mcse[name] for name in order]
    table["mcse_diff"] = [0.0 if name == leader else math.hypot(mcse[leader], mcse[name]) for name in order]
    diff = table["elpd_diff"].to_numpy(float)
    sigma = np.hypot(table["dse"].to_numpy(float), table["mcse_diff"].to_numpy(float))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(sigma > 0, np.abs(diff) / sigma, np.where(np.abs(diff) < 1e-9, 0.0, np.inf))
    table["z"] = z
    table["pareto_k_max"] = [float(np.max(elpds[name].pareto_k)) for name in order]
    table["converged"] = [converged[name] for name in order]
    seps = {name: separation(trees[leader], trees[name], names=(leader, name))
            for name in order[1:] if converged[name] and converged[leader]}
    rivals = [n for n in order[1:] if n in seps]
    verdict, reason, sep = {}, {}, {}
    for name, s in seps.items():
        sep[name] = s.z
        zj = float(table.loc[name, "z"])
        verdict[name] = (NOT_IDENTIFIABLE if not s.identifiable else WORSE if zj > 4 else WEAK if zj >= 2 else TIE)
        reason[name] = s.reason
    for name in order:
        if not converged[name]:
            verdict[name], reason[name] = NOT_CONVERGED, _advice(trees[name])
        elif name not in verdict:  # a converged rival of a reference that did not converge
            verdict[name], reason[name] = NO_RIVAL, f"the reference {leader} did not converge: no comparison"
    if converged[leader]:
        if not rivals:
            verdict[leader], reason[leader] = NO_RIVAL, "no other fit converged: nothing to compare the leader with"
        else:
            runner = rivals[0]
            sep[leader] = sep[runner]
            verdict[leader] = {NOT_IDENTIFIABLE: NOT_IDENTIFIABLE, TIE: TIE}.get(verdict[runner], BEST)
            reason[leader] = f"against the runner-up {runner}: " + reason[runner]
    table["separation"] = [sep.get(name, math.nan) for name in order]
    table["identifiable"] = [bool(sep.get(name, 0.0) >= MIN_SEPARATION) for name in order]
    table["verdict"] = [verdict[name] for name in order]
    table["reason"] = [reason[name] for name in order]
    return table

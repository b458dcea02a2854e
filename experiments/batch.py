"""Batch sweeps of the experiments part on the generic batch layer: power over (seed, N), design tables.

Both run through :func:`tactilab.data_schemas.batch.run_batch`: serial with ``workers=0``, on a
LocalCluster or a running Dask scheduler otherwise; one result file per key in ``out_dir``;
a rerun with the same ``out_dir`` resumes; a failing point goes into ``errors.tsv``.

- :func:`power_sweep`: simulated power of telling two transduction models apart
  (:func:`~.model_power.power_analysis`, ``method="simulate"``) for every (seed, number of
  trials N); the seed index and N form the key, so each point's simulated experiments come
  from ``SeedSequence(seed, spawn_key=(stable_hash(key),))`` whatever the worker count.
- :func:`design_sweep`: the synthesis design table (:func:`tactilab.forward.design_table`) over
  (depth, window width, number of pairs), one task per design point.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from tactilab.data_schemas.batch import read_result, run_batch

from .model_power import power_analysis

__all__ = ["power_sweep", "design_sweep"]


def _power_point(item, rng, *, true_model, true_params, rival, design, task, n_repeats, z):
    import xarray as xr

    res = power_analysis(true_model, true_params, rival, design, task=task, method="simulate",
                         n_repeats=n_repeats, rng=rng)
    return xr.Dataset({"p_select": res.p_select(item["n"], z=z)}, attrs={"mu_nats": res.mu, "sigma_nats": res.sigma})


def _check_counts(values, name: str, minimum: int) -> list[int]:
    out = [int(v) for v in np.atleast_1d(values)]
    if not out or any(o != v or o < minimum for o, v in zip(out, np.atleast_1d(values))):
        raise ValueError(f"{name}: need whole numbers >= {minimum}, got {values!r}")
    return out


def power_sweep(true_model, true_params: dict, rival, design, n_trials: Sequence[int], *, n_seeds: int, seed: int,
                out_dir, task: str = "2ifc", n_repeats: int = 100, z: float = 4.0, client=None,
                workers: int | None = None, scheduler: str | None = None, per_task: int = 1, progress: bool = True,
                echo: Callable[[str], None] = print):
    """Simulated power over (seed, N): P(truth beats rival by > z standard errors after N trials).

    Parameters
    ----------
    true_model, rival : TransductionModel
    true_params : dict
        As in :func:`~.model_power.power_analysis`.
    design : list of (Stimulus, n_trials)
        Design proportions (scaled to each N).
    n_trials : sequence of int
        Numbers of trials N (each >= 1).
    n_seeds : int
        Independent replicate power estimates per N (each from ``n_repeats`` simulated experiments).
    seed : int
        Batch seed; the point with key ``seed-SSSS/n-N`` uses ``task_rng(seed, key)``.
    out_dir : path
        Output folder (resumable).
    task, n_repeats, z
        As in :func:`~.model_power.power_analysis` and ``PowerResult.p_select``.
    client, workers, scheduler, per_task, progress
        Where and how to run: see :func:`tactilab.data_schemas.batch.run_batch`.

    Returns
    -------
    xarray.Dataset
        ``p_select`` (seed, n_trials), NaN for a failed point (listed in ``errors.tsv`` and in
        ``attrs["failed"]``); ``p_select_mean`` (n_trials) over the seeds that ran; ``p_asymptotic``
        (n_trials) from the asymptotic formula; attrs ``mu_nats``, ``sigma_nats``, ``n_run``,
        ``n_skipped``, ``n_failed``.
    """
    import xarray as xr

    ns = _check_counts(n_trials, "n_trials", 1)
    (n_seeds,) = _check_counts(n_seeds, "n_seeds", 1)
    asym = power_analysis(true_model, true_params, rival, design, task=task)  # validates every argument once
    items = {f"seed-{s:04d}/n-{n}": {"seed_index": s, "n": n} for s in range(n_seeds) for n in ns}
    shared = dict(true_model=true_model, true_params=dict(true_params), rival=rival, design=list(design), task=task,
                  n_repeats=int(n_repeats), z=float(z))
    rep = run_batch(_power_point, items, seed=seed, out_dir=out_dir, client=client, workers=workers,
                    scheduler=scheduler, shared=shared, per_task=per_task, progress=progress, echo=echo)
    grid = np.full((n_seeds, len(ns)), np.nan)
    for key in rep.done:
        grid[items[key]["seed_index"], ns.index(items[key]["n"])] = float(read_result(out_dir, key)["p_select"])
    ok = ~np.isnan(grid)
    mean = np.array([grid[ok[:, j], j].mean() if ok[:, j].any() else np.nan for j in range(len(ns))])
    return xr.Dataset(
        {"p_select": (("seed", "n_trials"), grid), "p_select_mean": ("n_trials", mean),
         "p_asymptotic": ("n_trials", [asym.p_select(n, z=z) for n in ns])},
        coords={"seed": np.arange(n_seeds), "n_trials": ns},
        attrs=dict(mu_nats=asym.mu, sigma_nats=asym.sigma, z=float(z), n_repeats=int(n_repeats), seed=int(seed),
                   n_run=rep.n_run, n_skipped=rep.n_skipped, n_failed=rep.n_failed, failed=";".join(rep.errors)))


def _design_point(item, rng):
    import xarray as xr

    from tactilab.forward import design_table

    row = design_table([item["depth"]], [item["width"]], [item["pairs"]]).iloc[0]
    return xr.Dataset({k: float(v) for k, v in row.items()})


def design_sweep(depths, widths, pairs_list, *, out_dir, seed: int = 0, client=None, workers: int | None = None,
                 scheduler: str | None = None, per_task: int = 1, progress: bool = True,
                 echo: Callable[[str], None] = print):
    """The synthesis design table over (depth, width, pairs), one batch task per design point.

    Parameters
    ----------
    depths, widths : sequence of float
        Receptor depths and window widths, m (each > 0).
    pairs_list : sequence of int
        Numbers of tractor pairs.
    out_dir : path
        Output folder (resumable).
    seed : int
        Batch seed (the design points are deterministic; kept for the file attributes).
    client, workers, scheduler, per_task, progress
        See :func:`tactilab.data_schemas.batch.run_batch`.

    Returns
    -------
    xarray.Dataset
        The columns of :func:`tactilab.forward.design_table` (``d_m``, ``pitch_m``, ...) as
        variables over (depth, width, pairs), SI units; NaN where a point failed (see
        ``attrs["failed"]`` and ``errors.tsv``).
    """
    import xarray as xr

    zs, ws = [float(v) for v in np.atleast_1d(depths)], [float(v) for v in np.atleast_1d(widths)]
    for name, vals in (("depths", zs), ("widths", ws)):
        if not vals or not all(np.isfinite(v) and v > 0 for v in vals):
            raise ValueError(f"{name}: need finite values > 0 in m, got {vals!r}; e.g. [1e-3, 2e-3]")
    ps = _check_counts(pairs_list, "pairs_list", 1)
    items = {f"depth={z!r}m/width={w!r}m/pairs={n}": {"depth": z, "width": w, "pairs": n, "at": (i, j, k)}
             for i, z in enumerate(zs) for j, w in enumerate(ws) for k, n in enumerate(ps)}
    rep = run_batch(_design_point, items, seed=seed, out_dir=out_dir, client=client, workers=workers,
                    scheduler=scheduler, per_task=per_task, progress=progress, echo=echo)
    data: dict[str, np.ndarray] = {}
    for key in rep.done:
        ds = read_result(out_dir, key).to_dataset()
        for name in ds.data_vars:
            if name in ("depth_m", "width_m", "pairs"):
                continue
            data.setdefault(name, np.full((len(zs), len(ws), len(ps)), np.nan))[items[key]["at"]] = float(ds[name])
    return xr.Dataset({k: (("depth", "width", "pairs"), v) for k, v in data.items()},
                      coords={"depth": ("depth", zs, {"units": "m"}), "width": ("width", ws, {"units": "m"}),
                              "pairs": ps},
                      attrs=dict(n_run=rep.n_run, n_skipped=rep.n_skipped, n_failed=rep.n_failed,
                                 failed=";".join(rep.errors)))

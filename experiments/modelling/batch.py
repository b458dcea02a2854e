"""Batch jobs of the experiments part on the generic batch layer: model fits per subject, power, design tables.

All run through :func:`tactilab.core.batch.run_batch`: serial with ``workers=0``, on a
LocalCluster or a running Dask scheduler otherwise; one result file per key in ``out_dir``;
a rerun with the same ``out_dir`` resumes; a failing point goes into ``errors.tsv``.

- :func:`power_sweep`: simulated power of telling two transduction models apart
  (:func:`~.model_power.power_analysis`, ``method="simulate"``) for every (seed, number of
  trials N); the seed index and N form the key, so each point's simulated experiments come
  from ``SeedSequence(seed, spawn_key=(stable_hash(key),))`` whatever the worker count.
- :func:`design_sweep`: the synthesis design table (:func:`tactilab.forward.design_table`) over
  (depth, window width, number of pairs), one task per design point.
- :func:`compare_many`: transduction fits (:func:`~.models.fit_transduction`) of every model to
  every subject's sessions, one task per (subject, model) with the key ``<subject>/<model name>``,
  then one PSIS-LOO comparison (:func:`~.models.compare_models`) per subject, gathered into a
  table over (subject, model); :func:`sessions_by_subject` groups session files by the subject
  code they recorded.
"""

from __future__ import annotations

import pathlib
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from tactilab.core.batch import batch_client, read_result, result_path, run_batch, write_netcdf_atomic
from tactilab.core.memory import check_count
from tactilab.core.netcdf import cf_ready

from .model_power import REPEAT_BYTES, power_analysis

__all__ = ["power_sweep", "design_sweep", "compare_many", "sessions_by_subject"]


def _power_point(item, rng, *, true_model, true_params, rival, design, task, n_repeats, z):
    import xarray as xr

    res = power_analysis(true_model, true_params, rival, design, task=task, method="simulate",
                         n_repeats=n_repeats, rng=rng)
    return xr.Dataset({"p_select": ((), res.p_select(item["n"], z=z),
                                    {"units": "1", "long_name": "probability that the true model is selected"})},
                      attrs={"mu_nats": res.mu, "sigma_nats": res.sigma})


#: bytes of bookkeeping per batch point of :func:`power_sweep` (its key, its item, its cell of the table)
POINT_BYTES = 1024


def _check_counts(values, name: str, minimum: int) -> list[int]:
    out = [int(v) for v in np.atleast_1d(values)]
    if not out or any(o != v or o < minimum for o, v in zip(out, np.atleast_1d(values))):
        raise ValueError(f"{name}: need whole numbers >= {minimum}, got {values!r}")
    return out


def check_power_sweep(n_trials, n_seeds, n_repeats) -> tuple[list[int], int, int]:
    """The sweep's sizes, checked before any point runs: whole numbers >= 1 within the memory rule
    (one batch point per seed and trial count, one z value per simulated experiment).

    Returns
    -------
    n_trials : list of int
    n_seeds, n_repeats : int
    """
    ns = _check_counts(n_trials, "n_trials", 1)
    (seeds,) = _check_counts(n_seeds, "n_seeds", 1)
    (repeats,) = _check_counts(n_repeats, "n_repeats", 1)
    check_count(seeds, POINT_BYTES * len(ns), "n_seeds", f"seeds ({len(ns)} trial count(s), about "
                                                         f"{POINT_BYTES} bytes of batch bookkeeping each)")
    check_count(repeats, REPEAT_BYTES, "n_repeats", "simulated experiments (a z value each)")
    return ns, seeds, repeats


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
        Where and how to run: see :func:`tactilab.core.batch.run_batch`.

    Returns
    -------
    xarray.Dataset
        ``p_select`` (seed, n_trials), NaN for a failed point (listed in ``errors.tsv`` and in
        ``attrs["failed"]``); ``p_select_mean`` (n_trials) over the seeds that ran; ``p_asymptotic``
        (n_trials) from the asymptotic formula; attrs ``mu_nats``, ``sigma_nats``, ``n_run``,
        ``n_skipped``, ``n_failed``.
    """
    import xarray as xr

    ns, n_seeds, _ = check_power_sweep(n_trials, n_seeds, n_repeats)
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
        See :func:`tactilab.core.batch.run_batch`.

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


# ----------------------------------------------------------------------------- model fits per subject
#: variables of the gathered comparison table (arviz_stats.compare's columns and compare_models' additions)
COMPARE_COLUMNS = ("rank", "elpd", "p", "elpd_diff", "weight", "se", "dse", "mcse", "mcse_diff", "z", "pareto_k_max",
                   "separation")


def sessions_by_subject(paths) -> dict[str, list[str]]:
    """Session files grouped by the subject code each recorded: subject -> absolute paths, sorted.

    Parameters
    ----------
    paths : sequence of path
        Session ``.sqlite`` files (any subjects, any order).
    """
    from ..session import session_header

    out: dict[str, list[str]] = {}
    for path in paths:
        if not pathlib.Path(path).is_file():
            raise ValueError(f"sessions: no session file at {str(path)!r}")
        out.setdefault(str(session_header(path).meta["subject"]), []).append(str(pathlib.Path(path).resolve()))
    if not out:
        raise ValueError("sessions: empty; give at least one session .sqlite file")
    return {k: sorted(v) for k, v in sorted(out.items())}


def _fit_point(item, rng, *, models, options):
    """One task: fit one model to one subject's trials -> the fit's DataTree plus a ``summary`` group."""
    import xarray as xr

    from .models import fit_transduction

    fit = fit_transduction(models[item["model"]], item["trials"], rng=rng, **options)
    tree = fit.tree.copy()
    for group in tree.children:
        tree[group].attrs = {}  # arviz stamps the creation time: keep the file a function of the inputs only
    names = list(fit.params)
    summary = xr.Dataset({stat: ("parameter", [getattr(fit.params[n], stat) for n in names])
                          for stat in ("map", "mean", "median")} |
                         {"lower": ("parameter", [fit.params[n].ci95[0] for n in names]),
                          "upper": ("parameter", [fit.params[n].ci95[1] for n in names])},
                         coords={"parameter": names},
                         attrs={"units": "threshold_strain in strain (dimensionless); exponent, lapse, false_alarm "
                                         "dimensionless", "interval": "2.5 % and 97.5 % posterior quantiles"})
    for name in summary.data_vars:  # every transduction parameter is dimensionless (strain, exponent, rates)
        summary[name].attrs.update(units="1")
    tree["summary"] = xr.DataTree(summary)
    tree.attrs.update(subject=item["subject"], model=item["model"], converged=int(fit.converged))
    return tree


def _compare_subject(paths: dict[str, str]):
    """Compare the finished fits of one subject (model -> result file); run where the files are."""
    import warnings

    import xarray as xr

    from .comparison import compare_models

    trees = {m: xr.open_datatree(p, engine="h5netcdf").load() for m, p in paths.items()}
    summaries = {m: t["summary"].to_dataset() for m, t in trees.items()}
    converged = {m: bool(t.attrs["converged"]) for m, t in trees.items()}
    if len(trees) < 2:
        return None, summaries, converged, []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        table = compare_models(trees)
    return table, summaries, converged, sorted({" ".join(str(w.message).split())[:200] for w in caught})


def compare_many(subjects: Mapping, models: Sequence, *, seed: int, out_dir, statistic: str = "peak",
                 method: str = "grid", n_ensembles: int = 4, sampler_options: Mapping | None = None, client=None,
                 workers: int | None = None, scheduler: str | None = None, per_task: int = 1, progress: bool = True,
                 echo: Callable[[str], None] = print):
    """Fit every transduction model to every subject's trials and compare the models per subject.

    One batch task per (subject, model), key ``<subject>/<model name>``, seeded by
    ``SeedSequence(seed, spawn_key=(stable_hash(key),))``: a fit does not depend on the worker
    count, the order or the other subjects. Each fit is ``<out_dir>/results/<key>.nc`` (its
    DataTree: ``posterior``, ``log_likelihood``, ``observed_data``, ``sample_stats`` and a
    ``summary`` group); a rerun with the same ``out_dir`` resumes; a failing fit goes into
    ``errors.tsv``. The PSIS-LOO comparison of each subject then runs where the files are (on the
    workers when there are any).

    Parameters
    ----------
    subjects : mapping of str to trials
        Subject code -> what :func:`~.models.fit_transduction` takes: session ``.sqlite`` path(s),
        a list of TrialRecord or a DataFrame (see :func:`sessions_by_subject`).
    models : sequence of str or TransductionModel
        At least two; hypothesis strings (``"zx@1mm"``) are built with ``statistic``. Names unique.
    seed : int
        Batch seed.
    out_dir : path
        Output folder (resumable): ``results/``, ``errors.tsv``, ``compare_many.nc``.
    statistic : {"peak", "rms"}
        Statistic of models given as strings.
    method, n_ensembles, sampler_options
        As in :func:`~.models.fit_transduction` (``grid``: the same fits for every seed;
        ``n_ensembles`` and ``sampler_options`` for ``emcee`` only).
    client, workers, scheduler, per_task, progress
        See :func:`tactilab.core.batch.run_batch`.

    Returns
    -------
    xarray.Dataset
        Over (subject, model): ``rank`` (0 = the leader; -1 where not compared), ``elpd``, ``p``,
        ``elpd_diff``, ``weight``, ``se``, ``dse``, ``mcse``, ``mcse_diff``, ``z``, ``pareto_k_max`` (nats, NaN where not
        compared), ``separation`` (expected separation from the leader on the subject's trials, in
        standard errors), ``verdict`` (:data:`~.comparison.VERDICTS`; ``failed`` for a fit that
        failed, ``not compared`` when fewer than two fits of a subject finished), ``reason``,
        ``converged``; over (subject, model, parameter): ``map``, ``mean``, ``median``,
        ``lower``, ``upper`` (95 %). Attrs: ``seed``, ``n_run``, ``n_skipped``, ``n_failed``,
        ``failed`` (keys, ``;``-separated), ``warnings`` (PSIS warnings, ``|``-separated).
    """
    from .models import TransductionModel

    if not isinstance(subjects, Mapping) or not subjects:
        raise ValueError("subjects: give a mapping subject code -> trials (session paths, TrialRecords or a "
                         "DataFrame), e.g. sessions_by_subject(paths)")
    built = [m if isinstance(m, TransductionModel) else TransductionModel(m, statistic=statistic) for m in models]
    names = [m.name for m in built]
    if len(built) < 2 or len(set(names)) != len(names):
        raise ValueError(f"models: give at least two different models, got {names}; e.g. ['zx@1mm', 'xx@1mm']")
    subs = [str(s) for s in subjects]
    for s in subs:
        if not s or "/" in s:
            raise ValueError(f"subjects: a subject code must be non-empty without '/', got {s!r}; e.g. 'S01'")
    items = {f"{s}/{m}": {"subject": s, "model": m, "trials": _trials(t)} for s, t in zip(subs, subjects.values())
             for m in names}
    if method not in ("grid", "emcee"):
        raise ValueError(f"method: must be 'grid' or 'emcee', got {method!r}")
    options = dict(method="grid") if method == "grid" else dict(
        method="emcee", n_ensembles=int(n_ensembles), sampler_options=dict(sampler_options or {}, progress=False))
    if method == "grid" and sampler_options:
        raise ValueError(f"sampler_options: only for method='emcee', got {dict(sampler_options)}; drop them or pass "
                         "method='emcee'")
    shared = dict(models=dict(zip(names, built)), options=options)
    with batch_client(workers, scheduler, client=client, echo=echo) as cl:
        rep = run_batch(_fit_point, items, seed=seed, out_dir=out_dir, client=cl, workers=0 if cl is None else None,
                        shared=shared, per_task=per_task, progress=progress, echo=echo)
        done = set(rep.done)
        jobs = [{m: str(result_path(out_dir, f"{s}/{m}")) for m in names if f"{s}/{m}" in done} for s in subs]
        parts = [_compare_subject(j) for j in jobs] if cl is None else cl.gather(cl.map(_compare_subject, jobs,
                                                                                         pure=False))
    return _gather_comparison(subs, names, parts, dict(
        seed=int(seed), n_run=rep.n_run, n_skipped=rep.n_skipped, n_failed=rep.n_failed, failed=";".join(rep.errors)),
        out_dir)


def _trials(trials):
    if isinstance(trials, str | pathlib.PurePath):
        return str(pathlib.Path(trials).resolve())
    if isinstance(trials, list | tuple) and trials and all(isinstance(t, str | pathlib.PurePath) for t in trials):
        return [str(pathlib.Path(t).resolve()) for t in trials]
    return trials


def _gather_comparison(subs, names, parts, attrs, out_dir):
    import xarray as xr

    shape = (len(subs), len(names))
    data = {c: np.full(shape, np.nan) for c in COMPARE_COLUMNS}
    data["rank"] = np.full(shape, -1, dtype=np.int64)
    verdict = np.full(shape, "failed", dtype=object)
    reason = np.full(shape, "", dtype=object)
    converged = np.zeros(shape, dtype=bool)
    params = sorted({p for _, summaries, _, _ in parts for s in summaries.values() for p in s["parameter"].values},
                    key=["threshold_strain", "exponent", "lapse", "false_alarm"].index)
    stats = {k: np.full(shape + (len(params),), np.nan) for k in ("map", "mean", "median", "lower", "upper")}
    notes = set()
    for i, (table, summaries, conv, warns) in enumerate(parts):
        notes.update(warns)
        for m, summary in summaries.items():
            j = names.index(m)
            converged[i, j] = conv[m]
            verdict[i, j] = "not compared"
            for k in stats:
                for p, v in zip(summary["parameter"].values, summary[k].values):
                    stats[k][i, j, params.index(p)] = v
        if table is not None:
            for m, row in table.iterrows():
                j = names.index(m)
                for c in COMPARE_COLUMNS:
                    data[c][i, j] = row[c]
                verdict[i, j] = row["verdict"]
                reason[i, j] = row["reason"]
    dims = ("subject", "model")
    ds = xr.Dataset({**{c: (dims, v) for c, v in data.items()}, "verdict": (dims, verdict.astype(str)),
                     "reason": (dims, reason.astype(str)),
                     "converged": (dims, converged),
                     **{k: (dims + ("parameter",), v) for k, v in stats.items()}},
                    coords={"subject": subs, "model": names, "parameter": params},
                    attrs={**attrs, "warnings": " | ".join(sorted(notes)),
                           "units": "elpd, elpd_diff, se, dse, mcse, mcse_diff in nats (PSIS-LOO); threshold_strain in strain"})
    for name in ds.data_vars:  # PSIS-LOO columns in nats, parameters dimensionless (strain, rates): all "1"
        if ds[name].dtype.kind in "iuf":
            ds[name].attrs.setdefault("units", "1")
    ds = cf_ready(ds)  # the table returned is the file's (CF attributes included)
    write_netcdf_atomic(ds, pathlib.Path(out_dir) / "compare_many.nc")
    return ds

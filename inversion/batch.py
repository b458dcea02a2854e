"""Invert many recordings of one defect scene: serial or on Dask, resumable, same answer on any worker count.

:func:`invert_many` runs one task per recording through the generic batch layer
(:mod:`tactilab.core.batch`): the defect position by emcee
(:func:`~.scene_inversion.invert_defect_position`, all ensembles of a recording in its task, so
the between-ensemble R-hat is computed there) and the load-density profile with its credible
band (:func:`~.scene_inversion.defect_profile`). Each recording's seed is derived from its key
(its path relative to the batch root), so results are bitwise identical for 0, 1 or N workers.
Each recording's result is ``<out_dir>/results/<key>.nc`` (a DataTree with the groups
``position``, ``profile`` and ``posterior``, the emcee draws); the gathered tree is also written
to ``<out_dir>/invert_many.nc``; the results are read back on the workers when there are any
(reading a netCDF4 group costs tens of milliseconds).
"""

from __future__ import annotations

import os
import pathlib
import time
import warnings
from collections.abc import Callable, Mapping

import numpy as np

from tactilab.core.batch import batch_client, result_path, run_batch, write_netcdf_atomic
from tactilab.core.netcdf import cf_ready
from tactilab.data_schemas.recording import Recording

from .scene_check import check_scene_recording
from .scene_inversion import defect_problem, defect_profile, invert_defect_position

__all__ = ["invert_many", "recording_keys"]

#: file suffixes read as recordings when a batch folder is given
RECORDING_SUFFIXES = (".nc", ".json", ".parquet")
#: half-width of the profile's credible band, in posterior standard deviations (95 %, Gaussian)
BAND_Z = 1.959963984540054


def recording_keys(recordings, exclude=None) -> dict[str, object]:
    """Key -> item (absolute path string or :class:`Recording`) for a batch of recordings.

    Parameters
    ----------
    recordings : path, sequence or mapping
        A folder (every ``*.nc``, ``*.json``, ``*.parquet`` below it, sorted; key = path relative
        to the folder); a sequence of file paths and/or Recording records (key of a path: its path
        relative to the deepest folder holding them all; of a record: ``recording-<index>``); or a
        mapping key -> path or Recording.
    exclude : path, optional
        Folder whose files are never taken as recordings (the batch's own output folder).
    """
    if isinstance(recordings, Mapping):
        return {str(k): (v if isinstance(v, Recording) else str(pathlib.Path(v).resolve())) for k, v in recordings.items()}
    if isinstance(recordings, str | os.PathLike):
        root = pathlib.Path(recordings).resolve()
        if not root.is_dir():
            raise ValueError(f"recordings: {str(recordings)!r} is not a folder; give a folder of recording files "
                             "(.nc, .json, .parquet), a list of paths or of Recording records")
        skip = pathlib.Path(exclude).resolve() if exclude is not None else None
        files = sorted(p for p in root.rglob("*") if p.is_file() and p.suffix in RECORDING_SUFFIXES
                       and not p.name.startswith(".") and not (skip is not None and p.is_relative_to(skip)))
        if not files:
            raise ValueError(f"recordings: no recording files ({', '.join(RECORDING_SUFFIXES)}) under {str(root)!r}")
        return {p.relative_to(root).as_posix(): str(p) for p in files}
    items = list(recordings)
    if not items:
        raise ValueError("recordings: empty; give at least one recording path or Recording record")
    paths = [pathlib.Path(r).resolve() for r in items if not isinstance(r, Recording)]
    root = pathlib.Path(os.path.commonpath([p.parent for p in paths])) if paths else None
    out = {}
    for i, r in enumerate(items):
        key = f"recording-{i:05d}" if isinstance(r, Recording) else pathlib.Path(r).resolve().relative_to(root).as_posix()
        if key in out:
            raise ValueError(f"recordings: {key!r} appears twice; give each recording once")
        out[key] = r if isinstance(r, Recording) else str(pathlib.Path(r).resolve())
    return out


def _check_scene(scene):
    from tactilab.data_schemas.files import load_scene
    from tactilab.data_schemas.scene import Scene

    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    if scene.contact is None or getattr(scene.surface, "kind", None) != "defect":
        raise ValueError("scene: the defect inversion needs a finger contact and an isolated defect surface "
                         f"(kind 'defect'), got contact {scene.contact is not None}, surface kind "
                         f"{getattr(scene.surface, 'kind', None)!r}")
    return scene


def _invert_recording(item, rng: np.random.Generator, *, scene, options: dict):
    """One task: read (if a path), defect position by emcee, profile with its band -> DataTree."""
    import xarray as xr

    from tactilab.data_schemas.recording_io import read_recording

    if not isinstance(item, Recording):  # a file records the scene that made it: it must be this one
        check_scene_recording(scene, item, sample=options["sample"], allow_mismatch=options["allow_scene_mismatch"])
    rec = item if isinstance(item, Recording) else read_recording(item)
    problem = defect_problem(scene, rec, max_data=options["max_data"])  # once, for the position and the profile
    res, info = invert_defect_position(scene, rec, rng, sample=options["sample"], problem=problem,
                                       **options["sampler"])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        post, crit, x = defect_profile(scene, rec, n_grid=options["n_grid"], criterion=options["criterion"],
                                       problem=problem)
    draws = res.tree["posterior"].to_dataset()
    names = [v for v in draws.data_vars]
    flat = {n: draws[n].values.ravel() for n in names}
    summary = res.summary
    position = xr.Dataset(
        {"mean": ("parameter", [float(np.mean(flat[n])) for n in names]),
         "sd": ("parameter", [float(np.std(flat[n], ddof=1)) for n in names]),
         "lower": ("parameter", [float(np.quantile(flat[n], 0.025)) for n in names]),
         "upper": ("parameter", [float(np.quantile(flat[n], 0.975)) for n in names]),
         "r_hat": ("parameter", [float(summary.loc[n, "r_hat"]) for n in names]),
         "ess_bulk": ("parameter", [float(summary.loc[n, "ess_bulk"]) for n in names])},
        coords={"parameter": names, "parameter_units": ("parameter", [_UNIT.get(n, "1") for n in names],
                                                        {"long_name": "SI unit of each parameter"})},
        attrs={"units": "SI per parameter: x0, y0 and depth in m, amplitude in m^2, young_modulus in Pa, "
                        "normal_force in N, friction dimensionless",
               "interval": "2.5 % and 97.5 % posterior quantiles",
               "converged": int(res.converged), "message": res.message,
               "rhat_between_max": float(res.diagnostics["rhat_between_max"]),
               "n_steps": int(res.diagnostics["n_steps"])})
    for name, text in _POSITION_NAMES.items():
        position[name].attrs.update(long_name=text, units="see parameter_units" if name in _PER_PARAMETER else "1")
    density = {"units": "m^2/m"}
    profile = xr.Dataset(
        {"mean": ("x", post.mean, {**density, "long_name": "posterior mean defect-load density"}),
         "std": ("x", post.std, {**density, "long_name": "posterior sd of the defect-load density"}),
         "lower": ("x", post.mean - BAND_Z * post.std, {**density, "long_name": "lower end of the 95 % band"}),
         "upper": ("x", post.mean + BAND_Z * post.std, {**density, "long_name": "upper end of the 95 % band"})},
        coords={"x": ("x", x, {"units": "m", "frame": "world", "long_name": "position along the scan line"})},
        attrs={"units": "m^2 of effective defect area per m of scan line (a load density, not a height)",
               "band": "95 % pointwise credible band (mean +- 1.96 std, Gaussian posterior)",
               "criterion": options["criterion"], **{f"lam_{k}": float(v) for k, v in crit.lam.items()}})
    draws.attrs = {}  # arviz stamps the creation time; keep the file a function of the inputs only
    return xr.DataTree.from_dict(
        {"/": xr.Dataset(attrs={"source": "record" if isinstance(item, Recording) else str(item),
                                "sensor_ids": ",".join(info["sensor_ids"]), "time_stride": int(info["time_stride"]),
                                "noise_std_pa": float(info["noise_std"]),
                                "warnings": " | ".join(str(w.message) for w in caught)}),
         "/position": position, "/profile": profile, "/posterior": draws})


#: SI units of the sampled and integrated parameters (a stacked ``parameter`` dimension has one per entry)
_UNIT = {"x0": "m", "y0": "m", "depth": "m", "amplitude": "m^2", "young_modulus": "Pa", "normal_force": "N"}
_POSITION_NAMES = {"mean": "posterior mean", "sd": "posterior standard deviation", "lower": "2.5 % posterior quantile",
                   "upper": "97.5 % posterior quantile", "r_hat": "R-hat (rank-normalised split)",
                   "ess_bulk": "bulk effective sample size"}
_PER_PARAMETER = ("mean", "sd", "lower", "upper")


def invert_many(recordings, scene, *, client=None, seed: int, out_dir, workers: int | None = None,
                scheduler: str | None = None, per_task: int = 1, sample=(), max_data: int = 1500, n_grid: int = 200,
                criterion: str = "evidence", sampler_options: Mapping | None = None, progress: bool = True,
                echo: Callable[[str], None] = print, allow_scene_mismatch: bool = False):
    """Defect position and load profile of many recordings of one scene, gathered along ``recording``.

    Parameters
    ----------
    recordings : folder, sequence or mapping
        Recording files (``.nc``, ``.json``, ``.parquet``) and/or :class:`Recording` records; see
        :func:`recording_keys` for the keys (a file's key is its path relative to the batch root).
    scene : Scene or path
        The scene that produced the recordings (a ``.toml``/``.json`` scene file or a record);
        scattered once to every worker.
    client : distributed.Client, optional
        Run on this client. Otherwise ``scheduler`` (an address) or ``workers`` (0: serial
        in-process; N: a LocalCluster of N one-thread processes; None: one per core).
    seed : int
        Batch seed; the recording with key ``k`` uses ``SeedSequence(seed, spawn_key=(stable_hash(k),))``.
    out_dir : path
        Output folder: ``results/`` (one file per recording), ``errors.tsv``, ``invert_many.nc``.
        Reusing it resumes the batch (finished recordings are not recomputed).
    per_task : int
        Recordings per Dask task.
    sample, max_data, n_grid, criterion
        As in :func:`~.scene_inversion.invert_defect_position` and :func:`~.scene_inversion.defect_profile`.
    sampler_options : mapping, optional
        Further keywords of :func:`~.mcmc.sample_scene_posterior` (``max_steps``, ``n_walkers``, ...).
    progress : bool
        Progress bar over recordings.
    allow_scene_mismatch : bool
        Invert a recording file whose recorded scene differs from ``scene`` (with a warning) instead
        of failing it (:func:`~.scene_check.check_scene_recording`).

    Returns
    -------
    xarray.DataTree
        ``/position``: ``mean``, ``sd``, ``lower``, ``upper`` (95 % quantiles), ``r_hat``,
        ``ess_bulk`` with dims (recording, parameter), SI units; ``converged``, ``n_steps``,
        ``rhat_between_max`` per recording. ``/profile``: ``mean``, ``std``, ``lower``, ``upper``
        with dims (recording, x), m^2/m, ``x`` in m. Root attrs: ``seed``, ``n_run``, ``n_skipped``,
        ``n_failed``, ``failed`` (keys, ``;``-separated), ``out_dir``, ``wall_s`` (the batch, s),
        ``gather_s`` (reading the results back, on the workers when there are any, s). Failed recordings are left
        out (their reasons are in ``errors.tsv``); the emcee draws stay in the per-recording files.
    """
    import xarray as xr

    scene = _check_scene(scene)
    if criterion not in ("gcv", "lcurve", "discrepancy", "evidence"):
        raise ValueError(f"criterion: must be one of gcv, lcurve, discrepancy, evidence, got {criterion!r}")
    items = recording_keys(recordings, exclude=out_dir)
    options = dict(sample=tuple(sample), allow_scene_mismatch=bool(allow_scene_mismatch), max_data=int(max_data), n_grid=int(n_grid), criterion=criterion,
                   sampler=dict(sampler_options or {}, progress=False))
    with batch_client(workers, scheduler, client=client, echo=echo) as cl:
        report = run_batch(_invert_recording, items, seed=seed, out_dir=out_dir, client=cl,
                           workers=0 if cl is None else None, shared={"scene": scene, "options": options},
                           per_task=per_task, progress=progress, echo=echo)
        t0 = time.perf_counter()
        paths = [str(result_path(out_dir, k)) for k in report.done]
        parts = [_read_summary(p) for p in paths] if cl is None else cl.gather(cl.map(_read_summary, paths, pure=False))
        gather_s = time.perf_counter() - t0
    attrs = dict(seed=int(seed), n_run=report.n_run, n_skipped=report.n_skipped, n_failed=report.n_failed,
                 failed=";".join(report.errors), out_dir=str(out_dir), wall_s=float(report.wall_s),
                 gather_s=float(gather_s))
    tree = _gather(parts, report.done, attrs) if parts else xr.DataTree(xr.Dataset(attrs=attrs))
    tree = cf_ready(tree)  # the tree returned is the file's (CF attributes included)
    write_netcdf_atomic(tree, pathlib.Path(out_dir) / "invert_many.nc")
    return tree


def _read_summary(path: str) -> tuple:
    """The ``position`` and ``profile`` groups and the source of one result file (run where the files are)."""
    import xarray as xr

    position = xr.load_dataset(path, group="position", engine="h5netcdf")
    profile = xr.load_dataset(path, group="profile", engine="h5netcdf")
    return position, profile, xr.load_dataset(path, engine="h5netcdf").attrs["source"]


def _gather(parts: list, done: list, attrs: dict):
    """Concatenate the per-recording (position, profile, source) along ``recording``."""
    import xarray as xr

    keys = xr.DataArray(done, dims="recording", name="recording")
    position = xr.concat([p for p, _, _ in parts], dim=keys, combine_attrs="override")
    for name in ("converged", "n_steps", "rhat_between_max"):
        position[name] = ("recording", [p.attrs[name] for p, _, _ in parts], {"units": "1"})
    position["converged"] = position["converged"].astype(bool)
    position.attrs = {k: parts[0][0].attrs[k] for k in ("units", "interval")}
    profile = xr.concat([q for _, q, _ in parts], dim=keys, join="exact", combine_attrs="override")
    profile.attrs = {k: parts[0][1].attrs[k] for k in ("units", "band", "criterion")}
    root = xr.Dataset({"source": ("recording", [s for _, _, s in parts])}, coords={"recording": keys}, attrs=attrs)
    return xr.DataTree.from_dict({"/": root, "/position": position, "/profile": profile})

"""Metamer scans on the generic batch layer: the tractor metamer of a grating over (display, pitch, phase).

:func:`metamer_scan` runs one batch task (:func:`tactilab.core.batch.run_batch`) per
(display, pitch, phase): the best tractor-load match (:func:`~.metameres.metamer_pair`) of a
sinusoidal indentation ``H = A sin(2 pi x / p + phase)`` on one row of the display, scored under
a receptor hypothesis (relative residual, d', P(correct) in 2IFC, metameric or not). Serial with
``workers=0``, on a LocalCluster or a running Dask scheduler otherwise; the tractor families
(one per display) are built once and scattered once to every worker; one result file per point
in ``out_dir/results``; a rerun with the same ``out_dir`` resumes; a failing point goes into
``errors.tsv``. The scan is deterministic (no random draws); its points are still keyed, so the
answer is the same bit for bit on any number of workers.
"""

from __future__ import annotations

import pathlib
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from tactilab.core.batch import read_result, run_batch, write_netcdf_atomic
from tactilab.core.memory import check_count
from tactilab.core.netcdf import cf_ready
from tactilab.forward import ReceptorHypothesis

from .metamer_families import SinusoidFamily, TractorFamily, check_receptor_memory
from .metameres import metamer_pair

__all__ = ["metamer_scan"]

#: scalar results of one scan point, gathered over (display, pitch, phase)
SCAN_VARIABLES = ("relative_residual", "dprime", "p_correct_2ifc", "scan_rms", "n_at_limit")
#: the scan's variables are ratios, probabilities, d' and counts: dimensionless
_SCAN_UNITS = {name: "1" for name in SCAN_VARIABLES}


def _scan_point(item, rng, *, families, hypothesis, receptors, amplitude, bounds, scan_frames, criterion):
    """One task: the tractor metamer of one grating on one display -> Dataset (scores and loads)."""
    import xarray as xr

    family = families[item["display"]]
    grating = SinusoidFamily(item["pitch"], item["phase"])
    phases = None if scan_frames is None else item["phase"] + np.linspace(0, 2 * np.pi, scan_frames, endpoint=False)
    pair = metamer_pair(grating.stimulus([amplitude]), family, hypothesis, receptors,
                        bounds=bounds, criterion=criterion, scan_phases=phases)
    at_limit = 0 if family.limit is None or bounds is None else int(np.sum(np.abs(pair.params) >= family.limit * (1 - 1e-9)))
    return xr.Dataset(
        {"relative_residual": pair.relative_residual,
         "dprime": np.nan if pair.dprime is None else pair.dprime,
         "p_correct_2ifc": np.nan if pair.p_correct_2ifc is None else pair.p_correct_2ifc,
         "metameric": bool(pair.metameric) if pair.metameric is not None else False,
         "scan_rms": np.nan if pair.scan_rms is None else pair.scan_rms,
         "n_at_limit": at_limit,
         "loads": ("tractor", pair.params, {"units": "N/m"})},
        coords={"tractor_x": ("tractor", family.tractor_x, {"units": "m"})})


def _values(values, name: str, *, positive: bool) -> list[float]:
    out = [float(v) for v in np.atleast_1d(np.asarray(values, dtype=float))]
    if not out or not all(np.isfinite(v) and (v > 0 or not positive) for v in out):
        rule = "finite values > 0 in m" if positive else "finite values in rad"
        raise ValueError(f"{name}: need {rule}, got {values!r}; e.g. {'[2e-3, 4e-3]' if positive else '[0.0, 1.57]'}")
    return out


def metamer_scan(pitches: Sequence[float], phases: Sequence[float], displays, hypothesis: ReceptorHypothesis | str,
                 *, amplitude: float, young_modulus: float, receptors, out_dir, seed: int = 0, bounds="family",
                 scan_frames: int | None = None, criterion: float = 1.0, client=None, workers: int | None = None,
                 scheduler: str | None = None, per_task: int = 1, progress: bool = True,
                 echo: Callable[[str], None] = print):
    """The tractor metamer of a sinusoidal grating for every (display, pitch, phase), as a batch.

    Parameters
    ----------
    pitches : sequence of float
        Grating pitches p, m (each > 0).
    phases : sequence of float
        Spatial phases of the grating, rad.
    displays : sequence or mapping of DisplayDescription
        Tractor displays (first row each, loads bounded by traction limit x tractor width);
        a mapping gives their names, else their ``display_id`` (unique).
    hypothesis : ReceptorHypothesis or str
        Receptor readouts, with a noise std for d' (e.g. ``ReceptorHypothesis.parse("xx,zx@1.25mm").with_noise(1e-3)``).
    amplitude : float
        Grating amplitude A, m (> 0).
    young_modulus : float
        Skin Young's modulus E, Pa (> 0).
    receptors : array_like, shape (n_receptors,)
        Receptor positions x, m.
    out_dir : path
        Output folder (resumable): ``results/`` (one file per point, with the tractor loads),
        ``errors.tsv``, ``metamer_scan.nc``.
    seed : int
        Batch seed (the scan draws nothing; kept in the file attributes).
    bounds : "family" or None
        "family": each tractor's load limit; None: unbounded.
    scan_frames : int, optional
        Frames of a travelling scan over one pitch (``scan_rms``); None: no scan.
    criterion : float
        d' below which a pair is metameric.
    client, workers, scheduler, per_task, progress
        See :func:`tactilab.core.batch.run_batch`.

    Returns
    -------
    xarray.Dataset
        Over (display, pitch, phase): ``relative_residual`` (||diff|| / ||target||, not
        squared), ``dprime``, ``p_correct_2ifc``, ``scan_rms`` (dimensionless; NaN where a point
        failed or no noise/scan was given), ``n_at_limit`` (tractors at their load limit; -1 where
        failed), ``metameric`` (bool), ``finished`` (bool). ``pitch`` in m, ``phase`` in rad.
        Attrs: ``hypothesis``, ``amplitude_m``, ``young_modulus_pa``, ``n_run``, ``n_skipped``,
        ``n_failed``, ``failed``. The tractor loads (N/m) are in the per-point files.
    """
    import xarray as xr

    from tactilab.data_schemas.display import DisplayDescription

    ps = _values(pitches, "pitches", positive=True)
    phs = _values(phases, "phases", positive=False)
    named = dict(displays) if isinstance(displays, Mapping) else {getattr(d, "display_id", None): d for d in displays}
    if not named or not all(isinstance(d, DisplayDescription) for d in named.values()) or (
            not isinstance(displays, Mapping) and len(named) != len(list(displays))):
        raise ValueError("displays: give DisplayDescription records with different display_id (or a mapping name -> "
                         "record), e.g. [DisplayDescription.wh2008(), DisplayDescription.stress2()]")
    for value, name, unit in ((amplitude, "amplitude", "m"), (young_modulus, "young_modulus", "Pa")):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be finite and > 0 {unit}, got {value!r}")
    if bounds not in ("family", None):
        raise ValueError(f"bounds: must be 'family' (the load limits) or None (unbounded), got {bounds!r}")
    if scan_frames is not None and (int(scan_frames) != scan_frames or scan_frames < 1):
        raise ValueError(f"scan_frames: must be an integer >= 1 (frames over one pitch) or None, got {scan_frames!r}")
    h = hypothesis if isinstance(hypothesis, ReceptorHypothesis) else ReceptorHypothesis.parse(str(hypothesis))
    x = np.asarray(receptors, dtype=float).reshape(-1)
    families = {str(k): TractorFamily.from_display(d, float(young_modulus)) for k, d in named.items()}
    # the memory rule, before any point runs (a failure per point would hide it in errors.tsv)
    check_receptor_memory(x.size, max(f.n_params for f in families.values()), h.n_depths)
    if scan_frames is not None:
        check_count(int(scan_frames), 16, "scan_frames", "frames (a phase and a residual each)")
    items = {f"display={d}/pitch={p!r}m/phase={ph!r}rad": {"display": d, "pitch": p, "phase": ph, "at": (i, j, k)}
             for i, d in enumerate(families) for j, p in enumerate(ps) for k, ph in enumerate(phs)}
    shared = dict(families=families, hypothesis=h, receptors=x, amplitude=float(amplitude), bounds=bounds,
                  scan_frames=None if scan_frames is None else int(scan_frames), criterion=float(criterion))
    rep = run_batch(_scan_point, items, seed=seed, out_dir=out_dir, client=client, workers=workers,
                    scheduler=scheduler, shared=shared, per_task=per_task, progress=progress, echo=echo)
    shape = (len(families), len(ps), len(phs))
    data = {v: np.full(shape, np.nan) for v in SCAN_VARIABLES}
    data["n_at_limit"] = np.full(shape, -1, dtype=np.int64)
    metameric, finished = np.zeros(shape, dtype=bool), np.zeros(shape, dtype=bool)
    for key in rep.done:
        point, at = read_result(out_dir, key).to_dataset(), items[key]["at"]
        for v in SCAN_VARIABLES:
            data[v][at] = point[v].values
        metameric[at], finished[at] = bool(point["metameric"]), True
    dims = ("display", "pitch", "phase")
    ds = xr.Dataset({**{v: (dims, a) for v, a in data.items()}, "metameric": (dims, metameric),
                     "finished": (dims, finished)},
                    coords={"display": list(families), "pitch": ("pitch", ps, {"units": "m"}),
                            "phase": ("phase", phs, {"units": "rad"})},
                    attrs=dict(hypothesis=str(h), amplitude_m=float(amplitude), young_modulus_pa=float(young_modulus),
                               criterion=float(criterion), seed=int(seed), n_run=rep.n_run, n_skipped=rep.n_skipped,
                               n_failed=rep.n_failed, failed=";".join(rep.errors)))
    for name, units in _SCAN_UNITS.items():
        ds[name].attrs.update(units=units)
    ds = cf_ready(ds)  # the dataset returned is the file's (CF attributes included)
    write_netcdf_atomic(ds, pathlib.Path(out_dir) / "metamer_scan.nc")
    return ds

"""Batch jobs on the generic layer: transduction fits per (subject, model) with their comparison
(tactilab.experiments.compare_many), metamer scans over (display, pitch, phase)
(tactilab.inversion.metamer_scan), and one BLAS thread on the serial path as on the workers.

Oracles: each batch point equals the direct call with the same per-key generator
(``task_rng(seed, key)``); results are bitwise identical for 0, 1 and 2 workers; a rerun resumes
(the tasks run are counted); a failing item lands in errors.tsv and the batch goes on. Few MCMC
steps keep the fits fast (convergence is not the point here).
"""

from __future__ import annotations

import sys

import cloudpickle
import numpy as np
import pandas as pd
import pytest
import xarray as xr

from tactilab.core import batch as B
from tactilab.core import read_result, run_batch, task_rng
from tactilab.data_schemas import DisplayDescription, Stimulus
from tactilab.experiments import TransductionModel, compare_many, compare_models, fit_transduction
from tactilab.forward import ReceptorHypothesis
from tactilab.inversion import SinusoidFamily, TractorFamily, metamer_pair, metamer_scan

cloudpickle.register_pickle_by_value(sys.modules[__name__])

GRATING = Stimulus(amplitude_m=1e-6, pitch_m=4e-3, speed_m_per_s=0.02, duration_s=0.1)
FAST = {"max_steps": 100, "check_every": 50}
MODELS = ["zx@1mm", "zx@3mm"]


def trials_of(seed: int, n_per: int = 8, t: float = 2e-4) -> pd.DataFrame:
    """2IFC trials of an observer reading zx@1mm (threshold strain ``t``), gratings of 2 and 6 mm pitch."""
    model, rng, rows = TransductionModel("zx@1mm"), np.random.default_rng(seed), []
    for p in (2e-3, 6e-3):
        for a in (0.25e-6, 0.5e-6, 1e-6, 2e-6):
            stim = GRATING.model_copy(update={"amplitude_m": a, "pitch_m": p})
            blank = stim.model_copy(update={"amplitude_m": 0.0})
            prob = model.p_correct([(stim, blank)], "2ifc", t, 1.0, 0.02)[0]
            for ok in rng.random(n_per) < prob:
                first = bool(rng.random() < 0.5)
                rows.append({"stimuli": [stim, blank] if first else [blank, stim], "target": "1" if first else "2",
                             "correct": bool(ok)})
    return pd.DataFrame(rows)


@pytest.fixture(scope="module")
def client():
    import distributed

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  env=dict(B.ONE_THREAD_ENV)) as cluster, distributed.Client(cluster) as cl:
        yield cl


@pytest.fixture(scope="module")
def client1():
    import distributed

    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  env=dict(B.ONE_THREAD_ENV)) as cluster, distributed.Client(cluster) as cl:
        yield cl


def _files_equal(dir_a, dir_b, keys) -> bool:
    for k in keys:
        a, b = read_result(dir_a, k), read_result(dir_b, k)
        if set(a.groups) != set(b.groups):
            return False
        for g in a.groups:
            da, db = a[g].to_dataset(), b[g].to_dataset()
            if not (da.equals(db) and all(da[v].dtype == db[v].dtype for v in da.data_vars)):
                return False
    return True


# ----------------------------------------------------------------------------- fits per subject
@pytest.fixture(scope="module")
def subjects():
    return {"S01": trials_of(1), "S02": trials_of(2), "S03": pd.DataFrame({"level": [1.0, 2.0]})}  # S03 is broken


@pytest.fixture(scope="module")
def serial_fits(subjects, tmp_path_factory):
    out = tmp_path_factory.mktemp("fits0")
    return out, compare_many(subjects, MODELS, seed=5, out_dir=out, workers=0, progress=False)


@pytest.mark.filterwarnings("ignore:Estimated shape parameter of Pareto:UserWarning")
@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_compare_many_equals_direct_fits_and_records_the_broken_subject(serial_fits, subjects):
    out, table = serial_fits
    assert (table.attrs["n_run"], table.attrs["n_skipped"], table.attrs["n_failed"]) == (4, 0, 2)
    assert table.attrs["failed"] == "S03/zx@1mm;S03/zx@3mm"
    lines = (out / "errors.tsv").read_text().splitlines()
    assert lines[0] == "key\treason" and len(lines) == 3 and lines[1].startswith("S03/zx@1mm\tValueError: trials:")
    assert list(table["verdict"].sel(subject="S03").values) == ["failed", "failed"]
    assert int(table["rank"].sel(subject="S03", model="zx@1mm")) == -1
    # the oracle: the direct fits with each key's generator, compared directly
    fits = {m: fit_transduction(TransductionModel(m), subjects["S02"]) for m in MODELS}  # the grid: no seed
    direct = compare_models(fits)
    for m in MODELS:
        row = table.sel(subject="S02", model=m)
        for col in ("elpd", "elpd_diff", "dse", "pareto_k_max", "weight"):
            assert float(row[col]) == float(direct.loc[m, col]), (m, col)
        # mcse (and z through it) is a difference of two nearly equal elpds (PSIS and quadrature), which
        # may differ in the last bits between the batch (fits read back from its files) and in-memory fits
        for col in ("mcse", "z", "separation"):
            assert float(row[col]) == pytest.approx(float(direct.loc[m, col]), rel=1e-12, abs=1e-15), (m, col)
        assert str(row["verdict"].values) == direct.loc[m, "verdict"]
        assert str(row["reason"].values) == direct.loc[m, "reason"]
        lo, hi = fits[m].params["threshold_strain"].ci95
        assert float(row["lower"].sel(parameter="threshold_strain")) == lo
        assert float(row["upper"].sel(parameter="threshold_strain")) == hi
        assert bool(row["converged"]) == fits[m].converged
        draws = read_result(out, f"S02/{m}")["posterior"].to_dataset()
        assert np.array_equal(draws["threshold_strain"].values, fits[m].tree["posterior"]["threshold_strain"].values)
    on_disk = xr.load_dataset(out / "compare_many.nc", engine="h5netcdf")
    assert on_disk.equals(table)


@pytest.mark.slow
def test_compare_many_same_bits_for_0_1_and_2_workers_and_resume(serial_fits, subjects, tmp_path, client, client1):
    out0, table0 = serial_fits
    keys = [f"{s}/{m}" for s in ("S01", "S02") for m in MODELS]
    t1 = compare_many(subjects, MODELS, seed=5, out_dir=tmp_path / "w1", client=client1, progress=False)
    reordered = {k: subjects[k] for k in reversed(list(subjects))}
    t2 = compare_many(reordered, MODELS, seed=5, out_dir=tmp_path / "w2", client=client, progress=False, per_task=3)
    assert t1.attrs["n_run"] == t2.attrs["n_run"] == 4 and t2.attrs["n_failed"] == 2
    assert t1.drop_attrs().identical(table0.drop_attrs())
    assert t2.sel(subject=list(subjects)).drop_attrs().identical(table0.drop_attrs())
    assert _files_equal(out0, tmp_path / "w1", keys) and _files_equal(out0, tmp_path / "w2", keys)
    again = compare_many(subjects, MODELS, seed=5, out_dir=tmp_path / "w2", client=client, progress=False)
    assert (again.attrs["n_run"], again.attrs["n_skipped"], again.attrs["n_failed"]) == (0, 4, 2)  # only S03 retried
    assert again.drop_attrs().identical(table0.drop_attrs())


def test_compare_many_bad_input(tmp_path):
    with pytest.raises(ValueError, match="subjects: give a mapping subject code"):
        compare_many([trials_of(1)], MODELS, seed=0, out_dir=tmp_path, workers=0)
    with pytest.raises(ValueError, match=r"models: give at least two different models, got \['zx@1mm', 'zx@1mm'\]"):
        compare_many({"S01": trials_of(1)}, ["zx@1mm", "zx@1mm"], seed=0, out_dir=tmp_path, workers=0)
    with pytest.raises(ValueError, match="subjects: a subject code must be non-empty without '/', got 'a/b'"):
        compare_many({"a/b": trials_of(1)}, MODELS, seed=0, out_dir=tmp_path, workers=0)
    with pytest.raises(ValueError, match="method: must be 'grid' or 'emcee', got 'mcmc'"):
        compare_many({"S01": trials_of(1)}, MODELS, seed=0, out_dir=tmp_path, workers=0, method="mcmc")
    with pytest.raises(ValueError, match="sampler_options: only for method='emcee'"):
        compare_many({"S01": trials_of(1)}, MODELS, seed=0, out_dir=tmp_path, workers=0, sampler_options=FAST)


def test_compare_many_emcee_option_gives_verdicts_of_the_same_vocabulary(tmp_path):
    """The emcee path still runs through the batch: its short chains (FAST) do not converge, so no
    row gets a verdict beyond 'no verdict: fit not converged'; a converged one would get the table's."""
    from tactilab.experiments.modelling import VERDICTS

    table = compare_many({"S01": trials_of(1)}, MODELS, seed=0, out_dir=tmp_path, workers=0, method="emcee",
                         sampler_options=FAST, progress=False)
    for m in MODELS:
        row = table.sel(subject="S01", model=m)
        assert str(row["verdict"].values) in VERDICTS
        if not bool(row["converged"]):
            assert str(row["verdict"].values) == "no verdict: fit not converged"
            assert "--max-steps" in str(row["reason"].values)
    assert read_result(tmp_path, "S01/zx@1mm").attrs["method"] == "emcee"


# ----------------------------------------------------------------------------- metamer scans
DISPLAYS = [DisplayDescription.wh2008(), DisplayDescription.stress2()]
HYP = ReceptorHypothesis.parse("xx,zx@1.25mm").with_noise(1e-3)
X = np.linspace(-5e-3, 5e-3, 41)
SCAN = dict(amplitude=20e-6, young_modulus=1.54e6, receptors=X, scan_frames=3, progress=False)


@pytest.mark.slow
def test_metamer_scan_points_equal_direct_pairs_same_bits_on_workers_and_resume(tmp_path, client, client1):
    pitches, phases = [2e-3, 5e-3], [0.0, 1.0]
    s0 = metamer_scan(pitches, phases, DISPLAYS, HYP, out_dir=tmp_path / "w0", workers=0, **SCAN)
    assert s0.attrs["n_run"] == 8 and bool(s0["finished"].all())
    fam = TractorFamily.from_display(DISPLAYS[1], 1.54e6)
    pair = metamer_pair(SinusoidFamily(5e-3, 1.0).stimulus([20e-6]), fam, HYP, X,
                        scan_phases=1.0 + np.linspace(0, 2 * np.pi, 3, endpoint=False))
    point = s0.sel(display="STReSS2", pitch=5e-3, phase=1.0)
    assert float(point["relative_residual"]) == pair.relative_residual and float(point["dprime"]) == pair.dprime
    assert float(point["scan_rms"]) == pair.scan_rms and bool(point["metameric"]) == pair.metameric
    key = "display=STReSS2/pitch=0.005m/phase=1.0rad"
    assert np.array_equal(read_result(tmp_path / "w0", key)["loads"].values, pair.params)
    keys = [k.name for k in (tmp_path / "w0" / "results").glob("*.nc")]
    s1 = metamer_scan(pitches, phases, DISPLAYS, HYP, out_dir=tmp_path / "w1", client=client1, **SCAN)
    s2 = metamer_scan(pitches[::-1], phases, DISPLAYS[::-1], HYP, out_dir=tmp_path / "w2", client=client, per_task=3,
                      **SCAN)
    assert s1.drop_attrs().identical(s0.drop_attrs())
    assert s2.sel(display=s0["display"].values, pitch=pitches).drop_attrs().identical(s0.drop_attrs())
    keys = [B.unquote_key(k) for k in keys]
    assert len(keys) == 8 and _files_equal(tmp_path / "w0", tmp_path / "w2", keys)
    again = metamer_scan(pitches, phases, DISPLAYS, HYP, out_dir=tmp_path / "w2", client=client, **SCAN)
    assert (again.attrs["n_run"], again.attrs["n_skipped"]) == (0, 8)


def test_metamer_scan_failing_point_lands_in_errors(tmp_path, monkeypatch):
    import tactilab.inversion.metamer_batch as MB

    real = MB.metamer_pair

    def flaky(target, *args, **kwargs):
        if target.family.pitch == 3e-3:
            raise RuntimeError("solver\tdiverged")
        return real(target, *args, **kwargs)

    monkeypatch.setattr(MB, "metamer_pair", flaky)
    scan = metamer_scan([2e-3, 3e-3], [0.0], DISPLAYS[:1], HYP, out_dir=tmp_path, workers=0, **SCAN)
    assert scan.attrs["n_failed"] == 1 and scan.attrs["failed"] == "display=WH2008/pitch=0.003m/phase=0.0rad"
    assert (tmp_path / "errors.tsv").read_text().splitlines()[1] == \
        "display=WH2008/pitch=0.003m/phase=0.0rad\tRuntimeError: solver diverged"
    bad = scan.sel(display="WH2008", pitch=3e-3, phase=0.0)
    assert not bool(bad["finished"]) and np.isnan(float(bad["dprime"])) and int(bad["n_at_limit"]) == -1
    assert bool(scan["finished"].sel(pitch=2e-3).all())
    monkeypatch.setattr(MB, "metamer_pair", real)
    again = metamer_scan([2e-3, 3e-3], [0.0], DISPLAYS[:1], HYP, out_dir=tmp_path, workers=0, **SCAN)
    assert (again.attrs["n_run"], again.attrs["n_skipped"], again.attrs["n_failed"]) == (1, 1, 0)


def test_metamer_scan_bad_input(tmp_path):
    args = ([2e-3], [0.0], DISPLAYS, HYP)
    with pytest.raises(ValueError, match=r"pitches: need finite values > 0 in m, got \[-0.002\]"):
        metamer_scan([-2e-3], [0.0], DISPLAYS, HYP, out_dir=tmp_path, workers=0, **SCAN)
    with pytest.raises(ValueError, match="phases: need finite values in rad"):
        metamer_scan([2e-3], [np.nan], DISPLAYS, HYP, out_dir=tmp_path, workers=0, **SCAN)
    with pytest.raises(ValueError, match="displays: give DisplayDescription records with different display_id"):
        metamer_scan([2e-3], [0.0], DISPLAYS * 2, HYP, out_dir=tmp_path, workers=0, **SCAN)
    with pytest.raises(ValueError, match="amplitude: must be finite and > 0 m, got 0.0"):
        metamer_scan(*args, out_dir=tmp_path, workers=0, **{**SCAN, "amplitude": 0.0})
    with pytest.raises(ValueError, match="bounds: must be 'family'"):
        metamer_scan(*args, out_dir=tmp_path, workers=0, bounds="tight", **SCAN)
    with pytest.raises(ValueError, match="scan_frames: must be an integer >= 1"):
        metamer_scan(*args, out_dir=tmp_path, workers=0, **{**SCAN, "scan_frames": 0})


# ----------------------------------------------------------------------------- one BLAS thread
def blas_task(item, rng):
    """Threads each BLAS library runs with inside the task, and a BLAS-heavy result (matrix products)."""
    from threadpoolctl import threadpool_info

    a = rng.standard_normal((300, 300))
    out = a
    for _ in range(5):
        out = np.tanh(out @ a / 300.0)
    threads = sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})
    return xr.Dataset({"out": (("i", "j"), out), "blas_threads": ("lib", threads)})


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_one_blas_thread_serially_and_on_workers_same_bits(tmp_path, client):
    from threadpoolctl import threadpool_limits

    items = {f"k{i}": i for i in range(4)}
    with threadpool_limits(limits=2):  # the calling process may use more BLAS threads; the tasks use one
        serial = run_batch(blas_task, items, seed=1, out_dir=tmp_path / "s", workers=0, progress=False)
    remote = run_batch(blas_task, items, seed=1, out_dir=tmp_path / "p", client=client, progress=False)
    assert serial.n_run == remote.n_run == 4
    for k in items:
        a, b = read_result(tmp_path / "s", k), read_result(tmp_path / "p", k)
        assert list(a["blas_threads"].values) == [1] and list(b["blas_threads"].values) == [1]
        assert np.array_equal(a["out"].values, b["out"].values)


# ----------------------------------------------------------------------------- tasks the cluster loses
def logged(item, rng, *, log):
    with open(log, "a") as f:
        f.write(f"{item}\n")
    return xr.Dataset({"v": ("i", rng.standard_normal(2))})


def _lost(*args, **kwargs):
    """A lost task's stand-in: the cluster never ran the task's function."""
    return None


def _cancelling(client, monkeypatch, which):
    """Make ``client.submit`` cancel the futures whose submission index is in ``which`` (a lost task).
    A lost submission runs :func:`_lost` in place of the task, so that it did no work whatever the
    timing (cancelling the real task raced with a worker that had already run it, on a loaded machine)."""
    real, count = client.submit, [0]

    def submit(fn, *args, **kwargs):
        lost = which(count[0])
        count[0] += 1
        if not lost:
            return real(fn, *args, **kwargs)
        fut = real(_lost, *args, **kwargs)
        fut.cancel()
        return fut

    monkeypatch.setattr(client, "submit", submit)
    return count


def test_a_lost_task_is_submitted_again_and_nothing_is_computed_twice(tmp_path, client, monkeypatch):
    log = tmp_path / "calls.log"
    items = {f"k{i}": f"k{i}" for i in range(6)}
    count = _cancelling(client, monkeypatch, lambda i: i == 0)
    rep = run_batch(logged, items, seed=2, out_dir=tmp_path / "o", client=client, shared={"log": str(log)},
                    per_task=2, progress=False)
    assert count[0] == 4  # 3 tasks + the lost one again
    assert rep.n_failed == 0 and rep.done == list(items) and rep.n_run + rep.n_skipped == 6
    assert sorted(log.read_text().split()) == sorted(items)  # every item computed exactly once
    assert np.array_equal(read_result(tmp_path / "o", "k0")["v"].values, task_rng(2, "k0").standard_normal(2))


@pytest.mark.slow
def test_a_task_lost_every_time_records_its_items_as_failed(tmp_path, client, monkeypatch):
    items = {f"k{i}": f"k{i}" for i in range(4)}
    _cancelling(client, monkeypatch, lambda i: i in (0, 2, 3))  # the first task's three submissions
    rep = run_batch(logged, items, seed=2, out_dir=tmp_path, client=client, shared={"log": str(tmp_path / "l")},
                    per_task=2, progress=False)
    assert rep.n_run == 2 and sorted(rep.errors) == ["k0", "k1"]
    assert rep.errors["k0"].startswith(f"task lost by the cluster {B.TASK_TRIES} times, last: FutureCancelledError")
    assert (tmp_path / "errors.tsv").read_text().count("task lost by the cluster") == 2

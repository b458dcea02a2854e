"""Batches: the generic layer (tactilab.core.batch), the batch inversion
(tactilab.inversion.batch.invert_many) and its CLI options (tactilab.cli.batch_options).

Generic layer: per-key seeds, atomic results, resume, errors.tsv, killed workers and clients,
missing extra, unreachable scheduler. Inversion: two simulated defect-scan recordings (the defect
at x = -0.4 mm and +0.4 mm) and one corrupt file; few MCMC steps keep it fast (convergence is not
the point; bitwise identity for 0, 1 and 2 workers, resume and error handling are).

One two-worker LocalCluster (processes) is shared by the module (starting one and importing the
inversion stack in its workers takes several seconds); the task functions below are pickled by
value so that the worker processes need not import this test module.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import cloudpickle
import numpy as np
import pytest
import xarray as xr

from tactilab.cli.batch_options import add_batch_options, run_invert_batch
from tactilab.core import batch as B
from tactilab.core import batch_cluster as BC
from tactilab.core.batch import read_result, result_path, run_batch, stable_hash, task_rng
from tactilab.data_schemas import Scan, SensorArray, load_example, read_recording
from tactilab.forward import simulate_scene
from tactilab.inversion.batch import invert_many, recording_keys

cloudpickle.register_pickle_by_value(sys.modules[__name__])


def draw(item, rng, *, scale=1.0, log=None, kill_key=None, sleep=0.0):
    """A task: three normal draws times ``scale``; ``item == "fail"`` raises; may kill its own worker once."""
    key = item
    if kill_key is not None and key == kill_key:
        marker = Path(log).with_suffix(".killed")
        if not marker.exists():
            marker.write_text("killed once")
            os.kill(os.getpid(), signal.SIGKILL)
    if key == "fail":
        raise ValueError("this item is broken\non two lines")
    time.sleep(sleep)
    if log is not None:
        with open(log, "a") as f:
            f.write(f"{key}\n")
    return xr.Dataset({"v": ("i", scale * rng.standard_normal(3))})


@pytest.fixture(scope="module")
def client():
    import distributed

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  env=dict(B.ONE_THREAD_ENV)) as cluster, distributed.Client(cluster) as cl:
        yield cl


def _executing(dask_worker) -> int:
    return dask_worker.state.executing_count


def _values(out, keys):
    return {k: read_result(out, k)["v"].values for k in keys}


def test_stable_hash_is_sha256_and_process_independent():
    h = stable_hash("scans/a.nc")
    assert h == int(hashlib.sha256(b"scans/a.nc").hexdigest()[:16], 16)
    code = "from tactilab.core.batch import stable_hash; print(stable_hash('scans/a.nc'))"
    for hseed in ("0", "123"):
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             env={**os.environ, "PYTHONHASHSEED": hseed}, check=True)
        assert int(out.stdout) == h
    a, b = task_rng(7, "x").standard_normal(4), task_rng(7, "y").standard_normal(4)
    assert not np.array_equal(a, b) and np.array_equal(a, task_rng(7, "x").standard_normal(4))
    ss = np.random.SeedSequence(7, spawn_key=(stable_hash("x"),))
    assert np.array_equal(a, np.random.default_rng(ss).standard_normal(4))


def test_serial_results_errors_and_resume(tmp_path):
    items = {k: k for k in ("a", "b/c.nc", "fail", "d e")}
    rep = run_batch(draw, items, seed=3, out_dir=tmp_path, workers=0, shared={"scale": 2.0}, progress=False)
    assert (rep.n_run, rep.n_skipped, rep.n_failed) == (3, 0, 1)
    assert rep.done == ["a", "b/c.nc", "d e"]
    assert result_path(tmp_path, "b/c.nc").name == "b%2Fc.nc.nc"
    lines = (tmp_path / "errors.tsv").read_text().splitlines()
    assert lines == ["key\treason", "fail\tValueError: this item is broken on two lines"]
    got = read_result(tmp_path, "a")
    assert np.array_equal(got["v"].values, 2.0 * task_rng(3, "a").standard_normal(3))
    assert got.attrs["batch_key"] == "a" and got.attrs["batch_seed"] == 3 and got.attrs["batch_compute_s"] > 0
    assert not list((tmp_path / "results").glob(".*"))  # no temporary file left
    again = run_batch(draw, items, seed=3, out_dir=tmp_path, workers=0, shared={"scale": 2.0}, progress=False)
    assert (again.n_run, again.n_skipped, again.n_failed) == (0, 3, 1)
    assert "3 skipped" in again.summary() and "errors.tsv" in again.summary()


@pytest.mark.slow
def test_same_bits_on_any_worker_count_order_and_chunking(tmp_path, client):
    keys = [f"k{i}" for i in range(9)]
    serial = run_batch(draw, {k: k for k in keys}, seed=11, out_dir=tmp_path / "s", workers=0, progress=False)
    shuffled = {k: k for k in reversed(keys)}
    par = run_batch(draw, shuffled, seed=11, out_dir=tmp_path / "p", client=client, per_task=4,
                    shared={"scale": 1.0}, progress=False)
    assert serial.n_run == par.n_run == 9
    a, b = _values(tmp_path / "s", keys), _values(tmp_path / "p", keys)
    assert all(np.array_equal(a[k], b[k]) for k in keys)


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_worker_killed_mid_batch_then_rerun_recomputes_nothing(tmp_path, client):
    log = tmp_path / "calls.log"
    items = {f"k{i}": f"k{i}" for i in range(8)}
    shared = {"log": str(log), "kill_key": "k3"}
    rep = run_batch(draw, items, seed=1, out_dir=tmp_path / "o", client=client, shared=shared, progress=False)
    assert log.with_suffix(".killed").exists()  # the worker did die once
    assert rep.n_failed == 0 and rep.done == list(items)
    calls = log.read_text().split()
    assert sorted(calls) == sorted(items)  # every item computed exactly once
    again = run_batch(draw, items, seed=1, out_dir=tmp_path / "o", client=client, shared=shared, progress=False)
    assert (again.n_run, again.n_skipped) == (0, 8) and log.read_text().split() == calls


@pytest.mark.slow
def test_client_killed_mid_batch_then_rerun_finishes_without_recomputing(tmp_path, client):
    log, out = tmp_path / "calls.log", tmp_path / "o"
    items = {f"k{i:02d}": f"k{i:02d}" for i in range(16)}
    script = tmp_path / "client.py"
    script.write_text(textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_batch import draw
        from tactilab.core.batch import run_batch
        if __name__ == "__main__":
            run_batch(draw, {items!r}, seed=2, out_dir={str(out)!r}, scheduler={client.scheduler.address!r},
                      shared={{"log": {str(log)!r}, "sleep": 0.2}}, progress=False)
    """))
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while len(list((out / "results").glob("k*.nc"))) < 3 and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    proc.kill()
    proc.wait()
    while time.monotonic() < deadline and sum(client.run(_executing).values()):  # orphaned tasks end
        time.sleep(0.05)
    before = len(list((out / "results").glob("k*.nc")))
    assert 3 <= before < 16
    rep = run_batch(draw, items, seed=2, out_dir=out, client=client, shared={"log": str(log)}, progress=False)
    assert rep.n_run == 16 - before and rep.n_skipped == before and rep.done == list(items)
    assert sorted(log.read_text().split()) == sorted(items)  # nothing that had finished was recomputed


def test_shared_objects_are_scattered_once(tmp_path, client, monkeypatch):
    calls = []
    real = client.scatter
    monkeypatch.setattr(client, "scatter", lambda *a, **k: calls.append(k) or real(*a, **k))
    items = {f"k{i}": f"k{i}" for i in range(6)}
    rep = run_batch(draw, items, seed=0, out_dir=tmp_path, client=client, shared={"scale": 3.0}, progress=False)
    assert rep.n_run == 6 and calls == [{"broadcast": True, "hash": False}]
    assert np.array_equal(read_result(tmp_path, "k0")["v"].values, 3.0 * task_rng(0, "k0").standard_normal(3))


def test_bad_results_and_arguments(tmp_path):
    rep = run_batch(lambda item, rng: np.zeros(2), {"x": 1}, seed=0, out_dir=tmp_path, workers=0, progress=False)
    assert rep.errors == {"x": "TypeError: task result: must be an xarray Dataset or DataTree, got ndarray"}
    with pytest.raises(ValueError, match="per_task: must be an integer >= 1"):
        run_batch(draw, {"a": "a"}, seed=0, out_dir=tmp_path, workers=0, per_task=0)
    with pytest.raises(ValueError, match="key: must be a non-empty string"):
        run_batch(draw, {"": "a"}, seed=0, out_dir=tmp_path, workers=0)
    with pytest.raises(ValueError, match=r"workers: must be an integer >= 0 \(0 = serial"):
        run_batch(draw, {"a": "a"}, seed=0, out_dir=tmp_path, workers=-1)


def test_missing_extra_names_the_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if the dask extra were not installed
    with pytest.raises(ImportError, match=r"pip install 'tactilab\[dask\]'.*workers=0"):
        run_batch(draw, {"a": "a"}, seed=0, out_dir=tmp_path, workers=2, progress=False)
    assert run_batch(draw, {"a": "a"}, seed=0, out_dir=tmp_path, workers=0, progress=False).n_run == 1


def test_unreachable_scheduler_is_one_clear_error(tmp_path, monkeypatch):
    monkeypatch.setattr(BC, "CONNECT_TIMEOUT_S", 1.0)
    with pytest.raises(OSError, match=r"scheduler: cannot reach the Dask scheduler at 'tcp://127.0.0.1:9' within 1 s"):
        run_batch(draw, {"a": "a"}, seed=0, out_dir=tmp_path, scheduler="tcp://127.0.0.1:9", progress=False)


# ----------------------------------------------------------------------------- batch inversion
FAST = dict(n_walkers=8, check_every=20, max_steps=20, n_start=8)
TRUTH = {"a/recording.nc": -0.4e-3, "b/recording.nc": 0.4e-3}


def small_scene(x0=0.0):
    base = load_example("fingertip_defect")
    sensors = SensorArray(positions_m=np.array([[0.0, 0.0], [1e-3, 0.0], [-1e-3, 1e-3]]), depth_m=2e-3,
                          components=("zz",), noise_std=20.0)
    scan = Scan(speed_m_per_s=0.02, duration_s=0.4, sampling_rate_hz=75.0, start_position_m=-4e-3)
    surface = base.surface.model_copy(update={"position_m": (x0, 0.0)})
    return base.model_copy(update={"sensors": sensors, "scan": scan, "surface": surface})


@pytest.fixture(scope="module")
def recs(tmp_path_factory):
    root = tmp_path_factory.mktemp("scans")
    for i, (key, x0) in enumerate(TRUTH.items()):
        simulate_scene(small_scene(x0), root / key.split("/")[0], rng=np.random.default_rng(i), plots=False)
    (root / "corrupt.nc").write_bytes(b"this is not a netCDF file")
    return root


@pytest.fixture(scope="module")
def serial(recs, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    return out, invert_many(recs, small_scene(), seed=4, out_dir=out, workers=0, sampler_options=FAST, n_grid=40,
                            progress=False)


def _same(t1: xr.DataTree, t2: xr.DataTree) -> bool:
    return all(t1[g].to_dataset().identical(t2[g].to_dataset()) for g in ("position", "profile"))


def test_serial_batch_recovers_positions_and_records_the_corrupt_file(serial, recs):
    out, tree = serial
    assert list(tree["recording"].values) == list(TRUTH)
    assert (tree.attrs["n_run"], tree.attrs["n_skipped"], tree.attrs["n_failed"]) == (2, 0, 1)
    assert tree.attrs["wall_s"] > 0 and tree.attrs["gather_s"] > 0
    errors = (out / "errors.tsv").read_text().splitlines()
    assert errors[0] == "key\treason" and errors[1].startswith("corrupt.nc\tOSError") and len(errors) == 2
    pos = tree["position"].to_dataset()
    for key, x0 in TRUTH.items():
        est = pos.sel(recording=key, parameter="x0")
        assert abs(float(est["mean"]) - x0) < 0.05e-3  # the defect is found (mean within 50 um)
        assert float(est["lower"]) < float(est["mean"]) < float(est["upper"])
    prof = tree["profile"].to_dataset()
    peaks = prof["x"].values[prof["mean"].argmax("x").values]
    assert np.allclose(peaks, list(TRUTH.values()), atol=0.35e-3)  # the profile peaks at the defect
    assert np.all(prof["upper"] > prof["lower"])
    on_disk = xr.open_datatree(out / "invert_many.nc", engine="h5netcdf").load()
    assert _same(on_disk, tree)


@pytest.mark.slow
def test_same_bits_for_0_1_and_2_workers(serial, recs, tmp_path, client):
    out0, tree0 = serial
    lines = []
    tree1 = invert_many(recs, small_scene(), seed=4, out_dir=tmp_path / "w1", workers=1, sampler_options=FAST,
                        n_grid=40, progress=False, echo=lines.append)
    assert lines and lines[0].startswith("dask: LocalCluster of 1 worker process(es) x 1 thread, dashboard http")
    tree2 = invert_many(sorted(recs.rglob("recording.nc"), reverse=True), small_scene(), seed=4,
                        out_dir=tmp_path / "w2", client=client, sampler_options=FAST, n_grid=40, progress=False)
    assert tree1.attrs["n_failed"] == 1 and tree2.attrs["n_failed"] == 0  # the list form holds no corrupt file
    assert _same(tree0, tree1)
    assert _same(tree0, tree2.sel(recording=list(TRUTH)))

    for key in TRUTH:  # the emcee draws themselves, bit for bit
        draws = [read_result(d, key)["posterior"].to_dataset() for d in (out0, tmp_path / "w1", tmp_path / "w2")]
        assert draws[0].identical(draws[1]) and draws[0].identical(draws[2])


def test_rerun_resumes_and_cli_summary(serial, recs, tmp_path, capsys):
    out0, tree0 = serial
    out = tmp_path / "resumed"
    shutil.copytree(out0, out)
    parser = argparse.ArgumentParser()
    parser.add_argument("--scene")
    parser.add_argument("--out")
    add_batch_options(parser)
    args = parser.parse_args(["--batch", str(recs), "--workers", "0", "--out", str(out)])
    args.scene = small_scene()
    args.quiet = True
    assert run_invert_batch(args) == 1  # the corrupt file fails again
    text = capsys.readouterr().out
    assert "0 recording(s) inverted, 2 skipped (done before), 1 failed" in text
    assert "errors.tsv (failed: corrupt.nc)" in text and "invert_many.nc (gathered)" in text
    again = xr.open_datatree(out / "invert_many.nc", engine="h5netcdf").load()
    assert _same(again, tree0)


def test_cli_option_errors(recs, tmp_path):
    parser = argparse.ArgumentParser()
    add_batch_options(parser)
    with pytest.raises(SystemExit):
        parser.parse_args(["--workers", "-1"])
    args = parser.parse_args(["--batch", str(tmp_path / "missing")])
    with pytest.raises(ValueError, match="--batch: must be a folder of recording files"):
        run_invert_batch(args)
    args = parser.parse_args(["--batch", str(recs), "--workers", "0"])
    args.max_steps = 0
    with pytest.raises(ValueError, match="--max-steps: must be >= 1 step, got 0"):
        run_invert_batch(args)


def test_recording_keys_and_bad_input(recs, tmp_path):
    keys = recording_keys(recs)
    assert list(keys) == ["a/recording.nc", "b/recording.nc", "corrupt.nc"]
    assert keys["corrupt.nc"] == str((recs / "corrupt.nc").resolve())
    rec = read_recording(recs / "a" / "recording.nc")
    mixed = recording_keys([recs / "b" / "recording.nc", rec, recs / "a" / "recording.nc"])
    assert list(mixed) == ["b/recording.nc", "recording-00001", "a/recording.nc"] and mixed["recording-00001"] is rec
    assert list(recording_keys({"left": rec})) == ["left"]
    assert list(recording_keys(recs, exclude=recs / "a")) == ["b/recording.nc", "corrupt.nc"]
    with pytest.raises(ValueError, match="recordings: .* is not a folder"):
        recording_keys(recs / "corrupt.nc")
    with pytest.raises(ValueError, match="recordings: no recording files"):
        recording_keys(tmp_path)
    with pytest.raises(ValueError, match="recordings: empty"):
        recording_keys([])
    with pytest.raises(ValueError, match="recordings: 'a/recording.nc' appears twice"):
        recording_keys([recs / "a" / "recording.nc", recs / "b" / "recording.nc", recs / "a" / "recording.nc"])
    with pytest.raises(ValueError, match="scene: the defect inversion needs a finger contact and an isolated defect"):
        invert_many(recs, load_example("sliding_grating"), seed=0, out_dir=tmp_path, workers=0)
    with pytest.raises(ValueError, match="criterion: must be one of gcv"):
        invert_many(recs, small_scene(), seed=0, out_dir=tmp_path, workers=0, criterion="aic")

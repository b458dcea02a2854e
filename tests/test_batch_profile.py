"""The LocalCluster that a batch starts is set up for long Python-heavy tasks (docs/scale-out.md).

- no statistical profiler on the workers (it samples every thread's stack every 10 ms; on emcee
  tasks it cost about a tenth of each task's time);
- housekeeping ticks slowed down, and glibc's own memory trimming (Dask's 64 KiB
  ``MALLOC_TRIM_THRESHOLD_`` made large temporaries page-fault on every call);
- result files written with a process-local lock: xarray otherwise takes a ``distributed.Lock``
  (a scheduler round trip per lock) for every HDF5 write inside a task or beside a ``Client``.
"""

from __future__ import annotations

import os
import sys

import cloudpickle

import dask
import distributed  # noqa: F401 - loads the distributed.* configuration defaults
import numpy as np
import pytest
import xarray as xr

from tactilab.core import cf_ready, read_result, run_batch, write_netcdf_atomic
from tactilab.core.batch import BATCH_CLUSTER_CONFIG, batch_client

cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers cannot import this file


def _settings() -> dict:
    return {"profile": bool(dask.config.get("distributed.worker.profile.enabled")),
            "tick": dask.config.get("distributed.admin.tick.interval"),
            "memory_monitor": dask.config.get("distributed.worker.memory.monitor-interval"),
            "malloc_trim": os.environ.get("MALLOC_TRIM_THRESHOLD_"),
            "blas": os.environ.get("OPENBLAS_NUM_THREADS")}


def test_local_cluster_workers_get_the_batch_settings(monkeypatch):
    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "65536")  # as left by a Dask cluster with Dask's defaults
    before = {k: v for k, v in _settings().items() if k in ("profile", "tick", "memory_monitor")}
    with batch_client(workers=1, echo=lambda line: None) as cl:
        answers = list(cl.run(_settings).values())
    assert answers == [{"profile": False, "tick": "1s", "memory_monitor": "1s", "malloc_trim": None, "blas": "1"}]
    after = {k: v for k, v in _settings().items() if k in before}
    assert after == before  # the caller's own Dask configuration is left as it was
    assert dask.config.get("distributed.nanny.pre-spawn-environ").get("MALLOC_TRIM_THRESHOLD_") == 65536
    assert "MALLOC_TRIM_THRESHOLD_" not in BATCH_CLUSTER_CONFIG["distributed.nanny.pre-spawn-environ"]


def _locks_taken(monkeypatch) -> list:
    import distributed

    made = []
    real = distributed.Lock.__init__

    def counting(self, *args, **kwargs):
        made.append(args)
        real(self, *args, **kwargs)

    monkeypatch.setattr(distributed.Lock, "__init__", counting)
    return made


def test_writes_beside_a_client_take_no_cluster_lock(tmp_path, monkeypatch):
    import distributed

    ds = xr.Dataset({"v": ("x", np.arange(4.0))})
    made = _locks_taken(monkeypatch)
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None):
        ds.to_netcdf(tmp_path / "plain.nc", engine="h5netcdf")  # what xarray does on its own
        assert made, "xarray no longer takes a distributed.Lock beside a Client: the guard may go"
        made.clear()
        path = write_netcdf_atomic(ds, tmp_path / "guarded.nc")
    assert made == []
    assert path == tmp_path / "guarded.nc" and sorted(p.name for p in tmp_path.iterdir()) == ["guarded.nc", "plain.nc"]
    xr.testing.assert_identical(xr.load_dataset(path, engine="h5netcdf"), cf_ready(ds))  # CF attributes added


def _count_cluster_locks() -> None:
    """(In a worker) count every distributed.Lock made from now on (the count lives on the module:
    functions pickled by value do not share this file's globals)."""
    import distributed

    real = distributed.Lock.__init__
    distributed.tactilab_test_locks = []

    def counting(self, *args, **kwargs):
        distributed.tactilab_test_locks.append(args)
        real(self, *args, **kwargs)

    distributed.Lock.__init__ = counting


def _cluster_locks() -> int:
    import distributed

    return len(distributed.tactilab_test_locks)


def _item(item, rng):
    return xr.Dataset({"v": ("x", rng.normal(size=3))}, attrs={"item": item})


def test_result_files_in_a_worker_take_no_cluster_lock(tmp_path):
    with batch_client(workers=1, echo=lambda line: None) as cl:
        cl.run(_count_cluster_locks)
        report = run_batch(_item, {"a": "a", "b": "b"}, seed=0, out_dir=tmp_path, client=cl, progress=False)
        assert list(cl.run(_cluster_locks).values()) == [0]
    assert report.n_run == 2 and read_result(tmp_path, "b").attrs["item"] == "b"


def test_a_failed_write_leaves_no_file(tmp_path, monkeypatch):
    def broken(self, path, engine):
        open(path, "wb").write(b"half")
        raise OSError("disk full")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", broken)
    with pytest.raises(OSError, match="disk full"):
        write_netcdf_atomic(xr.Dataset({"v": ("x", [1.0])}), tmp_path / "result.nc")
    assert list(tmp_path.iterdir()) == []


def test_concurrent_writers_leave_the_dask_configuration_as_it_was(tmp_path):
    """Threads writing at once (a worker with several threads) each set and restore the scheduler
    setting in turn; afterwards it is what it was, and every file holds its own data."""
    from concurrent.futures import ThreadPoolExecutor

    before = dask.config.get("scheduler", None)

    def write(i: int):
        return write_netcdf_atomic(xr.Dataset({"v": ("x", np.full(50, float(i)))}), tmp_path / f"f{i}.nc")

    with ThreadPoolExecutor(8) as pool:
        paths = list(pool.map(write, range(40)))
    assert dask.config.get("scheduler", None) == before
    for i, path in enumerate(paths):
        assert float(xr.load_dataset(path, engine="h5netcdf")["v"].mean()) == i

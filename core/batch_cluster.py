"""Where a batch runs: the Dask client, the LocalCluster set up for batches, one BLAS thread.

Part of the batch layer (:mod:`tactilab.core.batch`, which re-exports these names).
Dask (``dask``, ``distributed``) is optional: ``pip install 'tactilab[dask]'``.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator

#: environment of the worker processes: one BLAS / OpenMP thread each
ONE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
#: seconds to wait for a scheduler given by address before giving up
CONNECT_TIMEOUT_S = 5.0
_INSTALL = "pip install 'tactilab[dask]'"

_CONTROLLER: list = []  # this process's threadpoolctl controller, made once (scanning the libraries costs ~1 ms)


def _controller():
    if not _CONTROLLER:
        try:
            from threadpoolctl import ThreadpoolController
        except ImportError:  # the worker processes get ONE_THREAD_ENV instead
            _CONTROLLER.append(None)
        else:
            import scipy.linalg  # noqa: F401 - load scipy's own BLAS first, so that it is limited too

            _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0]


@contextlib.contextmanager
def one_thread() -> Iterator[None]:
    """Limit BLAS/OpenMP to one thread inside the block (threadpoolctl, from the dask extra, when installed).

    FFTs need no limit: ``numpy.fft`` runs on one thread and ``scipy.fft`` uses one unless given
    ``workers``. Without threadpoolctl the serial path keeps the caller's BLAS threads (start
    Python with ``OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1`` then); worker processes get
    ``ONE_THREAD_ENV`` in any case.
    """
    controller = _controller()
    if controller is None:
        yield
        return
    with controller.limit(limits=1):
        yield


def _require_distributed():
    try:
        import distributed
    except ImportError as err:
        raise ImportError(f"batch on Dask: needs the optional packages dask and distributed; install them with "
                          f"{_INSTALL}, or run serially with workers=0 (--workers 0)") from err
    return distributed


@contextlib.contextmanager
def batch_client(workers: int | None = None, scheduler: str | None = None, *, client=None,
                 echo: Callable[[str], None] = print) -> Iterator[object]:
    """The Dask client a batch runs on, or None for the serial in-process path.

    Parameters
    ----------
    workers : int, optional
        0: serial in-process (no Dask needed). N >= 1: a ``LocalCluster`` of N one-thread worker
        processes on this machine. None: one worker per CPU core.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); then ``workers`` is ignored
        and nothing is started. Unreachable within ``CONNECT_TIMEOUT_S`` seconds -> OSError.
    client : distributed.Client, optional
        Use this client as is (it is not closed).
    echo : callable
        Receives the dashboard line when a cluster is started.
    """
    if client is not None:
        yield client
        return
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers or workers < 0):
        raise ValueError(f"workers: must be an integer >= 0 (0 = serial in-process), got {workers!r}")
    if scheduler is None and workers == 0:
        yield None
        return
    distributed = _require_distributed()
    os.environ.update(ONE_THREAD_ENV)  # inherited by worker processes started from here on
    if scheduler is not None:
        try:
            cl = distributed.Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as err:
            raise OSError(f"scheduler: cannot reach the Dask scheduler at {scheduler!r} within {CONNECT_TIMEOUT_S:g} s "
                          f"({type(err).__name__}); check the address (e.g. tcp://host:8786) and that the scheduler "
                          f"runs, or leave the scheduler out to start a LocalCluster on this machine") from None
        with cl:
            yield cl
        return
    n = int(workers) if workers is not None else (os.cpu_count() or 1)
    import logging

    logging.getLogger("distributed").setLevel(logging.ERROR)  # no dashboard/bokeh chatter
    with local_cluster(n) as cluster, distributed.Client(cluster) as cl:
        echo(f"dask: LocalCluster of {n} worker process(es) x 1 thread, dashboard {cl.dashboard_link}")
        yield cl


#: Dask settings of the batch cluster (see :func:`local_cluster`): what a batch of long Python-heavy
#: tasks does not need, and what slowed them down when measured (docs/scale-out.md)
_DASK_MALLOC_TRIM = 65536  # Dask's default distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_
BATCH_CLUSTER_CONFIG = {
    # the statistical profiler samples every thread's stack every 10 ms
    "distributed.worker.profile.enabled": False,
    # event-loop health check every 20 ms -> 1 s (still warns of a loop blocked for 3 s)
    "distributed.admin.tick.interval": "1s",
    # nanny memory check every 100 ms -> 1 s (a worker over its memory limit is stopped within 1 s)
    "distributed.worker.memory.monitor-interval": "1s",
    # the dashboard's CPU/memory samples every 500 ms -> 5 s
    "distributed.admin.system-monitor.interval": "5s",
    # Dask sets MALLOC_TRIM_THRESHOLD_=64 KiB in its workers, so glibc hands freed memory back at
    # once and large temporaries page-fault on every call; keep glibc's default, as in-process
    "distributed.nanny.pre-spawn-environ": {k: int(v) for k, v in ONE_THREAD_ENV.items()},
}


def local_cluster(n: int, dashboard_address: str | None = ":0"):
    """A ``distributed.LocalCluster`` of ``n`` one-thread worker processes set up for batches.

    One BLAS/OpenMP thread per worker (:data:`ONE_THREAD_ENV`), and the settings of
    :data:`BATCH_CLUSTER_CONFIG`: no statistical profiler on the workers, slower housekeeping
    ticks, and glibc's own memory trimming. The nannies hand this configuration to the worker
    processes they start; the caller's Dask configuration is left as it was.
    """
    import dask
    import distributed

    if os.environ.get("MALLOC_TRIM_THRESHOLD_") == str(_DASK_MALLOC_TRIM):
        # left in this process's environment by a Dask cluster started earlier with Dask's defaults
        # (its nanny sets it here before it spawns a worker): the workers would inherit it
        del os.environ["MALLOC_TRIM_THRESHOLD_"]
    with dask.config.set(BATCH_CLUSTER_CONFIG):
        return distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                        dashboard_address=dashboard_address, env=dict(ONE_THREAD_ENV))

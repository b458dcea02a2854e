"""The LocalCluster that a batch starts runs its workers without Dask's statistical profiler.

The profiler samples every thread's stack every 10 ms; on Python-heavy tasks (emcee) it cost
about a tenth of each task's time (docs/scale-out.md).
"""

from __future__ import annotations

import dask

from tactilab.data_schemas.batch import batch_client


def _profile_enabled() -> bool:
    return bool(dask.config.get("distributed.worker.profile.enabled"))


def test_local_cluster_workers_run_without_the_profiler():
    with batch_client(workers=1, echo=lambda line: None) as cl:
        answers = cl.run(_profile_enabled)
    assert answers and set(answers.values()) == {False}
    assert _profile_enabled()  # the caller's own configuration is left as it was

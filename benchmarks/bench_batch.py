"""Benchmark: batches on Dask, serial vs LocalCluster(n_workers=1, 2), and why small tasks are batched.

Run:  .venv/bin/python benchmarks/bench_batch.py [--recordings 200] [--fft 10000] [--fft-files N] [--workers 1,2]
      .venv/bin/python benchmarks/bench_batch.py --quick     # a few minutes on 2 idle cores (scaled-down counts)

Part 1, defect scans: ``--recordings`` recordings simulated by ``tactilab.forward.simulate_scene``
(3 stress sensors at 2 mm depth, 30 samples; the defect at a random x in [-1, 1] mm, white noise
20 Pa), each inverted by ``tactilab.inversion.invert_many`` for the defect position (emcee,
4 ensembles x 8 walkers x 20 steps, after an 8-point multistart; deliberately short) and the
load profile with its band (40 nodes). Serial (``workers=0``) and on a LocalCluster of 1 and 2
one-thread worker processes. Columns: wall time of the batch (cluster start-up excluded, given
separately), speedup over serial, mean compute time per task (the callable alone; it grows when
other jobs share the cores), busy = sum of task compute times / (workers x wall), overhead per task = (workers x wall - sum of task compute
times) / tasks, peak resident memory per worker process (the largest), and whether every
result is bitwise identical to the serial run.

Part 2, small FFT inversions: ``--fft`` exact Gaussian posteriors (``gaussian_posterior`` on the
fft path, 64-node periodic grid, pressure -> sigma_zz at 0.5 mm) through ``run_batch``, one
result file per inversion at 1 and at 100 inversions per Dask task, and 100 inversions per key
(one file per 100), serial and on 2 workers. With ``--fft-files`` below ``--fft`` the
one-file-per-inversion runs use that many inversions and are extrapolated linearly to ``--fft``
(rows marked EXTRAPOLATED). Per-item costs, each measured on its own: the inversion alone, the
writing of one result file (in-process) and the Dask round trip of a no-op task (2 workers);
they feed the weak-scaling plan in docs/scale-out.md.

The table is printed; docs/scale-out.md quotes it with the machine it ran on.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one BLAS thread, also serially
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import pathlib
import resource
import shutil
import tempfile
import time

import numpy as np

from tactilab.core import read_result, run_batch
from tactilab.data_schemas import Scan, SensorArray, load_example
from tactilab.forward import simulate_scene
from tactilab.inversion import StationaryPrior, gaussian_posterior, halfspace_fourier_operator, invert_many

FAST = dict(n_walkers=8, check_every=20, max_steps=20, n_start=8)


def small_scene(x0: float = 0.0):
    """The defect scene of the benchmark (SI units), the defect at world x = ``x0`` m."""
    base = load_example("fingertip_defect")
    sensors = SensorArray(positions_m=np.array([[0.0, 0.0], [1e-3, 0.0], [-1e-3, 1e-3]]), depth_m=2e-3,
                          components=("zz",), noise_std=20.0)
    scan = Scan(speed_m_per_s=0.02, duration_s=0.4, sampling_rate_hz=75.0, start_position_m=-4e-3)
    surface = base.surface.model_copy(update={"position_m": (x0, 0.0)})
    return base.model_copy(update={"sensors": sensors, "scan": scan, "surface": surface})


def make_recordings(root: pathlib.Path, n: int, rng: np.random.Generator) -> None:
    """``n`` simulated scans under ``root/scan-XXXX/recording.nc``."""
    for i, x0 in enumerate(rng.uniform(-1e-3, 1e-3, n)):
        simulate_scene(small_scene(float(x0)), root / f"scan-{i:04d}", rng=rng, plots=False)


def _peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def _cluster(n: int):
    import distributed

    from tactilab.core.batch import local_cluster

    t0 = time.perf_counter()
    cluster = local_cluster(n, dashboard_address=None)  # the cluster a batch starts
    client = distributed.Client(cluster)
    return cluster, client, time.perf_counter() - t0


def _compute_s(out, keys) -> float:
    return sum(float(read_result(out, k).attrs["batch_compute_s"]) for k in keys)


def _same(out_a, out_b, keys) -> bool:
    """Every group's data of every key equal bit for bit (attributes such as timings aside)."""
    for k in keys:
        a, b = read_result(out_a, k), read_result(out_b, k)
        for group in a.groups:
            da, db = a[group].to_dataset(), b[group].to_dataset()
            if not (da.equals(db) and all(da[v].dtype == db[v].dtype for v in da.data_vars)):
                return False
    return True


def bench_recordings(n: int, workers: list[int], tmp: pathlib.Path) -> list[dict]:
    """Part 1: rows of the defect-scan table."""
    scans = tmp / "scans"
    t0 = time.perf_counter()
    make_recordings(scans, n, np.random.default_rng(2026))
    print(f"simulated {n} recordings in {time.perf_counter() - t0:.1f} s")
    scene = small_scene()
    rows = []
    common = dict(seed=1, sampler_options=FAST, n_grid=40, progress=False)
    invert_many([scans / "scan-0000" / "recording.nc"], scene, out_dir=tmp / "warm", workers=0, **common)  # imports
    out0 = tmp / "serial"
    tree = invert_many(scans, scene, out_dir=out0, workers=0, **common)
    if tree.attrs["n_failed"]:
        raise RuntimeError(f"{tree.attrs['n_failed']} recording(s) failed: see {out0 / 'errors.tsv'}")
    keys = list(tree["recording"].values)
    wall0 = float(tree.attrs["wall_s"])
    print(f"serial: {wall0:.1f} s", flush=True)
    c0 = _compute_s(out0, keys)
    rows.append(dict(run="serial (workers=0)", start=0.0, wall=wall0, speedup=1.0, compute=c0 / n, busy=c0 / wall0,
                     overhead=(wall0 - c0) / n, rss=_peak_rss_mib(), same=True))
    for w in workers:
        cluster, client, start = _cluster(w)
        client.run(lambda: __import__("tactilab.inversion.scene_inversion"))  # imports are start-up, not work
        start_total = start
        out = tmp / f"w{w}"
        tree = invert_many(scans, scene, out_dir=out, client=client, **common)
        wall = float(tree.attrs["wall_s"])
        rss = max(client.run(_peak_rss_mib).values())
        client.close()
        cluster.close()
        print(f"{w} worker(s): {wall:.1f} s", flush=True)
        c = _compute_s(out, keys)
        rows.append(dict(run=f"LocalCluster(n_workers={w})", start=start_total, wall=wall, speedup=wall0 / wall,
                         compute=c / n, busy=c / (w * wall), overhead=(w * wall - c) / n, rss=rss,
                         same=_same(out0, out, keys)))
    return rows


def _one_fft(rng, operator, prior, noise_std):
    n = operator.multiplier.size
    lam = prior.spectrum((n,), operator.spacing)
    truth = np.fft.irfft(np.sqrt(lam[: n // 2 + 1]) * np.fft.rfft(rng.standard_normal(n)), n)
    data = operator.matvec(truth) + noise_std * rng.standard_normal(n)
    post = gaussian_posterior(operator, data, prior, noise_std)
    return post.mean, post.std


def _fft_task(item, rng, *, operator, prior, noise_std, group=1):
    """``group`` small FFT inversions of fields and noisy data drawn from ``rng``; one result."""
    import xarray as xr

    out = [_one_fft(rng, operator, prior, noise_std) for _ in range(group)]
    return xr.Dataset({"mean": (("case", "x"), [m for m, _ in out]), "std": (("case", "x"), [s for _, s in out])})


def _noop(i):
    return i


def dask_round_trip(client, n: int = 1000) -> float:
    """Seconds per task of a no-op through the scheduler (submit, run, gather; no file), ``n`` tasks."""
    client.gather(client.map(_noop, range(50), pure=False))  # warm
    t0 = time.perf_counter()
    client.gather(client.map(_noop, range(n), pure=False))
    return (time.perf_counter() - t0) / n


def bench_fft(n: int, tmp: pathlib.Path, n_files: int | None = None) -> tuple[list[dict], dict]:
    """Part 2: tiny inversions on 2 workers: ``n_files`` (default ``n``) at 1 and 100 per task with one file
    each, and ``n`` at 100 per key (one file per 100), also serially. Returns the rows and the per-item
    costs derived from them (s): one inversion, the Dask round trip of a task, one result file."""
    shared = dict(operator=halfspace_fourier_operator((64,), 50e-6, 0.5e-3),
                  prior=StationaryPrior(variance=1e6, correlation_length=0.5e-3), noise_std=10.0)
    t0 = time.perf_counter()
    for _ in range(200):
        _one_fft(np.random.default_rng(0), **shared)
    t_inv = (time.perf_counter() - t0) / 200
    print(f"one inversion alone (no file): {1e3 * t_inv:.3f} ms")
    n_one = n if n_files is None else min(n, n_files)
    items = {f"fft-{i:05d}": i for i in range(n_one)}
    groups = {f"fft-group-{i:03d}": i for i in range(-(-n // 100))}
    rows = []
    cluster, client, _ = _cluster(2)
    client.run(lambda: __import__("tactilab.inversion.gaussian"))
    rt = dask_round_trip(client)
    print(f"Dask round trip per no-op task (2 workers): {1e3 * rt:.2f} ms")
    for label, its, per_task, extra in (("1 per task, 1 per file", items, 1, {}),
                                        ("100 per task, 1 per file", items, 100, {}),
                                        ("100 per file (one key = 100 inversions)", groups, 1, {"group": 100})):
        rep = run_batch(_fft_task, its, seed=3, out_dir=tmp / f"fft-{len(rows)}", client=client,
                        shared=dict(shared, **extra), per_task=per_task, progress=False)
        count = len(its) * extra.get("group", 1)
        rows.append(dict(run=f"LocalCluster(2), {label}", inversions=count, tasks=-(-len(its) // per_task),
                         files=len(its), wall=rep.wall_s, per_item_ms=1e3 * rep.wall_s / count, kind="measured"))
        print(rows[-1], flush=True)
    client.close()
    cluster.close()
    rep = run_batch(_fft_task, groups, seed=3, out_dir=tmp / "fft-serial", workers=0, shared=dict(shared, group=100),
                    progress=False)
    rows.append(dict(run="serial, 100 per file", inversions=100 * len(groups), tasks=len(groups), files=len(groups),
                     wall=rep.wall_s, per_item_ms=1e3 * rep.wall_s / (100 * len(groups)), kind="measured",
                     same=_same(tmp / "fft-serial", tmp / "fft-2", list(groups))))
    if n_one < n:  # the one-file-per-inversion runs were scaled down: extrapolate them linearly to n
        for i in (0, 1):
            r = rows[i]
            rows.append(dict(run=r["run"], inversions=n, tasks=-(-n // (1 if i == 0 else 100)), files=n,
                             wall=r["per_item_ms"] * n / 1e3, per_item_ms=r["per_item_ms"],
                             kind=f"EXTRAPOLATED from {n_one}"))
    costs = dict(inversion=t_inv, round_trip=rt, file=result_file_s(tmp / "files", shared))
    return rows, costs


def result_file_s(folder: pathlib.Path, shared: dict, n: int = 50) -> float:
    """Seconds to write one result of a single inversion (netCDF4 via h5netcdf, atomic rename), in-process."""
    from tactilab.core.batch import _write_atomic, result_path

    (folder / "results").mkdir(parents=True)
    result = _fft_task(0, np.random.default_rng(0), **shared)
    t0 = time.perf_counter()
    for i in range(n):
        _write_atomic(result, result_path(folder, f"k{i}"), f"k{i}", 0, 0.0)
    return (time.perf_counter() - t0) / n


#: ``--quick``: counts for a run of a few minutes on 2 cores (the tables say what was scaled down)
QUICK = dict(recordings=48, fft=10000, fft_files=400)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--recordings", type=int, default=200, help="number of defect-scan recordings (count)")
    parser.add_argument("--fft", type=int, default=10000, help="number of small FFT inversions (count)")
    parser.add_argument("--fft-files", type=int, default=None,
                        help="inversions in the one-file-per-inversion runs (count; default: --fft); fewer are "
                             "extrapolated linearly to --fft and marked EXTRAPOLATED")
    parser.add_argument("--workers", default="1,2", help="LocalCluster sizes, comma-separated (counts)")
    parser.add_argument("--quick", action="store_true",
                        help=f"a run of a few minutes on 2 cores: --recordings {QUICK['recordings']} --fft "
                             f"{QUICK['fft']} --fft-files {QUICK['fft_files']}")
    args = parser.parse_args(argv)
    if args.quick:
        args.recordings, args.fft, args.fft_files = QUICK["recordings"], QUICK["fft"], QUICK["fft_files"]
    workers = [int(w) for w in args.workers.split(",") if w.strip()]
    t_start = time.perf_counter()
    print(f"machine: {os.cpu_count()} CPU cores, load average {os.getloadavg()[0]:.1f} at start")
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="bench_batch_"))
    try:
        if args.recordings:
            rows = bench_recordings(args.recordings, workers, tmp)
            print(f"\n{args.recordings} defect-scan recordings, one task each")
            print("| run | start-up (s) | wall (s) | speedup | compute per task (s) | busy | overhead per task (ms) "
                  "| peak RSS per worker (MiB) | bitwise = serial |\n|---|---|---|---|---|---|---|---|---|")
            for r in rows:
                print(f"| {r['run']} | {r['start']:.1f} | {r['wall']:.1f} | {r['speedup']:.2f} | {r['compute']:.2f} | "
                      f"{r['busy']:.2f} | {1e3 * r['overhead']:.0f} | {r['rss']:.0f} | {'yes' if r['same'] else 'NO'} |")
        if args.fft:
            rows, costs = bench_fft(args.fft, tmp, args.fft_files)
            print("\nsmall FFT inversions (64 nodes)")
            print("| run | inversions | Dask tasks | files | wall (s) | per inversion (ms) | |\n|---|---|---|---|---|---|---|")
            for r in rows:
                print(f"| {r['run']} | {r['inversions']} | {r['tasks']} | {r['files']} | {r['wall']:.1f} | "
                      f"{r['per_item_ms']:.2f} | {r['kind']} |")
            print(f"serial and 2-worker results of the grouped run bitwise identical: {rows[3]['same']}")
            print(f"per-item costs: one inversion {1e3 * costs['inversion']:.2f} ms; one result file written "
                  f"(h5netcdf, atomic rename) {1e3 * costs['file']:.1f} ms; Dask round trip of a no-op task "
                  f"{1e3 * costs['round_trip']:.2f} ms (wall per task, 2 workers)")
        print(f"load average {os.getloadavg()[0]:.1f} at the end; whole benchmark {time.perf_counter() - t_start:.0f} s")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()

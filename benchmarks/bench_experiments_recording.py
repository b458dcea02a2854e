"""Benchmark: durable per-trial write cost, and resume (replay) time as a session grows.

Run: ``python benchmarks/bench_experiments_recording.py [--trials 300] [--quick]``

Table 1 -- per-trial durable write cost: the four events of a trial (planned, presented,
response, complete + trial row) as the runner commits them now, in TWO transactions (planned
with presented, response with complete), against the former four (one per event), in WAL mode
with ``synchronous=FULL`` (one fsync per commit), on the working folder's disk and on tmpfs. Baseline:
the same writes with ``synchronous=OFF`` (no fsync: not durable), and the "write everything at
exit" pattern of runners that lose a session on a crash (its per-trial share).

Table 2 -- replay time for ``tactilab experiment resume`` as the session grows: read the log,
validate every trial record, and replay the procedure (staircase; psi with a 30 x 5 x 3 grid
over 30 levels). "exact" checks that the replayed estimate equals the live one bit for bit.
A resume now replays once (the command line reads only the header first: "header s"); it used
to replay twice.

Table 3 -- accuracy of the demo's staircase design (two interleaved 1-up-2-down tracks, 40
trials) against the simulated observer's true 70.7 % point, over seeds.
"""

from __future__ import annotations

import argparse
import json
import os
import sqlite3
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.demo.experiments import DEMO_PROTOCOL
from tactilab.experiments.session.responses import true_threshold_2ifc
from tactilab.experiments.devices.display import Display, PlaybackReport
from tactilab.experiments.session.recording import Recorder
from tactilab.experiments.session.responses import SimulatedObserver
from tactilab.experiments.session.resume import replay_session, session_header
from tactilab.experiments.session.runner import new_session

PAYLOAD = {"block": 0, "track": 1, "parameter": "amplitude_m", "level": 2.5e-6, "target": "2",
           "stimuli": [{"amplitude_m": 0.0, "pitch_m": 2e-3, "speed_m_per_s": 0.04, "duration_s": 0.3}] * 2}
RECORD = json.dumps({**PAYLOAD, "procedure_state": {"levels": [2.5e-6, 3e-6], "reversals": [[1e-6] * 6] * 2},
                     "response": "2", "rt_s": 0.4, "utc": "2026-11-22T05:00:00+00:00"})


def write_cost(folder: Path, n_trials: int, synchronous: str, commits: int = 2) -> list[float]:
    """Seconds per trial for the runner's writes of one trial: ``commits`` = 2 (now) or 4 (before)."""
    path = folder / f"bench-{synchronous}-{time.monotonic_ns()}.sqlite"
    recorder = Recorder.create(path, {"bench": True})
    recorder.connection.execute(f"PRAGMA synchronous={synchronous}")
    costs = []
    try:
        for i in range(n_trials):
            start = time.perf_counter()
            row = [("INSERT INTO trials VALUES (?, ?)", (i, RECORD))]
            if commits == 4:
                recorder.log("trial_planned", i, 0, PAYLOAD)
                recorder.log("stimulus_presented", i, 0, {"stimuli": PAYLOAD["stimuli"]})
                recorder.log("response", i, 0, {"response": "2", "rt_s": 0.4})
                recorder.log("trial_complete", i, 0, {"outcome": True}, extra=row)
            else:
                recorder.log_events([("trial_planned", i, 0, PAYLOAD),
                                     ("stimulus_presented", i, 0, {"stimuli": PAYLOAD["stimuli"]})])
                recorder.log_events([("response", i, 0, {"response": "2", "rt_s": 0.4}),
                                     ("trial_complete", i, 0, {"outcome": True})], extra=row)
            costs.append(time.perf_counter() - start)
    finally:
        recorder.close()
    return costs


def write_at_exit_cost(folder: Path, n_trials: int) -> float:
    """Per-trial share of writing all rows once at the end (one transaction, one fsync)."""
    path = folder / f"bench-exit-{time.monotonic_ns()}.sqlite"
    start = time.perf_counter()
    connection = sqlite3.connect(path)
    connection.execute("PRAGMA synchronous=FULL")
    connection.execute("CREATE TABLE trials (trial_index INTEGER PRIMARY KEY, record TEXT)")
    connection.executemany("INSERT INTO trials VALUES (?, ?)", [(i, RECORD) for i in range(n_trials)])
    connection.commit()
    connection.close()
    return (time.perf_counter() - start) / n_trials


class NullDisplay(Display):
    """Plays instantly: the replay benchmark needs sessions, not playback."""

    def _play(self, frames, frame_rate_hz):
        return PlaybackReport(frames_sent=len(frames), late=0, missing=0, acked=len(frames))

    def _zero(self):
        pass


def make_protocol(method: str, n_trials: int) -> Protocol:
    stimulus = {"amplitude_m": "2um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s", "duration_s": "2ms",
                "ramp_s": 0}
    if method == "staircase":
        procedure = {"method": "staircase", "parameter": "amplitude_m", "tracks": [
            {"start": "8um", "step_sizes": [0.2, 0.05], "min_level": "0.2um", "max_level": "50um",
             "max_trials": n_trials // 2}] * 2}
    else:
        procedure = {"method": "psi", "parameter": "amplitude_m", "n_trials": n_trials,
                     "levels": {"start": "0.3um", "stop": "30um", "n": 30, "scale": "log"},
                     "parameters": {"threshold": {"start": "0.5um", "stop": "20um", "n": 30, "scale": "log"},
                                    "slope": [1.0, 2.0, 3.0, 4.0, 6.0], "lapse": [0.0, 0.02, 0.05]}}
    return Protocol.model_validate({"name": "bench", "seed": 1, "iti_s": 0, "task": {"kind": "2ifc"},
                                    "stimulus": stimulus, "procedure": procedure})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=300, help="trials for the write-cost table")
    parser.add_argument("--quick", action="store_true", help="smaller sessions for the replay table")
    parser.add_argument("--seeds", type=int, default=12, help="seeds for the demo-design accuracy table")
    args = parser.parse_args()

    folders = {"disk (working dir)": Path(tempfile.mkdtemp(prefix="tactilab-bench-", dir="."))}
    if Path("/dev/shm").is_dir():
        folders["tmpfs (/dev/shm)"] = Path(tempfile.mkdtemp(prefix="tactilab-bench-", dir="/dev/shm"))
    print(f"Per-trial durable write cost, {args.trials} trials (target < 5 ms)")
    print(f"{'storage':<20} {'mode':<26} {'median ms':>10} {'p95 ms':>8} {'ratio to no-fsync':>18}")
    for name, folder in folders.items():
        full = write_cost(folder, args.trials, "FULL")
        full4 = write_cost(folder, args.trials, "FULL", commits=4)
        off = write_cost(folder, args.trials, "OFF")
        exit_share = write_at_exit_cost(folder, args.trials)
        base = statistics.median(off)
        for mode, costs in (("2 commits, sync=FULL (now)", full), ("4 commits, sync=FULL (was)", full4),
                            ("2 commits, sync=OFF", off)):
            print(f"{name:<20} {mode:<26} {1e3 * statistics.median(costs):>10.3f} "
                  f"{1e3 * float(np.percentile(costs, 95)):>8.3f} {statistics.median(costs) / base:>18.1f}")
        print(f"{name:<20} {'all at exit (not durable)':<26} {1e3 * exit_share:>10.3f} {'':>8} "
              f"{exit_share / base:>18.2f}")

    sizes = (50, 200, 600) if args.quick else (100, 300, 1000, 3000)
    shm = folders.get("tmpfs (/dev/shm)", folders["disk (working dir)"])
    print("\nResume replay time vs session length (read log + validate records + replay procedure)")
    print(f"{'procedure':<10} {'trials':>7} {'header s':>9} {'replay s':>9} {'ms/trial':>9} {'exact':>6}")
    for method in ("staircase", "psi"):
        for n in sizes:
            protocol = make_protocol(method, n)
            path = shm / f"replay-{method}-{n}.sqlite"
            live = new_session(protocol, path, NullDisplay(DisplayDescription.braille_row()),
                               SimulatedObserver(protocol), subject="B1", realtime=False)
            start = time.perf_counter()
            session_header(path)
            header = time.perf_counter() - start
            start = time.perf_counter()
            state = replay_session(path)
            elapsed = time.perf_counter() - start
            exact = state.procedure.estimate() == live.estimate
            print(f"{method:<10} {n:>7} {header:>9.4f} {elapsed:>9.3f} {1e3 * elapsed / n:>9.3f} {str(exact):>6}")
    print(f"\nDemo staircase design (experiments/demo.py) over {args.seeds} seeds: estimate / observer's true "
          "70.7 % point - 1")
    errors = []
    for seed in range(args.seeds):
        protocol = Protocol.model_validate({**DEMO_PROTOCOL, "seed": seed})
        observer = SimulatedObserver(protocol)
        path = shm / f"demo-{seed}.sqlite"
        result = new_session(protocol, path, NullDisplay(DisplayDescription.braille_row()), observer,
                             subject="B2", realtime=False)
        errors.append(result.estimate["threshold"] / true_threshold_2ifc(observer, protocol) - 1)
    print(f"{'seeds':>6} {'mean error %':>13} {'sd %':>6} {'worst %':>8}")
    print(f"{args.seeds:>6} {100 * np.mean(errors):>13.1f} {100 * np.std(errors):>6.1f} "
          f"{100 * max(errors, key=abs):>8.1f}")
    for folder in folders.values():
        for file in folder.iterdir():
            file.unlink()
        os.rmdir(folder)


if __name__ == "__main__":
    main()

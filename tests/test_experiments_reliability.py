"""Reliability of the runner: kill -9 at random points, full disks, read-only files, locks.

The kill test runs each session in a forked child process (the parent has already imported
everything, so a child starts in milliseconds) and sends it SIGKILL after a random delay,
then resumes, possibly killing it again, until the session completes. The child reports each
``trial_complete`` commit through a pipe right after it returns, so the parent knows which
trials were durably completed before the kill. Oracles: every reported trial is in the
database; the final session equals an uninterrupted run with the same seed (same trial
sequence, same responses, same procedure state and estimates); interrupted trials are
repeated and marked. One session is also killed through the real command line.
"""

from __future__ import annotations

import os
import shutil
import signal
import threading
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments.session import recording
from tactilab.experiments.session.recording import Recorder, RecordingError, SessionLockedError, SessionLog
from tactilab.experiments.session.responses import SimulatedObserver
from tactilab.experiments.session.resume import replay_session, resume_session, session_status
from tactilab.experiments.session.runner import new_session
from tactilab.experiments.devices.simulated_display import SimulatedDisplay

pytestmark = [
    pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork (POSIX)"),
    # numpy's idle BLAS worker threads trigger this warning; the children never share them
    pytest.mark.filterwarnings("ignore:This process .* is multi-threaded:DeprecationWarning"),
]


@pytest.fixture
def fast_dir(tmp_path):
    """A folder in RAM when available (/dev/shm): kill -9 durability needs the commit to reach
    the OS, not the platter, and tmpfs makes the 20+ sessions fast. Power-loss durability
    (fsync, synchronous=FULL) is checked in the recorder tests and the benchmark."""
    shm = Path("/dev/shm")
    if not (shm.is_dir() and os.access(shm, os.W_OK)):
        yield tmp_path
        return
    folder = Path(tempfile.mkdtemp(prefix="tactilab-kill-", dir=shm))
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)

STIMULUS = {"amplitude_m": "3um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s",
            "duration_s": "40ms", "ramp_s": "10ms"}
PROCEDURES = [
    {"method": "staircase", "parameter": "amplitude_m", "tracks": [
        {"start": "4um", "step_sizes": [0.2, 0.1], "min_level": "0.3um", "max_level": "8um", "max_trials": 4},
        {"start": "0.5um", "down": 3, "step_sizes": [0.2], "min_level": "0.3um", "max_level": "8um",
         "max_trials": 4}]},
    {"method": "psi", "parameter": "amplitude_m", "levels": {"start": "0.3um", "stop": "8um", "n": 12, "scale": "log"},
     "parameters": {"threshold": {"start": "0.5um", "stop": "6um", "n": 10, "scale": "log"},
                    "slope": [1.5, 3.0], "lapse": [0.0, 0.04]}, "n_trials": 8},
    {"method": "constant_stimuli", "parameter": "amplitude_m", "levels": ["0.5um", "1.5um", "3um"],
     "repeats_per_block": 1, "n_blocks": 3},
]


def protocol_for(seed: int) -> Protocol:
    return Protocol.model_validate({"name": "kill", "seed": seed, "iti_s": 0,
                                    "task": {"kind": "2ifc", "interval_gap_s": "100ms"},
                                    "stimulus": STIMULUS, "procedure": PROCEDURES[seed % len(PROCEDURES)]})


def _components(protocol):
    return SimulatedDisplay(DisplayDescription.braille_row(), realtime=False), SimulatedObserver(protocol)


def _child(path, protocol, resume: bool, pipe_w: int) -> None:
    """Runs in the forked child: report each durable trial_complete, then run or resume."""
    original = Recorder.complete_trial

    def reporting(self, record, *args):
        original(self, record, *args)
        os.write(pipe_w, f"{record.trial_index}\n".encode())

    Recorder.complete_trial = reporting
    try:
        display, observer = _components(protocol)
        if resume:
            resume_session(path, display, observer, realtime=False)
        else:
            new_session(protocol, path, display, observer, subject="S01", realtime=False)
        os._exit(0)
    except BaseException:  # noqa: BLE001 - any failure is reported through the exit status
        import traceback

        os.write(2, traceback.format_exc().encode())
        os._exit(3)


def run_killed(path, protocol, delay_s: float | None, resume: bool) -> tuple[int, set[int]]:
    """Fork a runner, SIGKILL it after ``delay_s`` (None: let it finish); return (status, acked trials)."""
    assert threading.active_count() == 1, [t.name for t in threading.enumerate()]
    read_fd, write_fd = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - child
        os.close(read_fd)
        _child(path, protocol, resume, write_fd)
    os.close(write_fd)
    if delay_s is not None:
        time.sleep(delay_s)
        os.kill(pid, signal.SIGKILL)
    _, status = os.waitpid(pid, 0)
    with os.fdopen(read_fd) as pipe:
        acked = {int(line) for line in pipe.read().split()}
    return status, acked


def _comparable(trial):
    return (trial.trial_index, trial.block, trial.track, trial.level, trial.target, trial.response,
            trial.correct, trial.rt_s, trial.procedure_state,
            [s.model_dump() for s in trial.stimuli], trial.seed)


@pytest.mark.slow
def test_kill_minus_9_at_random_points_loses_nothing_and_resumes_exactly(fast_dir, seed):
    """>= 20 sessions, each killed 1-3 times at random delays; compare with uninterrupted runs."""
    rng = np.random.default_rng(seed)
    n_sessions, kills, repeated_seen = 21, 0, 0
    for s in range(n_sessions):
        protocol = protocol_for(1000 + s)
        reference = fast_dir / f"ref{s}.sqlite"
        display, observer = _components(protocol)
        t0 = time.perf_counter()
        new_session(protocol, reference, display, observer, subject="S01", realtime=False)
        duration = time.perf_counter() - t0
        path = fast_dir / f"kill{s}.sqlite"
        acked_all: set[int] = set()
        n_total = len(SessionLog(reference).trials())
        for attempt in range(int(rng.integers(1, 4))):
            resume = path.exists()
            done = len(SessionLog(path).trials()) if resume else 0
            if done == n_total:
                break
            # a random point within the (remaining) run: the first kill always lands mid-session
            delay = float(rng.uniform(0, 0.8 * duration * (n_total - done) / n_total))
            status, acked = run_killed(path, protocol, delay, resume)
            kills += os.WIFSIGNALED(status)
            acked_all |= acked
            if path.exists():
                done = {t.trial_index for t in SessionLog(path).trials()}
                assert acked_all <= done, f"session {s}: completed trials lost: {sorted(acked_all - done)}"
        while not (path.exists() and session_status(path)["status"] == "complete"):
            status, acked = run_killed(path, protocol, None, path.exists())  # finish without kills
            assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0, f"session {s}: resume failed"
        final, expected = SessionLog(path).trials(), SessionLog(reference).trials()
        assert [_comparable(t) for t in final] == [_comparable(t) for t in expected]
        assert replay_session(path).procedure.estimate() == replay_session(reference).procedure.estimate()
        repeated_seen += sum(t.repeated for t in final)
        events = SessionLog(path).events()
        for trial in final:  # repeated exactly when an earlier attempt reached the display
            earlier = {e["kind"] for e in events if e["trial_index"] == trial.trial_index
                       and e["attempt"] is not None and e["attempt"] < trial.attempt}
            assert trial.repeated == ("stimulus_presented" in earlier)
    print(f"{kills} kills over {n_sessions} sessions, {repeated_seen} repeated trials")
    assert kills >= 20, f"only {kills} runs were actually killed"
    assert repeated_seen > 0, "no interrupted trial was ever repeated: the kills missed every trial"


@pytest.mark.slow
def test_cli_run_killed_then_resumed(tmp_path):
    """The real command line, killed with SIGKILL mid-session, resumes to the same trials.

    The first run plays in real time (2 x 40 ms + 100 ms per trial) so that it is still running when
    the kill comes; the resume runs without waiting."""
    protocol = protocol_for(7)
    toml = tmp_path / "p.toml"
    toml.write_text(
        'name = "kill"\nseed = 7\niti_s = 0\n[task]\nkind = "2ifc"\ninterval_gap_s = "100ms"\n[stimulus]\n'
        + "".join(f'{k} = "{v}"\n' for k, v in STIMULUS.items())
        + '[procedure]\nmethod = "psi"\nparameter = "amplitude_m"\n'
        'levels = { start = "0.3um", stop = "8um", n = 12, scale = "log" }\nn_trials = 8\n'
        '[procedure.parameters]\nthreshold = { start = "0.5um", stop = "6um", n = 10, scale = "log" }\n'
        "slope = [1.5, 3.0]\nlapse = [0.0, 0.04]\n")
    assert Protocol.from_toml(toml) == protocol
    cmd = [sys.executable, "-m", "tactilab.cli", "experiment"]
    session = tmp_path / "sessions" / "sub-S07_ses-01_task-kill.sqlite"
    proc = subprocess.Popen(cmd + ["run", str(toml), "--subject", "S07", "--responses", "simulated",
                                   "--quiet", "--out", str(tmp_path / "sessions"), "--clipped", "allow"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # kill once at least 3 trials are durable
        if session.exists() and len(SessionLog(session).trials()) >= 3:
            break
        time.sleep(0.01)
    proc.kill()
    proc.wait()
    assert proc.returncode == -signal.SIGKILL, "the run finished before it could be killed"
    assert 3 <= len(SessionLog(session).trials()) < 8
    out = subprocess.run(cmd + ["resume", str(session), "--no-wait", "--quiet"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "complete after 8 trials" in out.stdout
    reference = tmp_path / "ref.sqlite"
    display = SimulatedDisplay(DisplayDescription.braille_row(), realtime=False)
    # the CLI's observer feels what the simulated display renders (its default --observer-strain)
    new_session(protocol, reference, display, SimulatedObserver(protocol, display=display), subject="S07",
                realtime=False, clipped="allow")
    assert [_comparable(t) for t in SessionLog(session).trials()] == \
        [_comparable(t) for t in SessionLog(reference).trials()]

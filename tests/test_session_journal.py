"""Signals from the first instruction and a journal that recovers itself (issue 26, items 2-3).

A SIGKILL at each SQL statement of ``resume``'s open (a fault-injection hook: SQLite's trace
callback kills the forked child as the statement starts) leaves a session that status, export
and resume still read; a SIGTERM while the file is opened or replayed is a clean stop; a reader
holding a read transaction at close is reported, never silent, and folded in by the next
status; a hot journal is recovered by a read-write open or reported with the command that
recovers it. Each run happens in a forked child (everything is imported already).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import sqlite3
import sys
import threading
import time

import pytest

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments.devices.simulated_display import SimulatedDisplay
from tactilab.experiments.session import recording, resume
from tactilab.experiments.session.recording import NotSelfContainedWarning, Recorder, SessionLog, file_state
from tactilab.experiments.session.responses import SimulatedObserver
from tactilab.experiments.session.resume import resume_session, session_status
from tactilab.experiments.session.runner import Runner, new_session

pytestmark = [
    pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork (POSIX)"),
    pytest.mark.filterwarnings("ignore:This process .* is multi-threaded:DeprecationWarning"),
]

PROTOCOL = Protocol.model_validate({
    "name": "journal", "seed": 3, "iti_s": 0, "task": {"kind": "2ifc", "interval_gap_s": "100ms"},
    "stimulus": {"amplitude_m": "3um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s", "duration_s": "40ms",
                 "ramp_s": "10ms"},
    "procedure": {"method": "constant_stimuli", "parameter": "amplitude_m", "levels": ["0.5um", "3um"],
                  "repeats_per_block": 1, "n_blocks": 2}})


def _components():
    return SimulatedDisplay(DisplayDescription.braille_row(), realtime=False), SimulatedObserver(PROTOCOL)


@pytest.fixture(scope="module")
def stopped_session(tmp_path_factory):
    """A session stopped cleanly after 2 of 4 trials (a stop arrives as trial 2 starts)."""
    path = tmp_path_factory.mktemp("base") / "sub-S01_ses-01_task-journal.sqlite"
    original = Runner.run_trial

    def stopping(self, index, *args):
        if index == 2:
            raise KeyboardInterrupt("SIGTERM")
        return original(self, index, *args)

    Runner.run_trial = stopping
    try:
        result = new_session(PROTOCOL, path, *_components(), subject="S01", realtime=False)
    finally:
        Runner.run_trial = original
    assert result.status == "interrupted" and result.n_completed == 2
    assert file_state(path)["self_contained"] and path.read_bytes()[18:20] == b"\x02\x02"
    return path


def _fork(work) -> int:
    """Run ``work()`` in a forked child; its exit status (0: returned, 3: raised) or -signal."""
    assert threading.active_count() == 1, [t.name for t in threading.enumerate()]
    pid = os.fork()
    if pid == 0:  # pragma: no cover - child
        try:
            work()
            os._exit(0)
        except BaseException:  # noqa: BLE001 - reported through the exit status
            import traceback

            os.write(2, traceback.format_exc().encode())
            os._exit(3)
    _, status = os.waitpid(pid, 0)
    return -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)


def _kill_at_statement(n: int, path) -> None:
    """The fault-injection hook: SIGKILL this process at its n-th file operation: taking the
    session's lock, opening a connection, or starting an SQL statement on any connection (the
    trace callback runs before SQLite executes the statement)."""
    connect, lock, seen = sqlite3.connect, recording._FileLock.__init__, [0]

    def point(*_) -> None:
        seen[0] += 1
        if seen[0] == n:
            os.kill(os.getpid(), signal.SIGKILL)

    def traced(*args, **kwargs):
        point()
        connection = connect(*args, **kwargs)
        connection.set_trace_callback(point)
        return connection

    def locking(self, *args, **kwargs):
        point()
        lock(self, *args, **kwargs)

    sqlite3.connect = traced
    recording._FileLock.__init__ = locking

    def stop_at_first_trial(self, index, *args):  # a stop where the first stimulus would start:
        raise KeyboardInterrupt("SIGTERM")  # the stop is logged and the file closed (more kill points)

    Runner.run_trial = stop_at_first_trial
    assert resume_session(path, *_components(), realtime=False).status == "interrupted"


@pytest.mark.parametrize("at_rest", ["wal", "delete"])
def test_a_sigkill_at_each_statement_of_resumes_open_leaves_every_command_working(stopped_session, tmp_path,
                                                                                  at_rest, capsys):
    """At rest in WAL there is no journal-mode switch to interrupt; a session closed in rollback
    mode by an older version is switched once, and a kill there leaves nothing unreadable. The
    points run from the lock through the replay and ``session_resumed`` to a stop at the first
    stimulus, its ``session_stopped`` and the close's checkpoint (a kill inside the close)."""
    killed = 0
    for n in range(1, 60):
        path = tmp_path / f"{n}" / stopped_session.name
        path.parent.mkdir()
        shutil.copy(stopped_session, path)
        if at_rest == "delete":
            with contextlib.closing(sqlite3.connect(path)) as db:
                db.execute("PRAGMA journal_mode=DELETE")
        status = _fork(lambda: _kill_at_statement(n, path))
        if status == 0:  # the run got through its close: every operation before was a kill point
            break
        assert status == -signal.SIGKILL
        killed += 1
        info = session_status(path)  # status works (and folds a leftover log in: writable folder)
        assert info["completed"] == 2 and info["status"] == "interrupted" and info["self_contained"], info
        assert not list(path.parent.glob("*-journal")) and not list(path.parent.glob("*-wal"))
        if n % 4 == 0 or n < 3:  # export and resume to the end (every 4th point keeps the test short)
            assert cli_main(["experiment", "export", str(path), "--format", "csv", "--out", str(path.parent)]) == 0
            result = resume_session(path, *_components(), realtime=False)
            assert result.status == "complete" and result.n_completed == 4
        shutil.rmtree(path.parent)
    assert killed >= 20, killed
    capsys.readouterr()


def _signal_during(target, name: str, signum: int):
    """Patch ``target.name`` to send this process ``signum`` as it starts."""
    original = getattr(target, name)

    def signalled(*args, **kwargs):
        os.kill(os.getpid(), signum)
        return original(*args, **kwargs)

    setattr(target, name, signalled)


@pytest.mark.parametrize("where", ["replay", "open"])
def test_sigterm_while_resume_opens_or_replays_is_a_clean_stop(stopped_session, tmp_path, where):
    path = tmp_path / stopped_session.name
    shutil.copy(stopped_session, path)

    def work():
        if where == "replay":
            _signal_during(resume, "replay_log", signal.SIGTERM)
        else:  # inside the held block of Recorder.open: delivered once the file is open
            _signal_during(recording.Recorder, "_connect", signal.SIGTERM)
        result = resume_session(path, *_components(), realtime=False)
        os._exit(0 if result.status == "interrupted" and result.n_completed == 2 else 4)

    assert _fork(work) == 0
    log = SessionLog(path)
    try:
        events, n = log.events(), len(log.trials())
    finally:
        log.close()
    assert n == 2 and events[-1]["kind"] == "session_stopped"
    reason = events[-1]["payload"]["reason"]
    assert "SIGTERM" in reason and "before the first stimulus" in reason
    assert file_state(path)["self_contained"] and not list(tmp_path.glob("*-wal"))
    assert resume_session(path, *_components(), realtime=False).status == "complete"


def test_a_reader_in_a_transaction_at_close_is_reported_and_folded_in_later(stopped_session, tmp_path, capsys,
                                                                          monkeypatch):
    path = tmp_path / stopped_session.name
    shutil.copy(stopped_session, path)
    recorder = Recorder.open(path)
    recorder.log("session_resumed", payload={"completed": 2, "repeating": []})
    reader = sqlite3.connect(f"file:{path}?mode=ro", uri=True, isolation_level=None)
    reader.execute("BEGIN")
    reader.execute("SELECT count(*) FROM events").fetchone()  # holds a read transaction
    with pytest.warns(NotSelfContainedWarning, match="is not yet one self-contained file .*experiment status"):
        assert recorder.close() is False
    assert file_state(path)["wal_bytes"] > 0
    monkeypatch.setattr(recording, "folder_writable", lambda folder: False)  # as on read-only media
    assert cli_main(["experiment", "status", str(path)]) == 2
    err = capsys.readouterr().err
    assert "is not self-contained" in err and "to fold the log in" in err and len(err.splitlines()) == 1
    monkeypatch.undo()
    assert cli_main(["experiment", "status", str(path)]) == 0
    assert "file: not self-contained" in capsys.readouterr().out  # the reader still holds the log
    reader.execute("COMMIT")
    reader.close()
    assert cli_main(["experiment", "status", str(path)]) == 0  # the last reader folds the log in
    assert "not self-contained" not in capsys.readouterr().out
    assert file_state(path)["self_contained"] and sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    monkeypatch.setattr(recording, "folder_writable", lambda folder: False)
    assert session_status(path)["completed"] == 2  # read as immutable, nothing created
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


def test_a_hot_journal_is_recovered_or_reported_with_the_command(stopped_session, tmp_path, monkeypatch, capsys):
    """An older version's session at rest in rollback mode, killed inside a big transaction."""
    path = tmp_path / stopped_session.name
    shutil.copy(stopped_session, path)
    with contextlib.closing(sqlite3.connect(path)) as db:
        db.execute("PRAGMA journal_mode=DELETE")

    def torn():
        db = sqlite3.connect(path, isolation_level=None)
        db.execute("PRAGMA cache_size=1")  # spill to the file before the commit
        db.execute("BEGIN")
        db.execute("UPDATE trials SET record = 'torn'")
        db.executemany("INSERT INTO events (kind, utc, monotonic_ns, payload) VALUES ('response', '', 0, ?)",
                       [("x" * 500,)] * 400)
        os.kill(os.getpid(), signal.SIGKILL)

    assert _fork(torn) == -signal.SIGKILL
    assert file_state(path)["hot_journal"]
    monkeypatch.setattr(recording, "folder_writable", lambda folder: False)
    assert cli_main(["experiment", "status", str(path)]) == 2
    err = capsys.readouterr().err
    assert "has a hot journal" in err and "tactilab experiment status COPY" in err and len(err.splitlines()) == 1
    monkeypatch.undo()
    info = session_status(path)  # a read-write open rolls the journal back
    assert info["completed"] == 2 and info["self_contained"] and not file_state(path)["hot_journal"]


def test_a_stop_before_the_session_is_opened_is_a_clean_stop_of_the_command(stopped_session, tmp_path):
    """The command's handlers are installed from its first instruction: a SIGTERM while ``resume``
    reads the header (before the file is opened for writing) exits 130 with one line, no traceback."""
    path = tmp_path / stopped_session.name
    shutil.copy(stopped_session, path)
    read, write = os.pipe()

    def work():
        sys.stderr = open(write, "w", closefd=False)  # noqa: SIM115 - the child's stderr, to the pipe
        _signal_during(resume, "SessionLog", signal.SIGTERM)
        code = cli_main(["experiment", "resume", str(path), "--responses", "simulated", "--no-wait", "--quiet"])
        sys.stderr.flush()
        os._exit(code)

    assert _fork(work) == 130
    os.close(write)
    with os.fdopen(read) as pipe:
        err = pipe.read()
    assert err.strip() == "tactilab: interrupted", err
    assert session_status(path)["completed"] == 2 and file_state(path)["self_contained"]


@pytest.mark.parametrize("where", ["create", "start_up"])
def test_sigterm_while_run_starts_is_a_clean_stop(tmp_path, where):
    """``new_session``: a SIGTERM while the file is created (held, delivered once it exists) logs
    ``session_stopped`` before the first stimulus; one before the file exists leaves no file."""
    path = tmp_path / "s.sqlite"

    def work():
        display, observer = _components()
        if where == "create":
            _signal_during(recording.Recorder, "_connect", signal.SIGTERM)
        else:
            _signal_during(display, "zero", signal.SIGTERM)
        try:
            result = new_session(PROTOCOL, path, display, observer, subject="S01", realtime=False)
        except KeyboardInterrupt:
            os._exit(130)
        os._exit(0 if result.status == "interrupted" and result.n_completed == 0 else 4)

    if where == "start_up":
        assert _fork(work) == 130 and not path.exists()  # KeyboardInterrupt, before anything was written
        return
    assert _fork(work) == 0
    log = SessionLog(path)
    try:
        kinds, reason = [e["kind"] for e in log.events()], log.events()[-1]["payload"].get("reason", "")
    finally:
        log.close()
    assert kinds == ["session_started", "session_stopped"] and "SIGTERM" in reason
    assert file_state(path)["self_contained"] and sorted(p.name for p in tmp_path.iterdir()) == ["s.sqlite"]


def test_signals_held_holds_a_signal_taken_by_another_thread():
    """A process-directed signal may be taken by any thread that does not block it (scipy's FFT
    starts worker threads); the hold must not depend on the main thread's mask. Nested holds keep
    it until the outermost one ends; then it is delivered once, as KeyboardInterrupt."""
    from tactilab.experiments.session import signals_held, stop_signals

    before, reached = signal.getsignal(signal.SIGTERM), False
    release = threading.Event()
    other = threading.Thread(target=release.wait, daemon=True)  # a thread with the default signal mask
    other.start()
    try:
        with stop_signals(), pytest.raises(KeyboardInterrupt, match="SIGTERM"):
            with signals_held():
                with signals_held():
                    os.kill(os.getpid(), signal.SIGTERM)
                    os.kill(os.getpid(), signal.SIGTERM)
                    for _ in range(20):  # give the other thread time to take it, and the handler to run
                        time.sleep(0.01)
                reached = True
            raise AssertionError("the held signal was not delivered when the hold ended")
    finally:
        release.set()
        other.join()
    assert reached, "the signal was delivered inside the hold"
    assert signal.getsignal(signal.SIGTERM) == before

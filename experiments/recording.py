"""Durable session recording: SQLite in WAL mode with ``synchronous=FULL``, one commit per event.

A session is one SQLite file. Table ``meta`` holds the session's provenance (subject code,
protocol JSON, seed, package version, display id, response source); table ``events`` holds
every event in order, each committed (and fsynced) before the runner takes the next step:

``session_started``, ``session_resumed``, ``trial_planned``, ``stimulus_presented`` (written
BEFORE the display is driven), ``response``, ``trial_complete``, ``safety_intervention``,
``session_stopped``, ``session_failed``, ``session_complete``, ``display_fault`` (a stimulus that
did not reach the display as commanded: the trial is not scored and is repeated on resume).

Table ``trials`` holds one validated :class:`TrialRecord` (JSON) per completed trial, written
in the same transaction as its ``trial_complete`` event. A session is locked while a runner
holds it: an OS file lock (``flock``) on ``<file>.lock``, released by the kernel even when the
process is killed, so a second runner is refused and a killed one never leaves a stale lock.
"""

from __future__ import annotations

import json
import os
import sqlite3
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from tactilab.data_schemas.experiment_records import TrialRecord

SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS events (
    id INTEGER PRIMARY KEY AUTOINCREMENT, kind TEXT NOT NULL, trial_index INTEGER,
    attempt INTEGER, utc TEXT NOT NULL, monotonic_ns INTEGER NOT NULL, payload TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS trials (trial_index INTEGER PRIMARY KEY, record TEXT NOT NULL);
"""
EVENT_KINDS = ("session_started", "session_resumed", "trial_planned", "stimulus_presented",
               "response", "trial_complete", "safety_intervention", "session_stopped",
               "session_failed", "session_complete", "display_fault")


class RecordingError(OSError):
    """Writing to the session database failed (disk full, read-only, I/O error)."""


class SessionLockedError(OSError):
    """Another runner holds the session."""


def utc_now() -> str:
    """Current UTC time, ISO 8601 with microseconds."""
    return datetime.now(UTC).isoformat(timespec="microseconds")


class _FileLock:
    """An exclusive, non-blocking OS lock on ``path`` (flock; msvcrt on Windows)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.handle = open(path, "a+")  # noqa: SIM115 - held for the session's life
        try:
            if os.name == "nt":  # pragma: no cover - exercised on Windows only
                import msvcrt

                msvcrt.locking(self.handle.fileno(), msvcrt.LK_NBLCK, 1)
            else:
                import fcntl

                fcntl.flock(self.handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self.handle.seek(0)
            holder = self.handle.read().strip() or "another process"
            self.handle.close()
            raise SessionLockedError(
                f"session: {path.with_suffix('')} is locked by a running runner ({holder}); wait "
                "for it to finish or stop it, then resume"
            ) from None
        self.handle.seek(0)
        self.handle.truncate()
        self.handle.write(f"pid {os.getpid()} since {utc_now()}")
        self.handle.flush()

    def release(self) -> None:
        if not self.handle.closed:
            self.handle.close()  # closing the descriptor releases the lock


class Recorder:
    """A locked, durable event log for one session.

    Use :meth:`create` for a new session and :meth:`open` to continue one. Every write commits
    before returning; failures raise :class:`RecordingError` naming the cause and the fix.
    """

    def __init__(self, path: Path, connection: sqlite3.Connection, lock: _FileLock) -> None:
        self.path, self.connection, self._lock = path, connection, lock

    @staticmethod
    def _connect(path: Path, lock: _FileLock) -> sqlite3.Connection:
        try:
            connection = sqlite3.connect(path, isolation_level=None, timeout=5.0)
            mode = connection.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            connection.execute("PRAGMA synchronous=FULL")
            connection.executescript(SCHEMA)
        except sqlite3.Error as exc:
            lock.release()
            raise RecordingError(
                f"session: cannot open {path} for writing ({exc}); check that the file and its "
                "folder are writable and the disk has space"
            ) from None
        if mode.lower() != "wal":
            lock.release()
            raise RecordingError(f"session: {path} cannot use WAL journaling (got {mode!r}); use a local disk")
        return connection

    @classmethod
    def create(cls, path: str | Path, meta: dict[str, Any]) -> Recorder:
        """Create a new session file with its metadata, atomically, and lock it.

        The file is built as ``<name>.partial`` and renamed into place, so a session file
        either exists with its full metadata or not at all (a kill during creation leaves
        nothing to resume). An existing file is refused.
        """
        path = Path(path)
        if path.exists():
            raise FileExistsError(
                f"session: {path} already exists; resume it with `tactilab experiment resume "
                f"{path}` or choose another --out / --session"
            )
        path.parent.mkdir(parents=True, exist_ok=True)
        lock = _FileLock(lock_path(path))
        partial = path.with_name(path.name + ".partial")
        try:
            partial.unlink(missing_ok=True)
            connection = sqlite3.connect(partial, isolation_level=None)
            connection.execute("PRAGMA journal_mode=WAL")
            connection.executescript(SCHEMA)
            connection.execute("BEGIN IMMEDIATE")
            connection.executemany("INSERT INTO meta VALUES (?, ?)",
                                   [(k, json.dumps(v)) for k, v in meta.items()])
            connection.execute("COMMIT")
            connection.close()
            os.link(partial, path)  # atomic, and never replaces a file that appeared meanwhile
            partial.unlink()
            _fsync_folder(path.parent)
        except sqlite3.Error as exc:
            lock.release()
            raise RecordingError(
                f"session: cannot create {path} ({exc}); check that the folder is writable and "
                "the disk has space"
            ) from None
        except BaseException:
            lock.release()
            raise
        return cls(path, cls._connect(path, lock), lock)

    @classmethod
    def open(cls, path: str | Path) -> Recorder:
        """Open an existing session for writing, taking its lock."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"session: no session file {path}; give the .sqlite file that `experiment run` printed")
        lock = _FileLock(lock_path(path))
        return cls(path, cls._connect(path, lock), lock)

    def _write(self, statements: list[tuple[str, tuple]]) -> None:
        try:
            self.connection.execute("BEGIN IMMEDIATE")
            for sql, params in statements:
                self.connection.execute(sql, params)
            self.connection.execute("COMMIT")
        except sqlite3.Error as exc:
            try:
                self.connection.execute("ROLLBACK")
            except sqlite3.Error:
                pass
            raise RecordingError(
                f"recording: writing to {self.path} failed ({exc}); free disk space or make the "
                "file writable, then resume the session"
            ) from None

    def log(self, kind: str, trial_index: int | None = None, attempt: int | None = None,
            payload: dict[str, Any] | None = None, extra: list[tuple[str, tuple]] = ()) -> None:
        """Append one event and commit it (with ``extra`` statements in the same transaction)."""
        if kind not in EVENT_KINDS:
            raise ValueError(f"kind: must be one of {EVENT_KINDS}, got {kind!r}")
        row = (kind, trial_index, attempt, utc_now(), time.monotonic_ns(),
               json.dumps(payload or {}, default=_json_default))
        self._write([("INSERT INTO events (kind, trial_index, attempt, utc, monotonic_ns, payload) "
                      "VALUES (?, ?, ?, ?, ?, ?)", row), *extra])

    def complete_trial(self, record: TrialRecord, payload: dict[str, Any]) -> None:
        """Commit the ``trial_complete`` event and the trial row together."""
        self.log("trial_complete", record.trial_index, record.attempt, payload,
                 extra=[("INSERT INTO trials VALUES (?, ?)", (record.trial_index, record.model_dump_json()))])

    def close(self) -> None:
        """Close the database and release the lock."""
        try:
            self.connection.close()
        finally:
            self._lock.release()


def _json_default(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, (set, tuple)):
        return list(value)
    return str(value)


def _fsync_folder(folder: Path) -> None:
    """Make a rename durable (POSIX: fsync the directory)."""
    if os.name == "nt":  # pragma: no cover
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def lock_path(path: Path) -> Path:
    """The lock file of a session file."""
    return path.with_name(path.name + ".lock")


class SessionLog:
    """Read-only view of a session file (safe while a runner writes: WAL readers do not block)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"session: no session file {self.path}; give the .sqlite file that `experiment run` printed")
        try:
            self.connection = sqlite3.connect(f"file:{self.path}?mode=ro", uri=True)
            self.connection.execute("SELECT count(*) FROM events").fetchone()
        except sqlite3.Error as exc:
            raise ValueError(f"session: {self.path} is not a tactilab session database ({exc}); give the .sqlite "
                             "file that `experiment run` printed") from None

    def meta(self) -> dict[str, Any]:
        """The session's metadata, decoded."""
        return {k: json.loads(v) for k, v in self.connection.execute("SELECT key, value FROM meta")}

    def events(self, kind: str | None = None) -> list[dict[str, Any]]:
        """Events in order, each a dict with id, kind, trial_index, attempt, utc, monotonic_ns, payload."""
        sql = "SELECT id, kind, trial_index, attempt, utc, monotonic_ns, payload FROM events"
        rows = self.connection.execute(sql + (" WHERE kind = ?" if kind else "") + " ORDER BY id",
                                       (kind,) if kind else ())
        keys = ("id", "kind", "trial_index", "attempt", "utc", "monotonic_ns", "payload")
        return [{**dict(zip(keys, r)), "payload": json.loads(r[-1])} for r in rows]

    def trials(self) -> list[TrialRecord]:
        """Completed trials, validated, in trial order."""
        rows = self.connection.execute("SELECT record FROM trials ORDER BY trial_index")
        return [TrialRecord.model_validate_json(r[0]) for r in rows]

    def is_locked(self) -> bool:
        """Whether a runner holds the session now."""
        try:
            _FileLock(lock_path(self.path)).release()
        except SessionLockedError:
            return True
        return False

    def close(self) -> None:
        """Close the connection."""
        self.connection.close()

"""Durable session recording: SQLite in WAL mode with ``synchronous=FULL``, two commits per trial.

A session is one SQLite file. Table ``meta`` holds the session's provenance (subject code,
protocol JSON, seed, package version, display id, response source); table ``events`` holds
every event in order, committed (and fsynced) before the runner takes the next step; a trial
commits twice: ``trial_planned`` with ``stimulus_presented`` just before the display is driven,
and ``response`` with ``trial_complete`` and the trial row. The events are:

``session_started``, ``session_resumed``, ``trial_planned``, ``stimulus_presented`` (written
BEFORE the display is driven), ``response``, ``trial_complete``, ``safety_intervention``,
``session_stopped``, ``session_failed``, ``session_complete``, ``display_fault`` (a stimulus that
did not reach the display as commanded: the trial is not scored and is repeated on resume),
``planned_stimuli_dropped`` (after ``session_started``, under ``clipped = "drop"``: the planned
stimuli the display would limit, left out of the protocol the session runs).

Table ``trials`` holds one validated :class:`TrialRecord` (JSON) per completed trial, written
in the same transaction as its ``trial_complete`` event.

One owner per session: a runner holds an OS lock (``flock``) on the database file itself,
released by the kernel even when the process is killed (no lock file to delete or leave behind),
and records itself in the ``owner`` table (a random token, its pid and host, a heartbeat). Every
commit checks, inside its own transaction, that the token is still its own and moves the
heartbeat; a runner that finds another owner stops (:class:`SessionTakenOverError`) before the
next stimulus.

Journal: a session stays in WAL mode for its whole life (no journal-mode switch on open, so a
kill while ``resume`` opens the file leaves no rollback journal). Closing checkpoints the log
into the database and removes ``-wal`` and ``-shm``, so a finished or stopped session is ONE
self-contained file; a close that cannot (a reader holding a read transaction, a kill inside
the close) is reported with a :class:`NotSelfContainedWarning`, never silently. Readers finish
such a file: :class:`SessionLog` opens the session read-write with ``query_only`` when its folder
is writable, so a hot journal (left by a killed older version) is rolled back and the last
reader's close checkpoints the log; from a read-only folder it reads a self-contained file as
immutable and refuses one that is not with the command that finishes it
(:func:`file_state` says which).
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import sqlite3
import time
import uuid
import warnings
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from tactilab.core.outputs import printable
from tactilab.data_schemas.identifiers import check_label
from tactilab.data_schemas.experiment_records import TrialRecord

#: Metadata every session has and every reader (status, export, resume) relies on.
REQUIRED_META = ("protocol", "subject", "session", "seed", "display_id", "responses", "package_version")

SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS events (
    id INTEGER PRIMARY KEY AUTOINCREMENT, kind TEXT NOT NULL, trial_index INTEGER,
    attempt INTEGER, utc TEXT NOT NULL, monotonic_ns INTEGER NOT NULL, payload TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS trials (trial_index INTEGER PRIMARY KEY, record TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS owner (
    id INTEGER PRIMARY KEY CHECK (id = 1), token TEXT NOT NULL, pid INTEGER NOT NULL,
    host TEXT NOT NULL, since_utc TEXT NOT NULL, heartbeat_utc TEXT NOT NULL);
"""
EVENT_KINDS = ("session_started", "session_resumed", "trial_planned", "stimulus_presented",
               "response", "trial_complete", "safety_intervention", "session_stopped",
               "session_failed", "session_complete", "display_fault", "planned_stimuli_dropped")


#: the tables a session file holds (``sqlite_sequence`` is SQLite's own, for AUTOINCREMENT)
TABLES = ("meta", "events", "trials", "owner", "sqlite_sequence")


def check_schema(connection: sqlite3.Connection, path: Path) -> None:
    """Refuse a session file that holds anything but its tables and their automatic indexes.

    A trigger or a view is SQL that runs when the runner writes or a reader reads (a trigger
    could rewrite a scored trial on resume), so such a file is refused before any statement
    touches its tables.

    Raises
    ------
    ValueError
        Naming the first foreign object (its type and name) and the fix.
    """
    rows = connection.execute("SELECT type, name, tbl_name FROM sqlite_master").fetchall()
    for kind, name, table in rows:
        expected = (kind == "table" and name in TABLES) or (
            kind == "index" and str(name).startswith("sqlite_autoindex_") and table in TABLES)
        if not expected:
            raise ValueError(
                f"session: {printable(str(path))} holds a {printable(str(kind))} {printable(str(name))[:80]!r}, "
                f"which no tactilab session has (only the tables {', '.join(TABLES[:4])}): it is not a tactilab "
                "session, or it was edited; give the .sqlite file that `experiment run` printed, or restore it "
                "from a copy")


class NotSelfContainedWarning(UserWarning):
    """A session's close could not fold its log into the ``.sqlite`` file (it stays safe)."""


def _sidecar(path: Path, suffix: str) -> Path:
    return path.with_name(path.name + suffix)


def _has_content(path: Path) -> bool:
    try:
        return path.stat().st_size > 0
    except OSError:
        return False


def folder_writable(folder: Path) -> bool:
    """Whether a session's folder accepts new files (the -wal and -shm a WAL reader needs)."""
    return os.access(folder, os.W_OK | os.X_OK)


def file_state(path: str | Path) -> dict[str, Any]:
    """Whether a session is one self-contained file, and if not, what holds the rest.

    Returns
    -------
    dict
        ``self_contained`` (bool: no ``-wal`` with content and no hot ``-journal``),
        ``wal_bytes`` (size of ``<file>-wal``, 0 when absent), ``hot_journal`` (bool) and
        ``folder_writable`` (bool).
    """
    path = Path(path)
    wal = _sidecar(path, "-wal")
    wal_bytes = wal.stat().st_size if _has_content(wal) else 0
    hot = _has_content(_sidecar(path, "-journal"))
    return {"self_contained": wal_bytes == 0 and not hot, "wal_bytes": wal_bytes, "hot_journal": hot,
            "folder_writable": folder_writable(path.parent)}


class RecordingError(OSError):
    """Writing to the session database failed (disk full, read-only, I/O error)."""


class SessionLockedError(OSError):
    """Another runner holds the session."""


def utc_now() -> str:
    """Current UTC time, ISO 8601 with microseconds."""
    return datetime.now(UTC).isoformat(timespec="microseconds")


class SessionTakenOverError(RecordingError):
    """Another runner became the session's owner; this one must stop writing (and driving)."""


class _FileLock:
    """An exclusive, non-blocking OS lock on the session database file itself (flock; msvcrt on
    Windows). SQLite's own locks are POSIX record locks, independent of ``flock``; the kernel
    releases the lock when the process dies, and there is no separate lock file to delete."""

    def __init__(self, path: Path, shared: bool = False) -> None:
        self.path = path
        self.handle = open(path, "rb")  # noqa: SIM115 - held for the session's life
        try:
            if os.name == "nt":  # pragma: no cover - exercised on Windows only
                import msvcrt

                msvcrt.locking(self.handle.fileno(), msvcrt.LK_NBRLCK if shared else msvcrt.LK_NBLCK, 1)
            else:
                import fcntl

                fcntl.flock(self.handle.fileno(), (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
        except OSError:
            self.handle.close()
            raise SessionLockedError(
                f"session: {path} is locked by a running runner ({_owner_text(path)}); wait for it "
                "to finish or stop it, then resume"
            ) from None

    def release(self) -> None:
        if not self.handle.closed:
            self.handle.close()  # closing the descriptor releases the lock


def _owner_text(path: Path) -> str:
    """``pid N on HOST since T, heartbeat H`` from the session's owner row (best effort)."""
    try:
        connection = sqlite3.connect(_reader_uri(path), uri=True, timeout=0.5)
        try:
            row = connection.execute("SELECT pid, host, since_utc, heartbeat_utc FROM owner").fetchone()
        finally:
            connection.close()
    except (sqlite3.Error, ValueError):
        row = None
    if row is None:
        return "another process"
    return f"pid {row[0]} on {row[1]} since {row[2]}, last heartbeat {row[3]}"


class Recorder:
    """A locked, durable event log for one session.

    Use :meth:`create` for a new session and :meth:`open` to continue one. Every write commits
    before returning; failures raise :class:`RecordingError` naming the cause and the fix.
    """

    def __init__(self, path: Path, connection: sqlite3.Connection, lock: _FileLock) -> None:
        self.path, self.connection, self._lock = path, connection, lock
        self.token = uuid.uuid4().hex
        now = utc_now()
        try:
            connection.execute("INSERT OR REPLACE INTO owner VALUES (1, ?, ?, ?, ?, ?)",
                               (self.token, os.getpid(), socket.gethostname(), now, now))
        except sqlite3.Error as exc:
            self.close()
            raise RecordingError(f"session: cannot record the owner of {path} ({exc}); check that the "
                                 "file is writable and the disk has space") from None

    @staticmethod
    def _connect(path: Path, lock: _FileLock) -> sqlite3.Connection:
        try:
            connection = sqlite3.connect(path, isolation_level=None, timeout=5.0)
            try:
                check_schema(connection, path)  # before any statement writes: no trigger ever fires
            except ValueError:
                connection.close()
                lock.release()
                raise
            mode = connection.execute("PRAGMA journal_mode").fetchone()[0]
            if mode.lower() != "wal":  # a session closed by an older version (rollback journal at rest)
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
        partial = path.with_name(path.name + ".partial")
        lock = None
        try:
            partial.unlink(missing_ok=True)
            connection = sqlite3.connect(partial, isolation_level=None)
            lock = _FileLock(partial)  # the same inode as `path` once linked: locked before it appears
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
            if lock is not None:
                lock.release()
            raise RecordingError(
                f"session: cannot create {path} ({exc}); check that the folder is writable and "
                "the disk has space"
            ) from None
        except BaseException:
            if lock is not None:
                lock.release()
            raise
        return cls(path, cls._connect(path, lock), lock)

    @classmethod
    def open(cls, path: str | Path) -> Recorder:
        """Open an existing session for writing, taking its lock."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"session: no session file {path}; give the .sqlite file that `experiment run` printed")
        lock = _FileLock(path)
        return cls(path, cls._connect(path, lock), lock)

    def _write(self, statements: list[tuple[str, tuple]]) -> None:
        try:
            self.connection.execute("BEGIN IMMEDIATE")
            owner = self.connection.execute("SELECT token, pid, host, heartbeat_utc FROM owner").fetchone()
            if owner is None or owner[0] != self.token:
                self.connection.execute("ROLLBACK")
                raise SessionTakenOverError(
                    f"recording: {self.path} is now owned by another runner "
                    f"({'none' if owner is None else f'pid {owner[1]} on {owner[2]}, heartbeat {owner[3]}'}); "
                    "this runner stopped writing; check which process drives the display"
                )
            self.connection.execute("UPDATE owner SET heartbeat_utc = ? WHERE id = 1", (utc_now(),))
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
            payload: dict[str, Any] | None = None, extra: list[tuple[str, tuple]] = ()) -> str:
        """Append one event and commit it (with ``extra`` statements in the same transaction).

        Returns the event's UTC time stamp (ISO 8601).
        """
        return self.log_events([(kind, trial_index, attempt, payload)], extra)[0]

    def log_events(self, events: list[tuple[str, int | None, int | None, dict[str, Any] | None]],
                   extra: list[tuple[str, tuple]] = ()) -> list[str]:
        """Append several events, in order, and commit them in ONE transaction (one fsync).

        Each event is ``(kind, trial_index, attempt, payload)``, optionally with a fifth item,
        its UTC time stamp (ISO 8601; default now). Returns the events' UTC time stamps.
        """
        rows, stamps = [], []
        for kind, trial_index, attempt, payload, *utc in events:
            if kind not in EVENT_KINDS:
                raise ValueError(f"kind: must be one of {EVENT_KINDS}, got {kind!r}")
            stamps.append(utc[0] if utc else utc_now())
            rows.append(("INSERT INTO events (kind, trial_index, attempt, utc, monotonic_ns, payload) "
                         "VALUES (?, ?, ?, ?, ?, ?)",
                         (kind, trial_index, attempt, stamps[-1], time.monotonic_ns(),
                          json.dumps(payload or {}, default=_json_default))))
        self._write([*rows, *extra])
        return stamps

    def complete_trial(self, record: TrialRecord, payload: dict[str, Any],
                       response: dict[str, Any] | None = None) -> list[str]:
        """Commit the ``response`` event (when given), the ``trial_complete`` event and the trial
        row together, in one transaction; returns the events' UTC time stamps."""
        events = [] if response is None else [
            ("response", record.trial_index, record.attempt, response, record.utc_response.isoformat())]
        events.append(("trial_complete", record.trial_index, record.attempt, payload))
        return self.log_events(events, extra=[("INSERT INTO trials VALUES (?, ?)",
                                               (record.trial_index, record.model_dump_json()))])

    def close(self) -> bool:
        """Checkpoint the log into the database file, close, release the lock.

        The session stays in WAL mode; once the log is checkpointed and this was the last
        connection, SQLite removes ``-wal`` and ``-shm`` and the session is one self-contained
        file. When that fails (a reader holds a read transaction, the disk fails) the data are
        still safe, and the failure is reported with a :class:`NotSelfContainedWarning` naming
        the command that finishes the file (``tactilab experiment status``).

        Returns
        -------
        bool
            Whether the session is now one self-contained file.
        """
        problem = None
        try:
            with contextlib.suppress(sqlite3.Error):  # a held reader: give up in ~0.4 s, not 10 x 5 s
                self.connection.execute("PRAGMA busy_timeout = 20")
            for _ in range(10):  # a reader (status, export) may hold a read transaction for a moment
                try:
                    busy = self.connection.execute("PRAGMA wal_checkpoint(TRUNCATE)").fetchone()[0]
                except sqlite3.Error as exc:
                    problem, busy = " ".join(str(exc).split()), 1
                if not busy:
                    problem = None
                    break
                problem = problem or "a reader held the log"
                time.sleep(0.02)
            try:
                self.connection.close()
            except sqlite3.Error as exc:
                problem = " ".join(str(exc).split())
        finally:
            self._lock.release()
        state = file_state(self.path)
        if not state["self_contained"]:
            warnings.warn(
                f"session: {self.path} is not yet one self-contained file ({problem or 'the log was not folded in'}; "
                f"{state['wal_bytes']} bytes in {self.path.name}-wal); its data are safe; run `tactilab experiment "
                f"status {self.path}` once no other process reads it to finish it, and copy it only then",
                NotSelfContainedWarning, stacklevel=2)
        return state["self_contained"]


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


def _reader_uri(path: Path) -> str:
    """How a reader opens ``path``: read-write (queries only) from a writable folder, so that it
    rolls back a hot journal and, as the last connection, folds a leftover log into the file;
    immutable from a read-only folder when the file is self-contained.

    Raises
    ------
    ValueError
        From a read-only folder, when a hot journal or a log holds part of the session.
    """
    state = file_state(path)
    if state["folder_writable"]:
        return f"file:{path}?mode=rw"
    if state["hot_journal"]:
        raise ValueError(
            f"session: {path} has a hot journal ({path.name}-journal, left by a killed process) in a read-only "
            f"folder; its data are intact: copy the .sqlite and its -journal to a writable folder and run "
            f"`tactilab experiment status COPY` (a read-write open recovers it)")
    if state["wal_bytes"]:
        raise ValueError(
            f"session: {path} is not self-contained ({state['wal_bytes']} bytes of its log are in "
            f"{path.name}-wal) and its folder is read-only; copy the .sqlite with its -wal and -shm to a "
            f"writable folder and run `tactilab experiment status COPY` to fold the log in")
    return f"file:{path}?immutable=1"


class SessionLog:
    """Query-only view of a session file (safe while a runner writes: WAL readers do not block)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"session: no session file {self.path}; give the .sqlite file that `experiment run` printed")
        try:
            self.connection = sqlite3.connect(_reader_uri(self.path), uri=True)
            check_schema(self.connection, self.path)
            self.connection.execute("PRAGMA query_only=1")  # reads only, whatever the file holds
            self.connection.execute("SELECT count(*) FROM events").fetchone()
        except sqlite3.Error as exc:
            raise ValueError(f"session: {self.path} is not a tactilab session database ({exc}); give the .sqlite "
                             "file that `experiment run` printed") from None

    def owner(self) -> dict[str, Any] | None:
        """The last owner's pid, host, start and heartbeat (UTC), or None for an older session."""
        try:
            row = self.connection.execute("SELECT pid, host, since_utc, heartbeat_utc FROM owner").fetchone()
        except sqlite3.Error:
            return None
        return None if row is None else dict(zip(("pid", "host", "since_utc", "heartbeat_utc"), row))

    def _damaged(self, exc: Exception) -> ValueError:
        return ValueError(f"session: {self.path} is damaged or not a tactilab session ({' '.join(str(exc).split())[:200]}); "
                          "restore it from a copy, or give the .sqlite file that `experiment run` printed")

    def meta(self) -> dict[str, Any]:
        """The session's metadata, decoded.

        Raises
        ------
        ValueError
            If the file is torn, foreign or its metadata is not JSON (one line naming the file).
        """
        try:
            meta = {k: json.loads(v) for k, v in self.connection.execute("SELECT key, value FROM meta")}
        except (sqlite3.Error, ValueError) as exc:
            raise self._damaged(exc) from None
        missing = [k for k in REQUIRED_META if k not in meta]
        if missing:  # status, export and resume all read these: one line here, never a KeyError there
            raise ValueError(f"session: {self.path} lacks the metadata {missing}; it is not a complete tactilab "
                             "session (was it edited or cut short while being created?); restore it from a copy")
        # re-validated on every read: these become file names (exports) and printed lines (status)
        protocol = meta["protocol"]
        labels = {"subject": meta["subject"], "session": meta["session"],
                  "protocol.name": protocol.get("name") if isinstance(protocol, dict) else None}
        for key, value in labels.items():
            try:
                check_label(value, key)
            except ValueError as exc:
                raise ValueError(f"session: {printable(str(self.path))} holds an invalid {exc}; the file was edited, "
                                 "restore it from a copy") from None
        return meta

    def events(self, kind: str | None = None) -> list[dict[str, Any]]:
        """Events in order, each a dict with id, kind, trial_index, attempt, utc, monotonic_ns, payload."""
        sql = "SELECT id, kind, trial_index, attempt, utc, monotonic_ns, payload FROM events"
        try:
            rows = self.connection.execute(sql + (" WHERE kind = ?" if kind else "") + " ORDER BY id",
                                           (kind,) if kind else ()).fetchall()
        except sqlite3.Error as exc:
            raise self._damaged(exc) from None
        keys = ("id", "kind", "trial_index", "attempt", "utc", "monotonic_ns", "payload")
        try:
            return [{**dict(zip(keys, r)), "payload": json.loads(r[-1])} for r in rows]
        except (sqlite3.Error, ValueError) as exc:
            raise self._damaged(exc) from None

    def trials(self) -> list[TrialRecord]:
        """Completed trials, validated, in trial order."""
        try:
            rows = self.connection.execute("SELECT record FROM trials ORDER BY trial_index").fetchall()
            return [TrialRecord.model_validate_json(r[0]) for r in rows]
        except (sqlite3.Error, ValueError) as exc:
            raise self._damaged(exc) from None

    def is_locked(self) -> bool:
        """Whether a runner holds the session now."""
        try:
            _FileLock(self.path, shared=True).release()
        except SessionLockedError:
            return True
        return False

    def close(self) -> None:
        """Close the connection."""
        self.connection.close()

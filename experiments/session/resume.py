"""Resume a killed session exactly, and report a session's status.

:func:`replay_session` reads the log, rebuilds the procedure by replaying the completed trials
(checking that each recorded level is the one the protocol and seed choose), and finds the
interrupted trial: one that was planned (and maybe presented) but never completed.
:func:`resume_session` then runs on: the interrupted trial is repeated with the same
parameters (its randomness comes from ``(seed, trial_index)``) and recorded with
``attempt > 0``, and with ``repeated = True`` when an earlier attempt reached the display
(a ``stimulus_presented`` event exists; a trial cut short before that was never felt).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tactilab.data_schemas.experiment import Protocol
from tactilab.data_schemas.experiment_records import TrialRecord

from ..devices import Display, description_differences, description_record
from ..procedures import Procedure, make_procedure, outcome_of, replay
from .recording import Recorder, SessionLog, file_state
from .responses import ResponseSource
from .runner import Runner, RunResult, stopped, trial_generators
from .signals import signals_held, stop_signals


@dataclass
class Replayed:
    """A session rebuilt from its log."""

    meta: dict[str, Any]
    protocol: Protocol
    trials: list[TrialRecord]
    procedure: Procedure
    attempts: dict[int, tuple[int, bool]]  # interrupted trial -> (next attempt number, repeated)
    events: list[dict[str, Any]]


def session_protocol(meta: dict[str, Any], path: Path | str) -> Protocol:
    """The session's protocol, validated from its metadata (data only: names, never import paths).

    Raises
    ------
    ValueError
        If the metadata lacks a key, or the protocol or the recorded likelihood name is invalid
        or inconsistent (an edited or foreign file); one line naming the file.
    """
    missing = [k for k in ("protocol", "subject", "session", "seed", "display_id", "responses")
               if k not in meta]
    if missing:
        raise ValueError(f"session: {path} lacks the metadata {missing}; it is not a complete tactilab "
                         "session (was it edited or cut short while being created?)")
    try:
        protocol = Protocol.model_validate(meta["protocol"])
    except ValueError as exc:
        raise ValueError(f"session: {path} holds an invalid protocol ({_one_line(exc)}); the file was "
                         "edited or is damaged") from None
    recorded = meta.get("likelihood")
    if recorded is not None and recorded != getattr(protocol.procedure, "likelihood", None):
        raise ValueError(
            f"session: {path} records likelihood {str(recorded)[:80]!r}, which is not its protocol's; "
            "the metadata was edited (a session names a registered likelihood, never code)"
        )
    return protocol


def _one_line(exc: Exception) -> str:
    errors = getattr(exc, "errors", None)
    if callable(errors):
        first = errors()[0]
        loc = ".".join(str(x) for x in first.get("loc", ()))
        return f"{loc}: {str(first.get('msg', '')).removeprefix('Value error, ')}"[:300]
    return str(exc).splitlines()[0][:300]


def replay_log(log: SessionLog) -> Replayed:
    """Rebuild a session's procedure state and find its interrupted trial (imports nothing)."""
    meta = log.meta()
    protocol = session_protocol(meta, log.path)
    trials, events = log.trials(), log.events()
    for expected, trial in enumerate(trials):
        if trial.trial_index != expected:
            raise ValueError(
                f"session: completed trials are not contiguous (trial {expected} missing, found "
                f"{trial.trial_index}); the log of {log.path} is damaged"
            )
    kind = protocol.task.kind
    history = [{"trial_index": t.trial_index, "track": t.track, "level": t.level,
                "outcome": outcome_of(kind, t.target, t.response)} for t in trials]
    source = _design_source(meta, protocol)
    procedure = make_procedure(protocol.procedure, protocol.task.guess_rate, **source.keywords())
    replay(procedure, history, lambda i: trial_generators(protocol.seed, i)[0])
    pending = [e for e in events if e["trial_index"] == len(trials) and e["attempt"] is not None]
    attempts = {}
    if pending:
        # a new attempt number keeps the events of each attempt apart; the trial counts as
        # REPEATED only if an earlier attempt reached the display (the subject may have felt it)
        presented = any(e["kind"] == "stimulus_presented" for e in pending)
        attempts[len(trials)] = (max(e["attempt"] for e in pending) + 1, presented)
    return Replayed(meta, protocol, trials, procedure, attempts, events)


def _design_source(meta: dict[str, Any], protocol: Protocol):
    """The strain source the session's design predicted from (``design_strain``): rebuilt from the
    recorded display description or the recorded protocol's [finger] (sessions recorded before
    ``design_strain`` was kept predicted from the ideal surface)."""
    from .design_source import recorded_design_source

    description = None
    if meta.get("design_strain") == "display" and meta.get("display_description") is not None:
        from tactilab.data_schemas.display import DisplayDescription

        try:
            description = DisplayDescription.model_validate(meta["display_description"])
        except ValueError as exc:
            raise ValueError(f"session: the recorded display description is invalid ({_one_line(exc)}); the "
                             "metadata was edited") from None
    return recorded_design_source(meta, protocol, description)


@dataclass
class SessionHeader:
    """What a session says about itself without a replay: metadata, protocol, progress."""

    meta: dict[str, Any]
    protocol: Protocol
    n_completed: int
    interrupted_trial: int | None


def session_header(path: str | Path) -> SessionHeader:
    """Read a session's metadata, protocol and progress WITHOUT replaying it (cheap; imports
    nothing): the command line uses it before :func:`resume_session`, which replays once."""
    log = SessionLog(path)
    try:
        meta = log.meta()
        protocol = session_protocol(meta, log.path)
        n = log.connection.execute("SELECT count(*) FROM trials").fetchone()[0]
        pending = log.connection.execute(
            "SELECT count(*) FROM events WHERE trial_index = ? AND attempt IS NOT NULL", (n,)).fetchone()[0]
        return SessionHeader(meta, protocol, int(n), int(n) if pending else None)
    finally:
        log.close()


def replay_session(path: str | Path) -> Replayed:
    """Read-only replay of a session file (no lock taken, nothing imported)."""
    log = SessionLog(path)
    try:
        return replay_log(log)
    finally:
        log.close()


def resume_session(path: str | Path, display: Display, responses: ResponseSource, *,
                   realtime: bool = True,
                   progress: bool = False) -> RunResult:
    """Continue a killed or stopped session where it left off (locks it first).

    The log is replayed to rebuild the procedure's state; an interrupted trial is repeated. A
    session whose psi likelihood is a custom one needs it registered first
    (:func:`tactilab.experiments.register_likelihood`); nothing is imported from the file.

    Parameters
    ----------
    path : str or Path
        The session's SQLite file.
    display : Display
        A bare display of the same description the session was recorded on.
    responses : ResponseSource
        The same kind and configuration the session was recorded with.
    realtime, progress : bool
        As in :func:`tactilab.experiments.session.runner.new_session`.

    Returns
    -------
    RunResult

    Raises
    ------
    SessionLockedError
        If a runner still holds the session.
    ValueError
        If the session is already complete, or its log does not match its protocol.
    """
    recorder = state = None
    with stop_signals():  # a stop while the file is opened or replayed is a clean stop too
        try:
            with signals_held():  # opened and locked whole; a stop that came meanwhile is delivered after
                recorder = Recorder.open(path)
            log = SessionLog(path)
            try:
                state = replay_log(log)
            finally:
                log.close()
            if any(e["kind"] == "session_complete" for e in state.events):
                raise ValueError(f"session: {path} is complete; nothing to resume (export it instead)")
            check_same_display(state.meta, display, path)
            recorded = state.meta.get("responses_config")
            if responses.name == state.meta.get("responses") and recorded and dict(responses.config) != recorded:
                raise ValueError(
                    f"responses: the session was recorded with {responses.name} responses configured as "
                    f"{recorded}, got {dict(responses.config)}; resume with the same configuration"
                )
            display.zero()  # the device answers and is at rest; the host's look at its frames_applied starts here
            recorder.log("session_resumed", payload={
                "completed": len(state.trials), "repeating": sorted(state.attempts)})
            runner = Runner(state.protocol, recorder, display, responses, subject=state.meta["subject"],
                            session=state.meta["session"], procedure=state.procedure,
                            realtime=realtime, progress=progress)
            return runner.run(state.attempts)
        except KeyboardInterrupt as exc:
            if recorder is None:
                raise
            if state is None:  # stopped while replaying: the completed trials are counted, not replayed
                stopped(recorder, exc, None)
                return RunResult(recorder.path, "interrupted", session_header(path).n_completed, {})
            return stopped(recorder, exc, state.procedure)
        finally:
            if recorder is not None:
                with signals_held():
                    recorder.close()


def check_same_display(meta: dict[str, Any], display: Display, path: str | Path) -> None:
    """Refuse a display whose description differs from the one the session recorded.

    Raises
    ------
    ValueError
        Naming every field that differs (a laxer limit included); sessions recorded before
        descriptions were stored are checked by ``display_id``.
    """
    given, sha256 = description_record(display.description)
    recorded = meta.get("display_description")
    if recorded is None:
        if given["display_id"] != meta["display_id"]:
            raise ValueError(f"display: {path} was recorded on display {meta['display_id']!r}, got "
                             f"{given['display_id']!r}; resume on the same display")
        return
    if sha256 != meta.get("display_sha256"):
        diff = description_differences(recorded, given) or ["the description hash"]
        raise ValueError(
            f"display: {path} was recorded with another description of display {meta['display_id']!r} "
            f"({'; '.join(diff)}); resume with the recorded description (the default of `tactilab "
            "experiment resume`), or start a new session"
        )


def session_status(path: str | Path) -> dict[str, Any]:
    """Summary of a session: who, what, how far, the current estimate, whether it is running, and
    whether it is one self-contained file (``self_contained``; reading it from a writable folder
    folds a leftover log into it, see :func:`~.recording.file_state`)."""
    status = _status(path)
    status["self_contained"] = file_state(path)["self_contained"]  # after the reader closed
    return status


def _status(path: str | Path) -> dict[str, Any]:
    log = SessionLog(path)
    try:
        state = replay_log(log)
        kinds = [e["kind"] for e in state.events]
        ends = [k for k in kinds if k in ("session_complete", "session_failed", "session_resumed", "session_started")]
        if "session_complete" in kinds:
            status = "complete"
        elif log.is_locked():
            status = "running"
        elif ends and ends[-1] == "session_failed":
            status = "failed"  # an unexpected error; resuming is still possible
        else:
            status = "interrupted"  # killed, stopped by the subject or a signal, or a write failed
        return {
            "path": str(Path(path)), "subject": state.meta["subject"], "session": state.meta["session"],
            "task": state.protocol.name, "method": state.protocol.procedure.method,
            "parameter": state.protocol.procedure.parameter, "status": status,
            "stopped_cleanly": bool(kinds) and kinds[-1] == "session_stopped",
            "completed": len(state.trials), "planned": state.procedure.n_planned,
            "interrupted_trial": next(iter(state.attempts), None),
            "repeated_trials": sum(t.repeated for t in state.trials),
            "interrupted_was_presented": next(iter(state.attempts.values()), (0, False))[1],
            "safety_interventions": kinds.count("safety_intervention"),
            "estimate": state.procedure.estimate(), "seed": state.protocol.seed,
            "display_id": state.meta["display_id"], "display_sha256": state.meta.get("display_sha256"),
            "owner": log.owner(),
            "package_version": state.meta["package_version"],
        }
    finally:
        log.close()

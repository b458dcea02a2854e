"""The psychophysics runner: plan, record, present, respond, record -- two commits per trial.

Per trial, in this order:

1. the procedure picks the level, the task builds the stimuli (after the inter-trial interval);
2. ``trial_planned`` and ``stimulus_presented`` are committed (fsynced) together, BEFORE the
   display is driven, so a crash during the stimulus still shows that it may have been felt;
3. the display plays each interval through :class:`~tactilab.experiments.devices.safety.SafeDisplay`
   (which no stimulus bypasses; its interventions are logged as ``safety_intervention``);
4. ``response`` and ``trial_complete`` with the full :class:`TrialRecord` are committed together.

A crash before step 2 leaves no trace of the trial (it was never shown: it simply runs on
resume); a crash between 2 and 4 leaves a presented, incomplete trial that resume repeats.

All randomness of trial ``i`` comes from ``np.random.default_rng([seed, i])``: the procedure
uses its first spawned child, the task its second (the simulated observer uses
``[seed, i, 2]``). A resumed session therefore repeats an uninterrupted one exactly.
If a write fails (disk full, read-only file), the display is zeroed and the run stops with a
:class:`RecordingError` before the next stimulus; what was committed stays intact.

A failed trial is never scored: when an interval's playback was stopped early, any frame was
acknowledged with a status other than ``applied``, or more than
:data:`~tactilab.experiments.devices.MAX_UNACKED_FRACTION` of its frames got no acknowledgement, the display is zeroed, a ``display_fault`` event is logged
(``alarm`` is true for ``stale`` acknowledgements: another sender is ahead in sequence on the
link), the run stops with :class:`DisplayFault`, and the trial is repeated on resume.
"""

from __future__ import annotations

import contextlib
import os
import time
import uuid
import warnings
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any, Callable

import numpy as np

from tactilab.core import package_version  # defined once in core
from tactilab.data_schemas.experiment import Protocol, check_label, check_subject
from tactilab.data_schemas.experiment_records import TrialRecord

from ..devices import (Display, DisplayError, DisplayFault, SafeDisplay, check_frame_rate,
                       description_record, display_fault, foreign_reason, render_drive)
from ..procedures import PlannedLevel, Procedure, make_procedure, plan_trial, score
from .progress import NoBar, progress_bar
from .recording import Recorder, RecordingError, utc_now
from .responses import ResponseSource
from .signals import signals_held, stop_signals


def trial_generators(seed: int, trial_index: int) -> tuple[np.random.Generator, np.random.Generator]:
    """(procedure, task) generators of one trial, spawned from ``default_rng([seed, trial_index])``."""
    procedure_rng, task_rng = np.random.default_rng([seed, trial_index]).spawn(2)
    return procedure_rng, task_rng


@dataclass(frozen=True)
class RunResult:
    """How a run ended: ``status`` is 'complete' or 'interrupted' (other failures raise)."""

    path: Path
    status: str
    n_completed: int
    estimate: dict[str, Any]

    def __repr__(self) -> str:
        """Status, trial count and the estimate (keys carry their units); short."""
        est = ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v!r}" for k, v in
                        list(self.estimate.items())[:6])
        return f"RunResult(status={self.status!r}, {self.n_completed} trials, estimate {{{est}}}, path={str(self.path)!r})"

    def _repr_html_(self) -> str:
        """The short repr for notebooks (escaped, monospace)."""
        import html

        return "<pre>" + html.escape(repr(self)) + "</pre>"


class Runner:
    """Drive one session: ``Runner(...).run()``.

    Parameters
    ----------
    protocol : Protocol
        The validated protocol.
    recorder : Recorder
        The session's open, locked recorder.
    display : Display
        Any display; the runner wraps it in ``SafeDisplay`` itself.
    responses : ResponseSource
        Terminal or simulated observer.
    subject, session : str
        Pseudonymous subject code and session label.
    procedure : Procedure
        Fresh, or rebuilt by replay (resume).
    realtime : bool
        Wait the inter-trial and inter-interval pauses (False for dry runs and tests).
    progress : bool
        Show a tqdm bar with the trial count and the current estimate on standard error,
        unless that is the subject's screen (:mod:`.progress`).
    """

    def __init__(self, protocol: Protocol, recorder: Recorder, display: Display,
                 responses: ResponseSource, *, subject: str, session: str, procedure: Procedure,
                 realtime: bool = True, progress: bool = False,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.protocol, self.recorder, self.responses = protocol, recorder, responses
        self.subject, self.session, self.procedure = subject, session, procedure
        self.realtime, self.progress, self.sleep = realtime, progress, sleep
        # always wrapped: every stimulus passes the safety layer, and its events reach the log
        self.display = SafeDisplay(display, self._on_safety)
        self.display_id = str(display.description.display_id)
        self._current: tuple[int | None, int | None] = (None, None)
        self._interventions = 0
        self.log_failed = False  # True when even the stop could not be logged

    def _on_safety(self, event: dict) -> None:
        self._interventions += 1
        self.recorder.log("safety_intervention", *self._current, payload=event)

    def run(self, attempts: dict[int, tuple[int, bool]] | None = None) -> RunResult:
        """Run trials until the procedure is finished.

        ``attempts`` maps an interrupted trial's index to ``(attempt, repeated)`` (from resume).
        """
        attempts = attempts or {}
        stops = contextlib.ExitStack()
        stops.enter_context(stop_signals())
        if self.progress:  # the running estimate is the experimenter's: never on the subject's screen
            bar = progress_bar(self.responses, total=self.procedure.n_planned, initial=self.procedure.n_done,
                               desc=f"sub-{self.subject} ses-{self.session}", session_path=self.recorder.path)
        else:
            bar = NoBar()
        try:
            while True:
                index = self.procedure.n_done
                procedure_rng, task_rng = trial_generators(self.protocol.seed, index)
                planned = self.procedure.next_trial(index, procedure_rng)
                if planned is None:
                    break
                self.run_trial(index, *attempts.get(index, (0, False)), planned, task_rng)
                bar.update(1)
                bar.set_postfix_str(format_estimate(self.procedure.estimate(), self.protocol.procedure.parameter))
            self.display.zero()
            self.recorder.log("session_complete", payload={"estimate": self.procedure.estimate()})
            return RunResult(self.recorder.path, "complete", self.procedure.n_done, self.procedure.estimate())
        except KeyboardInterrupt as exc:
            self._stop("session_stopped", f"interrupted ({exc.args[0] if exc.args else 'Ctrl-C or q'})")
            return RunResult(self.recorder.path, "interrupted", self.procedure.n_done, self.procedure.estimate())
        except RecordingError as exc:
            self._stop(None, "")
            raise RecordingError(
                f"{exc}. The run stopped before the next stimulus; {self.procedure.n_done} completed "
                f"trials are safe in {self.recorder.path}"
            ) from None
        except BaseException as exc:
            self._stop("session_failed", f"{type(exc).__name__}: {exc}")
            raise
        finally:
            bar.close()
            stops.close()

    def _stop(self, kind: str | None, reason: str) -> None:
        """Zero the display, then log why the run stopped (when the log itself still works)."""
        try:
            self.display.zero()
        except DisplayError as exc:  # the device may be what failed; its watchdog zeroes it
            reason = f"{reason}; final ZERO failed: {' '.join(str(exc).split())}"
        finally:
            if kind is not None:
                try:
                    self.recorder.log(kind, payload={"reason": reason})
                except RecordingError:
                    # the log may be what failed; the caller still learns why the run stopped
                    self.log_failed = True

    def run_trial(self, index: int, attempt: int, repeated: bool, planned: PlannedLevel,
                  task_rng: np.random.Generator) -> TrialRecord:
        """Run one trial (steps 1-5 of the module docstring) and return its record."""
        plan = plan_trial(self.protocol, index, planned, task_rng)
        self._current = (index, attempt)
        commanded = [s.model_dump() for s in plan.stimuli]
        if self.realtime and index > 0:
            self.sleep(self.protocol.iti_s)
        # ONE commit (one fsync) for the plan and the presentation, BEFORE the display is driven
        planned_utc, presented_utc = self.recorder.log_events([
            ("trial_planned", index, attempt, {
                "block": plan.block, "track": plan.track, "parameter": plan.parameter, "level": plan.level,
                "target": plan.target, "stimuli": commanded}),
            ("stimulus_presented", index, attempt, {"stimuli": commanded})])
        utc_planned, utc_presented = datetime.fromisoformat(planned_utc), datetime.fromisoformat(presented_utc)
        before = self._interventions
        reports, onset_ns = [], 0
        for k, stimulus in enumerate(plan.stimuli):
            if k and self.realtime:
                self.sleep(plan.gap_s)
            frames = render_drive(self.display.description, **stimulus.model_dump())
            self.display.load(frames, stimulus.frame_rate_hz)
            if k == 0:  # the response clock starts at the first stimulus onset (its first frame's due time)
                onset_ns = time.monotonic_ns() + round(self.display.onset_delay_s * 1e9)
                self.responses.arm(plan, onset_ns)
            try:
                report = self.display.play()
            except DisplayFault:
                raise
            except DisplayError as exc:  # the link failed mid-trial (device lost): a fault like any other
                report, fault = None, {"reason": " ".join(str(exc).split()), "frames_sent": exc.frames_sent}
            else:
                fault = display_fault(report)
            if fault is not None:  # never scored: zero, log, stop; resume repeats the trial
                with contextlib.suppress(DisplayError):  # a lost device cannot answer; its watchdog zeroes it
                    self.display.zero()
                # what the display played of this aborted attempt, every interval so far (the status counts it)
                played = sum(r.frames_sent for r in reports) + int(fault.get("frames_sent") or 0)
                self.recorder.log("display_fault", index, attempt, {**fault, "interval": k,
                                                                    "frames_sent_trial": played})
                raise DisplayFault(
                    f"display fault in trial {index}, interval {k}: {fault['reason']}. The display is "
                    f"zeroed and the trial was not scored; fix the link or the device, then resume "
                    f"{self.recorder.path} (the trial is repeated)"
                )
            reports.append(report)
        response = self.responses.collect(plan)
        # before scoring: did anything else drive the display during this trial (between its
        # stimuli, or while the subject answered)? Its frames_applied counter says so
        foreign = self.display.audit()
        if foreign:
            self.recorder.log("display_fault", index, attempt, {
                "reason": foreign_reason(foreign), "alarm": True, "foreign": foreign, "interval": None,
                "frames_sent_trial": sum(r.frames_sent for r in reports)})
            raise DisplayFault(
                f"display fault in trial {index}: {foreign_reason(foreign)}. The display is zeroed and the "
                f"trial was not scored; find the other process, then resume {self.recorder.path} (the trial "
                "is repeated)")
        correct, outcome = score(self.protocol, plan, response.label)
        response_payload = {"response": response.label, "rt_s": response.rt_s,
                            "monotonic_ns": response.monotonic_ns}
        utc_response = datetime.fromisoformat(utc_now())
        self.procedure.update(planned, outcome)
        record = TrialRecord(
            subject=self.subject, session=self.session, block=plan.block, trial_index=index,
            attempt=attempt, repeated=repeated, track=plan.track, parameter=plan.parameter,
            level=plan.level, stimuli=list(plan.stimuli), target=plan.target,
            procedure_state=self.procedure.record_state(), response=response.label, correct=correct,
            rt_s=response.rt_s, utc_planned=utc_planned, utc_presented=utc_presented,
            utc_response=utc_response, monotonic_onset_ns=onset_ns,
            monotonic_response_ns=response.monotonic_ns, seed=self.protocol.seed,
            package_version=package_version(), display_id=self.display_id,
            frames_sent=sum(r.frames_sent for r in reports), frames_late=sum(r.late for r in reports),
            frames_missing=sum(r.missing for r in reports), frames_skipped=sum(r.skipped for r in reports),
            safety_interventions=self._interventions - before)
        # ONE commit (one fsync) for the response, the completion and the trial row
        self.recorder.complete_trial(record, {"outcome": outcome, "correct": correct}, response_payload)
        self._current = (None, None)
        return record


def format_estimate(estimate: dict[str, Any], parameter: str) -> str:
    """One line for humans: ``amplitude threshold 2.47 um`` (``estimate: n/a`` before there is one).

    A procedure that weighs models (``p_<model>`` entries, e.g. model discrimination) shows their
    posterior probabilities instead: ``P(zx@1mm) 0.93, P(zx@2mm) 0.07``, and its verdict once reached.
    """
    models = {key[2:]: p for key, p in estimate.items() if key.startswith("p_") and p is not None}
    if models:
        text = ", ".join(f"P({name}) {float(p):.2f}" for name, p in models.items())
        verdict = estimate.get("verdict")
        return f"{text}; {verdict}" if verdict else text
    value = estimate.get("threshold")
    if value is None:
        return "estimate: n/a"
    name, scale, unit = DISPLAY_UNITS[parameter]
    return f"{name} threshold {value * scale:.3g} {unit}"


#: parameter -> (short name, factor from SI, unit) for progress and plots
DISPLAY_UNITS = {"amplitude_m": ("amplitude", 1e6, "um"), "pitch_m": ("pitch", 1e3, "mm"),
                 "speed_m_per_s": ("speed", 1e3, "mm/s"), "duration_s": ("duration", 1e3, "ms")}


def new_session(protocol: Protocol, path: str | Path, display: Display, responses: ResponseSource, *,
                subject: str, session: str = "01", subject_pattern: str | None = None, realtime: bool = True,
                progress: bool = False, on_created: Callable[[Path], None] | None = None,
                clipped: str | None = None) -> RunResult:
    """Create a session file at ``path`` and run the protocol to the end (or to an interruption).

    Parameters
    ----------
    protocol : Protocol
        The validated protocol (stimulus fields in SI: m, m/s, s, Hz).
    path : str or Path
        The SQLite session file to create (``sub-<ID>_ses-<NN>_task-<name>.sqlite``).
    display : Display
        A bare display; the runner wraps it in the safety layer (limits in Pa, m, 1/s).
    responses : ResponseSource
        Where responses come from (terminal or simulated observer); its ``config`` is recorded.
    subject, session : str
        BIDS labels (1-32 letters or digits; pseudonymous codes, never names: a subject code
        that looks like a name or a date is refused, see
        :func:`tactilab.data_schemas.identifiers.check_subject`).
    subject_pattern : str, optional
        The lab's own subject-code pattern (a regular expression the whole code must match),
        replacing the name and date heuristics.
    realtime : bool
        Wait in real time between trials and during playback (False: dry runs only).
    progress : bool
        Show a tqdm bar over trials (not on the subject's screen, :mod:`.progress`).
    on_created : callable, optional
        Called with the session file's path once the file exists (after the start checks), e.g.
        to tell the user where it is.
    clipped : {"refuse", "drop", "allow"}, optional
        A planned stimulus the display would limit (clip, slew- or duty-limit) refuses the protocol
        before any file exists (``refuse``, :func:`~.display_check.check_display_limits`), is left
        out (``drop``: a level or design candidate, :func:`~.display_check.drop_clipped`; the
        count is warned, the list is recorded in the metadata's ``clipped`` and a
        ``planned_stimuli_dropped`` event, the protocol recorded is the one run), or is limited by
        the safety layer at run time and recorded as interventions (``allow``). Default: the
        protocol's ``clipped`` (itself ``refuse`` by default).

    Returns
    -------
    RunResult
        Status, trial count and the procedure's estimate (SI).

    Raises
    ------
    FileExistsError
        If ``path`` exists (resume it instead).
    DisplayError
        If the display does not answer a ZERO (no session file is created then).
    SessionLockedError
        If another runner holds it.
    RecordingError
        If a write fails; the run stops before the next stimulus.
    KeyboardInterrupt
        On Ctrl-C or a stop signal (SIGTERM, SIGHUP, SIGQUIT, SIGUSR1: handled from this call's
        first instruction) before the session file exists; once it exists a stop is logged and
        the result is ``interrupted``.
    """
    with stop_signals():  # from the first instruction: a stop during start-up is a clean stop
        return _new_session(protocol, path, display, responses, subject=subject, session=session,
                            subject_pattern=subject_pattern, realtime=realtime, progress=progress,
                            on_created=on_created, clipped=clipped)


def _new_session(protocol: Protocol, path: str | Path, display: Display, responses: ResponseSource, *,
                 subject: str, session: str, subject_pattern: str | None, realtime: bool, progress: bool,
                 on_created: Callable[[Path], None] | None, clipped: str | None) -> RunResult:
    check_subject(subject, "subject", subject_pattern)
    check_label(session, "session")
    # before any file exists: the device answers (a ZERO round trip: it is there and at rest)
    # and the first stimulus renders, so no empty or failed session litters the folder
    display.zero()
    rates = sorted({s.frame_rate_hz for s in protocol.planned_stimuli()})
    try:  # every stimulus the protocol plans can be played (a candidate may set its own frame rate);
        check_frame_rate(rates[-1], display.description)  # checked BEFORE anything is rendered
    except ValueError as exc:
        raise ValueError(f"protocol: a planned stimulus's {exc} (frame rates planned: {rates} Hz)") from None
    render_drive(display.description, **protocol.stimulus.model_dump())
    from .design_source import design_source
    from .display_check import plan_for_display

    protocol, clipping = plan_for_display(protocol, display.description, clipped)
    source = design_source(display.description, protocol)  # what the display renders, else the [finger]'s contact
    if source.strain != "display" and protocol.procedure.method == "model_discrimination":
        fallback = ("the protocol's [finger] pressing the gratings (the solved contact)" if source.strain == "contact"
                    else "the ideal surface")
        warnings.warn("display: it is commanded in deflection and its strain needs the tractor stiffness, which "
                      f"its description does not hold; the design predicts from {fallback}", stacklevel=3)
    description, description_sha256 = description_record(display.description)
    meta = {"session_id": uuid.uuid4().hex, "created_utc": utc_now(),
            "subject": subject, "session": session, "protocol": protocol.model_dump(mode="json"),
            "seed": protocol.seed, "package_version": package_version(),
            "display_id": str(display.description.display_id), "display_description": description,
            "display_sha256": description_sha256, "responses": responses.name,
            "responses_config": dict(responses.config),
            "likelihood": getattr(protocol.procedure, "likelihood", None),
            "clipped": clipping, "design_strain": source.strain}
    # built before the file exists: an unregistered method or likelihood leaves no session behind
    procedure = make_procedure(protocol.procedure, protocol.task.guess_rate, **source.keywords())
    recorder = None
    try:
        with signals_held():  # the file is created and locked whole
            recorder = Recorder.create(path, meta)
            recorder.log("session_started", payload={"pid": os.getpid()})
            if clipping["dropped"]:
                recorder.log("planned_stimuli_dropped", payload=clipping)
        if on_created is not None:
            on_created(Path(path))
        runner = Runner(protocol, recorder, display, responses, subject=subject, session=session,
                        procedure=procedure, realtime=realtime, progress=progress)
        return runner.run()
    except KeyboardInterrupt as exc:
        if recorder is None:
            raise  # nothing was written: the caller reports the stop
        return stopped(recorder, exc, procedure)
    finally:
        if recorder is not None:
            with signals_held():
                recorder.close()


def stopped(recorder: Recorder, exc: KeyboardInterrupt, procedure: Procedure | None) -> RunResult:
    """Log a stop that came before the runner took over (while opening or replaying the session)."""
    reason = f"interrupted ({exc.args[0] if exc.args else 'Ctrl-C'}) before the first stimulus"
    with signals_held():
        with contextlib.suppress(RecordingError):  # the stop is reported by the result either way
            recorder.log("session_stopped", payload={"reason": reason})
    if procedure is None:
        return RunResult(recorder.path, "interrupted", 0, {})
    return RunResult(recorder.path, "interrupted", procedure.n_done, procedure.estimate())

"""``tactilab experiment``: run, resume, export and inspect psychophysics sessions."""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from .common import make_out

from .experiment_analysis import add_subcommands as add_analysis_subcommands

NAME = "experiment"
HELP = "run, resume, export or inspect a psychophysics session (SQLite log, SI units)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    add_analysis_subcommands(sub)  # fit, compare, power: cli/experiment_analysis.py

    run = sub.add_parser("run", help="run a protocol file (TOML; quantities take unit suffixes: 20um, 40mm/s, 500ms)")
    run.add_argument("protocol", type=Path, help="protocol TOML file")
    run.add_argument("--subject", required=True,
                     help="pseudonymous subject code, letters and digits only (never a name), e.g. S01; codes that "
                          "look like names or dates (JaneDoe, 19850412) are refused")
    run.add_argument("--subject-pattern", default=None, metavar="REGEX",
                     help="the lab's own subject-code pattern (a regular expression the whole code must match, e.g. "
                          "'S[0-9]{3}'); replaces the name and date checks")
    _device_args(run)
    run.add_argument("--responses", default="terminal",
                     help="'terminal' (single keypresses) or 'simulated' (model observer); default terminal")
    run.add_argument("--out", type=Path, default=Path("sessions"),
                     help="folder for the session file sub-<ID>_ses-<NN>_task-<name>.sqlite (default ./sessions)")
    run.add_argument("--session", dest="session_label", default=None,
                     help="session label (letters/digits); default: the next free number, 01, 02, ...")
    _observer_args(run)

    resume = sub.add_parser("resume", help="continue a killed or stopped session exactly (repeats the interrupted trial)")
    resume.add_argument("session", type=Path, help="session .sqlite file")
    _device_args(resume, resume=True)
    resume.add_argument("--responses", default=None,
                        help="'terminal' or 'simulated'; default: what the session was started with")
    _observer_args(resume)

    export = sub.add_parser("export", help="export trials: BIDS-style beh TSV + JSON sidecar, CSV or Parquet (SI units)")
    export.add_argument("session", type=Path, help="session .sqlite file")
    export.add_argument("--format", default="bids",
                        help="bids, csv, parquet (needs pyarrow) or json (the whole session); default bids")
    export.add_argument("--out", type=Path, default=None, help="output folder (default: the session's folder)")

    status = sub.add_parser("status", help="show progress, status and the current estimate of a session (SI -> um/mm)")
    status.add_argument("session", type=Path, help="session .sqlite file")


def _device_args(p: argparse.ArgumentParser, resume: bool = False) -> None:
    p.add_argument("--display", default="simulated",
                   help="'simulated' or 'udp://HOST:PORT' (frames of tractions in Pa at the device rate, 1 kHz default)")
    p.add_argument("--device", default=None if resume else "braille-row",
                   help="display description: 'braille-row', 'stress2' or a .json description file (limits in Pa, "
                        "m, 1/s); " + ("default: the description the session recorded (another one is refused)"
                                       if resume else "default braille-row"))
    p.add_argument("--max-skipped", type=float, default=0.01,
                   help="udp: fraction (0-1) of a stimulus's frames that may be skipped because the host fell more "
                        "than half a period behind (late frames are never sent in a burst); beyond it the trial "
                        "aborts as a display fault (default 0.01)")
    p.add_argument("--no-wait", action="store_true",
                   help="do not wait in real time (inter-trial pauses, simulated playback): dry runs only")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _observer_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--observer-threshold", default=None,
                   help="simulated observer: RMS deviatoric strain at 1 mm depth felt at d' = 1 (strain, "
                        "dimensionless; default 2e-3, or on resume the session's own observer)")
    p.add_argument("--observer-strain", default=None,
                   help="simulated observer feels 'surface' (the ideal virtual surface's strain at 1 mm depth) "
                        "or 'display' (the simulated display's strain after the safety limits); default "
                        "surface, or on resume the session's own")


def _fitted_thresholds(path) -> list[str]:
    """The psychometric fit's threshold with its 95 % interval, one line per condition."""
    from tactilab.experiments.analysis import fit_summary

    try:
        return [f"fitted: {line}" for line in fit_summary([path])]
    except ValueError as exc:  # too few trials, or a session with no levels to fit
        return [f"fitted: no psychometric fit yet ({' '.join(str(exc).split())})"]


def _print_result(result, parameter: str) -> int:
    from tactilab.experiments.runner import format_estimate

    print(f"session {result.path}: {result.status} after {result.n_completed} trials; "
          f"procedure's running {format_estimate(result.estimate, parameter)}")
    if result.n_completed:
        for line in _fitted_thresholds(result.path):
            print(line)
    if result.status == "interrupted":
        print(f"resume with: tactilab experiment resume {result.path}")
        return 130
    return 0


#: library parameter (as it starts a library error) -> the flag that sets it, per call
_DEVICE, _DISPLAY = {"spec": "--device"}, {"spec": "--display", "url": "--display",
                                     "max_skipped_fraction": "--max-skipped"}
_RESPONSES = {"spec": "--responses", "kind": "--responses", "threshold": "--observer-threshold",
              "strain": "--observer-strain"}


@contextlib.contextmanager
def _flags(mapping: dict[str, str]):
    """Re-word a library error that names a parameter so that it names the CLI flag instead."""
    try:
        yield
    except ValueError as exc:
        text = str(exc)
        for parameter, flag in mapping.items():
            if text.startswith(parameter + ":") or text.startswith(parameter + " "):
                raise ValueError(flag + text[len(parameter):]) from None
        raise


def _zero_and_close(display, responses, report: bool) -> None:
    """The last word to the display is ZERO, whatever happened. A ZERO that fails is reported on
    stderr when ``report`` (the run ended normally); otherwise the error that ended the run goes on
    alone, in one line."""
    try:
        try:
            display.zero()
        except Exception as exc:  # noqa: BLE001 - the device may be what failed
            if report:
                print(f"tactilab experiment: warning: final ZERO failed ({' '.join(str(exc).split())}); "
                      "the device's watchdog zeroes it when frames stop", file=sys.stderr)
    finally:
        try:
            responses.close()
        finally:
            display.close()


class _Described:
    """Just a description, to check it before any display is opened."""

    def __init__(self, description) -> None:
        self.description = description


#: exit status of a run or resume stopped by a display fault (the trial was not scored)
EXIT_DISPLAY_FAULT = 3


def run(args: argparse.Namespace) -> int:
    from tactilab.experiments.display import DisplayError

    try:
        return _run(args)
    except DisplayError as exc:
        print(f"tactilab experiment: display error: {' '.join(str(exc).split())}", file=sys.stderr)
        return EXIT_DISPLAY_FAULT


def _run(args: argparse.Namespace) -> int:
    from tactilab.data_schemas.experiment import Protocol, check_label, check_subject
    from tactilab.experiments import factory

    if args.action == "run":
        check_subject(args.subject, "--subject", args.subject_pattern)
        if args.session_label is not None:
            check_label(args.session_label, "--session")
        protocol = Protocol.from_toml(args.protocol)
        with _flags(_DEVICE):
            description = factory.description_from_spec(args.device)
        make_out(args.out)
        with _flags({"folder": "--out"}):
            path, label = factory.next_session_path(args.out, args.subject, protocol.name)
        if args.session_label is not None:
            label = args.session_label
            path = args.out / f"sub-{args.subject}_ses-{label}_task-{protocol.name}.sqlite"
        with _flags(_DISPLAY):
            display = factory.display_from_spec(args.display, description, realtime=not args.no_wait,
                                                 max_skipped_fraction=args.max_skipped)
        try:
            with _flags(_RESPONSES):
                responses = factory.make_responses(args.responses, protocol, display,
                                                   threshold=args.observer_threshold, strain=args.observer_strain)
        except BaseException:
            display.close()
            raise
        from tactilab.experiments.runner import new_session

        print(f"session file: {path}", flush=True)
        ended = False
        try:
            result = new_session(protocol, path, display, responses, subject=args.subject, session=label,
                                 subject_pattern=args.subject_pattern,
                                 realtime=not args.no_wait, progress=not args.quiet)
            ended = True
        finally:
            _zero_and_close(display, responses, ended)
        return _print_result(result, protocol.procedure.parameter)

    if args.action == "resume":
        from tactilab.data_schemas.display import DisplayDescription
        from tactilab.experiments.resume import check_same_display, resume_session, session_header

        state = session_header(args.session)  # no replay here: resume_session replays once
        recorded_description = state.meta.get("display_description")
        if args.device is None and recorded_description is not None:
            description = DisplayDescription.model_validate(recorded_description)
        else:
            with _flags(_DEVICE):
                description = factory.description_from_spec(args.device or "braille-row")
        with _flags({"display": "--device"}):
            check_same_display(state.meta, _Described(description), args.session)
        kind = args.responses or state.meta["responses"]
        with _flags(_DISPLAY):
            display = factory.display_from_spec(args.display, description, realtime=not args.no_wait,
                                                 max_skipped_fraction=args.max_skipped)
        recorded = state.meta.get("responses_config") if kind == state.meta["responses"] else None
        try:
            with _flags(_RESPONSES):
                responses = factory.make_responses(kind, state.protocol, display, threshold=args.observer_threshold,
                                                   strain=args.observer_strain, recorded=recorded)
        except BaseException:
            display.close()
            raise
        print(f"resuming {args.session}: {state.n_completed} trials done"
              + (f", repeating interrupted trial {state.interrupted_trial}"
                 if state.interrupted_trial is not None else ""), flush=True)
        ended = False
        try:
            result = resume_session(args.session, display, responses, realtime=not args.no_wait,
                                    progress=not args.quiet)
            ended = True
        finally:
            _zero_and_close(display, responses, ended)
        return _print_result(result, state.protocol.procedure.parameter)

    if args.action == "export":
        from tactilab.experiments.export import export_session

        out = args.out if args.out is not None else args.session.parent
        if args.out is not None and args.session.is_file():  # a missing session is reported by export_session
            make_out(args.out)
        with _flags({"format": "--format"}):
            written = export_session(args.session, out, args.format)
        for path in written:
            print(f"wrote {path}")
        return 0

    from tactilab.experiments.resume import session_status

    info = session_status(args.session)
    for key, value in info.items():
        print(f"{key}: {value}")
    if info.get("completed"):
        for line in _fitted_thresholds(args.session):
            print(line)
    return 0

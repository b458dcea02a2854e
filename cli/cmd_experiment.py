"""``tactilab experiment``: run, resume, export and inspect psychophysics sessions."""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from tactilab.core.outputs import printable

from .common import PRINTED_WARNINGS, RunReport, make_out, print_warning

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
    run.add_argument("--clipped", default=None, choices=("refuse", "drop", "allow"),
                     help="a planned stimulus (level, staircase bound, design candidate) the display would limit "
                          "(amplitude, slew, duty): 'refuse' the protocol before the session starts (the error "
                          "names the stimulus and the limit), 'drop' it (levels and design candidates; the count "
                          "is printed and recorded; a staircase's bounds are refused) or 'allow' the safety layer "
                          "to limit it; default: the protocol's clipped field (itself 'refuse' by default)")
    _summary_args(run)

    resume = sub.add_parser("resume", help="continue a killed or stopped session exactly (repeats the interrupted trial)")
    resume.add_argument("session", type=Path, help="session .sqlite file")
    _device_args(resume, resume=True)
    resume.add_argument("--responses", default=None,
                        help="'terminal' or 'simulated'; default: what the session was started with")
    _observer_args(resume)
    _summary_args(resume)

    export = sub.add_parser("export", help="export trials: a BIDS beh dataset (TSV + sidecar describing every "
                                           "column), CSV, Parquet or JSON (SI units, the unit in each column name)")
    export.add_argument("session", type=Path, help="session .sqlite file")
    export.add_argument("--format", default="bids",
                        help="bids, csv, parquet (needs pyarrow), json (the whole session) or psychopy (PsychoPy's "
                             "trial-per-row CSV); default bids")
    export.add_argument("--out", type=Path, default=None,
                        help="output folder; for bids the dataset root, to which the session is added (default: "
                             "<session's folder>/bids); for the others default the session's folder")
    export.add_argument("--force", action="store_true", help="replace the session's files if they were exported before")
    export.add_argument("--author", action="append", default=None, dest="authors", metavar="NAME",
                        help="bids: an author of the dataset (repeat for each; written to a new "
                             "dataset_description.json as Authors)")
    export.add_argument("--json", action="store_true", help="print only the files written, as one JSON object")

    status = sub.add_parser("status", help="progress, status, safety interventions, frame timing and the fitted "
                                           "threshold of a session, as a table (mm, um, ms, counts)")
    status.add_argument("session", type=Path, help="session .sqlite file")
    status.add_argument("--json", action="store_true",
                        help="print the same as one JSON object (SI units, the unit in each key, e.g. rt_median_s)")


def _device_args(p: argparse.ArgumentParser, resume: bool = False) -> None:
    p.add_argument("--display", default="simulated",
                   help="'simulated', 'udp://HOST:PORT' (frames of tractions in Pa at the device rate, 1 kHz default) "
                        "or a device kind an installed plug-in registers")
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
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar (the bar, with the running estimate, goes to stderr, never to the "
                        "subject's terminal)")


def _observer_args(p: argparse.ArgumentParser) -> None:
    from .experiment_observer import add_observer_args

    add_observer_args(p)  # --observer, --observer-statistic, --observer-threshold, --observer-strain


def _summary_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--export", default=None, metavar="FORMAT",
                   help="at the end, export the session: bids (to <session's folder>/bids), csv, parquet or json")
    p.add_argument("--json", action="store_true",
                   help="print only the end-of-run summary, as one JSON object on stdout (SI units, the unit in "
                        "each key); progress and messages go to stderr")


def _finish(result, parameter: str, args: argparse.Namespace, warned: list[str], responses) -> int:
    """The end of a run or resume: one line, then the summary block with the fitted thresholds (or JSON).

    A session stopped before its end is resumed with the same subject: its running estimate is
    not printed where the subject sees it (``responses.on_screen``)."""
    from tactilab.experiments.session import format_estimate

    info = sys.stderr if args.json else sys.stdout
    hidden = result.status != "complete" and any(responses.on_screen(s) for s in {info, sys.stdout})
    if hidden:
        estimate = (f"running estimate and summary not shown on the subject's screen (`tactilab experiment "
                    f"status {result.path}` shows them)")
    else:
        estimate = f"procedure's running {format_estimate(result.estimate, parameter)}"
    print(f"session {result.path}: {result.status} after {result.n_completed} trials; {estimate}", file=info)
    exported = []
    if args.export is not None and result.status == "complete":
        from tactilab.experiments.session import export_session

        out = result.path.parent / "bids" if args.export == "bids" else result.path.parent
        with _flags({"format": "--export", "out": "--export"}):
            exported = [str(p) for p in export_session(result.path, out, args.export, overwrite=False)]
    elif args.export is not None:
        print(f"--export: not exported, the session is {result.status}; export it once it is complete", file=info)
    if not hidden:
        _print_summary(result.path, f"experiment {args.action}", args.json, warned, exported)
    if result.status == "interrupted":
        print(f"resume with: tactilab experiment resume {result.path}", file=info)
        return 130
    return 0


def _check_export(fmt: str | None) -> None:
    """Refuse a bad ``--export`` before the session starts, not after it ends."""
    from tactilab.experiments.session import FORMATS

    if fmt is not None and fmt not in FORMATS:
        raise ValueError(f"--export: must be one of {', '.join(FORMATS)}, got {fmt!r}")
    if fmt == "parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise ValueError("--export: 'parquet' needs the optional dependency pyarrow, which is not installed; "
                             "install it (`pip install pyarrow`) or use --export csv") from None


def _print_summary(path, command: str, as_json: bool, warned: list[str] = (), exported: list[str] = ()) -> None:
    """The session's summary table (``experiment status``'s), framed as a run summary, or one JSON object."""
    import json

    from tactilab.experiments.modelling import session_summary, summary_lines

    summary = session_summary(path)
    summary["warnings"] = list(warned) + summary["warnings"]
    summary["files"] = [str(path), *exported]
    if as_json:
        print(json.dumps({"command": command, **summary}))
        return
    print(f"--- tactilab {command}: summary ---")
    for line in summary_lines(summary):
        print(printable(line))  # a field read from the file never reaches the terminal raw
    print(printable(f"files: session {path}") + "".join(f"\n  {printable(str(p))}" for p in exported))


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
                print_warning("experiment", f"final ZERO failed ({exc}); the device's watchdog zeroes it when "
                              "frames stop")
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
    from tactilab.experiments.devices import DisplayError
    from tactilab.experiments.session import stop_signals

    try:
        with stop_signals():  # from the first instruction: a stop during start-up is a clean stop
            return _run(args)
    except DisplayError as exc:
        path = getattr(args, "session_path", None)
        if path is not None and Path(path).is_file():  # the run's summary first: what was done, what failed
            _print_summary(path, f"experiment {args.action}", args.json, list(PRINTED_WARNINGS))
        print(f"tactilab experiment: display error: {' '.join(str(exc).split())}", file=sys.stderr)
        return EXIT_DISPLAY_FAULT


def _run(args: argparse.Namespace) -> int:
    from tactilab.data_schemas.experiment import Protocol, check_label, check_subject
    from tactilab.experiments.devices import description_from_spec, open_display
    from tactilab.experiments.session import next_session_path

    from .experiment_observer import observer_responses

    if args.action in ("run", "resume"):
        _check_export(args.export)
    if args.action == "run":
        check_subject(args.subject, "--subject", args.subject_pattern)
        if args.session_label is not None:
            check_label(args.session_label, "--session")
        protocol = Protocol.from_toml(args.protocol)
        with _flags(_DEVICE):
            description = description_from_spec(args.device)
        make_out(args.out)
        with _flags({"folder": "--out"}):
            path, label = next_session_path(args.out, args.subject, protocol.name)
        if args.session_label is not None:
            label = args.session_label
            path = args.out / f"sub-{args.subject}_ses-{label}_task-{protocol.name}.sqlite"
        with _flags(_DISPLAY):
            display = open_display(args.display, description, realtime=not args.no_wait,
                                   max_skipped_fraction=args.max_skipped)
        try:
            with _flags(_RESPONSES):
                responses = observer_responses(args.responses, protocol, display, args)
        except BaseException:
            display.close()
            raise
        from tactilab.experiments.session import new_session

        def created(file) -> None:  # printed once the file exists: a refused start leaves none behind
            print(f"session file: {file}", flush=True, file=sys.stderr if args.json else sys.stdout)

        args.session_path = path
        ended, report = False, RunReport("experiment run")
        try:
            with report.collecting_warnings():
                result = new_session(protocol, path, display, responses, subject=args.subject, session=label,
                                     subject_pattern=args.subject_pattern, realtime=not args.no_wait,
                                     progress=not args.quiet, on_created=created, clipped=args.clipped)
            ended = True
        finally:
            _zero_and_close(display, responses, ended)
        return _finish(result, protocol.procedure.parameter, args, report.warnings, responses)

    if args.action == "resume":
        from tactilab.data_schemas.display import DisplayDescription
        from tactilab.experiments.session import check_same_display, resume_session, session_header

        state = session_header(args.session)  # no replay here: resume_session replays once
        recorded_description = state.meta.get("display_description")
        if args.device is None and recorded_description is not None:
            description = DisplayDescription.model_validate(recorded_description)
        else:
            with _flags(_DEVICE):
                description = description_from_spec(args.device or "braille-row")
        with _flags({"display": "--device"}):
            check_same_display(state.meta, _Described(description), args.session)
        kind = args.responses or state.meta["responses"]
        with _flags(_DISPLAY):
            display = open_display(args.display, description, realtime=not args.no_wait,
                                   max_skipped_fraction=args.max_skipped)
        recorded = state.meta.get("responses_config") if kind == state.meta["responses"] else None
        try:
            with _flags(_RESPONSES):
                responses = observer_responses(kind, state.protocol, display, args, recorded)
        except BaseException:
            display.close()
            raise
        print(f"resuming {args.session}: {state.n_completed} trials done"
              + (f", repeating interrupted trial {state.interrupted_trial}"
                 if state.interrupted_trial is not None else ""), flush=True,
              file=sys.stderr if args.json else sys.stdout)
        args.session_path = args.session
        ended, report = False, RunReport("experiment resume")
        try:
            with report.collecting_warnings():
                result = resume_session(args.session, display, responses, realtime=not args.no_wait,
                                        progress=not args.quiet)
            ended = True
        finally:
            _zero_and_close(display, responses, ended)
        return _finish(result, state.protocol.procedure.parameter, args, report.warnings, responses)

    if args.action == "export":
        import json

        from tactilab.experiments.session import export_session

        if args.out is not None:
            out = args.out
        else:
            out = args.session.parent / "bids" if args.format == "bids" else args.session.parent
        if args.session.is_file():  # a missing session is reported by export_session
            make_out(out)
        with _flags({"format": "--format", "out": "--out", "authors": "--author"}):
            written = export_session(args.session, out, args.format, overwrite=args.force, authors=args.authors)
        if args.json:
            print(json.dumps({"command": "experiment export", "format": args.format, "out": str(out),
                              "files": [str(p) for p in written]}))
        else:
            for path in written:
                print(printable(f"wrote {path}"))
        return 0

    _print_status(args)
    return 0


def _print_status(args: argparse.Namespace) -> None:
    """``experiment status``: the summary table, or one JSON object with ``--json``."""
    import json

    from tactilab.experiments.modelling import session_summary, summary_lines
    from tactilab.experiments.session import file_state

    summary = session_summary(args.session)
    state = file_state(args.session)  # read after the readers closed: the last one folds a leftover log in
    if args.json:
        print(json.dumps({"command": "experiment status", **summary, "self_contained": state["self_contained"]}))
        return
    for line in summary_lines(summary):
        print(printable(line))  # a field read from the file never reaches the terminal raw
    if not state["self_contained"] and summary["status"] != "running":
        print(printable(f"file: not self-contained ({state['wal_bytes']} bytes of the log in {args.session}-wal"
                        f"{', a hot journal' if state['hot_journal'] else ''}); run this command again once no "
                        "other process reads it, from a writable folder"))
    if summary["status"] in ("interrupted", "failed"):
        print(printable(f"resume with: tactilab experiment resume {args.session}"))

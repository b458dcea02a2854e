"""``tactilab demo``: the end-to-end main job on built-in example data."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .common import RunReport, add_report_options, choose_out

NAME = "demo"
HELP = "run the end-to-end demo on built-in example data and write a report folder"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=None,
                        help="report folder to write; default: a new folder ./tactilab-report (then -2, -3, ...); "
                             "an existing non-empty one needs --force. Figures use mm, kPa, µm and ms")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    add_report_options(parser)


def run(args: argparse.Namespace) -> int:
    # Imported here so that `tactilab --help` does not load the whole library.
    from tactilab.demo import SECTIONS

    report = RunReport("demo")
    out = report.watch(choose_out(args.out, Path("tactilab-report"), args.force).resolve())
    lines = sys.stderr if args.json else sys.stdout  # with --json, stdout holds only the JSON object
    with report.collecting_warnings():
        for section in SECTIONS:
            for line in section.run_demo(out, progress=not args.quiet):
                print(line, file=lines, flush=True)
            summary = (section.__doc__ or "").strip().splitlines()[0].split(":", 1)[-1].strip()
            report.computed.append(f"section {section.__name__.rsplit('.', 1)[-1]}: {summary}")
    report.method = "each section names its methods above; their error estimates are in the report's files"
    print(f"report written to {out}", file=lines, flush=True)
    report.emit(args.json)
    return 0

"""``tactilab demo``: the end-to-end main job on built-in example data."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "demo"
HELP = "run the end-to-end demo on built-in example data and write a report folder"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=Path("tactilab-report"),
                        help="report folder to write (default: ./tactilab-report); figures use mm and kPa")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> int:
    # Imported here so that `tactilab --help` does not load the whole library.
    from tactilab.demo import SECTIONS

    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    for section in SECTIONS:
        for line in section.run_demo(out, progress=not args.quiet):
            print(line, flush=True)
    print(f"report written to {out}")
    return 0

"""docs/cli.md lists every `tactilab` command and option with its unit rule, and the rules hold:
a bare number for a dimensional option, or a unit on a count or dimensionless one, is an error that
names the option."""

from __future__ import annotations

import argparse
import re
import sqlite3
import contextlib
from pathlib import Path

import pytest

from tactilab.cli.main import build_parser
from tactilab.cli.main import main as cli_main

ROOT = Path(__file__).resolve().parents[1]
RULES = {"length", "lengths", "pressure", "force", "forces", "time", "frequency", "hypothesis", "surface", "dimensionless",
         "fraction", "angles", "count", "counts", "seed", "path", "choice", "text", "flag"}
#: rule -> a wrong value, and what the one-line error must say besides the option's name
PROBES = {
    "length": ("2", "has no unit"), "lengths": ("2", "has no unit"), "pressure": ("2", "has no unit"),
    "force": ("2", "has no unit"), "forces": ("2", "has no unit"),
    "time": ("2", "has no unit"), "frequency": ("2", "has no unit"),
    "surface": ("sinusoid:A=2,p=4mm", "has no unit"),
    "count": ("3mm", ""), "counts": ("3mm", ""), "seed": ("3mm", ""),
    "dimensionless": ("3mm", ""), "fraction": ("3mm", ""), "angles": ("3mm", ""),
}


def exit_code(argv: list[str]) -> int:
    """The command's exit status (argparse's own usage errors exit through SystemExit)."""
    try:
        return cli_main(argv)
    except SystemExit as exc:
        return int(exc.code)


def walk(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ("tactilab",)):
    """Yield (command words, option or positional name, action) for the whole parser tree."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from walk(sub, (*prefix, name))
        elif not isinstance(action, argparse._HelpAction):
            yield " ".join(prefix), action.option_strings[0] if action.option_strings else action.dest, action


def documented() -> dict[tuple[str, str], str]:
    """(command, option) -> rule, from docs/cli.md's tables."""
    out, command = {}, None
    for line in (ROOT / "docs" / "cli.md").read_text().splitlines():
        heading = re.fullmatch(r"## `(tactilab[^`]*)`", line)
        if heading:
            command = heading.group(1)
            continue
        row = re.match(r"\| `([^`]+)` \| (\w+) \|", line)
        if row and command:
            assert (command, row.group(1)) not in out, f"docs/cli.md lists {row.group(1)} of {command} twice"
            out[(command, row.group(1))] = row.group(2)
    return out


def test_every_option_is_documented_with_a_known_rule():
    parsed = {(command, name) for command, name, _ in walk(build_parser())}
    docs = documented()
    missing = sorted(parsed - set(docs))
    assert not missing, f"add these to docs/cli.md with their unit rule: {missing}"
    stale = sorted(set(docs) - parsed)
    assert not stale, f"docs/cli.md lists options the parser does not have: {stale}"
    unknown = {k: v for k, v in docs.items() if v not in RULES}
    assert not unknown, f"unknown unit rules (use one of {sorted(RULES)}): {unknown}"
    flags = {(c, n) for c, n, a in walk(build_parser()) if a.nargs == 0}
    assert {k for k, v in docs.items() if v == "flag"} == flags


@pytest.fixture(scope="module")
def bases(tmp_path_factory):
    """A valid command line per command (an option given again at the end overrides its value)."""
    folder = tmp_path_factory.mktemp("cliref")
    protocol = folder / "p.toml"
    protocol.write_text('name = "ref"\nseed = 1\niti_s = 0\n[task]\nkind = "2ifc"\n[stimulus]\namplitude_m = "2um"\n'
                        'pitch_m = "2mm"\nspeed_m_per_s = "40mm/s"\nduration_s = "20ms"\nramp_s = "5ms"\n'
                        '[procedure]\nmethod = "staircase"\nparameter = "amplitude_m"\n[[procedure.tracks]]\n'
                        'start = "3um"\nstep_sizes = [0.2]\nmin_level = "0.3um"\nmax_level = "6um"\nmax_trials = 4\n')
    design = folder / "design.toml"
    design.write_text('[[trials]]\namplitude_m = "1um"\npitch_m = "2mm"\nspeed_m_per_s = "20mm/s"\nn = 40\n')
    assert cli_main(["experiment", "run", str(protocol), "--subject", "S01", "--responses", "simulated",
                     "--no-wait", "--quiet", "--out", str(folder)]) == 0
    session = folder / "sub-S01_ses-01_task-ref.sqlite"
    with contextlib.closing(sqlite3.connect(session)) as db, db:  # interrupted: resumable
        db.execute("DELETE FROM events WHERE kind = 'session_complete' OR trial_index >= 2")
        db.execute("DELETE FROM trials WHERE trial_index >= 2")
    run = [str(protocol), "--subject", "S02", "--responses", "simulated", "--no-wait", "--quiet", "--out", str(folder)]
    return {
        "tactilab stress": ["stress", str(folder / "missing.npz"), "--depth", "1mm"],
        "tactilab simulate": ["simulate", str(folder / "missing.toml")],
        "tactilab contact": ["contact", "sphere:R=10mm", "--grid", "16", "--out", str(folder / "contact")],
        "tactilab synthesis": ["synthesis", "--depth", "1mm"],
        "tactilab invert": ["invert", str(folder / "missing.nc"), "--scene", str(folder / "missing.toml")],
        "tactilab metamer": ["metamer", "--target", "sinusoid:A=0.5mm,p=4mm"],
        "tactilab experiment run": ["experiment", "run", *run],
        "tactilab experiment resume": ["experiment", "resume", str(session), "--no-wait", "--quiet",
                                       "--responses", "simulated"],
        "tactilab experiment export": ["experiment", "export", str(session), "--out", str(folder / "export")],
        "tactilab experiment status": ["experiment", "status", str(session)],
        "tactilab experiment fit": ["experiment", "fit", str(session)],
        "tactilab experiment compare": ["experiment", "compare", str(session), "--model", "zx@1mm",
                                        "--model", "xx@1mm"],
        "tactilab experiment power": ["experiment", "power", "--true", "zx@1mm", "--rival", "xx@1mm",
                                      "--design", str(design)],
        "tactilab device emulate": ["device", "emulate", "--port", "0", "--max-seconds", "1ms"],
    }


def test_a_wrong_unit_is_an_error_naming_the_option(bases, capsys):
    """Each dimensional option refuses a bare number, each count or dimensionless one a unit; one line, exit 2."""
    docs = documented()
    checked = 0
    for (command, option), rule in sorted(docs.items()):
        if rule not in PROBES or not option.startswith("--"):
            continue
        value, must_say = PROBES[rule]
        capsys.readouterr()
        code = exit_code([*bases[command], option, value])
        err = capsys.readouterr().err
        assert code == 2, (command, option, value, err)
        assert option in err and must_say in err and err.count("\n") == 1, (command, option, err)
        if must_say:  # the fix is shown: the same number with a unit
            assert "write it with a unit, e.g. '2" in err, (command, option, err)
        checked += 1
    assert checked >= 30


def test_hypothesis_depths_need_units(bases, capsys):
    for (command, option), rule in sorted(documented().items()):
        if rule != "hypothesis":
            continue
        argv = [*bases[command], option, "zx@2"]
        if option == "--model":
            argv += ["--model", "yy@1mm"]
        assert exit_code(argv) == 2, (command, option)
        err = capsys.readouterr().err
        assert "'2' has no unit" in err and "write it with a unit, e.g. '2mm'" in err, (command, option, err)

"""`experiment export --format bids`: a dataset the real BIDS validator accepts, every column described,
one name per quantity, flat per-interval stimulus columns, pseudonymous participants."""

from __future__ import annotations

import csv
import json
import re
import subprocess
from pathlib import Path

import pandas as pd
import pytest

from tactilab.cli.main import main as cli_main
from tactilab.experiments import session_dataframe
from tactilab.experiments.session.recording import SessionLog

ROOT = Path(__file__).resolve().parents[1]
VALIDATOR = ROOT / ".ci" / "node" / "node_modules" / ".bin" / "bids-validator"

PROTOCOL = """
name = "gratingdetection"
seed = 3
iti_s = 0
[task]
kind = "2ifc"
[stimulus]
amplitude_m = "2um"
pitch_m = "2mm"
speed_m_per_s = "40mm/s"
duration_s = "20ms"
ramp_s = "5ms"
[procedure]
method = "staircase"
parameter = "amplitude_m"
[[procedure.tracks]]
start = "3um"
step_sizes = [0.2]
min_level = "0.3um"
max_level = "6um"
max_trials = 6
"""


#: the validator's lockfile (exact versions of it and of every dependency), which the README's command installs
LOCK = ROOT / ".ci" / "bids-validator" / "package-lock.json"


def _install_line() -> str:
    """The validator install step of the README's test command (from the lockfile)."""
    return re.search(r"mkdir -p \.ci/node [^&]*&& npm ci [^&]*", (ROOT / "README.md").read_text()).group(0).strip()


def validate(folder: Path) -> dict:
    """Run the bids-validator npm package on ``folder``; its JSON report (issues: errors, warnings)."""
    if not VALIDATOR.exists():
        pytest.fail(f"the BIDS validator is not installed; run `{_install_line()}` in the repository root "
                    "(the README's test command does this)")
    out = subprocess.run([str(VALIDATOR), "--json", str(folder)], capture_output=True, text=True, timeout=120)
    return json.loads(out.stdout)


def _errors(report: dict) -> list[str]:
    return [f"{e['key']}: {e['reason']} {[f['file']['relativePath'] for f in e['files'] if f.get('file')]}"
            for e in report["issues"]["errors"]]


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bids")
    (folder / "p.toml").write_text(PROTOCOL)
    for subject in ("S01", "S02"):
        assert cli_main(["experiment", "run", str(folder / "p.toml"), "--subject", subject, "--responses",
                         "simulated", "--no-wait", "--quiet", "--out", str(folder / "sessions")]) == 0
    return sorted((folder / "sessions").glob("*.sqlite"))


def test_the_validator_pin_is_installed():
    if not VALIDATOR.exists():
        pytest.fail(f"the BIDS validator is not installed; run `{_install_line()}` in the repository root")
    version = subprocess.run([str(VALIDATOR), "--version"], capture_output=True, text=True, timeout=60)
    pinned = json.loads(LOCK.read_text())["packages"]["node_modules/bids-validator"]["version"]
    assert version.stdout.strip() == pinned == "1.15.0"


@pytest.mark.slow
def test_export_is_bids_valid_and_fails_validation_when_broken(sessions, tmp_path, capsys):
    out = tmp_path / "dataset"
    for path in sessions:  # two subjects into one dataset
        assert cli_main(["experiment", "export", str(path), "--format", "bids", "--out", str(out)]) == 0
    capsys.readouterr()
    report = validate(out)
    assert _errors(report) == [], _errors(report)
    assert report["summary"]["subjects"] == ["S01", "S02"] and report["summary"]["tasks"] == ["gratingdetection"]
    description = json.loads((out / "dataset_description.json").read_text())
    assert description["BIDSVersion"] == "1.9.0" and description["DatasetType"] == "raw"
    assert description["GeneratedBy"][0]["Name"] == "tactilab" and description["GeneratedBy"][0]["Version"]
    participants = pd.read_csv(out / "participants.tsv", sep="\t", dtype=str)
    assert list(participants.columns) == ["participant_id"]  # pseudonymous codes only, nothing else
    assert list(participants["participant_id"]) == ["sub-S01", "sub-S02"]
    assert "participant_id" in json.loads((out / "participants.json").read_text())
    # the check has teeth: an empty cell and a missing dataset description are errors
    tsv = next(out.rglob("sub-S01_*_beh.tsv"))
    tsv.write_text(tsv.read_text().replace("\tamplitude_m\t", "\t\t", 1))
    (out / "dataset_description.json").unlink()
    keys = {e["key"] for e in validate(out)["issues"]["errors"]}
    assert {"TSV_EMPTY_CELL", "DATASET_DESCRIPTION_JSON_MISSING"} <= keys, keys


def test_sidecar_describes_every_column_with_units_and_levels(sessions, tmp_path, capsys):
    assert cli_main(["experiment", "export", str(sessions[0]), "--out", str(tmp_path)]) == 0
    tsv = next(tmp_path.rglob("*_beh.tsv"))
    table = pd.read_csv(tsv, sep="\t", keep_default_na=False, quoting=csv.QUOTE_NONE)
    sidecar = json.loads(tsv.with_suffix(".json").read_text())
    for column in table.columns:
        assert sidecar[column]["Description"], column
        unit = {"_m": "m", "_s": "s", "_m_per_s": "m/s", "_hz": "Hz", "_rad": "rad"}
        expected = next((u for suffix, u in sorted(unit.items(), key=lambda kv: -len(kv[0]))
                         if column.endswith(suffix)), None)
        assert sidecar[column].get("Units") == expected or column == "level", (column, sidecar[column])
    assert sidecar["level"]["Units"] == "m" and sidecar["rt_s"]["Units"] == "s"
    assert sidecar["correct"]["Levels"] == {"True": "yes", "False": "no"}
    assert set(sidecar["response"]["Levels"]) == {"1", "2"} and set(sidecar["parameter"]["Levels"]) == {"amplitude_m"}
    assert set(sidecar["interval2_surface"]["Levels"]) == {"sinusoid", "square"}
    assert sidecar["TaskName"] == "gratingdetection" and sidecar["Seed"] == 3 and sidecar["SoftwareName"] == "tactilab"
    assert len(sidecar["DisplayDescriptionSHA256"]) == 64


def test_one_name_per_quantity_and_flat_interval_columns(sessions, tmp_path):
    from tactilab.experiments.session.export import export_session

    tsv = export_session(sessions[0], tmp_path)[0]
    table = pd.read_csv(tsv, sep="\t", keep_default_na=False, quoting=csv.QUOTE_NONE)
    frame = session_dataframe(sessions[0])
    trials = SessionLog(sessions[0]).trials()
    assert set(table.columns) <= set(frame.columns)  # the TSV's names are the DataFrame's
    assert "rt_s" in json.loads(SessionLog(sessions[0]).connection.execute(
        "SELECT record FROM trials").fetchone()[0])  # ... and the SQLite record's
    assert "response_time" not in table and "amplitude_m" not in table and "amplitude_m" not in frame
    assert list(table["rt_s"]) == pytest.approx([t.rt_s for t in trials])
    assert list(frame["rt_s"]) == pytest.approx([t.rt_s for t in trials])
    for k in (1, 2):
        for field in ("amplitude_m", "pitch_m", "speed_m_per_s", "duration_s"):
            want = [getattr(t.stimuli[k - 1], field) for t in trials]
            assert list(table[f"interval{k}_{field}"]) == pytest.approx(want)
            assert list(frame[f"interval{k}_{field}"]) == pytest.approx(want)
    # the blank interval is visible as such, and the JSON stimuli column (read by analysis) is kept
    assert all(min(t.stimuli[0].amplitude_m, t.stimuli[1].amplitude_m) == 0 for t in trials)
    assert [json.loads(s) for s in table["stimuli"]] == [[s.model_dump() for s in t.stimuli] for t in trials]


def test_export_never_overwrites_without_force(sessions, tmp_path, capsys):
    argv = ["experiment", "export", str(sessions[0]), "--out", str(tmp_path)]
    assert cli_main(argv) == 0
    capsys.readouterr()
    assert cli_main(argv) == 2
    err = capsys.readouterr().err
    assert "--out: " in err and "already exists" in err and "--force" in err and err.count("\n") == 1
    assert cli_main([*argv, "--force"]) == 0
    for fmt in ("csv", "json"):
        assert cli_main(["experiment", "export", str(sessions[0]), "--format", fmt, "--out", str(tmp_path)]) == 0
        assert cli_main(["experiment", "export", str(sessions[0]), "--format", fmt, "--out", str(tmp_path)]) == 2
        assert "add --force" in capsys.readouterr().err


def test_authors_go_into_the_dataset_description_and_bad_ones_are_refused(sessions, tmp_path, capsys):
    from tactilab.experiments.session import export_session

    out = tmp_path / "dataset"
    assert cli_main(["experiment", "export", str(sessions[0]), "--out", str(out), "--author", "Ada Lovelace",
                     "--author", "Alan Turing"]) == 0
    assert json.loads((out / "dataset_description.json").read_text())["Authors"] == ["Ada Lovelace", "Alan Turing"]
    with pytest.raises(ValueError, match="authors: must be a list of non-empty names"):
        export_session(sessions[0], tmp_path / "b", "bids", authors="Ada Lovelace")
    with pytest.raises(ValueError, match="authors: must be a list of non-empty names"):
        export_session(sessions[0], tmp_path / "c", "bids", authors=["Ada", " "])
    with pytest.raises(ValueError, match="authors: only a BIDS dataset has authors"):
        export_session(sessions[0], tmp_path, "csv", authors=["Ada"])
    capsys.readouterr()
    assert cli_main(["experiment", "export", str(sessions[0]), "--out", str(tmp_path / "d"), "--author", ""]) != 0
    assert "--author: must be a list of non-empty names" in capsys.readouterr().err

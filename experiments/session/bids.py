"""A BIDS behavioural (``beh``) dataset from a session: files, column descriptions, units.

Layout of the dataset root ``out`` (BIDS 1.9; checked by the ``bids-validator`` npm package in
``tests/test_bids_export.py``)::

    dataset_description.json   Name, BIDSVersion, DatasetType "raw", GeneratedBy tactilab <version>,
                               Authors (when given)
    participants.tsv (+ .json) participant_id only: the pseudonymous code, never a name
    README                     what the dataset is and how its columns are named
    sub-<id>/ses-<n>/beh/sub-<id>_ses-<n>_task-<name>_beh.tsv   one row per completed trial
    sub-<id>/ses-<n>/beh/sub-<id>_ses-<n>_task-<name>_beh.json  a description of EVERY column

Naming rule: a column has the same name in the TSV, in ``session_dataframe`` and in the session's
SQLite trial records; a dimensional quantity carries its SI unit in its name (``rt_s``,
``interval1_amplitude_m``) and the sidecar repeats it as BIDS ``Units`` (``s``, ``m``, ``m/s``,
``Hz``, ``rad``). Categorical columns list their ``Levels``.
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path
from typing import Any

import pandas as pd

from tactilab.core import package_version
from tactilab.core.outputs import output_path, write_atomic
from tactilab.data_schemas.experiment_records import INTERVAL_FIELDS, TrialRecord, trials_to_dataframe

#: the BIDS version the files follow
BIDS_VERSION = "1.9.0"

_FIELD_TEXT = {
    "surface": ("virtual surface shape", None),
    "amplitude_m": ("virtual surface height amplitude", "m"),
    "pitch_m": ("virtual surface spatial period", "m"),
    "speed_m_per_s": ("scanning speed (sign = direction)", "m/s"),
    "duration_s": ("stimulus duration", "s"),
    "ramp_s": ("raised-cosine onset and offset ramp", "s"),
    "phase_rad": ("phase of the surface at x = 0, t = 0", "rad"),
    "frame_rate_hz": ("drive frame rate", "Hz"),
}
_UNIT_OF = {"m": "m", "s": "s", "m_per_s": "m/s", "hz": "Hz", "rad": "rad"}
_BOOL_LEVELS = {"True": "yes", "False": "no"}

#: column -> (description, BIDS Units or None); the interval columns are added per session
COLUMNS: dict[str, tuple[str, str | None]] = {
    "trial_index": ("Trial number (0-based, in planned order)", None),
    "block": ("Block number (0-based)", None),
    "attempt": ("0, or how many earlier attempts of this trial were cut short by an interruption", None),
    "repeated": ("Whether an earlier, interrupted attempt of this trial had reached the display", None),
    "track": ("Interleaved staircase track (0-based)", None),
    "parameter": ("Stimulus parameter varied by the procedure (its SI unit in its name)", None),
    "level": ("Commanded level of the varied parameter, in the SI unit of 'parameter'", None),
    "target": ("Correct response label (n/a when no answer is correct)", None),
    "response": ("Response label", None),
    "correct": ("Whether the response was correct (n/a when no answer is correct)", None),
    "rt_s": ("Response time from the first stimulus onset (monotonic clock)", "s"),
    "utc_presented": ("UTC date and time when the stimulus was recorded as presented (ISO 8601)", None),
    "frames_sent": ("Display frames sent for the trial's stimuli (count)", None),
    "frames_late": ("Display frames sent late (count)", None),
    "frames_missing": ("Display frames never acknowledged (count)", None),
    "frames_skipped": ("Display frames skipped: due more than half a period ago, never sent late (count)", None),
    "safety_interventions": ("Safety-layer interventions during the trial (count)", None),
    "stimuli": ("Commanded stimulus of each interval, as a JSON list of objects (SI units, unit in each key)", None),
}


def unit_of(name: str) -> str | None:
    """BIDS ``Units`` of a column named with its SI unit (``amplitude_m`` -> ``m``), or None."""
    for suffix, unit in sorted(_UNIT_OF.items(), key=lambda kv: -len(kv[0])):
        if name.endswith("_" + suffix):
            return unit
    return None


def describe_columns(trials: list[TrialRecord], labels: list[str]) -> dict[str, dict[str, Any]]:
    """The sidecar entry (Description, Units, Levels) of every TSV column, in column order.

    ``labels`` are the task's response labels (Levels of ``target`` and ``response``).
    """
    parameters = sorted({t.parameter for t in trials})
    n_intervals = max((len(t.stimuli) for t in trials), default=0)
    out: dict[str, dict[str, Any]] = {}
    for name, (text, unit) in COLUMNS.items():
        entry: dict[str, Any] = {"Description": text}
        if unit:
            entry["Units"] = unit
        if name in ("repeated", "correct"):
            entry["Levels"] = dict(_BOOL_LEVELS)
        elif name in ("target", "response"):
            entry["Levels"] = {label: f"response '{label}'" for label in labels}
        elif name == "parameter":
            entry["Levels"] = {p: f"the stimulus field {p} (unit {unit_of(p) or 'none'})" for p in parameters}
        elif name == "level" and len(parameters) == 1 and unit_of(parameters[0]):
            entry["Units"] = unit_of(parameters[0])
        out[name] = entry
    for k in range(1, n_intervals + 1):
        for field in INTERVAL_FIELDS:
            text, unit = _FIELD_TEXT[field]
            entry = {"Description": f"Interval {k}: commanded {text} (n/a when the trial has fewer intervals)"}
            if unit:
                entry["Units"] = unit
            if field == "surface":
                entry["Levels"] = {"sinusoid": "sinusoidal grating", "square": "square-wave grating"}
            out[f"interval{k}_{field}"] = entry
    return out


def beh_table(trials: list[TrialRecord]) -> pd.DataFrame:
    """The trials as the TSV's table: the DataFrame's names, ``n/a`` for missing values."""
    frame = trials_to_dataframe(trials)
    frame["utc_presented"] = frame["utc_presented"].map(lambda t: t.isoformat())
    n_intervals = max((len(t.stimuli) for t in trials), default=0)
    columns = list(COLUMNS) + [f"interval{k}_{f}" for k in range(1, n_intervals + 1) for f in INTERVAL_FIELDS]
    table = frame[columns].astype(object)
    return table.where(table.notna(), "n/a")


def write_dataset(meta: dict[str, Any], trials: list[TrialRecord], out: Path, *, overwrite: bool,
                  authors: list[str] | None = None) -> list[Path]:
    """Write (or add one session to) the BIDS dataset at ``out``; return the files written.

    ``authors`` (one name per entry) goes into a new ``dataset_description.json`` as BIDS
    ``Authors``; without it the validator warns NO_AUTHORS (the dataset is still valid).

    Dataset-level files are created when missing (an existing ``dataset_description.json`` or
    README is kept); the subject joins ``participants.tsv`` once. The session's TSV and sidecar
    replace existing ones only when ``overwrite``.

    Raises
    ------
    ValueError
        When the session's files exist and ``overwrite`` is False, ``participants.tsv`` exists
        without a ``participant_id`` column, or ``authors`` is not a list of non-empty names.
    """
    authors = check_authors(authors)
    task = meta["protocol"]["name"]
    subject, session = meta["subject"], meta["session"]
    folder = output_path(out, f"sub-{subject}", f"ses-{session}", "beh", option="out")
    stem = f"sub-{subject}_ses-{session}_task-{task}"
    tsv = output_path(out, f"sub-{subject}", f"ses-{session}", "beh", f"{stem}_beh.tsv", option="out")
    sidecar = output_path(out, f"sub-{subject}", f"ses-{session}", "beh", f"{stem}_beh.json", option="out")
    if not overwrite and (os.path.lexists(tsv) or os.path.lexists(sidecar)):
        raise ValueError(f"out: {tsv} already exists; export to another folder, or add --force to replace it")
    folder.mkdir(parents=True, exist_ok=True)
    written = [tsv, sidecar]
    table = beh_table(trials)
    write_atomic(tsv, lambda p: table.to_csv(p, sep="\t", index=False, na_rep="n/a", quoting=csv.QUOTE_NONE),
                 option="out")
    labels = _labels(meta)
    description = {
        "TaskName": task,
        "TaskDescription": meta["protocol"].get("description", "") or f"tactilab protocol '{task}'",
        "SoftwareName": "tactilab",
        "SoftwareVersion": meta["package_version"],
        "DisplayID": meta["display_id"],
        "DisplayDescription": meta.get("display_description"),
        "DisplayDescriptionSHA256": meta.get("display_sha256"),
        "ResponseSource": meta["responses"],
        "Seed": meta["seed"],
        "Protocol": meta["protocol"],
        **describe_columns(trials, labels),
    }
    write_atomic(sidecar, lambda p: p.write_text(json.dumps(description, indent=2)), option="out")
    dataset = output_path(out, "dataset_description.json", option="out")
    if not os.path.lexists(dataset):
        _write_new(dataset, json.dumps({
            "Name": f"tactilab psychophysics: task {task}",
            "BIDSVersion": BIDS_VERSION,
            "DatasetType": "raw",
            "GeneratedBy": [{"Name": "tactilab", "Version": package_version(),
                             "Description": "tactilab experiment export --format bids"}],
            **({"Authors": authors} if authors else {}),
        }, indent=2))
        written.append(dataset)
    written += _participants(out, f"sub-{subject}")
    readme = output_path(out, "README", option="out")
    if not os.path.lexists(readme):
        _write_new(readme,
            "Psychophysics sessions recorded and exported by tactilab (tactile displays).\n\n"
            "One *_beh.tsv per session, one row per completed trial; its *_beh.json sidecar describes\n"
            "every column. A dimensional column carries its SI unit in its name (rt_s, interval1_amplitude_m)\n"
            "and in the sidecar's Units. Participant ids are pseudonymous codes.\n")
        written.append(readme)
    return written


def check_authors(authors) -> list[str] | None:
    """``authors`` as a list of stripped names (``None`` stays ``None``).

    Raises
    ------
    ValueError
        If it is a bare string or holds an empty or non-string name.
    """
    if authors is None:
        return None
    if isinstance(authors, str) or not all(isinstance(a, str) and a.strip() for a in authors) or not authors:
        raise ValueError(f"authors: must be a list of non-empty names (one author per entry), got {authors!r}; "
                         "e.g. ['Ada Lovelace', 'Alan Turing']")
    return [a.strip() for a in authors]


def _write_new(path: Path, text: str) -> None:
    """Write a dataset-level file whole (through a temporary file; never through a symlink)."""
    write_atomic(path, lambda p: p.write_text(text), option="out")


def _labels(meta: dict[str, Any]) -> list[str]:
    from tactilab.data_schemas.experiment import Task

    return Task.model_validate(meta["protocol"]["task"]).labels


def _participants(out: Path, participant: str) -> list[Path]:
    """Add ``participant`` to participants.tsv (created with its .json when missing)."""
    tsv = output_path(out, "participants.tsv", option="out")
    sidecar = output_path(out, "participants.json", option="out")
    written = []
    if os.path.lexists(tsv):
        table = pd.read_csv(tsv, sep="\t", dtype=str, keep_default_na=False)
        if "participant_id" not in table.columns:
            raise ValueError(f"out: {tsv} has no participant_id column; export to a new folder")
    else:
        table = pd.DataFrame({"participant_id": []}, dtype=str)
    if participant not in set(table["participant_id"]):
        row = {c: "n/a" for c in table.columns} | {"participant_id": participant}
        table = pd.concat([table, pd.DataFrame([row])], ignore_index=True).sort_values("participant_id")
        write_atomic(tsv, lambda p: table.to_csv(p, sep="\t", index=False, na_rep="n/a"), option="out")
        written.append(tsv)
    if not os.path.lexists(sidecar):
        _write_new(sidecar, json.dumps({"participant_id": {
            "Description": "Pseudonymous participant code (letters and digits; never a name or a birth date)"}},
            indent=2))
        written.append(sidecar)
    return written

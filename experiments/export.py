"""Export a session: BIDS-style ``*_beh.tsv`` with a JSON sidecar, CSV, Parquet or a DataFrame.

The BIDS layout is ``<out>/sub-<subject>/ses-<session>/beh/sub-<subject>_ses-<session>_task-<task>_beh.tsv``
with ``n/a`` for missing values and a sidecar describing each column (with units) and the
provenance (seed, package version, display id, the full display description and its SHA-256,
the protocol).
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from tactilab.data_schemas.experiment_records import (
    TEXT_COLUMNS, Session, TrialRecord, trials_from_dataframe, trials_to_dataframe)

from .recording import SessionLog

FORMATS = ("bids", "csv", "parquet", "json")

_BIDS_COLUMNS = {
    "trial_index": ("Trial number (0-based, in planned order)", None),
    "block": ("Block number (0-based)", None),
    "attempt": ("0, or how many earlier attempts of this trial were cut short by an interruption", None),
    "repeated": ("True when an earlier, interrupted attempt had reached the display", None),
    "track": ("Interleaved staircase track (0-based)", None),
    "parameter": ("Stimulus parameter varied by the procedure", None),
    "level": ("Commanded level of the varied parameter (SI)", "see parameter"),
    "amplitude_m": ("Virtual surface amplitude of the last interval", "m"),
    "pitch_m": ("Virtual surface period of the last interval", "m"),
    "speed_m_per_s": ("Scanning speed of the last interval (sign = direction)", "m/s"),
    "duration_s": ("Stimulus duration of the last interval", "s"),
    "target": ("Correct response label", None),
    "response": ("Response label", None),
    "correct": ("Whether the response was correct", None),
    "response_time": ("Response time from stimulus onset (monotonic clock)", "s"),
    "utc_presented": ("UTC time when the stimulus was recorded as presented", "ISO 8601"),
    "frames_late": ("Display frames sent late", None),
    "frames_missing": ("Display frames never acknowledged", None),
    "frames_skipped": ("Display frames skipped (due more than half a period ago; never sent late)", None),
    "safety_interventions": ("Safety-layer interventions during the trial", None),
}


def read_trials_csv(path: str | Path) -> list[TrialRecord]:
    """Read back the trials of a ``--format csv`` export (labels kept as text)."""
    frame = pd.read_csv(path, dtype={c: str for c in TEXT_COLUMNS}, keep_default_na=False,
                        na_values={"target": [""], "correct": [""]})
    return trials_from_dataframe(frame)


def session_record(path: str | Path) -> Session:
    """The whole session as a validated :class:`Session` (protocol, provenance, trials)."""
    from .resume import session_status

    log = SessionLog(path)
    try:
        meta, trials = log.meta(), log.trials()
    finally:
        log.close()
    status = session_status(path)["status"]
    return Session(session_id=meta["session_id"], subject=meta["subject"], session=meta["session"],
                   protocol=meta["protocol"], seed=meta["seed"], package_version=meta["package_version"],
                   display_id=meta["display_id"], display_description=meta.get("display_description"),
                   display_sha256=meta.get("display_sha256"), responses=meta["responses"], created_utc=meta["created_utc"],
                   status=status, trials=trials)


def session_dataframe(path: str | Path) -> pd.DataFrame:
    """All completed trials of a session as a DataFrame (see ``trials_to_dataframe``)."""
    log = SessionLog(path)
    try:
        return trials_to_dataframe(log.trials())
    finally:
        log.close()


def export_session(path: str | Path, out: str | Path, format: str = "bids") -> list[Path]:
    """Write a session's trials to ``out`` in ``format``; return the files written.

    Parameters
    ----------
    path : path
        The session's .sqlite file.
    out : path
        Output folder (created if needed).
    format : {"bids", "csv", "parquet", "json"}
        BIDS-style TSV + JSON sidecar, a CSV of every field, Parquet (needs pyarrow), or the
        whole :class:`Session` as JSON.

    Raises
    ------
    ValueError
        If ``format`` is unknown, or Parquet is asked for without pyarrow installed.
    """
    if format not in FORMATS:
        raise ValueError(f"format: must be one of {FORMATS}, got {format!r}")
    if format == "parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise ValueError(
                "format: 'parquet' needs the optional dependency pyarrow, which is not installed; "
                "install it (`pip install pyarrow`) or use format 'csv'"
            ) from None
    log = SessionLog(path)
    try:
        meta, trials = log.meta(), log.trials()
    finally:
        log.close()
    frame = trials_to_dataframe(trials)
    out = Path(out)
    stem = f"sub-{meta['subject']}_ses-{meta['session']}_task-{meta['protocol']['name']}"
    if format == "json":
        out.mkdir(parents=True, exist_ok=True)
        (out / f"{stem}_session.json").write_text(session_record(path).model_dump_json(indent=1))
        return [out / f"{stem}_session.json"]
    if format == "csv":
        out.mkdir(parents=True, exist_ok=True)
        frame.to_csv(out / f"{stem}_trials.csv", index=False)
        return [out / f"{stem}_trials.csv"]
    if format == "parquet":
        out.mkdir(parents=True, exist_ok=True)
        frame.to_parquet(out / f"{stem}_trials.parquet", index=False)
        return [out / f"{stem}_trials.parquet"]
    folder = out / f"sub-{meta['subject']}" / f"ses-{meta['session']}" / "beh"
    folder.mkdir(parents=True, exist_ok=True)
    bids = frame.rename(columns={"rt_s": "response_time"})
    bids["utc_presented"] = bids["utc_presented"].map(lambda t: t.isoformat())
    bids = bids[list(_BIDS_COLUMNS)].astype(object).where(bids[list(_BIDS_COLUMNS)].notna(), "n/a")
    tsv, sidecar = folder / f"{stem}_beh.tsv", folder / f"{stem}_beh.json"
    bids.to_csv(tsv, sep="\t", index=False, na_rep="n/a")
    description = {
        "TaskName": meta["protocol"]["name"],
        "TaskDescription": meta["protocol"].get("description", ""),
        "SoftwareName": "tactilab",
        "SoftwareVersion": meta["package_version"],
        "DisplayID": meta["display_id"],
        "DisplayDescription": meta.get("display_description"),
        "DisplayDescriptionSHA256": meta.get("display_sha256"),
        "ResponseSource": meta["responses"],
        "Seed": meta["seed"],
        "Protocol": meta["protocol"],
    }
    for column, (text, unit) in _BIDS_COLUMNS.items():
        description[column] = {"Description": text, **({"Units": unit} if unit else {})}
    sidecar.write_text(json.dumps(description, indent=2))
    return [tsv, sidecar]

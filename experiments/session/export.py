"""Export a session: a BIDS beh dataset, CSV, Parquet, JSON, PsychoPy's CSV or a DataFrame.

``--format bids`` writes a BIDS-valid dataset rooted at ``out`` (see :mod:`.bids`):
``dataset_description.json``, ``participants.tsv``/``.json``, a README and
``sub-<subject>/ses-<session>/beh/sub-<subject>_ses-<session>_task-<task>_beh.tsv`` with ``n/a``
for missing values and a sidecar describing every column (units, levels) and the provenance
(seed, package version, display id, the full display description and its SHA-256, the protocol).

One name per quantity: the TSV, the CSV, Parquet, :func:`session_dataframe` and the session's
SQLite trial records use the same column names, a dimensional one with its SI unit in the name
(``rt_s``, ``interval1_amplitude_m``).
"""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd

from tactilab.core.outputs import output_path, write_atomic
from tactilab.data_schemas.experiment_records import (
    TEXT_COLUMNS, Session, TrialRecord, trials_from_dataframe, trials_to_dataframe)

from .recording import SessionLog

FORMATS = ("bids", "csv", "parquet", "json", "psychopy")

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
    """All completed trials of a session as a DataFrame (see ``trials_to_dataframe``): every trial
    field under its record's name (``rt_s`` in s, ...), ``stimuli`` as JSON, and flat columns per
    interval (``interval1_amplitude_m``, ``interval2_pitch_m``, ...; SI)."""
    log = SessionLog(path)
    try:
        return trials_to_dataframe(log.trials())
    finally:
        log.close()


def export_session(path: str | Path, out: str | Path, format: str = "bids", *, overwrite: bool = True,
                   authors: list[str] | None = None) -> list[Path]:
    """Write a session's trials to ``out`` in ``format``; return the files written.

    Parameters
    ----------
    path : path
        The session's .sqlite file.
    out : path
        Output folder (created if needed).
    format : {"bids", "csv", "parquet", "json", "psychopy"}
        A BIDS beh dataset rooted at ``out`` (the session is added to it; the TSV and its
        sidecar are listed first), a CSV of every field, Parquet (needs pyarrow), the whole
        :class:`Session` as JSON, or a CSV in PsychoPy's trial-per-row shape
        (:mod:`.psychopy_export`, ``..._psychopy.csv``).
    overwrite : bool
        Replace the session's files when they exist (the CLI passes ``--force``).
    authors : list of str, optional
        BIDS only: the dataset's ``Authors`` (written when its ``dataset_description.json`` is
        created).

    Raises
    ------
    ValueError
        If ``format`` is unknown, Parquet is asked for without pyarrow installed, a file to
        write exists and ``overwrite`` is False, a file to write is a symlink (dangling or not),
        or a path would resolve outside ``out``. Files are written whole (a temporary file and
        ``os.replace``); the session's subject and session labels are re-validated on reading.
    """
    if format not in FORMATS:
        raise ValueError(f"format: must be one of {FORMATS}, got {format!r}")
    if authors is not None and format != "bids":
        raise ValueError(f"authors: only a BIDS dataset has authors, got format {format!r}; drop authors or "
                         "use format 'bids'")
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
    out = Path(out)
    if format == "bids":
        from .bids import write_dataset

        return write_dataset(meta, trials, out, overwrite=overwrite, authors=authors)
    stem = f"sub-{meta['subject']}_ses-{meta['session']}_task-{meta['protocol']['name']}"
    suffix = {"json": "session.json", "csv": "trials.csv", "parquet": "trials.parquet",
              "psychopy": "psychopy.csv"}[format]
    target = output_path(out, f"{stem}_{suffix}")  # inside `out`, and no symlink
    if os.path.lexists(target) and not overwrite:
        raise ValueError(f"out: {target} already exists; export to another folder, or add --force to replace it")
    out.mkdir(parents=True, exist_ok=True)
    if format == "json":
        text = session_record(path).model_dump_json(indent=1)
        write_atomic(target, lambda p: p.write_text(text), option="out")
    elif format == "csv":
        write_atomic(target, lambda p: trials_to_dataframe(trials).to_csv(p, index=False), option="out")
    elif format == "psychopy":
        from .psychopy_export import psychopy_frame

        write_atomic(target, lambda p: psychopy_frame(meta, trials).to_csv(p, index=False), option="out")
    else:
        write_atomic(target, lambda p: trials_to_dataframe(trials).to_parquet(p, index=False), option="out")
    return [target]

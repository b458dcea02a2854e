"""Trial records and sessions of a psychophysics run (pydantic v2, SI units).

A :class:`TrialRecord` is one completed trial as the runner commits it: who (a pseudonymous
subject code), which session, block and trial, what was commanded, the procedure's state after
the trial, the response with its correctness and response time, UTC and monotonic timestamps,
and the provenance (seed, package version, display id). :class:`Session` bundles the protocol
and the trials. Both round-trip through JSON; trial lists round-trip through a pandas
DataFrame with :func:`trials_to_dataframe` and :func:`trials_from_dataframe`.
"""

from __future__ import annotations

import json
import math
from datetime import datetime
from typing import Any, Literal

import pandas as pd
from pydantic import BaseModel, ConfigDict, Field, model_validator

from .experiment import Protocol, Stimulus, check_label

_JSON_COLUMNS = ("stimuli", "procedure_state")
#: Columns to read as text from CSV (labels such as session "01" must keep their zeros).
TEXT_COLUMNS = ("subject", "session", "parameter", "target", "response", "package_version", "display_id",
                "stimuli", "procedure_state")


class TrialRecord(BaseModel):
    """One completed trial. Times: UTC datetimes and ``time.monotonic_ns`` integers (ns)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    subject: str = Field(description="pseudonymous subject code (BIDS label), never a name")
    session: str = Field(description="session label, e.g. '01'")
    block: int = Field(ge=0)
    trial_index: int = Field(ge=0, description="0-based planned-trial index")
    attempt: int = Field(0, ge=0, description="0, or how many earlier attempts were cut short")
    repeated: bool = Field(False, description="an earlier attempt reached the display (may have been felt)")
    track: int = Field(0, ge=0, description="interleaved staircase track")
    parameter: str
    level: float = Field(description="commanded level of `parameter`, SI")
    stimuli: list[Stimulus] = Field(description="commanded stimulus of each interval (SI)")
    target: str | None = Field(description="correct response label, None when none is correct")
    procedure_state: dict[str, Any]
    response: str
    correct: bool | None
    rt_s: float = Field(description="response time from stimulus onset, s")
    utc_planned: datetime
    utc_presented: datetime
    utc_response: datetime
    monotonic_onset_ns: int
    monotonic_response_ns: int
    seed: int
    package_version: str
    display_id: str
    frames_sent: int = Field(0, ge=0)
    frames_late: int = Field(0, ge=0)
    frames_missing: int = Field(0, ge=0)
    frames_skipped: int = Field(0, ge=0, description="frames not sent: due more than half a period ago")
    safety_interventions: int = Field(0, ge=0)

    @model_validator(mode="after")
    def _check(self) -> TrialRecord:
        check_label(self.subject, "subject")
        check_label(self.session, "session")
        if not math.isfinite(self.level):
            raise ValueError(f"level: must be finite, got {self.level!r}")
        if not math.isfinite(self.rt_s) or self.rt_s < 0:
            raise ValueError(f"rt_s: must be finite and >= 0 s, got {self.rt_s!r}")
        if self.repeated and self.attempt == 0:
            raise ValueError(
                f"repeated: a repeated trial has attempt > 0, got repeated=True, attempt={self.attempt!r}; "
                "set the attempt number"
            )
        if not self.stimuli:
            raise ValueError("stimuli: a trial commands at least one stimulus, got none")
        return self


class Session(BaseModel):
    """A whole session: the protocol, its provenance and the completed trials."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    session_id: str
    subject: str
    session: str
    protocol: Protocol
    seed: int
    package_version: str
    display_id: str
    display_description: dict[str, Any] | None = Field(
        None, description="the full display description (geometry and limits) the session ran on")
    display_sha256: str | None = Field(None, description="SHA-256 of the description's canonical JSON")
    responses: str = Field(description="response source: 'terminal', 'simulated', ...")
    created_utc: datetime
    status: Literal["running", "interrupted", "complete", "failed"]
    trials: list[TrialRecord] = []

    @model_validator(mode="after")
    def _check(self) -> Session:
        check_label(self.subject, "subject")
        check_label(self.session, "session")
        indices = [t.trial_index for t in self.trials]
        if len(set(indices)) != len(indices):
            raise ValueError(f"trials: trial_index values must be unique, got {indices!r}")
        return self


#: Stimulus fields spread into flat ``interval<k>_<field>`` columns (k = 1, 2, ...; SI, unit in the name)
INTERVAL_FIELDS = ("surface", "amplitude_m", "pitch_m", "speed_m_per_s", "duration_s", "ramp_s", "phase_rad",
                   "frame_rate_hz")


def trials_to_dataframe(trials: list[TrialRecord]) -> pd.DataFrame:
    """One row per trial: every :class:`TrialRecord` field under its own name (``rt_s`` in s, ...).

    The nested fields stay as JSON strings (``stimuli``, which analysis code reads, and
    ``procedure_state``); each interval's commanded stimulus is also spread into flat columns
    ``interval1_amplitude_m``, ``interval1_pitch_m``, ..., ``interval2_amplitude_m``, ... (SI,
    the unit in the name; empty for a trial with fewer intervals), one per field of
    :data:`INTERVAL_FIELDS`.
    """
    columns = list(TrialRecord.model_fields)
    n_intervals = max((len(t.stimuli) for t in trials), default=0)
    flat = [f"interval{k + 1}_{f}" for k in range(n_intervals) for f in INTERVAL_FIELDS]
    rows = []
    for trial in trials:
        row = trial.model_dump(mode="json")
        for key in _JSON_COLUMNS:
            row[key] = json.dumps(row[key], sort_keys=True)
        for k, stimulus in enumerate(trial.stimuli):
            row.update({f"interval{k + 1}_{f}": getattr(stimulus, f) for f in INTERVAL_FIELDS})
        rows.append(row)
    frame = pd.DataFrame(rows, columns=columns + flat)
    for key in ("utc_planned", "utc_presented", "utc_response"):
        frame[key] = pd.to_datetime(frame[key], utc=True)
    return frame


def trials_from_dataframe(frame: pd.DataFrame) -> list[TrialRecord]:
    """Inverse of :func:`trials_to_dataframe` (extra analysis columns are ignored)."""
    missing = [c for c in TrialRecord.model_fields if c not in frame.columns]
    if missing:
        raise ValueError(f"frame: missing trial columns {missing}; pass a frame from trials_to_dataframe")
    trials = []
    for row in frame[list(TrialRecord.model_fields)].to_dict(orient="records"):
        for key in _JSON_COLUMNS:
            row[key] = json.loads(row[key])
        for key, value in list(row.items()):
            if isinstance(value, pd.Timestamp):
                row[key] = value.to_pydatetime()
            elif isinstance(value, float) and math.isnan(value) and key in ("target", "correct"):
                row[key] = None
            elif key == "correct" and isinstance(value, str):  # from CSV text
                row[key] = {"True": True, "False": False}.get(value, value)
        trials.append(TrialRecord.model_validate(row))
    return trials

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


def trials_to_dataframe(trials: list[TrialRecord]) -> pd.DataFrame:
    """One row per trial; nested fields (stimuli, procedure_state) as JSON strings.

    The commanded stimulus of the LAST interval is also spread into plain columns
    (``amplitude_m``, ``pitch_m``, ``speed_m_per_s``, ``duration_s``) for analysis.
    """
    columns = list(TrialRecord.model_fields)
    rows = []
    for trial in trials:
        row = trial.model_dump(mode="json")
        for key in _JSON_COLUMNS:
            row[key] = json.dumps(row[key], sort_keys=True)
        last = trial.stimuli[-1]
        row.update({k: getattr(last, k) for k in ("amplitude_m", "pitch_m", "speed_m_per_s", "duration_s")})
        rows.append(row)
    frame = pd.DataFrame(rows, columns=columns + ["amplitude_m", "pitch_m", "speed_m_per_s", "duration_s"])
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

"""A session's trials in PsychoPy's trial-per-row CSV shape (``export --format psychopy``).

PsychoPy's experiment handler writes one row per trial: the loop's counters
(``trials.thisRepN``, ``trials.thisTrialN``, ``trials.thisN``, ``trials.thisIndex``), the
condition's parameters, the key response (``key_resp.keys``, ``key_resp.corr``,
``key_resp.rt``) and the session's information (``participant``, ``session``, ``date``,
``expName``). A lab's PsychoPy analysis scripts read this file as they read their own:

- ``trials.thisN``: the trial's index (0-based); ``trials.thisRepN``: its block (the repetition
  of the condition set, 0-based); ``trials.thisTrialN``: its position within the block;
- ``trials.thisIndex``: the row of its condition in the protocol's condition list (the
  ``levels`` or the conditions table of constant stimuli); empty for adaptive procedures, as
  PsychoPy's staircases leave it;
- the varied parameter under its own name with its SI unit (``amplitude_m``), the other fields
  of a conditions table likewise (``pitch_m``), and every interval's commanded stimulus
  (``interval1_amplitude_m``, ...; SI);
- ``corrAns`` and ``key_resp.keys``: the correct and the pressed key (the protocol's key map);
  ``key_resp.corr``: 1 or 0 (empty when no answer is correct); ``key_resp.rt``: s from onset;
- ``date``: the session's creation, UTC, as PsychoPy writes it (``2026-11-27_06h49.10.000``).
"""

from __future__ import annotations

from datetime import datetime

import pandas as pd

from tactilab.data_schemas.experiment import Protocol
from tactilab.data_schemas.experiment_records import INTERVAL_FIELDS, TrialRecord

#: the loop's name in the column headers (PsychoPy Builder's default loop name)
LOOP = "trials"
#: the key-response component's name (PsychoPy Builder's default)
RESPONSE = "key_resp"


def _date(created_utc: str) -> str:
    stamp = datetime.fromisoformat(created_utc)
    return stamp.strftime("%Y-%m-%d_%Hh%M.%S.") + f"{stamp.microsecond // 1000:03d}"


def _shown(trial: TrialRecord, parameter: str):
    """The interval that showed the trial's level (the test stimulus; a 2IFC blank is amplitude 0)."""
    return next((s for s in trial.stimuli if getattr(s, parameter) == trial.level), trial.stimuli[0])


def _condition(conditions: list[dict], trial: TrialRecord) -> int | None:
    """The row of the condition the trial showed (its fields match an interval's), else None."""
    for i, fields in enumerate(conditions):
        if any(all(getattr(s, k) == v for k, v in fields.items()) for s in trial.stimuli):
            return i
    return None


def psychopy_frame(meta: dict, trials: list[TrialRecord]) -> pd.DataFrame:
    """One row per completed trial, in PsychoPy's wide-text layout (module docstring).

    Parameters
    ----------
    meta : dict
        The session's metadata (``SessionLog.meta()``): protocol, subject, session, creation time.
    trials : list of TrialRecord
        The completed trials, in order.

    Returns
    -------
    pandas.DataFrame
        Columns as listed in the module docstring; numbers in SI.
    """
    protocol = Protocol.model_validate(meta["protocol"])
    label_key = {label: key for key, label in protocol.task.key_map.items()}
    conditions = ([fields for _, fields in protocol.procedure.planned_fields()]
                  if protocol.procedure.method == "constant_stimuli" else [])
    parameter = protocol.procedure.parameter
    factors = [f for f in (conditions[0] if conditions else {}) if f != parameter]  # a conditions table's others
    n_intervals = max((len(t.stimuli) for t in trials), default=0)
    flat = [f"interval{k + 1}_{f}" for k in range(n_intervals) for f in INTERVAL_FIELDS]
    rows, first_of_block = [], {}
    for trial in trials:
        first_of_block.setdefault(trial.block, trial.trial_index)
        row = {f"{LOOP}.thisRepN": trial.block, f"{LOOP}.thisTrialN": trial.trial_index - first_of_block[trial.block],
               f"{LOOP}.thisN": trial.trial_index,
               f"{LOOP}.thisIndex": _condition(conditions, trial), parameter: trial.level}
        shown = _shown(trial, parameter)
        row.update({f: getattr(shown, f) for f in factors})
        for k, stimulus in enumerate(trial.stimuli):
            row.update({f"interval{k + 1}_{f}": getattr(stimulus, f) for f in INTERVAL_FIELDS})
        row.update({"corrAns": label_key.get(trial.target, trial.target) if trial.target is not None else None,
                    f"{RESPONSE}.keys": label_key.get(trial.response, trial.response),
                    f"{RESPONSE}.corr": None if trial.correct is None else int(trial.correct),
                    f"{RESPONSE}.rt": trial.rt_s, "participant": meta["subject"], "session": meta["session"],
                    "date": _date(meta["created_utc"]), "expName": protocol.name})
        rows.append(row)
    columns = [f"{LOOP}.thisRepN", f"{LOOP}.thisTrialN", f"{LOOP}.thisN", f"{LOOP}.thisIndex", parameter, *factors,
               *flat,
               "corrAns", f"{RESPONSE}.keys", f"{RESPONSE}.corr", f"{RESPONSE}.rt", "participant", "session", "date",
               "expName"]
    frame = pd.DataFrame(rows, columns=columns)
    for key in (f"{LOOP}.thisIndex", f"{RESPONSE}.corr"):
        frame[key] = frame[key].astype("Int64")  # integers with gaps, written as 3 and an empty cell
    return frame

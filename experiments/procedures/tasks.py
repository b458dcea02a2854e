"""Tasks: turn a chosen level into the stimuli of one trial, and score the response.

``2ifc``: the test level in one of two intervals (drawn at random), the reference (or a blank,
amplitude 0) in the other; the answer is the interval. ``2afc``: one stimulus showing one of two
labelled alternatives drawn at random. ``yes_no``: the test, or a blank on ``catch_rate`` of
trials. ``same_different``: the reference, then the reference again ("same", ``same_rate`` of
trials) or the test. ``magnitude_estimation``: the test; no answer is correct.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from tactilab.data_schemas.experiment import Protocol, Stimulus

from .base import PlannedLevel


@dataclass(frozen=True)
class PlannedStimulus(PlannedLevel):
    """A planned level that also fixes other stimulus fields (a multi-field candidate).

    ``fields``: ``(name, value)`` pairs, SI (``surface``: ``"sinusoid"`` or ``"square"``), that
    replace the protocol's ``[stimulus]`` values before the level is set.
    """

    fields: tuple[tuple[str, Any], ...] = ()


def base_stimulus(protocol: Protocol, planned: PlannedLevel) -> Stimulus:
    """The protocol's ``[stimulus]`` with the planned trial's ``fields`` (if any) put in, validated."""
    fields = dict(getattr(planned, "fields", ()))
    if not fields:
        return protocol.stimulus
    return Stimulus.model_validate({**protocol.stimulus.model_dump(), **fields})


@dataclass(frozen=True)
class TrialPlan:
    """Everything commanded on one trial (SI)."""

    trial_index: int
    block: int
    track: int
    parameter: str
    level: float
    stimuli: tuple[Stimulus, ...]
    target: str | None  # the correct response label; None when no answer is correct
    gap_s: float  # pause between intervals, s


def blank(stimulus: Stimulus) -> Stimulus:
    """The same stimulus with zero amplitude (the tractors stay still for the same time)."""
    return stimulus.model_copy(update={"amplitude_m": 0.0})


def plan_trial(protocol: Protocol, trial_index: int, planned: PlannedLevel,
               rng: np.random.Generator) -> TrialPlan:
    """Build the trial's stimuli from the procedure's level and the trial's task generator."""
    task, parameter = protocol.task, protocol.procedure.parameter
    base = base_stimulus(protocol, planned)
    test = base.with_level(parameter, planned.level)
    kind = task.kind
    if kind == "2ifc":
        other = protocol.reference if protocol.reference is not None else blank(test)
        first = int(rng.integers(2))
        stimuli, target = ((test, other), "1") if first == 0 else ((other, test), "2")
    elif kind == "2afc":
        label = task.labels[int(rng.integers(2))]
        override = task.alternatives[label]
        shown = Stimulus.model_validate({**base.model_dump(), **override}).with_level(
            parameter, planned.level)
        stimuli, target = (shown,), label
    elif kind == "yes_no":
        signal = bool(rng.random() >= task.catch_rate)
        stimuli, target = ((test,), "yes") if signal else ((blank(test),), "no")
    elif kind == "same_different":
        same = bool(rng.random() < task.same_rate)
        stimuli = (protocol.reference, protocol.reference if same else test)
        target = "same" if same else "different"
    else:
        stimuli, target = (test,), None
    return TrialPlan(trial_index, planned.block, planned.track, parameter, planned.level,
                     stimuli, target, task.interval_gap_s)


def score(protocol: Protocol, plan: TrialPlan, response: str) -> tuple[bool | None, bool | None]:
    """Return ``(correct, outcome)`` for the procedure.

    ``outcome`` is what adaptive procedures count as positive: correct in forced choice, "yes"
    in yes/no (None on catch trials, which say nothing about the level), "different" in
    same/different (None on 'same' trials), and None for magnitude ratings.
    """
    labels = protocol.task.labels
    if response not in labels:
        raise ValueError(f"response: must be one of {labels}, got {response!r}")
    if plan.target is None:
        return None, None
    return response == plan.target, outcome_of(protocol.task.kind, plan.target, response)


def outcome_of(kind: str, target: str | None, response: str) -> bool | None:
    """The procedure's outcome from the task kind, the correct label and the response."""
    if target is None:
        return None
    if kind in ("2ifc", "2afc"):
        return response == target
    if kind == "yes_no":
        return (response == "yes") if target == "yes" else None
    return (response == "different") if target == "different" else None

"""The procedure template: :class:`Procedure`, :class:`PlannedLevel` and :func:`replay`.

The built-in procedures derive from :class:`Procedure`: constant stimuli and transformed
staircases (:mod:`.staircase`), psi / QUEST+ (:mod:`.psi`); build one with
:func:`tactilab.experiments.procedures.make_procedure`.

Every procedure keeps its STATE (what it needs to choose the next level, ``_STATE_KEYS``) apart
from its HISTORY (what happened, ``_HISTORY_KEYS``), as CUQIpy's samplers do. The state is a
pure function of the protocol, the seed and the history, so :func:`replay` rebuilds it exactly
after a crash. Randomness comes only from the per-trial generator passed to
:meth:`Procedure.next_trial` (derived from ``(seed, trial_index)`` by the runner).

Outcomes are booleans: "positive" means correct in forced choice, "yes" in yes/no and
"different" in same/different; magnitude estimation records no outcome (``None``).
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

Likelihood = Callable[..., np.ndarray]


@dataclass(frozen=True)
class PlannedLevel:
    """The level chosen for one trial, SI, with its staircase track and block."""

    level: float
    track: int = 0
    block: int = 0


class Procedure(abc.ABC):
    """Template: :meth:`next_trial` and :meth:`update` guard; subclasses supply ``_next``/``_update``."""

    _STATE_KEYS: tuple[str, ...] = ()
    _HISTORY_KEYS: tuple[str, ...] = ("trial_index", "track", "block", "level", "outcome")

    def __init__(self, config: Any) -> None:
        self.config = config
        self.history: list[dict[str, Any]] = []
        self._pending: tuple[int, PlannedLevel] | None = None

    @property
    def n_done(self) -> int:
        """Number of completed trials."""
        return len(self.history)

    @property
    @abc.abstractmethod
    def n_planned(self) -> int:
        """Trials the procedure will run at most (for progress bars)."""

    @property
    @abc.abstractmethod
    def finished(self) -> bool:
        """True when no more trials are needed."""

    def next_trial(self, trial_index: int, rng: np.random.Generator) -> PlannedLevel | None:
        """Choose the next level, or return None when finished.

        Parameters
        ----------
        trial_index : int
            Must equal the number of completed trials (trials run in order).
        rng : numpy.random.Generator
            The trial's own generator (from ``(seed, trial_index)``).
        """
        if trial_index != self.n_done:
            raise ValueError(
                f"trial_index: trials run in order; expected {self.n_done}, got {trial_index}"
            )
        if self.finished:
            return None
        planned = self._next(rng)
        self._pending = (trial_index, planned)
        return planned

    def update(self, planned: PlannedLevel, outcome: bool | None) -> None:
        """Record the outcome of the trial planned last and advance the state.

        ``outcome`` None means the trial says nothing about the level (a yes/no catch trial, a
        magnitude rating): it is kept in the history, and adaptive state does not move.
        """
        if self._pending is None or self._pending[1] != planned:
            raise ValueError(
                f"planned: update() must follow next_trial() for the same trial, got {planned!r}; "
                "call next_trial first"
            )
        if outcome is not None and not isinstance(outcome, (bool, np.bool_)):
            raise ValueError(f"outcome: must be True, False or None, got {outcome!r}")
        trial_index, _ = self._pending
        self._pending = None
        outcome = None if outcome is None else bool(outcome)
        self.history.append({"trial_index": trial_index, "track": planned.track, "block": planned.block,
                             "level": planned.level, "outcome": outcome})
        self._update(planned, outcome)

    @abc.abstractmethod
    def _next(self, rng: np.random.Generator) -> PlannedLevel: ...

    @abc.abstractmethod
    def _update(self, planned: PlannedLevel, outcome: bool | None) -> None: ...

    @abc.abstractmethod
    def estimate(self) -> dict[str, float | None]:
        """Current estimate (threshold etc.), SI."""

    def state(self) -> dict[str, Any]:
        """The exact state (``_STATE_KEYS``), JSON-ready; replay reproduces it bit for bit."""
        return {key: _jsonable(getattr(self, "_" + key)) for key in self._STATE_KEYS}

    def record_state(self) -> dict[str, Any]:
        """The state stored with each trial row (compact; the exact state for small procedures)."""
        return {**self.state(), "estimate": self.estimate()}


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, list):
        return [_jsonable(v) for v in value]
    return value


def replay(procedure: Procedure, history: list[dict[str, Any]], rng_for: Callable[[int], np.random.Generator]) -> Procedure:
    """Rebuild ``procedure``'s state from a recorded history, checking every recorded level.

    Parameters
    ----------
    procedure : Procedure
        A fresh procedure from the same protocol.
    history : list of dict
        Recorded trials in order, each with ``_HISTORY_KEYS``.
    rng_for : callable
        ``trial_index -> procedure generator`` (the runner's derivation from the seed).

    Raises
    ------
    ValueError
        If a recorded level or track differs from what the procedure chooses: the log does not
        belong to this protocol and seed.
    """
    if procedure.n_done:
        raise ValueError(f"procedure: replay needs a fresh procedure, this one has {procedure.n_done} trials")
    for entry in history:
        planned = procedure.next_trial(entry["trial_index"], rng_for(entry["trial_index"]))
        if planned is None or planned.level != entry["level"] or planned.track != entry["track"]:
            raise ValueError(
                f"history: trial {entry['trial_index']} recorded level {entry['level']!r} (track "
                f"{entry['track']}), but the protocol and seed give {planned!r}; the log does not "
                "match this protocol"
            )
        procedure.update(planned, entry["outcome"])
    return procedure

"""Constant stimuli and transformed staircases, registered as ``constant_stimuli`` and ``staircase``.

Both register themselves (:func:`tactilab.experiments.procedures.register_procedure`) when this
module is imported; the registry imports it the first time a protocol names either method.
"""

from __future__ import annotations

import numpy as np

from tactilab.data_schemas.experiment import ConstantStimuliConfig, StaircaseConfig

from .base import PlannedLevel, Procedure
from .registry import register_procedure
from .tasks import PlannedStimulus


class ConstantStimuli(Procedure):
    """Every level ``repeats_per_block`` times per block, order shuffled per block."""

    _STATE_KEYS = ("block", "order", "position")

    def __init__(self, config: ConstantStimuliConfig, guess_rate: float = 0.0) -> None:
        super().__init__(config)
        self.guess_rate = guess_rate
        self._block, self._order, self._position = 0, [], 0

    @property
    def n_planned(self) -> int:
        return len(self.config.levels) * self.config.repeats_per_block * self.config.n_blocks

    @property
    def finished(self) -> bool:
        return self.n_done >= self.n_planned

    def _next(self, rng):
        if self._position >= len(self._order):
            # the first trial of each block draws that block's order from its own generator
            self._block = self.n_done // (len(self.config.levels) * self.config.repeats_per_block)
            order = np.repeat(np.arange(len(self.config.levels)), self.config.repeats_per_block)
            self._order, self._position = rng.permutation(order).tolist(), 0
        index = self._order[self._position]
        if self.config.conditions is None:
            return PlannedLevel(float(self.config.levels[index]), 0, self._block)
        fields = tuple((k, v) for k, v in self.config.conditions[index].items() if k != self.config.parameter)
        return PlannedStimulus(float(self.config.levels[index]), 0, self._block, fields)

    def _update(self, planned, outcome):
        self._position += 1

    def proportions(self) -> dict[float, tuple[int, int]]:
        """level -> (n positive, n with an outcome)."""
        counts: dict[float, list[int]] = {lv: [0, 0] for lv in self.config.levels}
        for h in self.history:
            if h["outcome"] is not None:
                counts[h["level"]][0] += h["outcome"]
                counts[h["level"]][1] += 1
        return {lv: (c[0], c[1]) for lv, c in counts.items()}

    def estimate(self):
        """Level where the proportion positive crosses halfway from guess to 1 (interpolated).

        None over a conditions table whose rows differ in more than the varied parameter: one
        crossing over several conditions means nothing (the per-condition fits report them)."""
        rows = self.config.conditions
        if rows is not None and len({tuple(sorted((k, v) for k, v in r.items() if k != self.config.parameter))
                                     for r in rows}) > 1:
            return {"threshold": None}
        pts = [(lv, k / n) for lv, (k, n) in sorted(self.proportions().items()) if n]
        target = (1 + self.guess_rate) / 2
        for (x0, p0), (x1, p1) in zip(pts, pts[1:]):
            if (p0 - target) * (p1 - target) <= 0 and p0 != p1:
                return {"threshold": x0 + (target - p0) * (x1 - x0) / (p1 - p0)}
        return {"threshold": None}


class Staircase(Procedure):
    """Interleaved transformed up/down staircases (Levitt 1971); a random unfinished track per trial."""

    _STATE_KEYS = ("levels", "run_positive", "run_negative", "directions", "reversals", "n_trials")

    def __init__(self, config: StaircaseConfig) -> None:
        super().__init__(config)
        tracks = config.tracks
        self._levels = [t.start for t in tracks]
        self._run_positive = [0] * len(tracks)
        self._run_negative = [0] * len(tracks)
        self._directions = [0] * len(tracks)  # -1 last step down, +1 up, 0 none yet
        self._reversals: list[list[float]] = [[] for _ in tracks]
        self._n_trials = [0] * len(tracks)

    @property
    def n_planned(self) -> int:
        return sum(t.max_trials for t in self.config.tracks)

    def _track_done(self, i: int) -> bool:
        t = self.config.tracks[i]
        return self._n_trials[i] >= t.max_trials or (
            t.max_reversals is not None and len(self._reversals[i]) >= t.max_reversals)

    @property
    def finished(self) -> bool:
        return all(self._track_done(i) for i in range(len(self.config.tracks)))

    def _next(self, rng):
        open_tracks = [i for i in range(len(self.config.tracks)) if not self._track_done(i)]
        track = open_tracks[int(rng.integers(len(open_tracks)))] if len(open_tracks) > 1 else open_tracks[0]
        return PlannedLevel(float(self._levels[track]), track, 0)

    def _update(self, planned, outcome):
        if outcome is None:
            return
        i, t = planned.track, self.config.tracks[planned.track]
        self._n_trials[i] += 1
        if outcome:
            self._run_positive[i], self._run_negative[i] = self._run_positive[i] + 1, 0
            direction = -1 if self._run_positive[i] >= t.down else 0
        else:
            self._run_negative[i], self._run_positive[i] = self._run_negative[i] + 1, 0
            direction = +1 if self._run_negative[i] >= t.up else 0
        if direction == 0:
            return
        self._run_positive[i] = self._run_negative[i] = 0
        if self._directions[i] != 0 and direction != self._directions[i]:
            self._reversals[i].append(self._levels[i])
        self._directions[i] = direction
        step = t.step_sizes[min(len(self._reversals[i]), len(t.step_sizes) - 1)]
        level = self._levels[i] * 10 ** (direction * step) if t.step_scale == "log" else \
            self._levels[i] + direction * step
        self._levels[i] = float(min(max(level, t.min_level), t.max_level))

    def track_estimate(self, i: int) -> float:
        """Mean of the last ``estimate_reversals`` reversals (geometric for log steps), else the level."""
        t = self.config.tracks[i]
        rev = self._reversals[i][-t.estimate_reversals:]
        if not rev:
            return float(self._levels[i])
        if t.step_scale == "log":
            return float(np.exp(np.mean(np.log(rev))))
        return float(np.mean(rev))

    def record_state(self):
        """The state per trial row, with only the reversals the estimate uses (rows stay small)."""
        state = self.state()
        state["n_reversals"] = [len(r) for r in self._reversals]
        state["reversals"] = [r[-t.estimate_reversals:] for r, t in zip(self._reversals, self.config.tracks)]
        return {**state, "estimate": self.estimate()}

    def estimate(self):
        per_track = [self.track_estimate(i) for i in range(len(self.config.tracks))]
        return {"threshold": float(np.mean(per_track)),
                **{f"threshold_track{i}": v for i, v in enumerate(per_track)}}


register_procedure("constant_stimuli", ConstantStimuliConfig,
                   lambda config, *, guess_rate=0.0: ConstantStimuli(config, guess_rate))
register_procedure("staircase", StaircaseConfig, lambda config, *, guess_rate=0.0: Staircase(config))

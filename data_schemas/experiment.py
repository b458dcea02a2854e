"""Psychophysics protocols, trial records and sessions (pydantic v2, SI units inside).

A :class:`Protocol` is what a TOML protocol file holds: the stimulus (a virtual surface that a
laterotactile display renders as a travelling wave), the task, the procedure that chooses the
level of one stimulus parameter on each trial, and the seed. Quantities in files may carry unit
suffixes (``"20um"``, ``"40mm/s"``, ``"500ms"``); they are converted to SI once, on loading,
with :func:`tactilab.data_schemas.units.to_si`. Bare numbers are SI.

A :class:`TrialRecord` is one completed trial as the runner records it; a :class:`Session` is a
whole session. Both round-trip through JSON, and trial records through a pandas DataFrame
(:func:`trials_to_dataframe`, :func:`trials_from_dataframe`).
"""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import numpy as np
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationInfo, model_validator

from .units import to_si

# The stimulus parameters a procedure may vary, with the dimension of their values.
PARAMETERS: dict[str, str] = {
    "amplitude_m": "length",
    "pitch_m": "length",
    "speed_m_per_s": "speed",
    "duration_s": "time",
}
TASKS = ("2afc", "2ifc", "yes_no", "same_different", "magnitude_estimation")
LIKELIHOOD_FAMILIES = ("weibull", "logistic", "normal_cdf", "gumbel")
_LABEL = re.compile(r"^[A-Za-z0-9]{1,32}$")
_IMPORT_PATH = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_]\w*$")


def _quantity(dimension: str):
    """Before-validator: a number (SI) or a string with a unit suffix, converted to SI."""

    def convert(value: Any, info: ValidationInfo) -> Any:
        if isinstance(value, (str, int, float)):  # bools too: to_si refuses them
            return to_si(value, dimension, name=info.field_name or "value")
        return value

    return BeforeValidator(convert)


def _finite(value: float, name: str) -> float:
    if not math.isfinite(value):
        raise ValueError(f"{name}: must be finite, got {value!r}; give a number")
    return value


def _positive(value: float, name: str, unit: str) -> float:
    _finite(value, name)
    if value <= 0:
        raise ValueError(f"{name}: must be > 0 {unit}, got {value!r}; give a positive value")
    return value


def check_label(value: str, name: str) -> str:
    if not _LABEL.match(value):
        raise ValueError(
            f"{name}: must be 1-32 letters or digits (a BIDS label; a pseudonymous code, never "
            f"a name), got {value!r}; use e.g. 'S01'"
        )
    return value


Length = Annotated[float, _quantity("length")]
Speed = Annotated[float, _quantity("speed")]
Time = Annotated[float, _quantity("time")]
Frequency = Annotated[float, _quantity("frequency")]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


class Stimulus(_Model):
    """A virtual surface H(x) scanned at a speed, and how the display's tractors render it.

    Each tractor at position x_n follows H(x_n + V t) (a travelling wave, physics.md 4a).
    """

    surface: Literal["sinusoid", "square"] = "sinusoid"
    amplitude_m: Length = Field(description="virtual surface height amplitude A, m (>= 0)")
    pitch_m: Length = Field(description="virtual surface period p, m (> 0)")
    speed_m_per_s: Speed = Field(description="scanning speed V, m/s (sign = direction)")
    duration_s: Time = Field(0.5, description="stimulus duration, s (> 0, <= 60)")
    ramp_s: Time = Field(0.02, description="raised-cosine onset/offset ramp, s (>= 0)")
    phase_rad: float = Field(0.0, description="phase of H at x = 0, t = 0, rad")
    frame_rate_hz: Frequency = Field(1000.0, description="drive frame rate, Hz (> 0)")

    @model_validator(mode="after")
    def _check(self) -> Stimulus:
        _finite(self.amplitude_m, "amplitude_m")
        if self.amplitude_m < 0:
            raise ValueError(f"amplitude_m: must be >= 0 m, got {self.amplitude_m!r}; give e.g. '20um'")
        _positive(self.pitch_m, "pitch_m", "m")
        _finite(self.speed_m_per_s, "speed_m_per_s")
        _finite(self.phase_rad, "phase_rad")
        _positive(self.duration_s, "duration_s", "s")
        if self.duration_s > 60:
            raise ValueError(f"duration_s: must be <= 60 s, got {self.duration_s!r}; split long stimuli")
        _finite(self.ramp_s, "ramp_s")
        if self.ramp_s < 0 or 2 * self.ramp_s > self.duration_s:
            raise ValueError(
                f"ramp_s: must lie in [0, duration_s / 2] = [0, {self.duration_s / 2!r}] s, got "
                f"{self.ramp_s!r}; shorten the ramp or lengthen the stimulus"
            )
        _positive(self.frame_rate_hz, "frame_rate_hz", "Hz")
        if self.frame_rate_hz * self.duration_s < 2:
            raise ValueError(
                f"frame_rate_hz: {self.frame_rate_hz!r} Hz gives fewer than 2 frames in "
                f"{self.duration_s!r} s; raise the frame rate (default 1 kHz)"
            )
        return self

    def with_level(self, parameter: str, level: float) -> Stimulus:
        """Return a copy with ``parameter`` set to ``level`` (SI), validated."""
        return Stimulus.model_validate({**self.model_dump(), parameter: level})


def _grid(raw: Any, dimension: str, name: str) -> list[float]:
    """Read a list of values or a ``{start, stop, n, scale}`` table, each value with units."""
    if isinstance(raw, dict):
        unknown = set(raw) - {"start", "stop", "n", "scale"}
        if unknown or not {"start", "stop", "n"} <= set(raw):
            raise ValueError(
                f"{name}: a grid table needs exactly start, stop, n and optional scale "
                f"('linear' or 'log'), got keys {sorted(raw)}; e.g. {{start='5um', stop='200um', n=20}}"
            )
        start = to_si(raw["start"], dimension, name=f"{name}.start")
        stop = to_si(raw["stop"], dimension, name=f"{name}.stop")
        n, scale = raw["n"], raw.get("scale", "linear")
        if isinstance(n, bool) or not isinstance(n, int) or not 2 <= n <= 10_000:
            raise ValueError(f"{name}.n: must be an integer in [2, 10000], got {n!r}")
        if scale not in ("linear", "log"):
            raise ValueError(f"{name}.scale: must be 'linear' or 'log', got {scale!r}")
        if scale == "log" and (start <= 0 or stop <= 0):
            raise ValueError(f"{name}: a log grid needs start and stop > 0, got {start!r}, {stop!r}")
        if stop <= start:
            raise ValueError(f"{name}: stop must exceed start, got start={start!r}, stop={stop!r}")
        values = np.geomspace(start, stop, n) if scale == "log" else np.linspace(start, stop, n)
        return [float(v) for v in values]
    if isinstance(raw, (list, tuple)):
        if not raw:
            raise ValueError(f"{name}: needs at least one value, got an empty list")
        return [to_si(v, dimension, name=f"{name}[{i}]") for i, v in enumerate(raw)]
    raise ValueError(f"{name}: expected a list of values or a {{start, stop, n}} table, got {raw!r}")


def _convert_levels(data: Any, fields: tuple[str, ...], grids: tuple[str, ...] = ()) -> Any:
    """Convert level-valued fields with the dimension of the varied ``parameter``."""
    if not isinstance(data, dict):
        return data
    parameter = data.get("parameter")
    if parameter not in PARAMETERS:
        raise ValueError(
            f"parameter: must be one of {sorted(PARAMETERS)}, got {parameter!r}; name the "
            "stimulus field the procedure varies"
        )
    dimension, out = PARAMETERS[parameter], dict(data)
    for key in fields:
        if key in out and out[key] is not None:
            out[key] = to_si(out[key], dimension, name=key)
    for key in grids:
        if key in out:
            out[key] = _grid(out[key], dimension, key)
    return out


class Task(_Model):
    """What the subject does on each trial and which keys answer it.

    ``2ifc``: two intervals, one holds the test level, the other the reference (or nothing);
    the subject names the interval with the test. ``2afc``: one stimulus, one of two labelled
    ``alternatives`` (overrides of stimulus fields, e.g. scanning direction) drawn at random;
    the subject names it. ``yes_no``: was there a stimulus (``catch_rate`` of trials are blank).
    ``same_different``: reference then comparison, equal on ``same_rate`` of trials.
    ``magnitude_estimation``: a rating from ``magnitude_min`` to ``magnitude_max`` (one digit).
    """

    kind: Literal["2afc", "2ifc", "yes_no", "same_different", "magnitude_estimation"]
    keys: dict[str, str] | None = Field(None, description="response label -> single key")
    alternatives: dict[str, dict[str, Any]] | None = None
    interval_gap_s: Time = Field(0.5, description="gap between intervals, s")
    catch_rate: float = Field(0.0, description="fraction of blank yes/no trials, [0, 1)")
    same_rate: float = Field(0.5, description="fraction of 'same' trials, (0, 1)")
    magnitude_min: int = 1
    magnitude_max: int = 9
    prompt: str | None = None

    @model_validator(mode="after")
    def _check(self) -> Task:
        _finite(self.interval_gap_s, "interval_gap_s")
        if self.interval_gap_s < 0:
            raise ValueError(f"interval_gap_s: must be >= 0 s, got {self.interval_gap_s!r}")
        if not 0 <= self.catch_rate < 1:
            raise ValueError(f"catch_rate: must lie in [0, 1), got {self.catch_rate!r}; e.g. 0.2")
        if not 0 < self.same_rate < 1:
            raise ValueError(f"same_rate: must lie in (0, 1), got {self.same_rate!r}; e.g. 0.5")
        if not 0 <= self.magnitude_min < self.magnitude_max <= 9:
            raise ValueError(
                f"magnitude_min/magnitude_max: need 0 <= min < max <= 9 (one digit key), got "
                f"{self.magnitude_min!r}, {self.magnitude_max!r}"
            )
        if self.kind == "2afc":
            if self.alternatives is None or len(self.alternatives) != 2:
                raise ValueError(
                    "alternatives: a 2afc task needs exactly two labelled alternatives, e.g. "
                    "{left = {speed_m_per_s = '-40mm/s'}, right = {speed_m_per_s = '40mm/s'}}, "
                    f"got {self.alternatives!r}"
                )
            for label, override in self.alternatives.items():
                check_label(label, "alternatives")
                bad = set(override) - set(Stimulus.model_fields)
                if bad:
                    raise ValueError(f"alternatives.{label}: unknown stimulus fields {sorted(bad)}")
        elif self.alternatives is not None:
            raise ValueError(f"alternatives: only a 2afc task takes alternatives, not {self.kind!r}; remove it")
        labels = self.labels
        if self.keys is not None:
            if set(self.keys) != set(labels):
                raise ValueError(
                    f"keys: must map exactly the responses {labels} to keys, got {sorted(self.keys)}"
                )
            keys = list(self.keys.values())
            if any(len(k) != 1 or not k.isprintable() or k in " q" for k in keys) or len(set(keys)) != len(keys):
                raise ValueError(
                    f"keys: need distinct single printable keys other than space and 'q' (quit), got {keys!r}"
                )
        return self

    @property
    def labels(self) -> list[str]:
        """The response labels, in key order."""
        if self.kind == "2ifc":
            return ["1", "2"]
        if self.kind == "2afc":
            return list(self.alternatives or {})
        if self.kind == "yes_no":
            return ["yes", "no"]
        if self.kind == "same_different":
            return ["same", "different"]
        return [str(v) for v in range(self.magnitude_min, self.magnitude_max + 1)]

    @property
    def key_map(self) -> dict[str, str]:
        """Key -> response label (defaults: 1/2, y/n, s/d, digits, f/j for 2afc)."""
        if self.keys is not None:
            return {k: label for label, k in self.keys.items()}
        defaults = {"2ifc": "12", "yes_no": "yn", "same_different": "sd", "2afc": "fj"}
        if self.kind in defaults:
            return dict(zip(defaults[self.kind], self.labels))
        return {label: label for label in self.labels}

    @property
    def guess_rate(self) -> float:
        """Chance rate of a correct answer for forced choice, else 0 (false-alarm floor)."""
        return 0.5 if self.kind in ("2afc", "2ifc") else 0.0


class ConstantStimuliConfig(_Model):
    """Method of constant stimuli: every level ``repeats_per_block`` times per block, shuffled."""

    method: Literal["constant_stimuli"]
    parameter: str
    levels: list[float]
    repeats_per_block: int = Field(5, ge=1, le=1000)
    n_blocks: int = Field(4, ge=1, le=1000)

    @model_validator(mode="before")
    @classmethod
    def _units(cls, data: Any) -> Any:
        return _convert_levels(data, (), ("levels",))


class StaircaseTrack(_Model):
    """One transformed up/down staircase: ``down`` positives in a row step down, ``up`` negatives step up.

    1-up-2-down converges on 70.7 % positive outcomes, 1-up-3-down on 79.4 % (Levitt 1971).
    ``step_sizes[k]`` applies after k reversals (the last one thereafter); in the parameter's
    unit for ``step_scale = 'linear'``, in log10 units for ``'log'`` (0.1 = x1.26).
    """

    start: float
    up: int = Field(1, ge=1, le=10)
    down: int = Field(2, ge=1, le=10)
    step_sizes: list[float]
    step_scale: Literal["linear", "log"] = "log"
    min_level: float
    max_level: float
    max_trials: int = Field(40, ge=1, le=10_000)
    max_reversals: int | None = Field(None, ge=1)
    estimate_reversals: int = Field(6, ge=1, description="mean of the last k reversal levels")

    @model_validator(mode="after")
    def _check(self) -> StaircaseTrack:
        for name in ("start", "min_level", "max_level"):
            _finite(getattr(self, name), name)
        if not self.step_sizes or any(not math.isfinite(s) or s <= 0 for s in self.step_sizes):
            raise ValueError(f"step_sizes: need at least one finite step > 0, got {self.step_sizes!r}")
        if not self.min_level <= self.start <= self.max_level or self.min_level >= self.max_level:
            raise ValueError(
                f"start: must lie in [min_level, max_level] with min < max, got start={self.start!r}, "
                f"min_level={self.min_level!r}, max_level={self.max_level!r}"
            )
        if self.step_scale == "log" and self.min_level <= 0:
            raise ValueError(f"min_level: a log staircase needs min_level > 0, got {self.min_level!r}")
        return self


class StaircaseConfig(_Model):
    """One or several interleaved staircases; each trial runs a track drawn at random."""

    method: Literal["staircase"]
    parameter: str
    tracks: list[StaircaseTrack] = Field(min_length=1, max_length=16)

    @model_validator(mode="before")
    @classmethod
    def _units(cls, data: Any) -> Any:
        data = _convert_levels(data, ())
        if isinstance(data, dict) and isinstance(data.get("tracks"), list):
            linear_steps = lambda t: isinstance(t, dict) and t.get("step_scale", "log") == "linear"
            dim = PARAMETERS[data["parameter"]]
            tracks = []
            for i, t in enumerate(data["tracks"]):
                if isinstance(t, dict):
                    t = dict(t)
                    for key in ("start", "min_level", "max_level"):
                        if key in t:
                            t[key] = to_si(t[key], dim, name=f"tracks[{i}].{key}")
                    if linear_steps(t) and isinstance(t.get("step_sizes"), list):
                        t["step_sizes"] = [to_si(s, dim, name=f"tracks[{i}].step_sizes") for s in t["step_sizes"]]
                tracks.append(t)
            data["tracks"] = tracks
        return data


class PsiConfig(_Model):
    """Bayesian adaptive method (psi / QUEST+): pick the level that minimises expected entropy.

    ``likelihood`` is a named family (``weibull``, ``logistic``, ``normal_cdf``, ``gumbel``;
    parameters ``threshold`` in the varied parameter's unit, ``slope``, ``lapse``) or an import
    path ``"package.module:function"`` to ANY callable ``f(level, **params) -> p(positive)``
    broadcasting ``level`` of shape (n_levels, 1) against parameter grids of shape (1, n_theta).
    The library API also takes the callable itself. ``parameters`` maps each parameter to its
    grid; a grid named ``threshold`` is read in the varied parameter's unit.
    """

    method: Literal["psi"]
    parameter: str
    levels: list[float]
    likelihood: str = "weibull"
    parameters: dict[str, list[float]]
    guess_rate: float | None = Field(None, description="defaults to the task's chance rate")
    n_trials: int = Field(40, ge=1, le=10_000)

    @model_validator(mode="before")
    @classmethod
    def _units(cls, data: Any) -> Any:
        data = _convert_levels(data, (), ("levels",))
        if isinstance(data, dict) and isinstance(data.get("parameters"), dict):
            dim = PARAMETERS[data["parameter"]]
            data["parameters"] = {
                k: _grid(v, dim if k == "threshold" else "dimensionless", f"parameters.{k}")
                for k, v in data["parameters"].items()
            }
        return data

    @model_validator(mode="after")
    def _check(self) -> PsiConfig:
        if self.likelihood not in LIKELIHOOD_FAMILIES and not _IMPORT_PATH.match(self.likelihood):
            raise ValueError(
                f"likelihood: must be one of {list(LIKELIHOOD_FAMILIES)} or an import path "
                f"'package.module:function', got {self.likelihood!r}"
            )
        if self.likelihood in LIKELIHOOD_FAMILIES and set(self.parameters) != {"threshold", "slope", "lapse"}:
            raise ValueError(
                f"parameters: the {self.likelihood!r} family needs grids for exactly threshold, slope "
                f"and lapse, got {sorted(self.parameters)}"
            )
        if "lapse" in self.parameters and any(not 0 <= v < 0.5 for v in self.parameters["lapse"]):
            raise ValueError(f"parameters.lapse: values must lie in [0, 0.5), got {self.parameters['lapse']!r}")
        if "slope" in self.parameters and any(v <= 0 for v in self.parameters["slope"]):
            raise ValueError(f"parameters.slope: values must be > 0, got {self.parameters['slope']!r}")
        if self.guess_rate is not None and not 0 <= self.guess_rate < 1:
            raise ValueError(f"guess_rate: must lie in [0, 1), got {self.guess_rate!r}")
        n_theta = math.prod(len(g) for g in self.parameters.values())
        if n_theta * len(self.levels) > 5_000_000:
            raise ValueError(
                f"parameters: the grid has {n_theta} points x {len(self.levels)} levels, above "
                "5e6; use coarser grids"
            )
        return self


ProcedureConfig = Annotated[
    Union[ConstantStimuliConfig, StaircaseConfig, PsiConfig], Field(discriminator="method")
]


class Protocol(_Model):
    """A psychophysics protocol: stimulus, task, procedure and seed (a TOML file on disk).

    Each trial's randomness comes from ``np.random.default_rng([seed, trial_index])``.
    """

    schema_version: Literal[1] = 1
    name: str = Field(description="task label, letters and digits (BIDS 'task-<name>')")
    description: str = ""
    seed: int = Field(ge=0, lt=2**63)
    task: Task
    stimulus: Stimulus
    reference: Stimulus | None = Field(None, description="comparison standard (2ifc, same_different)")
    procedure: ProcedureConfig
    iti_s: Time = Field(0.5, description="inter-trial interval, s")

    @model_validator(mode="after")
    def _check(self) -> Protocol:
        check_label(self.name, "name")
        _finite(self.iti_s, "iti_s")
        if not 0 <= self.iti_s <= 60:
            raise ValueError(f"iti_s: must lie in [0, 60] s, got {self.iti_s!r}")
        proc, kind = self.procedure, self.task.kind
        if kind == "same_different" and self.reference is None:
            raise ValueError("reference: a same_different task needs a reference stimulus; add [reference]")
        if kind == "magnitude_estimation" and proc.method != "constant_stimuli":
            raise ValueError(
                f"procedure.method: magnitude_estimation has no correct answer, so it needs "
                f"constant_stimuli, got {proc.method!r}"
            )
        for level in self.candidate_levels():
            try:  # every level the procedure can choose must give a valid stimulus
                self.stimulus.with_level(proc.parameter, level)
            except ValueError as exc:
                raise ValueError(
                    f"procedure: level {level!r} of {proc.parameter} gives an invalid stimulus "
                    f"({_first_error(exc)}); narrow the levels"
                ) from None
        for label, override in (self.task.alternatives or {}).items():
            if proc.parameter in override:
                raise ValueError(
                    f"task.alternatives.{label}: overrides {proc.parameter}, the parameter the "
                    "procedure varies; alternatives must differ in another field"
                )
            try:
                Stimulus.model_validate({**self.stimulus.model_dump(), **override})
            except ValueError as exc:
                raise ValueError(f"task.alternatives.{label}: {_first_error(exc)}") from None
        return self

    def candidate_levels(self) -> list[float]:
        """The levels (or the bounds of the range) the procedure may command, SI."""
        proc = self.procedure
        if proc.method == "staircase":
            return [v for t in proc.tracks for v in (t.min_level, t.max_level)]
        return list(proc.levels)

    @classmethod
    def from_toml(cls, path: str | Path) -> Protocol:
        """Load and validate a protocol file; unit suffixes are converted to SI here."""
        path = Path(path)
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{path}: not valid TOML ({exc}); fix the syntax") from None
        return cls.model_validate(data)

    def to_json(self) -> str:
        """Serialise to JSON (SI numbers); :meth:`model_validate_json` reads it back."""
        return self.model_dump_json()


def _first_error(exc: ValueError) -> str:
    errors = getattr(exc, "errors", None)
    if callable(errors):
        first = errors()[0]
        loc = ".".join(str(x) for x in first.get("loc", ()))
        msg = str(first.get("msg", "")).removeprefix("Value error, ")
        return f"{loc}: {msg}" if loc else msg
    return str(exc)

"""Procedure configurations of a protocol, and the validated field helpers they share.

A protocol's ``[procedure]`` table is validated by the configuration class registered for its
``method`` (:func:`register_procedure_config`; built in: :class:`ConstantStimuliConfig`,
:class:`StaircaseConfig`, :class:`PsiConfig`). A file holds data only: a method or a
likelihood is a registered NAME, never an import path. Levels are read in the
unit of the varied stimulus ``parameter`` (``"20um"`` for ``amplitude_m``), converted to SI once
with :func:`tactilab.data_schemas.units.to_si`; grids are lists or ``{start, stop, n, scale}``
tables. :mod:`tactilab.data_schemas.experiment` builds the protocol from these.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, ClassVar, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationInfo, model_validator

from tactilab.core import rules

from .identifiers import check_name
from .protocol_levels import FILE_EDGE, grid, level_si
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
def _quantity(dimension: str):
    """Before-validator: a number (SI) or a string with a unit suffix, converted to SI."""

    def convert(value: Any, info: ValidationInfo) -> Any:
        if isinstance(value, (str, int, float)):  # bools too: to_si refuses them
            return to_si(value, dimension, name=info.field_name or "value")
        return value

    return BeforeValidator(convert)


Length = Annotated[float, _quantity("length")]
Speed = Annotated[float, _quantity("speed")]
Time = Annotated[float, _quantity("time")]
Frequency = Annotated[float, _quantity("frequency")]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


def _from_file(info: ValidationInfo | None) -> bool:
    """True when validating a protocol file (context :data:`~.protocol_levels.FILE_EDGE`)."""
    context = getattr(info, "context", None)
    return isinstance(context, dict) and context.get("edge") == FILE_EDGE["edge"]


def _convert_levels(data: Any, grids: tuple[str, ...], info: ValidationInfo | None) -> Any:
    """Convert level-valued fields with the dimension of the varied ``parameter``."""
    if not isinstance(data, dict):
        return data
    parameter = data.get("parameter")
    if not isinstance(parameter, str) or parameter not in PARAMETERS:
        raise ValueError(
            f"parameter: must be one of {sorted(PARAMETERS)}, got {parameter!r}; name the "
            "stimulus field the procedure varies"
        )
    dimension, out = PARAMETERS[parameter], dict(data)
    for key in grids:
        if key in out:
            out[key] = grid(out[key], dimension, key, parameter=parameter, file=_from_file(info))
    return out


class ProcedureConfigBase(_Model):
    """Base of every procedure configuration: ``method`` names the registered procedure and
    ``parameter`` the stimulus field it varies. Subclasses add their own fields."""

    method: str
    parameter: str
    #: the fix an error about an invalid planned stimulus suggests (see :meth:`planned_fields`)
    planned_fix: ClassVar[str] = "narrow the levels"

    def candidate_levels(self) -> list[float]:
        """The levels (or the bounds of the range) the procedure may command, SI."""
        return [float(v) for v in getattr(self, "levels")]

    def planned_fields(self) -> list[tuple[str, dict[str, Any]]]:
        """Every stimulus the procedure may command, as the fields it sets on ``[stimulus]`` (SI).

        Returns ``(where, fields)`` pairs: ``where`` names the protocol entry that plans the
        stimulus (it starts the error if the stimulus is invalid), ``fields`` maps stimulus field
        names to SI values. The protocol merges each with its ``[stimulus]`` (and each 2afc
        alternative) exactly as a trial does and validates the result when it is loaded.
        Default: ``{parameter: level}`` for each of :meth:`candidate_levels`; for a staircase
        these are the bounds, which suffices because, the other fields fixed, every stimulus rule
        keeps a field inside an interval, so a range with valid bounds holds only valid levels.
        Procedures whose trials set more fields (``model_discrimination``) override it.
        """
        return [(f"procedure: level {level!r} of {self.parameter}", {self.parameter: level})
                for level in self.candidate_levels()]

    def without_planned(self, indices: set[int]) -> ProcedureConfigBase:
        """This configuration without the planned stimuli at ``indices`` of :meth:`planned_fields`
        (a protocol's ``clipped = "drop"``). Default: those entries of ``levels`` removed.

        Raises
        ------
        ValueError
            The configuration has no ``levels`` to drop from, or none would be left.
        """
        levels = getattr(self, "levels", None)
        if not isinstance(levels, list):
            raise ValueError(f"clipped: the {self.method!r} procedure cannot drop planned stimuli (it has no levels "
                             "list); use clipped = 'refuse' and change its range")
        kept = [v for i, v in enumerate(levels) if i not in indices]
        if not kept:
            raise ValueError(f"clipped: the display would limit all {len(levels)} levels of {self.parameter}; "
                             "nothing is left to run; lower the levels or pick a display that plays them")
        return type(self).model_validate({**self.model_dump(), "levels": kept})

    def n_planned(self) -> int:
        """The most trials the procedure will run (capped by :data:`MAX_PLANNED_TRIALS`).

        Default: ``n_trials`` if the configuration has it, else one trial per candidate level;
        configurations of other procedures override it.
        """
        n_trials = getattr(self, "n_trials", None)
        return int(n_trials) if n_trials is not None else len(self.candidate_levels())


#: The most trials one protocol may plan (a session of 100 000 trials is already days long).
MAX_PLANNED_TRIALS = 100_000


class ConstantStimuliConfig(ProcedureConfigBase):
    """Method of constant stimuli: every level ``repeats_per_block`` times per block, shuffled.

    ``conditions`` (instead of ``levels``): rows of stimulus fields in SI, each a condition (a
    conditions table, :mod:`tactilab.data_schemas.conditions`); ``levels`` is then each row's
    value of ``parameter``."""

    method: Literal["constant_stimuli"]
    parameter: str
    levels: list[float]
    conditions: list[dict[str, Any]] | None = None
    repeats_per_block: int = Field(5, ge=1, le=1000)
    n_blocks: int = Field(4, ge=1, le=1000)

    @model_validator(mode="before")
    @classmethod
    def _units(cls, data: Any, info: ValidationInfo) -> Any:
        if isinstance(data, dict) and data.get("conditions") is not None:
            from .conditions import condition_levels

            # the levels come from the table, whose column header gave their unit: already SI
            return _convert_levels(condition_levels(data), ("levels",), None)
        return _convert_levels(data, ("levels",), info)

    def planned_fields(self) -> list[tuple[str, dict[str, Any]]]:
        if self.conditions is None:
            return super().planned_fields()
        return [(f"procedure: condition {i} {row}", dict(row)) for i, row in enumerate(self.conditions)]

    def without_planned(self, indices: set[int]) -> ConstantStimuliConfig:
        if self.conditions is None:
            return super().without_planned(indices)
        kept = [row for i, row in enumerate(self.conditions) if i not in indices]
        if not kept:
            raise ValueError(f"clipped: the display would limit all {len(self.conditions)} conditions; nothing is "
                             "left to run; change the conditions or pick a display that plays them")
        return type(self).model_validate({**self.model_dump(), "conditions": kept, "levels": None})

    def n_planned(self) -> int:
        return len(self.levels) * self.repeats_per_block * self.n_blocks


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
            rules.finite(getattr(self, name), name)
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


class StaircaseConfig(ProcedureConfigBase):
    """One or several interleaved staircases; each trial runs a track drawn at random."""

    method: Literal["staircase"]
    parameter: str
    tracks: list[StaircaseTrack] = Field(min_length=1, max_length=16)

    @model_validator(mode="before")
    @classmethod
    def _units(cls, data: Any, info: ValidationInfo) -> Any:
        data = _convert_levels(data, (), info)
        if isinstance(data, dict) and isinstance(data.get("tracks"), list):
            linear_steps = lambda t: isinstance(t, dict) and t.get("step_scale", "log") == "linear"
            parameter = data["parameter"]
            dim, file = PARAMETERS[parameter], _from_file(info)
            tracks = []
            for i, t in enumerate(data["tracks"]):
                if isinstance(t, dict):
                    t = dict(t)
                    for key in ("start", "min_level", "max_level"):
                        if key in t:
                            t[key] = level_si(t[key], dim, f"tracks[{i}].{key}", parameter=parameter, file=file)
                    if linear_steps(t) and isinstance(t.get("step_sizes"), list):
                        t["step_sizes"] = grid(t["step_sizes"], dim, f"tracks[{i}].step_sizes", parameter=parameter,
                                             file=file)
                tracks.append(t)
            data["tracks"] = tracks
        return data

    def candidate_levels(self) -> list[float]:
        return [v for t in self.tracks for v in (t.min_level, t.max_level)]

    def without_planned(self, indices: set[int]) -> StaircaseConfig:
        """Refused: a staircase's planned stimuli are the bounds of its range, which it cannot drop."""
        i = min(indices, default=0)  # planned_fields lists each track's (min_level, max_level)
        bound = ("min_level", "max_level")[i % 2]
        where = f"tracks[{i // 2}].{bound} = {getattr(self.tracks[i // 2], bound)!r}"
        raise ValueError(f"clipped: a staircase cannot drop its own range ({where} would be limited by the "
                         "display, and a staircase may command any level between its bounds); bring the "
                         "track's bounds inside the display's limits")

    def n_planned(self) -> int:
        return sum(t.max_trials for t in self.tracks)


class PsiConfig(ProcedureConfigBase):
    """Bayesian adaptive method (psi / QUEST+): pick the level that minimises expected entropy.

    ``likelihood`` is a NAME: a built-in family (``weibull``, ``logistic``, ``normal_cdf``,
    ``gumbel``; parameters ``threshold`` in the varied parameter's unit, ``slope``, ``lapse``)
    or a likelihood registered from Python with
    ``tactilab.experiments.register_likelihood(name, f)`` (or by an installed plug-in), where
    ``f(level, **params) -> p(positive)`` broadcasts ``level`` of shape (n_levels, 1) against
    parameter grids of shape (1, n_theta). Never an import path: a protocol is data.
    ``parameters`` maps each parameter to its grid; a grid named ``threshold`` is read in the
    varied parameter's unit.
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
    def _units(cls, data: Any, info: ValidationInfo) -> Any:
        data = _convert_levels(data, ("levels",), info)
        if isinstance(data, dict) and isinstance(data.get("parameters"), dict):
            parameter = data["parameter"]
            dim, file = PARAMETERS[parameter], _from_file(info)
            data["parameters"] = {
                k: grid(v, dim if k == "threshold" else "dimensionless", f"parameters.{k}", parameter=parameter,
                        file=file)
                for k, v in data["parameters"].items()
            }
        return data

    @model_validator(mode="after")
    def _check(self) -> PsiConfig:
        check_name(self.likelihood, "likelihood", f"likelihood (built in: {', '.join(LIKELIHOOD_FAMILIES)})")
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


#: method name -> configuration class (the built-ins; experiments.register_procedure adds more)
PROCEDURE_CONFIGS: dict[str, type[ProcedureConfigBase]] = {
    "constant_stimuli": ConstantStimuliConfig, "staircase": StaircaseConfig, "psi": PsiConfig}


def register_procedure_config(name: str, config_cls: type) -> None:
    """Let protocols name ``method = name``, validated by ``config_cls``.

    Raises
    ------
    ValueError
        If ``name`` is not a registered-name string, is taken by another class, or
        ``config_cls`` is not a :class:`ProcedureConfigBase` subclass.
    """
    check_name(name, "name", "procedure")
    if not (isinstance(config_cls, type) and issubclass(config_cls, ProcedureConfigBase)):
        raise ValueError(
            f"config_cls: must be a subclass of tactilab.data_schemas.experiment_procedures."
            f"ProcedureConfigBase, got {config_cls!r}; derive the configuration from it"
        )
    if PROCEDURE_CONFIGS.get(name, config_cls) is not config_cls:
        raise ValueError(f"name: procedure {name!r} is already registered with "
                         f"{PROCEDURE_CONFIGS[name].__name__}; choose another name")
    PROCEDURE_CONFIGS[name] = config_cls


def procedure_config(data: Any, context: dict | None = None) -> Any:
    """Validate a ``[procedure]`` table with the class registered for its ``method``.

    ``context`` is the validation context (:data:`~.protocol_levels.FILE_EDGE` for a file).
    """
    if isinstance(data, ProcedureConfigBase) or not isinstance(data, dict):
        return data
    method = data.get("method")
    if not isinstance(method, str) or method not in PROCEDURE_CONFIGS:
        raise ValueError(
            f"method: must name a registered procedure, one of {sorted(PROCEDURE_CONFIGS)}, got "
            f"{method!r}; register new procedures from Python with "
            "tactilab.experiments.register_procedure(name, config_cls, factory)"
        )
    return PROCEDURE_CONFIGS[method].model_validate(data, context=context)

"""Psychophysics protocols, trial records and sessions (pydantic v2, SI units inside).

A :class:`Protocol` is what a TOML protocol file holds: the stimulus (a virtual surface that a
laterotactile display renders as a travelling wave), the task, the procedure that chooses the
level of one stimulus parameter on each trial, and the seed. Quantities in files may carry unit
suffixes (``"20um"``, ``"40mm/s"``, ``"500ms"``); they are converted to SI once, on loading,
with :func:`tactilab.data_schemas.units.to_si`. A bare number is SI only under a field whose
name carries its unit (``iti_s``); procedure levels need their unit written
(:mod:`tactilab.data_schemas.protocol_levels`). The procedure
configurations live in :mod:`tactilab.data_schemas.experiment_procedures`; trial records and
sessions in :mod:`tactilab.data_schemas.experiment_records`.
"""

from __future__ import annotations

import errno
import tomllib
import warnings
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, SerializeAsAny, ValidationError, ValidationInfo, field_validator, model_validator

from tactilab.core import rules

from . import design_config  # noqa: F401 - registers the built-in adaptive design's [procedure] table
from .base import format_validation_error
from .finger_config import FingerConfig
from .experiment_procedures import (  # noqa: F401 - the configs are part of this module's API
    LIKELIHOOD_FAMILIES, MAX_PLANNED_TRIALS, PARAMETERS, PROCEDURE_CONFIGS, TASKS, ConstantStimuliConfig,
    Frequency, Length, ProcedureConfigBase, PsiConfig, Speed, StaircaseConfig, StaircaseTrack, Time,
    _Model, procedure_config, register_procedure_config)
from .identifiers import check_label, check_name, check_subject  # noqa: F401 - part of this module's API
from .protocol_levels import FILE_EDGE
from .stimulus import MAX_FRAME_RATE_HZ, PITCH_RANGE_M, Stimulus  # noqa: F401 - part of this module's API

#: What a session does with a planned stimulus the display would limit (clip, slew- or duty-limit):
#: refuse the protocol, drop the stimulus (a level, a design candidate), or allow the safety layer to limit it
CLIPPED = ("refuse", "drop", "allow")

#: Caps on what a protocol file may hold (a protocol is a page of text, not a data dump).
MAX_PROTOCOL_BYTES = 1_000_000
MAX_TEXT_CHARS = 2000
MAX_PROMPT_CHARS = 300


def check_clipped(value: Any, name: str) -> str:
    """Return ``value`` if it is one of :data:`CLIPPED` (a protocol's or a session's ``clipped``)."""
    if value not in CLIPPED:
        raise ValueError(f"{name}: must be one of {CLIPPED}, got {value!r}; 'refuse' (the default) names the "
                         "first stimulus the display would limit, 'drop' leaves such stimuli out and counts them")
    return value


def _check_text(value: str | None, name: str, cap: int) -> None:
    """Text shown to people: capped, printable characters only (no terminal escape sequences)."""
    if value is None:
        return
    if len(value) > cap:
        raise ValueError(f"{name}: at most {cap} characters, got {len(value)}; shorten it")
    bad = sorted({repr(c) for c in value if not (c.isprintable() or c in "\n")})
    if bad:
        raise ValueError(f"{name}: only printable characters (and line breaks), got {', '.join(bad[:5])}; "
                         "remove control and escape characters")


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
        _check_text(self.prompt, "prompt", MAX_PROMPT_CHARS)
        rules.finite(self.interval_gap_s, "interval_gap_s", "s")
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
    procedure: SerializeAsAny[ProcedureConfigBase] = Field(
        description="validated by the configuration class registered for its `method`")
    iti_s: Time = Field(0.5, description="inter-trial interval, s")
    finger: FingerConfig | None = Field(None, description="the finger pressing physical gratings (contact-source "
                                                          "models and observers)")
    clipped: str = Field("refuse", description="a planned stimulus the display would limit: 'refuse' the "
                         "protocol, 'drop' the stimulus, or 'allow' the safety layer to limit it (see CLIPPED)")

    @field_validator("procedure", mode="before")
    @classmethod
    def _procedure(cls, value: Any, info: ValidationInfo) -> Any:
        return procedure_config(value, info.context)

    @model_validator(mode="after")
    def _check(self) -> Protocol:
        check_label(self.name, "name")
        _check_text(self.description, "description", MAX_TEXT_CHARS)
        rules.finite(self.iti_s, "iti_s", "s")
        check_clipped(self.clipped, "clipped")
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
        n_planned = proc.n_planned()
        if n_planned > MAX_PLANNED_TRIALS:
            raise ValueError(
                f"procedure: plans {n_planned} trials, above the cap of {MAX_PLANNED_TRIALS}; "
                "split the experiment into sessions"
            )
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
        self._check_planned()
        return self

    def _check_planned(self) -> None:
        """Every stimulus a trial can show must be valid: each of the procedure's planned field
        sets (a level; a model-discrimination candidate) merged with ``[stimulus]``, and with each
        2afc alternative, as ``tactilab.experiments.tasks.plan_trial`` merges them. The rules
        are :class:`Stimulus`'s own (one rule per quantity); the error names the first planned
        stimulus that breaks one, the rule and the value, and counts the others."""
        proc = self.procedure
        first: str | None = None
        broken: dict[str, int] = {}  # quantity -> how many planned stimuli break its rule
        seen: set[str] = set()
        for where, under, merged in self._planned():
            if where in seen:  # one failure per planned stimulus (its first variant)
                continue
            try:
                Stimulus.model_validate(merged)
            except ValueError as exc:
                seen.add(where)
                rule = _first_error(exc)
                quantity = rule.split(":", 1)[0]
                broken[quantity] = broken.get(quantity, 0) + 1
                if first is None:
                    first, first_quantity = f"{where}{under} gives an invalid stimulus ({rule})", quantity
        if first is None:
            return
        count = f"{broken[first_quantity]} of {len(proc.planned_fields())} planned stimuli break the {first_quantity} rule"
        others = [f"{q} ({n})" for q, n in broken.items() if q != first_quantity]
        raise ValueError(f"{first}; {count}{'; others break ' + ', '.join(others) if others else ''}; "
                         f"{proc.planned_fix}")

    def _planned(self):
        """``(where, under, fields)`` for every stimulus a trial can show, before validation."""
        base = self.stimulus.model_dump()
        variants = [("", {})] + [(f" under task.alternatives.{label}", override)
                                 for label, override in (self.task.alternatives or {}).items()]
        for where, fields in self.procedure.planned_fields():
            for under, override in variants:
                yield where, under, {**base, **fields, **override}

    def planned_stimuli(self) -> list[Stimulus]:
        """Every stimulus a trial can show, SI: each planned level or candidate merged with
        ``[stimulus]`` (under each 2afc alternative), and the ``[reference]``. A runner checks
        them against its display (frame rate) before a session file exists."""
        out = [Stimulus.model_validate(merged) for _, _, merged in self._planned()]
        return out + ([self.reference] if self.reference is not None else [])

    def candidate_levels(self) -> list[float]:
        """The levels (or the bounds of the range) the procedure may command, SI."""
        return self.procedure.candidate_levels()

    @classmethod
    def from_toml(cls, path: str | Path) -> Protocol:
        """Load and validate a protocol file; unit suffixes are converted to SI here.

        Raises
        ------
        OSError
            If the file cannot be read.
        ValueError
            Invalid TOML or an invalid protocol, in one line that starts with the file's path
            (a scene or load file given by mistake is named, not just its missing keys).
        """
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(errno.ENOENT, "protocol file not found (check the path and the current folder)",
                                    str(path))
        size = path.stat().st_size
        if size > MAX_PROTOCOL_BYTES:
            raise ValueError(f"{path}: {size} bytes, above the {MAX_PROTOCOL_BYTES}-byte cap of a protocol file; "
                             "a protocol is a short text file: give grids as {start, stop, n} tables")
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{path}: not valid TOML ({exc}); fix the syntax") from None
        except UnicodeDecodeError:
            raise ValueError(f"{path}: not UTF-8 text; give a TOML protocol file") from None
        except RecursionError:
            raise ValueError(f"{path}: nested too deeply to be a protocol; fix the file") from None
        procedure = data.get("procedure")
        if isinstance(procedure, dict) and isinstance(procedure.get("conditions"), str):
            from .conditions import read_conditions

            try:  # the table's rows become part of the protocol (a session records them)
                data["procedure"] = {**procedure, "conditions": read_conditions(path.parent, procedure["conditions"])}
            except (ValueError, OSError) as exc:
                raise ValueError(f"{path} (protocol): {exc}") from None
        try:
            with warnings.catch_warnings(record=True) as caught:  # an error supersedes the warnings
                protocol = cls.model_validate(data, context=FILE_EDGE)
            for item in caught:  # valid: the plausibility warnings are shown now
                warnings.warn_explicit(item.message, item.category, item.filename, item.lineno)
            return protocol
        except ValidationError as err:
            raise ValueError(format_validation_error(err, f"{path} (protocol)")) from None
        except (TypeError, RecursionError) as exc:  # a value of a type no validator expected
            raise ValueError(f"{path} (protocol): a value has the wrong type ({' '.join(str(exc).split())[:200]}); "
                             "compare the file with docs/experiments.md") from None

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

"""The :class:`Record` base model and the validated field types shared by every schema.

Every record that crosses a part boundary (material, sensors, surface, scene, recording,
display) is an immutable pydantic v2 model built on :class:`Record`:

- unknown keys are rejected (``extra="forbid"``), so a typo in a file never passes silently;
- records are frozen, and their numpy arrays are read-only;
- quantities are SI, and the unit is the field name's suffix: ``_m`` (m), ``_pa`` (Pa),
  ``_n`` (N), ``_s`` (s), ``_hz`` (Hz), ``_m_per_s`` (m/s);
- every value is checked on construction, and each error names the field, the rule, the
  value given and the fix;
- records round-trip exactly through JSON (``to_json`` / ``from_json``, ``save`` / ``load``);
  arrays are written as nested lists of floats, which JSON carries without loss.

Field types are built with :func:`finite`, :func:`positive`, :func:`non_negative`,
:func:`in_range` and :func:`float_array`; each takes an optional ``reason`` that the error
message quotes, e.g. ``positive("sensors sit inside the skin")``. What counts as positive is
the ground floor's rule (:func:`tactilab.core.rules.positive`); these validators add the record's
wording (the field, its unit, the reason).
"""

from __future__ import annotations

import json
import math
import pathlib
from typing import Annotated, Any, Self, TypeVar

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    PlainSerializer,
    ValidationError,
    ValidationInfo,
    WithJsonSchema,
)

from tactilab.core import rules

from .unit_keys import convert_units

# Longest suffix first: "_m_per_s" must win over "_s".
_SUFFIX_UNITS: tuple[tuple[str, str], ...] = (
    ("_m_per_s", "m/s"),
    ("_per_s", "1/s"),
    ("_hz", "Hz"),
    ("_pa", "Pa"),
    ("_n", "N"),
    ("_s", "s"),
    ("_m", "m"),
    ("_rad", "rad"),
)


def unit_of(field_name: str) -> str:
    """Return the SI unit a field name declares by its suffix (``""`` when it has none).

    >>> unit_of("depth_m"), unit_of("speed_m_per_s"), unit_of("poisson_ratio")
    ('m', 'm/s', '')
    """
    for suffix, unit in _SUFFIX_UNITS:
        if field_name.endswith(suffix):
            return unit
    return ""


def _field(info: ValidationInfo | None) -> str:
    name = info.field_name if info is not None else None
    return name or "value"


def _in_unit(field_name: str) -> str:
    unit = unit_of(field_name)
    return f" in {unit}" if unit else ""


def _reason(reason: str) -> str:
    return f" ({reason})" if reason else ""


def _check_finite(value: float, name: str, fix: str = "") -> float:
    if not math.isfinite(value):
        fix = fix or f"give a finite number{_in_unit(name)}"
        raise ValueError(f"{name} must be finite, got {value!r}; {fix}")
    return value


def finite(reason: str = "") -> AfterValidator:
    """A validator: the float must be finite (not NaN, not +-inf)."""

    def check(value: float, info: ValidationInfo) -> float:
        name = _field(info)
        if not math.isfinite(value):
            raise ValueError(
                f"{name} must be finite{_reason(reason)}, got {value!r}; "
                f"give a finite number{_in_unit(name)}"
            )
        return value

    return AfterValidator(check)


def positive(reason: str = "", fix: str = "") -> AfterValidator:
    """A validator: the float must be finite and > 0 (:func:`tactilab.core.rules.positive`)."""

    def check(value: float, info: ValidationInfo) -> float:
        name = _field(info)
        try:
            return rules.positive(value, name, unit_of(name) or "1")
        except ValueError:  # the rule failed: say which half, in the record's words
            _check_finite(value, name, fix)
            raise ValueError(
                f"{name} must be > 0{_reason(reason)}, got {value!r}; "
                + (fix or f"give a positive number{_in_unit(name)}")
            ) from None

    return AfterValidator(check)


def non_negative(reason: str = "", fix: str = "") -> AfterValidator:
    """A validator: the float must be finite and >= 0."""

    def check(value: float, info: ValidationInfo) -> float:
        name = _field(info)
        _check_finite(value, name, fix)
        if not value >= 0:
            raise ValueError(
                f"{name} must be >= 0{_reason(reason)}, got {value!r}; "
                + (fix or f"give zero or a positive number{_in_unit(name)}")
            )
        return value

    return AfterValidator(check)


def in_range(low: float, high: float, *, low_open: bool = False, high_open: bool = False,
             reason: str = "", fix: str = "") -> AfterValidator:
    """A validator: the float must be finite and lie in the interval from ``low`` to ``high``.

    ``low_open`` / ``high_open`` exclude the end point, e.g. ``in_range(-1, 0.5, low_open=True)``
    is the interval (-1, 0.5].
    """
    interval = f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"

    def check(value: float, info: ValidationInfo) -> float:
        name = _field(info)
        _check_finite(value, name, fix)
        above = value > low if low_open else value >= low
        below = value < high if high_open else value <= high
        if not (above and below):
            raise ValueError(
                f"{name} must lie in {interval}{_reason(reason)}, got {value!r}; "
                + (fix or f"give a number in {interval}")
            )
        return value

    return AfterValidator(check)


def at_least(minimum: int, reason: str = "", fix: str = "") -> AfterValidator:
    """A validator: the integer must be >= ``minimum``."""

    def check(value: int, info: ValidationInfo) -> int:
        name = _field(info)
        if value < minimum:
            raise ValueError(
                f"{name} must be >= {minimum}{_reason(reason)}, got {value!r}; "
                + (fix or f"give a whole number of at least {minimum}")
            )
        return value

    return AfterValidator(check)


def _array_validator(ndim: int | None, last_dim: int | None, reason: str):
    def convert(value: Any, info: ValidationInfo) -> np.ndarray:
        name = _field(info)
        try:
            array = np.array(value, dtype=float)
        except (TypeError, ValueError) as err:
            raise ValueError(
                f"{name} must be an array of numbers{_reason(reason)}, got {type(value).__name__} "
                f"that cannot be read as one ({err}); give a list or numpy array of floats"
                f"{_in_unit(name)}"
            ) from None
        if ndim is not None and array.ndim != ndim:
            want = f"({', '.join(['n'] * (ndim - 1) + [str(last_dim) if last_dim else 'n'])})"
            raise ValueError(
                f"{name} must have {ndim} dimension(s), shape {want}{_reason(reason)}, "
                f"got shape {array.shape}; reshape it"
            )
        if last_dim is not None and array.shape[-1] != last_dim:
            raise ValueError(
                f"{name} must have {last_dim} columns{_reason(reason)}, got shape {array.shape}; "
                f"give one row of {last_dim} values per entry"
            )
        if array.size == 0:
            raise ValueError(f"{name} must not be empty, got shape {array.shape}; give at least one value")
        bad = ~np.isfinite(array)
        if bad.any():
            index = tuple(int(i) for i in np.argwhere(bad)[0])
            raise ValueError(
                f"{name} must be finite everywhere, got {float(array[index])!r} at index {index} "
                f"({int(bad.sum())} non-finite entries); replace NaN/inf by measured numbers"
            )
        array.flags.writeable = False
        return array

    return BeforeValidator(convert)


def _array_to_list(array: np.ndarray) -> list:
    return array.tolist()


def float_array(ndim: int | None = None, last_dim: int | None = None, reason: str = ""):
    """An annotated numpy float array type for record fields.

    Accepts lists, tuples or arrays; stores a read-only ``float64`` ndarray; checks the
    number of dimensions, the length of the last axis, non-emptiness and finiteness; writes
    nested lists to JSON.
    """
    return Annotated[
        np.ndarray,
        _array_validator(ndim, last_dim, reason),
        PlainSerializer(_array_to_list, return_type=list, when_used="json"),
        WithJsonSchema({"type": "array", "items": {}}),
    ]


def format_validation_error(error: ValidationError, where: str = "") -> str:
    """Squeeze a pydantic ``ValidationError`` into one line: ``where: loc: message; ...``.

    Used at the file and command-line edges, where one clear line beats a report.
    """
    parts = []
    for item in error.errors():
        loc = ".".join(str(x) for x in item["loc"])
        msg = item["msg"].removeprefix("Value error, ")
        if item["type"] == "extra_forbidden":
            msg = "unknown key (check its spelling and unit suffix; the record does not have it)"
        elif item["type"] == "missing":
            msg = "missing; this key is required"
        parent, _, last = loc.rpartition(".")
        if loc and msg.startswith(last):
            parts.append(f"{parent}.{msg}" if parent else msg)  # the message already names the field
        else:
            parts.append(f"{loc}: {msg}" if loc else msg)
    prefix = f"{where}: " if where else ""
    return prefix + "; ".join(parts)


def _values_equal(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)
                and a.shape == b.shape and bool(np.array_equal(a, b)))
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return len(a) == len(b) and all(_values_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_values_equal(a[k], b[k]) for k in a)
    return bool(a == b)


class Record(BaseModel):
    """Base of every tactilab record: immutable, strict about keys, SI units, JSON round-trip.

    Equality compares field by field (arrays by value and shape), so
    ``Model.from_json(r.to_json()) == r`` holds for every valid record ``r``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, arbitrary_types_allowed=True,
                              validate_default=True)

    def __eq__(self, other: object) -> bool:
        if type(self) is not type(other):
            return NotImplemented
        return all(_values_equal(getattr(self, k), getattr(other, k)) for k in type(self).model_fields)

    def __hash__(self) -> int:
        return hash((type(self).__name__, self.to_json()))

    def to_json(self, indent: int | None = 2) -> str:
        """Return the record as JSON text, quantities in SI units."""
        return self.model_dump_json(indent=indent)

    @classmethod
    def from_json(cls, text: str | bytes, where: str = "", *, context: dict | None = None) -> Self:
        """Build and validate a record from JSON text (as written by :meth:`to_json`).

        SI JSON loads as is; quantities may also carry unit suffixes as in scene files
        (``"depth": "1.25mm"``, ``"depth_mm": 1.25``), converted to SI here, once.

        Raises
        ------
        ValueError
            Invalid JSON, an unknown unit or an invalid field, in one line that starts with
            ``where`` (e.g. the file name) when given.
        """
        prefix = f"{where}: " if where else ""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise ValueError(f"{prefix}not valid JSON ({err}); fix the file or re-save the record") from None
        if not isinstance(data, dict):
            raise ValueError(f"{prefix}a {cls.__name__} must be a JSON object, got {type(data).__name__}; "
                             "write it with Record.save")
        return record_from_dict(cls, data, where, context=context)

    def save(self, path: str | pathlib.Path) -> pathlib.Path:
        """Write the record as JSON (SI units) to ``path`` and return the path."""
        path = pathlib.Path(path)
        path.write_text(self.to_json() + "\n", encoding="utf-8")
        return path

    @classmethod
    def load(cls, path: str | pathlib.Path) -> Self:
        """Read a record saved by :meth:`save`.

        Raises
        ------
        OSError
            If the file cannot be read.
        ValueError
            If the file is not valid JSON for this record; the one-line message names the
            file, each offending field and the rule it broke. Unit suffixes are accepted as
            in :meth:`from_json`.
        """
        path = pathlib.Path(path)
        return cls.from_json(path.read_text(encoding="utf-8"), where=str(path), context={"folder": path.parent})

    def replace(self, **changes: Any) -> Self:
        """Return a copy with some fields changed, validated again (unlike ``model_copy``)."""
        data = {k: getattr(self, k) for k in type(self).model_fields}
        data.update(changes)
        return type(self).model_validate(data)


R = TypeVar("R", bound=Record)


def record_from_dict(model: type[R], data: dict, where: str = "", *, context: dict | None = None) -> R:
    """Convert a raw file table to SI and validate it as ``model``.

    Used by :meth:`Record.from_json` and by the TOML readers of :mod:`.files`.

    Parameters
    ----------
    model : type of Record
        The record to build.
    data : dict
        The raw table, as read from TOML or JSON; quantities may carry units.
    where : str
        Where the table came from (file name, table path), put at the start of errors.
    context : dict, optional
        Passed to the validators; ``{"folder": ...}`` is the folder of the file the table came
        from, against which records resolve the files they name (a ``measured`` surface).

    Raises
    ------
    ValueError
        One line naming ``where``, the key, the rule, the value and the fix.
    """
    prefix = f"{where}: " if where else ""
    if not isinstance(data, dict):
        raise ValueError(f"{prefix}a {model.__name__} must be a table, got {type(data).__name__}; "
                         "write key = value pairs")
    try:
        return model.model_validate(convert_units(model, data), context=context)
    except ValidationError as err:
        raise ValueError(format_validation_error(err, where or model.__name__)) from None
    except ValueError as err:
        raise ValueError(f"{prefix}{err}") from None

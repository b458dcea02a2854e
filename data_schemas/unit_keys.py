"""Unit suffixes at the file edge: turn a raw TOML/JSON table into SI field values, once.

Record fields carry their SI unit in their name (``depth_m``, ``young_modulus_pa``,
``duration_s``, ``speed_m_per_s``, ...). In a file the same quantity may be written

- under the field name, in SI or with a unit in a string: ``depth_m = 0.00125`` or
  ``depth_m = "1.25mm"``;
- under the bare base name, as a string WITH a unit: ``depth = "1.25mm"``,
  ``young_modulus = "200kPa"``, ``duration = "500ms"``;
- under the base name with another unit suffix, as a number: ``depth_mm = 1.25``,
  ``young_modulus_kpa = 200``, ``speed_mm_per_s = 20`` (``_per_`` stands for ``/``; the
  suffix is case-insensitive).

Lists (positions, height maps) convert element by element. Nested tables convert with their
own record's fields. :func:`convert_units` does this for any :class:`~.base.Record`; records
may rewrite file-only keys first through their ``_edge_prepare`` hook.
"""

from __future__ import annotations

import types
import typing
from typing import Any, Union

from pydantic import BaseModel

from tactilab.core.units import canonical_unit, natural_unit

from .units import SI_UNIT, UNITS, to_si

# Field-name suffix -> dimension; longest first. "_per_s" (rates in 1/s) is deliberately absent:
# it passes through unconverted rather than being mistaken for a time in s.
_FIELD_SUFFIXES: tuple[tuple[str, str | None], ...] = (
    ("_m_per_s", "speed"),
    ("_per_s", None),
    ("_n_per_m", "line_load"),
    ("_hz", "frequency"),
    ("_pa", "pressure"),
    ("_n", "force"),
    ("_s", "time"),
    ("_m", "length"),
)


def field_dimension(field_name: str) -> tuple[str, str] | None:
    """``(base name, dimension)`` of a unit-suffixed field, or None.

    >>> field_dimension("depth_m"), field_dimension("speed_m_per_s"), field_dimension("rows")
    (('depth', 'length'), ('speed', 'speed'), None)
    """
    for suffix, dimension in _FIELD_SUFFIXES:
        if field_name.endswith(suffix) and len(field_name) > len(suffix):
            if dimension is None:
                return None
            return field_name[: -len(suffix)], dimension
    return None


def _key_token(unit: str) -> str:
    return unit.replace("/", "_per_").lower()


def _units_for(dimension: str) -> dict[str, str]:
    """Key-suffix token -> unit string for one dimension (``"mm_per_s"`` -> ``"mm/s"``)."""
    return {_key_token(u): u for u, (d, _) in UNITS.items() if d == dimension and u not in ("", "1")}


def _convert(value: Any, dimension: str, where: str, default_unit: str | None) -> Any:
    if isinstance(value, list):
        return [_convert(v, dimension, f"{where}[{i}]", default_unit) for i, v in enumerate(value)]
    if value is None:
        return None
    if isinstance(value, (str, int, float)) and not isinstance(value, bool):
        return to_si(value, dimension, name=where, default_unit=default_unit)
    return value  # let the record's own validation name the problem


def _has_number(value: Any) -> bool:
    if isinstance(value, list):
        return any(_has_number(v) for v in value)
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    """Record classes named anywhere in a (possibly Optional/Union/Annotated/list) annotation."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    found: list[type[BaseModel]] = []
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _models_in(typing.get_args(annotation)[0])
    if origin in (Union, types.UnionType, list, tuple) or origin is not None:
        for arg in typing.get_args(annotation):
            found.extend(m for m in _models_in(arg) if m not in found)
    return found


def _pick_model(models: list[type[BaseModel]], data: dict) -> type[BaseModel] | None:
    if len(models) == 1:
        return models[0]
    kind = data.get("kind")
    for model in models:
        field = model.model_fields.get("kind")
        if field is not None and field.default == kind:
            return model
    return None


def _nested(annotation: Any, value: Any, where: str) -> Any:
    models = _models_in(annotation)
    if not models:
        return value
    if isinstance(value, dict):
        model = _pick_model(models, value)
        return convert_units(model, value, where) if model is not None else value
    if isinstance(value, list):
        return [_nested(annotation, v, f"{where}[{i}]") for i, v in enumerate(value)]
    return value


def convert_units(model: type[BaseModel], data: dict, where: str = "") -> dict:
    """Return ``data`` with every quantity of ``model`` under its SI field name, in SI.

    Parameters
    ----------
    model : type of Record
        The record the table describes.
    data : dict
        The raw table (from TOML or JSON).
    where : str
        Path of the table in the file (``"sensors"``), used in error messages.

    Raises
    ------
    ValueError
        An unknown unit (``depth = "3furlong"`` or ``depth_furlong = 3``), a unit of the wrong
        kind, a bare number under a base name with no unit, or one quantity given twice.
    """
    if not isinstance(data, dict):
        return data
    prefix = f"{where}." if where else ""
    prepare = getattr(model, "_edge_prepare", None)
    dimensions: dict[str, str] = {}
    if prepare is not None:
        data, dimensions = prepare(data, where)
    fields = model.model_fields
    by_base: dict[str, tuple[str, str]] = {}
    for name in fields:
        dim = dimensions.get(name)
        parsed = (name, dim) if dim is not None else field_dimension(name)
        if parsed is not None:
            by_base[parsed[0]] = (name, parsed[1])
    out: dict[str, Any] = {}
    source: dict[str, str] = {}
    for key, value in data.items():
        here = f"{prefix}{key}"
        target, dim, default_unit = key, None, None
        if key in fields:
            dim = dimensions.get(key) or (field_dimension(key) or (None, None))[1]
        elif key in by_base:
            target, dim = by_base[key]
            if _has_number(value) and target != key:
                raise ValueError(
                    f"{here} = {value!r} has no unit ({key} is a quantity in {SI_UNIT[dim]}); write "
                    f"{key} = \"{value}{natural_unit(key, dim) if dim != 'dimensionless' else ''}\" with a unit, "
                    f"or use {target} for SI"
                )
        else:
            for base, (name, base_dim) in sorted(by_base.items(), key=lambda kv: -len(kv[0])):
                if key.startswith(base + "_"):
                    token = canonical_unit(key[len(base) + 1:]).lower()
                    units = _units_for(base_dim)
                    if token not in units:
                        raise ValueError(
                            f"{here}: unknown unit suffix {key[len(base) + 1:]!r} for {base} (a {base_dim}); "
                            f"use one of {', '.join(base + '_' + t for t in units)} ({name} is SI)"
                        )
                    target, dim, default_unit = name, base_dim, units[token]
                    break
        if target in out:
            raise ValueError(
                f"{here}: {target} is given twice (as {source[target]} and {key}); keep one of them"
            )
        if dim is not None:
            value = _convert(value, dim, here, default_unit)
        elif target in fields:
            value = _nested(fields[target].annotation, value, here)
        out[target] = value
        source[target] = key
    return out

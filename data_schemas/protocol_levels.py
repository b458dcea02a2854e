"""Levels of a protocol's procedure: values in the unit of the varied parameter, read once.

A procedure's level fields (``levels``, a staircase track's ``start``, ``min_level``,
``max_level`` and linear ``step_sizes``, a psi ``threshold`` grid) carry no unit in their name:
they are in the unit of the stimulus ``parameter`` they vary (``"20um"`` for ``amplitude_m``).
In a protocol FILE each of them must therefore be written with its unit, the rule every file
field without a unit in its name follows (``docs/data_schemas.md``): a bare number
(``levels = [0.8, 1.2]``, ``start = 0.00002``) is refused, never read as metres. From Python
(``Protocol.model_validate``, a session's stored protocol) numbers are SI, as everywhere inside.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tactilab.core.units import SI_UNIT, factor, natural_unit

from .units import to_si

__all__ = ["FILE_EDGE", "grid", "level_si"]

#: The validation context a protocol file is read under (``model_validate(data, context=FILE_EDGE)``).
FILE_EDGE = {"edge": "file"}


def _is_bare(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _refuse_bare(values: list[Any], dimension: str, name: str, parameter: str, written: str) -> None:
    """Raise if a file gives a bare number for a level; the fix shows both readings of it."""
    bare = [v for v in values if _is_bare(v)]
    if not bare:
        return
    unit = natural_unit(parameter, dimension)
    as_si = [f'"{v / factor(unit, dimension):g}{unit}"' for v in bare[:3]]
    raise ValueError(
        f"{name} = {written} has no unit; in a protocol file every level of {parameter} (a {dimension}) "
        f"is written with its unit, e.g. {name} = {_example(name, bare, unit)}; a bare number is not read "
        f"as SI (as {SI_UNIT[dimension]} it would be {', '.join(as_si)})"
    )


def _example(name: str, bare: list[Any], unit: str) -> str:
    if name.endswith("]") or not (name.endswith("levels") or name.endswith("step_sizes")
                                  or name.endswith("threshold")):
        return f'"{bare[0]:g}{unit}"'
    return "[" + ", ".join(f'"{v:g}{unit}"' for v in bare[:3]) + (", ...]" if len(bare) > 3 else "]")


def level_si(value: Any, dimension: str, name: str, *, parameter: str, file: bool) -> float:
    """One level in SI; a bare number from a file is refused (it has no unit in its name).

    Parameters
    ----------
    value : str or float
        ``"20um"``; a number is SI unless ``file`` is true.
    dimension : str
        What the varied parameter measures (``"length"`` for ``amplitude_m``).
    name : str
        The field, for messages (``"tracks[0].start"``).
    parameter : str
        The varied stimulus field (``"amplitude_m"``): its natural unit is the fix's unit.
    file : bool
        True when the value comes from a protocol file (:data:`FILE_EDGE`).
    """
    if file and dimension != "dimensionless":
        _refuse_bare([value], dimension, name, parameter, repr(value))
    return to_si(value, dimension, name=name)


def grid(raw: Any, dimension: str, name: str, *, parameter: str = "", file: bool = False) -> list[float]:
    """Read a list of values or a ``{start, stop, n, scale}`` table, each value with units (SI out).

    ``parameter`` and ``file`` as in :func:`level_si`: in a file, each value needs its unit.
    """
    check = file and dimension != "dimensionless"
    if isinstance(raw, dict):
        unknown = set(raw) - {"start", "stop", "n", "scale"}
        if unknown or not {"start", "stop", "n"} <= set(raw):
            raise ValueError(
                f"{name}: a grid table needs exactly start, stop, n and optional scale "
                f"('linear' or 'log'), got keys {sorted(raw)}; e.g. {{start='5um', stop='200um', n=20}}"
            )
        if check:
            for key in ("start", "stop"):
                _refuse_bare([raw[key]], dimension, f"{name}.{key}", parameter, repr(raw[key]))
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
        if check:
            _refuse_bare(list(raw), dimension, name, parameter, repr(list(raw)))
        return [to_si(v, dimension, name=f"{name}[{i}]") for i, v in enumerate(raw)]
    raise ValueError(f"{name}: expected a list of values or a {{start, stop, n}} table, got {raw!r}")

"""Unit strings at the file and command-line edges, converted to SI once.

Quantities inside tactilab are SI (m, Pa, N, s, Hz, m/s). Files and options may write a
number with an explicit unit suffix, such as ``"1.25mm"``, ``"20 kPa"`` or ``"5ms"``;
:func:`to_si` turns it into the SI float and checks that the unit measures what the
field expects (a length for a depth, a pressure for a modulus).

This is the ground-floor parser: it knows units, not skin. The records part adds the plausibility
ranges of skin quantities on top (``tactilab.data_schemas.units.to_si``, which the file readers
and the command line use).
"""

from __future__ import annotations

import math
import re
from decimal import Decimal

__all__ = ["SI_UNIT", "UNITS", "canonical_unit", "factor", "natural_unit", "to_si"]

#: unit -> (dimension, factor to SI)
UNITS: dict[str, tuple[str, float]] = {
    "m": ("length", 1.0),
    "cm": ("length", 1e-2),
    "mm": ("length", 1e-3),
    "um": ("length", 1e-6),
    "µm": ("length", 1e-6),
    "nm": ("length", 1e-9),
    "Pa": ("pressure", 1.0),
    "kPa": ("pressure", 1e3),
    "MPa": ("pressure", 1e6),
    "GPa": ("pressure", 1e9),
    "N": ("force", 1.0),
    "mN": ("force", 1e-3),
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "us": ("time", 1e-6),
    "Hz": ("frequency", 1.0),
    "kHz": ("frequency", 1e3),
    "m/s": ("speed", 1.0),
    "cm/s": ("speed", 1e-2),
    "mm/s": ("speed", 1e-3),
    "N/m": ("line_load", 1.0),
    "N/mm": ("line_load", 1e3),
    "1/m": ("wavenumber", 1.0),
    "1/mm": ("wavenumber", 1e3),
    "rad/m": ("wavenumber", 1.0),
    "rad/mm": ("wavenumber", 1e3),
    "1": ("dimensionless", 1.0),
    "": ("dimensionless", 1.0),
}

#: dimension -> its SI unit
SI_UNIT = {
    "length": "m",
    "pressure": "Pa",
    "force": "N",
    "time": "s",
    "frequency": "Hz",
    "speed": "m/s",
    "line_load": "N/m",
    "wavenumber": "1/m",
    "dimensionless": "1",
}

# The unit a researcher most likely meant for a bare number, by dimension: the scale of a
# receptor (mm), of a skin traction (kPa), of a trial (ms). Names refine it (natural_unit).
_EXAMPLE_UNIT = {
    "length": "mm",
    "pressure": "kPa",
    "force": "N",
    "time": "ms",
    "frequency": "Hz",
    "speed": "mm/s",
    "line_load": "N/m",
    "wavenumber": "rad/mm",
}

# Quantities whose natural unit differs from their dimension's: a modulus is in MPa (skin
# 0.1 to 10 MPa), an amplitude or a height in um. Matched on the words of the name.
_NAMED_UNIT: dict[str, tuple[str, str]] = {
    "modulus": ("pressure", "MPa"),
    "amplitude": ("length", "um"),
    "a": ("length", "um"),  # the A of a sinusoid (A=..., p=...)
    "height": ("length", "um"),
    "heights": ("length", "um"),
    "rms": ("length", "um"),
    "roughness": ("length", "um"),
    "indentation": ("length", "um"),
}

# The Greek small letter mu (U+03BC) looks like the micro sign (U+00B5) the table uses.
_GREEK_MU, _MICRO_SIGN = "\u03bc", "\u00b5"


def canonical_unit(unit: str) -> str:
    """Return ``unit`` with the Greek letter mu (U+03BC) written as the micro sign (U+00B5).

    Both are typed for "micro" (``"μm"`` from a Greek keyboard, ``"µm"`` from a Mac's option-m),
    and both mean the same unit.
    """
    return unit.replace(_GREEK_MU, _MICRO_SIGN)


def natural_unit(name: str, dimension: str) -> str:
    """The unit a bare number given for ``name`` most likely meant, for the fix in messages.

    One rule for every hint: the option's natural unit at receptor scale, never a fixed one.
    A modulus is in MPa, an amplitude or a height in um, other lengths in mm, pressures in kPa,
    times in ms, forces in N (``natural_unit("--young-modulus", "pressure") == "MPa"``).

    Parameters
    ----------
    name : str
        The option or field name as written at the edge (``--young-modulus``,
        ``stimulus.amplitude``, ``sinusoid A``); a field's SI suffix (``_m``) is ignored.
    dimension : str
        What the value measures, one of ``SI_UNIT``'s keys.
    """
    words = re.split(r"[^a-z0-9]+", name.lower().split(".")[-1])
    for word in words:
        named = _NAMED_UNIT.get(word)
        if named is not None and named[0] == dimension:
            return named[1]
    return _EXAMPLE_UNIT.get(dimension, SI_UNIT.get(dimension, ""))

_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?inf|nan)\s*(\S*)\s*$")


def _known_units(dimension: str) -> str:
    """The units of ``dimension`` for error messages ("1 or no unit" for dimensionless)."""
    units = [u for u, (d, _) in UNITS.items() if d == dimension and u]
    return ", ".join(units) + (" or no unit" if dimension == "dimensionless" else "")


def factor(unit: str, dimension: str, *, name: str = "value") -> float:
    """Return the factor that converts ``unit`` to SI, checking its dimension.

    Raises
    ------
    ValueError
        If ``unit`` is unknown or measures another dimension than ``dimension``.
    """
    unit = canonical_unit(unit)
    if unit not in UNITS:
        raise ValueError(
            f"{name}: unknown unit {unit!r}; use one of {_known_units(dimension)} (SI: {SI_UNIT[dimension]})"
        )
    dim, f = UNITS[unit]
    if dim != dimension and not (unit == "" and dimension == "dimensionless"):
        wanted = "dimensionless number" if dimension == "dimensionless" else dimension
        raise ValueError(
            f"{name}: unit {unit!r} measures {dim}, but a {wanted} is expected; use one of {_known_units(dimension)}"
        )
    return f


def to_si(value: str | float | int, dimension: str, *, name: str = "value",
          default_unit: str | None = None) -> float:
    """Convert ``value`` to an SI float.

    Parameters
    ----------
    value : str or float
        A number with a unit suffix (``"1.25mm"``), or a number. A Python number (int or
        float) is taken in ``default_unit`` if given, else it is SI. A string without a unit
        (``"1.25"``) is an error for a dimensional quantity unless ``default_unit`` is given:
        at the edges (options, files) a bare number is never silently SI.
    dimension : str
        What the value measures: one of ``SI_UNIT``'s keys.
    name : str
        The argument or field name, used in error messages.
    default_unit : str, optional
        Unit of a bare number (for example ``"mm"`` in files that state it).

    Returns
    -------
    float
        The value in SI units.
    """
    if dimension not in SI_UNIT:
        raise ValueError(f"dimension: unknown dimension {dimension!r}; use one of {sorted(SI_UNIT)}")
    if isinstance(value, bool):
        raise ValueError(f"{name}: expected a number with a unit, got the boolean {value!r}")
    if isinstance(value, (int, float)):
        unit = default_unit if default_unit is not None else SI_UNIT[dimension]
        number = float(value)
    elif isinstance(value, str):
        match = _QUANTITY.match(value)
        if match is None:
            raise ValueError(
                f"{name}: cannot read {value!r} as a quantity; write a number and a unit, "
                f"e.g. '1.5{natural_unit(name, dimension)}'"
            )
        number = float(match.group(1))
        unit = canonical_unit(match.group(2))
        if not unit:
            if default_unit is not None:
                unit = default_unit
            elif dimension == "dimensionless" or not math.isfinite(number):
                unit = SI_UNIT[dimension]  # non-finite values get their own message below
            else:
                # A bare number at an edge is never silently SI: '--depth 1.25' is not 1.25 m.
                raise ValueError(
                    f"{name}: {value.strip()!r} has no unit, and a {dimension} needs one; "
                    f"write it with a unit, e.g. '{value.strip()}{natural_unit(name, dimension)}' "
                    f"(units: {_known_units(dimension)})"
                )
    else:
        raise ValueError(f"{name}: expected a number or a string like '1.5mm', got {type(value).__name__}")
    if not math.isfinite(number):
        raise ValueError(f"{name}: must be finite, got {value!r}; give a finite number with a unit, "
                         f"e.g. '1.5{natural_unit(name, dimension)}'")
    f = factor(unit, dimension, name=name)
    # decimal product, so "1.25mm" gives exactly the float nearest 1.25e-3
    si = number if f == 1.0 else float(Decimal(repr(number)) * Decimal(repr(f)))
    return si

"""Unit strings at the file and command-line edges, converted to SI once, with skin plausibility.

The parser lives on the ground floor (:mod:`tactilab.core.units`); this module adds the
plausibility ranges of skin quantities (:mod:`tactilab.data_schemas.plausibility`), which warn
when a value converted from a file or an option lies far outside what skin measures.
"""

from __future__ import annotations

from tactilab.core.units import SI_UNIT, UNITS, factor
from tactilab.core.units import to_si as _parse

from .plausibility import check_plausible

__all__ = ["SI_UNIT", "UNITS", "factor", "to_si"]


def to_si(value: str | float | int, dimension: str, *, name: str = "value",
          default_unit: str | None = None) -> float:
    """Convert ``value`` to an SI float and check it against the skin's plausible range.

    Parameters and errors are those of :func:`tactilab.core.units.to_si`; in addition a value
    outside the plausible range of the quantity ``name`` names gets a warning
    (:func:`tactilab.data_schemas.plausibility.check_plausible`).

    Returns
    -------
    float
        The value in SI units.
    """
    si = _parse(value, dimension, name=name, default_unit=default_unit)
    check_plausible(si, name, SI_UNIT[dimension])
    return si

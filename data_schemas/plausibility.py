"""Plausibility at the edges: values far outside the range of skin and tactile displays.

A value that converts cleanly can still be absurd: a 50 m grid spacing or a 1 Pa skin modulus
is almost always a unit mistake. Each quantity has one usual range, keyed by its name as it is
written at the edge (``--grid-spacing``, ``material.young_modulus``, ``depth_m``): the name is
reduced to its base (``grid_spacing``, ``young_modulus``, ``depth``). A value outside the range
emits a :class:`PlausibilityWarning` that names the value and the usual range; the ``tactilab``
command's ``--strict`` option turns these warnings into errors.
"""

from __future__ import annotations

import re
import sys
import warnings

#: base quantity name -> (lowest, highest) plausible SI value, and the usual range in words
PLAUSIBLE: dict[str, tuple[float, float, str]] = {
    "depth": (1e-6, 20e-3, "receptor and sensor depths are 1 um to 20 mm"),
    "grid_spacing": (1e-7, 10e-3, "grid spacings are 0.1 um to 10 mm"),
    "spacing": (1e-7, 10e-3, "grid spacings are 0.1 um to 10 mm"),
    "young_modulus": (1e3, 1e9, "skin and sensor moduli are 1 kPa to 1 GPa"),
    "watchdog": (0.0, 1.0, "display watchdogs are at most 1 s"),
    "pitch": (1e-6, 0.2, "grating pitches are 1 um to 200 mm"),
    "amplitude": (0.0, 20e-3, "stimulus amplitudes are at most 20 mm"),
    "finger_radius": (0.1e-3, 1.0, "finger and indenter radii are 0.1 mm to 1 m"),
}

_UNIT_SUFFIX = re.compile(r"_(m|pa|s|n|hz|m_per_s|n_per_m)$")


class PlausibilityWarning(UserWarning):
    """A value converts cleanly but lies far outside the range of skin and tactile displays."""


def base_quantity(name: str) -> str:
    """Reduce an edge name to its quantity: ``'--grid-spacing'`` -> ``'grid_spacing'``,
    ``'sensors.depth_m'`` -> ``'depth'``, ``'procedure.tracks[0].start'`` -> ``'start'``."""
    last = name.lstrip("-").replace("-", "_").split(".")[-1]
    last = re.sub(r"\[\d+\]$", "", last)
    return _UNIT_SUFFIX.sub("", last.lower())


def check_plausible(value: float, name: str, unit: str = "(SI)", *, stacklevel: int | None = None) -> None:
    """Warn (:class:`PlausibilityWarning`) if ``value`` (SI) is outside the usual range of ``name``.

    Parameters
    ----------
    value : float
        The value in SI units.
    name : str
        The option or field name as written at the edge; quantities without a usual range pass.
    unit : str
        The SI unit of ``value``, for the message.
    stacklevel : int, optional
        The caller's ``stacklevel`` for :func:`warnings.warn` (1: the caller's line); default:
        the caller's caller (a unit parser's user).
    """
    entry = PLAUSIBLE.get(base_quantity(name))
    if entry is None:
        return
    low, high, usual = entry
    if not low <= abs(value) <= high:
        warnings.warn(
            f"{name} = {value:g} {unit} is outside the usual range ({usual}); check its unit",
            PlausibilityWarning, stacklevel=3 if stacklevel is None else stacklevel + 1,
        )


def check_plausible_at_entry(value: float, name: str, unit: str, *, stacklevel: int) -> None:
    """:func:`check_plausible` for a Python entry point (``HalfSpace.strain``, ``HertzContact``).

    Warns only when the call comes from outside tactilab (a user's script): tactilab's own
    callers have checked the value at their edge (an option or a file field), under its name
    there, so the user sees one warning, not two.

    Parameters
    ----------
    value, name, unit
        As :func:`check_plausible`.
    stacklevel : int
        Frames from the caller of this function to the user's line (1: the caller's line).
    """
    frame = sys._getframe(stacklevel)
    if str(frame.f_globals.get("__name__", "")).startswith("tactilab."):
        return
    check_plausible(value, name, unit, stacklevel=stacklevel + 1)


#: Largest strain magnitude a linear-elastic (small-strain) answer may reach before it is flagged.
SMALL_STRAIN_LIMIT = 0.1


def check_small_strain(largest: float, where: str, *, stacklevel: int = 2) -> None:
    """Warn (:class:`PlausibilityWarning`) if a linear-elastic answer leaves the small-strain range.

    Linear elasticity holds for strains well below 0.1; above it the answer is outside the
    model (and usually a unit mistake in the load or the modulus). The ``tactilab`` command's
    ``--strict`` option turns the warning into an error.

    Parameters
    ----------
    largest : float
        The largest strain magnitude of the answer (dimensionless; a principal strain or a
        lower bound of it, such as the largest ``|eps_ij|``). NaN is flagged too.
    where : str
        What was computed, for the message (``"HalfSpace.strain"``, ``"tactilab stress"``).
    stacklevel : int
        Passed to :func:`warnings.warn` (the caller's line).
    """
    if not largest <= SMALL_STRAIN_LIMIT:  # NaN included
        warnings.warn(
            f"{where}: the largest strain is {largest:.3g} ({largest * 100:.3g} %), above the small-strain "
            f"limit {SMALL_STRAIN_LIMIT:g} of linear elasticity, so the answer is outside the model; lower the "
            "load or check the Young's modulus and its unit (skin is about 0.1 to 10 MPa)",
            PlausibilityWarning, stacklevel=stacklevel + 1,
        )

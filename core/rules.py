"""Input rules: one function per quantity, one message style, used by every part of tactilab.

This module names no touch concept: it knows lengths, moduli, ratios, arrays and tensor
components, not skin or sensors. Records, the solver, the inversion and the command line all
check their arguments here, so a rule cannot drift between them (``tests/test_rules.py`` runs
one table of good and bad values against every public entry point). Each error names the
argument, the rule, the value it got and the fix::

    depth: every depth must be finite and > 0 m (z points into the skin), got -0.001 at
    index 0; give depths below the surface as positive values in m, e.g. 1.25e-3

Rules
-----
- components: Voigt names ``xx, yy, zz, yz, zx, xy`` (:data:`COMPONENTS`, the one copy of
  the order); the aliases ``xz``, ``zy``, ``yx`` (:data:`COMPONENT_ALIASES`) are accepted
  everywhere and mean the same tensor entry; ``None`` means all six.
- depth(s): finite and > 0 m (z points into the skin).
- Poisson's ratio: in (-1, 0.5], the thermodynamic bounds of an isotropic solid (0.5 is
  incompressible and exact).
- Young's modulus: finite and > 0 Pa.
- grid spacing: finite and > 0 m, x first.
- any other positive length, force or rate: :func:`positive`; any finite number: :func:`finite`.
- arrays: :func:`finite_array` (no NaN or inf); dtypes: :func:`float_dtype`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

#: Voigt order of stress and strain components (tensor shear in the last three), docs/theory.md section 1
COMPONENTS = ("xx", "yy", "zz", "yz", "zx", "xy")
#: Poisson's ratio of an isotropic solid lies in (low, high]: the thermodynamic bounds (0.5 = incompressible)
POISSON_RATIO_BOUNDS = (-1.0, 0.5)
#: alternative spellings of the symmetric shear entries (alias -> Voigt name)
COMPONENT_ALIASES = {"xz": "zx", "zy": "yz", "yx": "xy"}

__all__ = [
    "COMPONENTS",
    "COMPONENT_ALIASES",
    "POISSON_RATIO_BOUNDS",
    "components",
    "depth",
    "depths",
    "finite",
    "finite_array",
    "float_dtype",
    "fraction",
    "poisson_ratio",
    "positive",
    "show",
    "spacing",
    "young_modulus",
]


def show(value) -> str:
    """repr for messages: numpy scalars as plain numbers ('nan', not 'np.float64(nan)')."""
    return repr(value.item()) if isinstance(value, np.generic) else repr(value)


def _number(value, name: str, what: str, fix: str) -> float:
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name}: {what}, got {value!r}; {fix}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: {what}, got {show(value)}; {fix}") from None


#: an example value per SI unit: (at a Python entry point, in SI; at a command-line option, with its suffix)
_EXAMPLE = {"m": ("1.25e-3", "1.25mm"), "Pa": ("1.5e6", "1.5MPa"), "N": ("0.8", "0.8N"), "s": ("5e-3", "5ms"),
            "Hz": ("100", "100Hz"), "m/s": ("0.02", "20mm/s"), "N/m": ("5e3", "5N/mm")}


def _say_unit(name: str, unit: str) -> str:
    """How to give a value of ``unit``: in SI at a Python entry point, with a unit suffix at a command-line
    option (a name that starts with ``--``), so the fix never names a unit the caller cannot type."""
    python, option = _EXAMPLE.get(unit, (None, None))
    if name.startswith("--"):
        return f"with a unit, e.g. {option}" if option else "with its unit"
    return f"in {unit}, e.g. {python}" if python else f"in {unit}"


def positive(value, name: str, unit: str = "m", fix: str = "") -> float:
    """A finite number > 0 (a length, force, modulus, rate ...), returned as float.

    Parameters
    ----------
    value : float
        The value to check.
    name : str
        The argument's name, as the caller spells it.
    unit : str
        Its SI unit, for the message ("1" for dimensionless: no unit named).
    fix : str
        How to fix a bad value; default "give a finite value > 0 in <unit>".

    Raises
    ------
    ValueError
        ``"<name>: must be finite and > 0 <unit>, got <value>; <fix>"``.
    """
    in_unit = "" if unit == "1" else f" {unit}"  # "1": dimensionless, no unit to name
    fix = fix or "give a finite value > 0" + (f" {_say_unit(name, unit)}" if in_unit else "")
    v = _number(value, name, f"must be finite and > 0{in_unit}", fix)
    if not math.isfinite(v) or v <= 0:
        raise ValueError(f"{name}: must be finite and > 0{in_unit}, got {show(value)}; {fix}")
    return v


def finite(value, name: str, unit: str = "1") -> float:
    """A finite number (no NaN or inf), returned as float; ``unit`` is its SI unit ("1": none), for the message."""
    fix = "give a finite number" + (f" {_say_unit(name, unit)}" if unit != "1" else "")
    v = _number(value, name, "must be finite", fix)
    if not math.isfinite(v):
        raise ValueError(f"{name}: must be finite, got {show(value)}; {fix}")
    return v


def young_modulus(value, name: str = "young_modulus") -> float:
    """Young's modulus: finite and > 0 Pa."""
    fix = (f"give E {_say_unit(name, 'Pa')}"
           + (" (skin is about 0.1 to 4 MPa)" if name.startswith("--") else " (skin is about 1e5 to 4e6 Pa)"))
    v = _number(value, name, "Young's modulus must be finite and > 0 Pa", fix)
    if not math.isfinite(v) or v <= 0:
        raise ValueError(f"{name}: Young's modulus must be finite and > 0 Pa, got {show(value)}; {fix}")
    return v


def poisson_ratio(value, name: str = "nu") -> float:
    """Poisson's ratio: in (-1, 0.5]; 0.5 (incompressible) is exact."""
    rule = "Poisson's ratio must lie in (-1, 0.5] (0.5 = incompressible)"
    fix = "skin is close to 0.5"
    v = _number(value, name, rule, fix)
    low, high = POISSON_RATIO_BOUNDS
    if not math.isfinite(v) or not low < v <= high:
        raise ValueError(f"{name}: {rule}, got {show(value)}; {fix}")
    return v


def depths(value, name: str = "depth") -> np.ndarray:
    """One depth or a non-empty 1-D sequence of depths, each finite and > 0 m.

    Returns
    -------
    ndarray, shape (n_depth,), m
    """
    try:
        d = np.atleast_1d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected one depth or a 1-D sequence of depths in m, got {value!r}; "
                         "give numbers in metres") from None
    if d.ndim != 1 or d.size == 0:
        raise ValueError(f"{name}: expected one depth or a non-empty 1-D sequence of depths in m, got shape {d.shape}; "
                         "give e.g. 1e-3 or [1e-3, 2e-3]")
    bad = ~np.isfinite(d) | (d <= 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name}: every depth must be finite and > 0 m (z points into the skin), got {show(d[i])} "
                         f"at index {i}; give depths below the surface as positive values {_say_unit(name, 'm')}")
    return d


def depth(value, name: str = "depth") -> float:
    """A single depth, finite and > 0 m."""
    if np.ndim(value) != 0:
        raise ValueError(f"{name}: expected one depth in m, got shape {np.shape(value)}; give a single number")
    return float(depths(value, name)[0])


def components(value: Sequence[str] | str | None, name: str = "components") -> tuple[str, ...]:
    """Stress or strain components: Voigt names, aliases accepted; a string is one name; None means all six.

    Returns
    -------
    tuple of str
        Canonical names from ``COMPONENTS`` (``xz`` -> ``zx``, ``zy`` -> ``yz``, ``yx`` -> ``xy``),
        in the order given.
    """
    if value is None:
        return COMPONENTS
    if isinstance(value, str):
        value = (value,)
    try:
        names = tuple(value)
    except TypeError:
        raise ValueError(f"{name}: expected a sequence of names from {COMPONENTS}, got {value!r}; "
                         "e.g. ('zz', 'zx')") from None
    if not names:
        raise ValueError(f"{name}: empty selection; pick names from {COMPONENTS}")
    canonical = []
    for comp in names:
        if not isinstance(comp, str) or COMPONENT_ALIASES.get(comp, comp) not in COMPONENTS:
            raise ValueError(f"{name}: unknown component {comp!r}; valid names are {COMPONENTS} "
                             f"(Voigt order; the aliases {tuple(COMPONENT_ALIASES)} are accepted)")
        canonical.append(COMPONENT_ALIASES.get(comp, comp))
    if len(set(canonical)) != len(canonical):
        raise ValueError(f"{name}: names repeat in {names!r} (aliases count as their Voigt name); "
                         "give each component once")
    return tuple(canonical)


def spacing(value, ndim: int, name: str = "spacing") -> tuple[float, ...]:
    """Grid spacing, x first: one value (dx = dy) or ``ndim`` values, each finite and > 0 m."""
    try:
        values = np.atleast_1d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        values = np.array([np.nan])
    if values.ndim == 1 and values.size == 1:
        values = np.repeat(values, ndim)
    if values.ndim != 1 or values.size != ndim:
        raise ValueError(
            f"{name}: expected one value or {ndim} values (dx{', dy' if ndim == 2 else ''}) in m, "
            f"got {np.size(value)}: {value!r}; give the grid spacing x first")
    if not np.all(np.isfinite(values)) or np.any(values <= 0):
        raise ValueError(f"{name}: grid spacing must be finite and > 0 m, got {value!r}; give it "
                         f"{_say_unit(name, 'm')}")
    return tuple(float(v) for v in values)


def finite_array(value, name: str, unit: str) -> np.ndarray:
    """A real float array with no NaN or inf; the error names the first bad index."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected real numbers in {unit}, got {type(value).__name__}") from None
    bad = ~np.isfinite(arr)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0]) if arr.ndim else ()
        raise ValueError(f"{name}: must be finite (no NaN or inf) in {unit}, got {show(arr[idx])} at index "
                         f"{idx if arr.ndim != 1 else idx[0]}; drop or fill the bad values first")
    return arr


def float_dtype(value, name: str = "dtype") -> np.dtype:
    """float32 or float64."""
    try:
        dt = np.dtype(value)
    except TypeError:
        raise ValueError(f"{name}: expected float32 or float64, got {value!r}") from None
    if dt not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ValueError(f"{name}: expected float32 or float64, got {dt}; use float64 for tolerances below 1e-6")
    return dt


def fraction(value, name: str, fix: str = "") -> float:
    """A finite number in [0, 1] (a share of frames, trials, samples), returned as float.

    Raises
    ------
    ValueError
        ``"<name>: must be a fraction in [0, 1], got <value>; <fix>"`` (NaN and inf included).
    """
    fix = fix or "give a number from 0 to 1, e.g. 0.01 for 1 %"
    v = _number(value, name, "must be a fraction in [0, 1]", fix)
    if not 0.0 <= v <= 1.0:  # also refuses NaN
        raise ValueError(f"{name}: must be a fraction in [0, 1], got {show(value)}; {fix}")
    return v


def workers(value, name: str = "workers") -> int:
    """A count of threads (FFT workers, frames solved side by side): a positive integer.

    Raises
    ------
    ValueError
        ``"<name>: threads must be a positive integer, got <value>; e.g. 1 or 2"`` (booleans,
        floats, zero and negatives included).
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name}: threads must be a positive integer, got {value!r}; e.g. 1 or 2 "
                         "(this machine's cores: os.cpu_count())")
    return int(value)

"""Receptor-hypothesis strings: which strain components receptors read, and at which depths.

A receptor hypothesis names the strain readouts of a population of receptors. Protocol files,
the command line and :class:`tactilab.forward.ReceptorHypothesis` share one grammar::

    components@depths[:shear][;noise=VALUE]

- ``components``: comma-separated names. Linear: ``xx, yy, zz, yz, zx, xy`` (Voigt strain
  components; the aliases ``xz``, ``zy``, ``yx`` name ``zx``, ``yz``, ``xy``) and ``volumetric``
  (the trace ``eps_xx + eps_yy + eps_zz``). Nonlinear invariants: ``max_shear``, ``von_mises``,
  ``octahedral``, ``deviatoric_norm``.
- ``depths``: comma-separated lengths with units (``1mm``, ``1.25mm``, ``500um``); a bare number
  is in metres. Each depth must be finite and > 0.
- ``shear`` (optional): ``tensor`` (default; shear read as ``eps_ij``) or ``engineering``
  (shear read as ``gamma_ij = 2 eps_ij``).
- ``noise`` (optional): the standard deviation of one reading, in the readout's units
  (dimensionless strain), finite and > 0.

Examples: ``"zx@1mm"``, ``"xx,zx@1mm,2mm"``, ``"max_shear@1.25mm:engineering"``,
``"xx,zx@1.25mm;noise=0.001"``.
"""

from __future__ import annotations

import math
from decimal import Decimal
from typing import NamedTuple

from tactilab.core.rules import COMPONENT_ALIASES, COMPONENTS

from .units import to_si

#: linear readouts: Voigt strain components (the one order, from tactilab.core.rules) and the volumetric strain
LINEAR_COMPONENTS = (*COMPONENTS, "volumetric")
#: nonlinear strain invariants
NONLINEAR_COMPONENTS = ("max_shear", "von_mises", "octahedral", "deviatoric_norm")
#: every readout name, canonical spelling
RECEPTOR_COMPONENTS = LINEAR_COMPONENTS + NONLINEAR_COMPONENTS
SHEAR_CONVENTIONS = ("tensor", "engineering")


class HypothesisSpec(NamedTuple):
    """The pieces of a receptor-hypothesis string, in SI.

    Attributes
    ----------
    components : tuple of str
        Canonical component names (aliases resolved), in the order given.
    depths_m : tuple of float
        Receptor depths, m.
    shear : {"tensor", "engineering"}
        Shear convention of the readouts.
    noise_std : float or None
        Noise standard deviation of one reading (readout units), or None when not given.
    """

    components: tuple[str, ...]
    depths_m: tuple[float, ...]
    shear: str
    noise_std: float | None


def _show(value: object) -> str:
    """repr for messages, numpy scalars as plain numbers."""
    item = getattr(value, "item", None)
    return repr(item()) if callable(item) and getattr(value, "ndim", 1) == 0 else repr(value)


def check_component(name: object) -> str:
    """Return the canonical name of one readout component, or raise naming the choices."""
    if not isinstance(name, str):
        raise ValueError(f"components: each component must be a string, got {name!r}; "
                         f"use one of {', '.join(RECEPTOR_COMPONENTS)}")
    key = name.strip()
    key = COMPONENT_ALIASES.get(key, key)
    if key not in RECEPTOR_COMPONENTS:
        raise ValueError(f"components: unknown component {name!r}; use one of {', '.join(RECEPTOR_COMPONENTS)} "
                         f"(aliases {', '.join(COMPONENT_ALIASES)})")
    return key


def check_components(names) -> tuple[str, ...]:
    """Canonical, distinct component names from a sequence (at least one)."""
    if isinstance(names, str):
        names = (names,)
    out = tuple(check_component(n) for n in names)
    if not out:
        raise ValueError("components: give at least one component, e.g. ('xx', 'zx')")
    if len(set(out)) != len(out):
        raise ValueError(f"components: each component may appear once (aliases count as the same), got {tuple(names)!r}")
    return out


def check_depth(value: object, name: str = "depths") -> float:
    """A receptor depth in m: finite and > 0."""
    try:
        d = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a depth in m, got {value!r}") from None
    if not math.isfinite(d) or d <= 0:
        raise ValueError(f"{name}: a receptor depth must be finite and > 0 m, got {_show(value)}; "
                         "receptors sit 0.5 to 3 mm deep, e.g. 1.25e-3")
    return d


def check_noise(value: object) -> float | None:
    """A noise standard deviation (readout units): None, or finite and > 0."""
    if value is None:
        return None
    try:
        s = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"noise_std: expected a number (strain per reading) or None, got {value!r}") from None
    if not math.isfinite(s) or s <= 0:
        raise ValueError(f"noise_std: must be finite and > 0 (strain per reading), got {_show(value)}; "
                         "give e.g. 1e-3, or None for no noise model")
    return s


def parse_hypothesis(text: str) -> HypothesisSpec:
    """Check a receptor-hypothesis string and return its pieces in SI.

    Parameters
    ----------
    text : str
        ``components@depths[:shear][;noise=VALUE]``, e.g. ``"xx,zx@1mm,2mm:engineering"``.

    Returns
    -------
    HypothesisSpec
        Components (canonical names), depths in m, shear convention, noise (or None).

    Raises
    ------
    ValueError
        Naming the piece that is wrong (missing ``@``, unknown component, bad depth or unit,
        unknown shear convention, bad noise) and how to write it.
    """
    if not isinstance(text, str):
        raise ValueError(f"hypothesis: expected a string like 'xx,zx@1.25mm', got {type(text).__name__}")
    example = "write components@depths[:shear], e.g. 'xx,zx@1.25mm' or 'max_shear@1mm,2mm:engineering'"
    body, sep, extra = text.partition(";")
    noise = None
    if sep:
        key, eq, value = extra.partition("=")
        if key.strip() != "noise" or not eq or not value.strip():
            raise ValueError(f"hypothesis: after ';' expected 'noise=VALUE', got {extra!r} in {text!r}; {example}")
        try:
            number = float(value)
        except ValueError:
            raise ValueError(f"hypothesis: noise must be a number (strain per reading), got {value!r} in {text!r}") from None
        noise = check_noise(number)
    if body.count("@") != 1:
        raise ValueError(f"hypothesis: expected exactly one '@' between components and depths, got {text!r}; {example}")
    comp_text, _, rest = body.partition("@")
    depth_text, colon, shear = rest.partition(":")
    shear = shear.strip() if colon else "tensor"
    if shear not in SHEAR_CONVENTIONS:
        raise ValueError(f"hypothesis: unknown shear convention {shear!r} in {text!r}; use 'tensor' or 'engineering'")
    names = [c.strip() for c in comp_text.split(",")]
    if not comp_text.strip() or any(not c for c in names):
        raise ValueError(f"hypothesis: empty component name in {text!r}; {example}")
    components = check_components(names)
    pieces = [d.strip() for d in depth_text.split(",")]
    if not depth_text.strip() or any(not d for d in pieces):
        raise ValueError(f"hypothesis: empty depth in {text!r}; give lengths with units, e.g. '1mm,2mm'")
    depths = tuple(check_depth(to_si(d, "length", name="hypothesis depth"), "hypothesis depth") for d in pieces)
    return HypothesisSpec(components, depths, shear, noise)


def format_depth(depth_m: float) -> str:
    """A depth (m) as a length string that :func:`parse_hypothesis` reads back exactly (``1.25mm``)."""
    d = float(depth_m)
    mm = (Decimal(repr(d)) * 1000).normalize()
    text = f"{mm:f}mm"
    if to_si(text, "length") == d:
        return text
    return f"{d!r}m"


def format_hypothesis(components, depths_m, shear: str = "tensor", noise_std: float | None = None) -> str:
    """The canonical string of a hypothesis; ``parse_hypothesis`` of it gives the same pieces back."""
    text = ",".join(components) + "@" + ",".join(format_depth(d) for d in depths_m)
    if shear != "tensor":
        text += f":{shear}"
    if noise_std is not None:
        text += f";noise={float(noise_std)!r}"
    return text

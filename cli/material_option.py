"""``--material FILE``: the skin material of a command, from a TOML or JSON file (edge handling only).

The file holds a ``[material]`` table (or is one): ``model = "elastic" | "prony" | "sls"``, the
moduli with units, Prony terms such as ``terms = [["1MPa", "70ms"]]``, or a ``layers`` list on a
``base`` (see ``tactilab.data_schemas.SkinMaterial``). It replaces ``--young-modulus`` and
``--nu``; giving both is an error, so a run never silently uses one and ignores the other.
"""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = ("skin material file (.toml with a [material] table, or .json): model elastic, prony or sls, or layers "
        "on a base; replaces --young-modulus and --nu (giving both is an error)")


def add_material_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--material FILE`` to a command's parser."""
    parser.add_argument("--material", type=Path, default=None, help=HELP)


def read_material_option(args: argparse.Namespace, replaces: tuple[str, ...] = ("young_modulus", "nu")):
    """The ``SkinMaterial`` of ``--material``, or None without it.

    Raises
    ------
    ValueError
        When an option it replaces was given too, or the file is not a valid material.
    """
    if getattr(args, "material", None) is None:
        return None
    given = ["--" + name.replace("_", "-") for name in replaces if getattr(args, name, None) is not None]
    if given:
        raise ValueError(f"--material: the material file sets the skin's moduli and Poisson's ratio, but "
                         f"{' and '.join(given)} {'was' if len(given) == 1 else 'were'} given too; drop "
                         f"{' and '.join(given)}, or drop --material")
    from tactilab.data_schemas import read_material

    return read_material(args.material)


#: the ``--time`` keyword for the relaxed state (a load held for ever)
RELAXED = "relaxed"


def read_time_option(text: str | None, name: str = "--time") -> float | None:
    """``--time`` in s: a time with a unit (``70ms``, >= 0) or ``relaxed`` (``inf``); None when not given.

    Raises
    ------
    ValueError
        For a bare number, a wrong unit, a negative or non-finite time.
    """
    if text is None:
        return None
    if str(text).strip().lower() == RELAXED:
        return float("inf")
    from tactilab.data_schemas.units import to_si

    value = to_si(text, "time", name=name)
    if not value >= 0:
        raise ValueError(f"{name}: must be >= 0 (0 is the instant the load is applied), got {text!r}; e.g. 70ms, "
                         f"or {RELAXED} for a load held until the skin has relaxed")
    return value


def describe_material(material) -> str:
    """One line for the run report: the model and its constants, in kPa and ms."""
    nu = f"nu = {material.poisson_ratio:g}"
    if material.layers:
        stack = ", ".join(f"{layer.thickness_m * 1e3:g} mm of {'relaxed ' if layer.terms else ''}E = "
                          f"{layer.young_modulus_pa / 1e3:g} kPa" + _terms(layer.terms) for layer in material.layers)
        base = material.base
        on = "a rigid base" if base is None or base == "rigid" else \
            f"a half-space of E = {base.young_modulus_pa / 1e3:g} kPa, nu = {base.poisson_ratio:g}"
        return f"layered skin: {stack} on {on}"
    if material.model == "elastic":
        return f"E = {material.young_modulus_pa / 1e3:g} kPa, {nu}"
    terms = ", ".join(f"{e / 1e3:g} kPa at {t * 1e3:g} ms" for e, t in material.prony_terms)
    return f"viscoelastic skin ({material.model}): relaxed E = {material.young_modulus_pa / 1e3:g} kPa, terms {terms}; {nu}"


def _terms(terms) -> str:
    """A viscoelastic layer's Prony terms for the report, in kPa and ms ('' for an elastic layer)."""
    if not terms:
        return ""
    return " (terms " + ", ".join(f"{t.modulus_pa / 1e3:g} kPa at {t.relaxation_time_s * 1e3:g} ms" for t in terms) + ")"

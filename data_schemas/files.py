"""Files at the edge: TOML scene files, JSON records and the built-in examples.

Quantities in files may carry units (``depth = "1.25mm"``, ``young_modulus_kpa = 200``; see
:mod:`.unit_keys`); they are converted to SI once, here. Errors come as ONE line that names the
file, the table and key, the rule, the value and the fix (a ``ValueError``; a missing file is an
``OSError``).

Built-in examples (package data in ``data_schemas/examples/``):

``fingertip_defect``  a fingertip (0.8 N, radius 10 mm, E = 1 MPa, nu = 0.5) sliding at
                      20 mm/s over one 50 um bump, sensed by 10 x 10 stress sensors at 3 mm.
``sliding_grating``   a frictionless finger sliding at 20 mm/s over a 2 mm sinusoidal grating,
                      sensed by a line of strain sensors at 1 mm (docs/theory.md 4a).
``tractor_display``   a STReSS2-like 6 x 10 tractor display rendering a virtual grating,
                      sensed by a line of strain sensors at 1 mm.
"""

from __future__ import annotations

import errno
import importlib.resources
import pathlib
import tomllib

from .base import R, record_from_dict
from .material import SkinMaterial
from .scene import Scene

_EXAMPLES_PACKAGE = "tactilab.data_schemas"
_EXAMPLES_DIR = "examples"


def read_toml_record(path: str | pathlib.Path, model: type[R], *, table: str | None = None) -> R:
    """Read one record from a TOML file, converting unit-suffixed quantities to SI once.

    Parameters
    ----------
    path : str or Path
        The TOML file.
    model : type of Record
        The record to build (``Scene``, ``SensorArray``, ``DisplayDescription``, ...).
    table : str, optional
        Dotted name of the table holding the record (``"sensors"``); default the whole file.

    Raises
    ------
    OSError
        If the file cannot be read.
    ValueError
        Invalid TOML, a missing table, an unknown unit or an invalid field, in one line.
    """
    path = pathlib.Path(path)
    text = path.read_text(encoding="utf-8")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path}: not valid TOML ({err}); fix the syntax") from None
    where = str(path)
    if table:
        for part in table.split("."):
            if not isinstance(data, dict) or part not in data:
                raise ValueError(f"{path}: table [{table}] is missing; add it or name another table")
            data = data[part]
        where = f"{path} [{table}]"
    return record_from_dict(model, data, where, context={"folder": path.parent})


def read_json_record(path: str | pathlib.Path, model: type[R]) -> R:
    """Read one record from a JSON file (SI, or with unit suffixes as in TOML files)."""
    return model.load(path)


def load_scene(path: str | pathlib.Path) -> Scene:
    """Load a :class:`~.scene.Scene` from a ``.toml`` scene file or a ``.json`` record.

    See ``data_schemas/examples/*.toml`` for the layout: top-level ``name`` and
    ``description``, then tables ``[material]``, ``[surface]`` (with ``kind``), ``[contact]``,
    ``[sensors]`` (optionally ``[sensors.grid]``), ``[scan]`` and optionally ``[display]``.
    """
    path = pathlib.Path(path)
    if path.suffix.lower() not in (".toml", ".json"):
        raise ValueError(f"{path}: a scene file must end in .toml or .json, got {path.suffix!r}; "
                         "rename it or convert it")
    if not path.is_file():
        raise FileNotFoundError(errno.ENOENT, "scene file not found (check the path and the current folder)",
                                str(path))
    if path.suffix.lower() == ".json":
        return Scene.load(path)
    return read_toml_record(path, Scene)


def read_material(path: str | pathlib.Path) -> SkinMaterial:
    """Read a :class:`~.material.SkinMaterial` from a TOML file (its ``[material]`` table, or the whole
    file when it has none) or a JSON record, units converted to SI once.

    Raises
    ------
    OSError
        If the file cannot be read.
    ValueError
        A wrong suffix or an invalid material, in one line naming the file.
    """
    path = pathlib.Path(path)
    if path.suffix.lower() not in (".toml", ".json"):
        raise ValueError(f"{path}: a material file must end in .toml or .json, got {path.suffix!r}; write a "
                         "[material] table in a .toml file")
    if path.suffix.lower() == ".json":
        return SkinMaterial.load(path)
    try:
        has_table = "material" in tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path}: not valid TOML ({err}); fix the syntax") from None
    return read_toml_record(path, SkinMaterial, table="material" if has_table else None)


def list_examples() -> list[str]:
    """Names of the built-in example scenes (without the ``.toml`` extension)."""
    folder = importlib.resources.files(_EXAMPLES_PACKAGE) / _EXAMPLES_DIR
    return sorted(p.name.removesuffix(".toml") for p in folder.iterdir() if p.name.endswith(".toml"))


def example_path(name: str) -> pathlib.Path:
    """Path of the built-in example ``name`` (``"fingertip_defect"`` or ``"fingertip_defect.toml"``).

    Raises
    ------
    ValueError
        If there is no such example; the message lists the available ones.
    """
    stem = name.removesuffix(".toml")
    available = list_examples()
    if stem not in available:
        raise ValueError(f"example {name!r} does not exist; use one of {available}")
    resource = importlib.resources.files(_EXAMPLES_PACKAGE) / _EXAMPLES_DIR / f"{stem}.toml"
    return pathlib.Path(str(resource))


def load_example(name: str) -> Scene:
    """Load the built-in example scene ``name`` (see :func:`list_examples`)."""
    return load_scene(example_path(name))

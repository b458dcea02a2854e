"""Lazy public faces (PEP 562): a part's ``__init__`` names its exports; modules load on first use.

Every face of tactilab (``tactilab.core``, ``tactilab.forward``, ...) is built with :func:`attach`.

Keeping the faces lazy keeps ``tactilab --help`` fast: importing ``tactilab.inversion`` does not
load emcee, arviz or matplotlib until a name that needs them is used. The module names come from
the face's own constant table, never from data.
"""

from __future__ import annotations

import functools
import importlib
import json
import sys
import warnings
from collections.abc import Callable, Mapping
from importlib.metadata import distributions
from pathlib import Path
from urllib.parse import unquote, urlparse


class ShadowedInstallWarning(UserWarning):
    """A part of tactilab was imported from a folder other than the installed distribution's."""


@functools.lru_cache(maxsize=1)
def _installed() -> tuple[dict[str, Path], Path | None]:
    """Package files of the installed distribution: ``({"forward/__init__.py": path, ...}, editable_root)``."""
    # the first installed copy (dist-info with its files or an editable link); a source tree's own
    # tactilab.egg-info, seen when Python runs from the checkout, lists neither and is skipped
    for dist in distributions(name="tactilab"):
        files = {}
        for f in dist.files or ():
            parts = Path(f).parts
            if len(parts) >= 3 and parts[0] == "tactilab" and parts[-1] == "__init__.py":
                files["/".join(parts[1:])] = Path(dist.locate_file(f)).resolve()
        root = None
        try:
            info = json.loads(dist.read_text("direct_url.json") or "{}")
        except (OSError, ValueError):
            info = {}
        if info.get("dir_info", {}).get("editable") and str(info.get("url", "")).startswith("file:"):
            root = Path(unquote(urlparse(info["url"]).path)).resolve()  # package-dir: tactilab.X -> X
        if files or root is not None:
            return files, root
    return {}, None


def check_origin(package: str, file: str | None) -> bool:
    """Warn (:class:`ShadowedInstallWarning`) when face ``package`` was loaded from outside the installed tactilab.

    ``tactilab`` is a regular package (``toplevel/__init__.py``), so an installed wheel wins over a
    folder named ``tactilab`` without ``__init__.py`` (a clone) in the current directory. An
    editable install is found only after Python has searched the current directory, so there such
    a folder still loads first, and this check says so. Returns True when the origin matches the
    installation (or nothing is installed).
    """
    rel = "/".join([*package.split(".")[1:], "__init__.py"])  # tactilab.forward.halfspace -> forward/halfspace/...
    files, root = _installed()
    expected = files.get(rel) or (root / rel if root is not None else None)
    if expected is None or file is None:
        return True
    actual = Path(file).resolve()
    if actual == expected.resolve():
        return True
    warnings.warn(f"{package} was imported from {actual.parent}, not from the installed tactilab "
                  f"({expected.parent}): a folder named 'tactilab' in the current directory or earlier on sys.path "
                  "shadows the installed package; run Python from another folder, or install that checkout "
                  "with 'pip install -e .'", ShadowedInstallWarning, stacklevel=3)
    return False


def moved_name(package: str, name: str, new_home: str, removed_in: str) -> object:
    """Return ``name`` from the module ``new_home``, warning that ``package.name`` moved there.

    The :class:`DeprecationWarning` points at the caller's line and says where to import the
    name from now and in which release the old spelling goes.
    """
    warnings.warn(f"{package}.{name} moved to {new_home}; import it from there ('from {new_home} import {name}'): "
                  f"the old name goes in tactilab {removed_in}", DeprecationWarning, stacklevel=3)
    return getattr(importlib.import_module(new_home), name)


def attach(package: str, exports: Mapping[str, str], moved: Mapping[str, str] | None = None,
           removed_in: str = "0.2.0") -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """Return ``(__getattr__, __dir__)`` for the face of ``package``.

    Parameters
    ----------
    package : str
        The face's ``__name__``, e.g. ``"tactilab.forward"``.
    exports : mapping of str to str
        Public name -> submodule (relative to ``package``) that defines it.
    moved : mapping of str to str, optional
        Names that used to live here -> the module to import them from now (a face, e.g.
        ``"tactilab.core"``, or a module for a moved module's names). They still
        resolve, with a :class:`DeprecationWarning` (see :func:`moved_name`), and are left out of
        ``dir()``.
    removed_in : str
        The release that drops the ``moved`` names, for the warning.
    """

    check_origin(package, getattr(sys.modules.get(package), "__file__", None))
    moved = dict(moved or {})

    def __getattr__(name: str) -> object:
        if name in moved:  # not cached, so every use warns
            return moved_name(package, name, moved[name], removed_in)
        try:
            submodule = exports[name]
        except KeyError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(importlib.import_module(f"{package}.{submodule}"), name)
        setattr(sys.modules[package], name, value)  # cache: later look-ups skip __getattr__
        return value

    def __dir__() -> list[str]:
        return sorted(set(exports) | set(vars(sys.modules[package])))

    return __getattr__, __dir__

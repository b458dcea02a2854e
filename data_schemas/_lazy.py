"""Lazy public faces (PEP 562): a part's ``__init__`` names its exports; modules load on first use.

Keeping the faces lazy keeps ``tactilab --help`` fast: importing ``tactilab.inversion`` does not
load emcee, arviz or matplotlib until a name that needs them is used. The module names come from
the face's own constant table, never from data.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from importlib.metadata import PackageNotFoundError, version


def package_version() -> str:
    """The installed distribution's version (``"unknown"`` when run from an uninstalled tree)."""
    try:
        return version("tactilab")
    except PackageNotFoundError:
        return "unknown"


def attach(package: str, exports: Mapping[str, str]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """Return ``(__getattr__, __dir__)`` for the face of ``package``.

    Parameters
    ----------
    package : str
        The face's ``__name__``, e.g. ``"tactilab.forward"``.
    exports : mapping of str to str
        Public name -> submodule (relative to ``package``) that defines it.
    """

    def __getattr__(name: str) -> object:
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

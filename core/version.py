"""The installed distribution's version, defined once for every face and every record."""

from __future__ import annotations

import functools
from importlib import metadata

__all__ = ["package_version"]


@functools.cache
def package_version() -> str:
    """The installed tactilab version, e.g. ``"0.1.0"``.

    Returns ``"0+unknown"`` (a valid PEP 440 version, so tools that parse it do not fail) when
    Python runs a source tree that was never installed.
    """
    try:
        return metadata.version("tactilab")
    except metadata.PackageNotFoundError:
        return "0+unknown"

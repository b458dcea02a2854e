"""Moved to the ground floor: the batch engine is :mod:`tactilab.core.batch_cluster` (import from :mod:`tactilab.core`).

Every name still resolves here, with a :class:`DeprecationWarning`, until tactilab 0.2.0.
"""

import importlib

from tactilab.core.faces import moved_name


def __getattr__(name: str) -> object:
    """Forward ``name`` to :mod:`tactilab.core.batch_cluster`, warning that it moved."""
    if name.startswith("__") or not hasattr(importlib.import_module("tactilab.core.batch_cluster"), name):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return moved_name(__name__, name, "tactilab.core.batch_cluster", "0.2.0")

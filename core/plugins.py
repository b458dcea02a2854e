"""Plug-ins are code that an installed distribution declares, never a file beside the data.

``importlib.metadata.entry_points`` reads every ``*.dist-info`` folder on ``sys.path``, and
``python -m`` puts the current folder first on ``sys.path``: a ``*.dist-info`` left beside a
protocol or a session (a downloaded folder, say) would then declare code that tactilab runs.
:func:`installed_entry_point` is the one place every registry loads an entry point from; it
skips distributions that live in the current folder (or in a ``sys.path`` entry that means it,
such as ``''``), so only distributions installed elsewhere (site-packages, a ``PYTHONPATH``
folder the user set) declare plug-ins.
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

__all__ = ["installed_entry_point", "is_beside_the_data"]


def is_beside_the_data(location: str | Path) -> bool:
    """Whether ``location`` (a distribution's folder) is the current folder."""
    try:
        return Path(location).resolve() == Path.cwd().resolve()
    except OSError:  # an unreadable or vanished folder declares nothing
        return True


def installed_entry_point(group: str, name: str) -> metadata.EntryPoint | None:
    """The entry point ``name`` of ``group`` declared by an installed distribution, or None.

    Parameters
    ----------
    group : str
        The entry-point group (``"tactilab.devices"``, ``"tactilab.likelihoods"``).
    name : str
        The entry point's name (the one a protocol or a display spec names).

    Returns
    -------
    importlib.metadata.EntryPoint or None
        The first match on ``sys.path`` among distributions outside the current folder; a
        distribution found in the current folder is never consulted.
    """
    for dist in metadata.distributions():
        try:
            location = dist.locate_file("")
        except (AttributeError, NotImplementedError):  # a distribution that is not on a path
            continue
        if is_beside_the_data(location):
            continue
        for entry in dist.entry_points.select(group=group, name=name):
            return entry
    return None

"""Which display a session opens: a registry of device kinds (as xarray's backends are), and presets.

A display spec is ``"NAME"`` or ``"NAME://TARGET"``: ``"simulated"``, ``"udp://HOST:PORT"``.
``NAME`` is looked up here, never imported: the built-in kinds (``simulated``, ``udp``) are
registered below; a new kind is registered from Python with :func:`register_device`, or declared
by an installed distribution in the ``tactilab.devices`` entry-point group (name -> opener). Only
the entry point of that exact name is loaded, i.e. code an installed distribution declared, as
for the likelihood plug-ins of :mod:`tactilab.experiments.procedures`.

An opener is ``opener(spec, description, *, realtime, max_skipped_fraction) -> Display``: ``spec``
is the whole spec (the opener parses its target), ``description`` the
:class:`~tactilab.data_schemas.display.DisplayDescription`, ``realtime`` whether playback waits
for the frame clock, ``max_skipped_fraction`` the fraction of a stimulus's frames that may be
skipped as late before playback aborts (openers of displays without a network ignore it).
It returns a bare display; the runner adds the safety layer.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from tactilab.core import rules
from tactilab.core.plugins import installed_entry_point
from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import check_name

from .display import Display

__all__ = ["ENTRY_POINT_GROUP", "DEVICE_PRESETS", "register_device", "registered_devices", "open_display",
           "description_from_spec"]

#: Installed plug-ins declare device kinds in this entry-point group (name -> opener).
ENTRY_POINT_GROUP = "tactilab.devices"

#: display descriptions known by name (``--device braille-row``)
DEVICE_PRESETS = {"braille-row": DisplayDescription.braille_row, "stress2": DisplayDescription.stress2}

Opener = Callable[..., Display]
_DEVICES: dict[str, Opener] = {}


def register_device(name: str, opener: Opener, *, replace: bool = False) -> None:
    """Register a device kind: display specs ``name`` or ``name://TARGET`` open with ``opener``.

    Parameters
    ----------
    name : str
        1-64 lower-case letters, digits or '_' (the scheme of the spec).
    opener : callable
        ``opener(spec, description, *, realtime, max_skipped_fraction) -> Display`` (see the
        module docstring).
    replace : bool
        Allow replacing another opener registered under ``name``.

    Raises
    ------
    ValueError
        If the name breaks the rule or is taken (and ``replace`` is False), or ``opener`` is
        not callable.
    """
    check_name(name, "name", "device")
    if not callable(opener):
        raise ValueError(f"opener: must be callable opener(spec, description, *, realtime, max_skipped_fraction) "
                         f"-> Display, got {opener!r}")
    if not replace and _DEVICES.get(name, opener) is not opener:
        raise ValueError(f"name: device {name!r} is already registered; pass replace=True to replace it")
    _DEVICES[name] = opener


def registered_devices() -> list[str]:
    """Device kinds registered in this process (entry-point plug-ins load on first use)."""
    return sorted(_DEVICES)


def _opener(name: str) -> Opener:
    if name not in _DEVICES:
        entry = installed_entry_point(ENTRY_POINT_GROUP, name)  # never a *.dist-info in the current folder
        if entry is not None:
            register_device(name, entry.load())
    if name not in _DEVICES:
        raise ValueError(
            f"spec: device {name!r} is not registered (known: {registered_devices()}); register it with "
            f"tactilab.experiments.devices.register_device({name!r}, opener), or install a plug-in that "
            f"declares {name!r} in the {ENTRY_POINT_GROUP!r} entry-point group"
        )
    return _DEVICES[name]


def open_display(spec: str, description: DisplayDescription, *, realtime: bool = True,
                 max_skipped_fraction: float = 0.01) -> Display:
    """The bare display a spec names (``"simulated"``, ``"udp://HOST:PORT"``, a registered kind).

    Parameters
    ----------
    spec : str
        ``NAME`` or ``NAME://TARGET``; ``NAME`` is a registered device kind.
    description : DisplayDescription
        The device's description (geometry, limits, command).
    realtime : bool
        Whether playback waits for the frame clock (a simulated display may run faster).
    max_skipped_fraction : float
        For UDP, the fraction of a stimulus's frames that may be skipped as late before
        playback aborts (see :class:`~tactilab.experiments.devices.UdpDisplay`).

    Raises
    ------
    ValueError
        If ``spec`` is not a string, its name breaks the naming rule or is not registered,
        ``max_skipped_fraction`` is not a fraction in [0, 1] (NaN included), or the opener
        refuses the target.
    TypeError
        If the registered opener returns something other than a :class:`Display`.
    """
    if not isinstance(spec, str):
        raise ValueError(f"spec: must be a display spec such as 'simulated' or 'udp://HOST:PORT', got {spec!r}")
    name = spec.split("://", 1)[0]
    check_name(name, "spec", "device")
    max_skipped_fraction = rules.fraction(max_skipped_fraction, "max_skipped_fraction")  # every kind: never ignored
    display = _opener(name)(spec, description, realtime=realtime, max_skipped_fraction=max_skipped_fraction)
    if not isinstance(display, Display):
        raise TypeError(f"opener: the opener registered for {name!r} returned {type(display).__name__}, not a "
                        "tactilab.experiments.devices.Display; return a Display subclass instance")
    return display


def description_from_spec(spec: str) -> DisplayDescription:
    """A preset name (:data:`DEVICE_PRESETS`) or a JSON description file -> the description.

    Raises
    ------
    ValueError
        If ``spec`` is neither a preset nor an existing ``.json`` file.
    """
    if spec in DEVICE_PRESETS:
        return DEVICE_PRESETS[spec]()
    path = Path(spec)
    if path.suffix.lower() == ".json" and path.is_file():
        return DisplayDescription.load(path)
    raise ValueError(
        f"spec: must be one of {sorted(DEVICE_PRESETS)} or an existing .json display "
        f"description, got {spec!r}"
    )


def _open_simulated(spec: str, description: DisplayDescription, *, realtime: bool = True,
                    max_skipped_fraction: float = 0.01) -> Display:
    """``"simulated"``: a :class:`~.simulated_display.SimulatedDisplay` (no target; nothing is skipped)."""
    if spec != "simulated":
        raise ValueError(f"spec: the simulated display takes no target, got {spec!r}; use 'simulated'")
    from .simulated_display import SimulatedDisplay  # loads the forward model only when used

    return SimulatedDisplay(description, realtime=realtime)


def _open_udp(spec: str, description: DisplayDescription, *, realtime: bool = True,
              max_skipped_fraction: float = 0.01) -> Display:
    """``"udp://HOST:PORT"``: a :class:`~.udp.UdpDisplay` (always real time)."""
    from .udp import UdpDisplay

    return UdpDisplay.from_url(spec, description, max_skipped_fraction=max_skipped_fraction)


register_device("simulated", _open_simulated)
register_device("udp", _open_udp)

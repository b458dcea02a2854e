"""Build response sources and session paths from short text specs.

Errors name this module's parameters (``spec``, ``threshold``, ``strain``, ``folder``); the
command line maps them to its own flags (``cli/cmd_experiment.py``). Displays and device
descriptions come from the device registry (:func:`tactilab.experiments.devices.open_display`,
:func:`~tactilab.experiments.devices.description_from_spec`).

- responses: ``"terminal"`` or ``"simulated"``;
- session path: the first free ``sub-<subject>_ses-<NN>_task-<task>.sqlite`` in a folder.
"""

from __future__ import annotations

from pathlib import Path

from tactilab.data_schemas.experiment import Protocol

from ..devices import Display
from .responses import ResponseSource, SimulatedObserver, TerminalResponses


def responses_from_spec(spec: str, protocol: Protocol, **observer) -> ResponseSource:
    """``"terminal"`` or ``"simulated"`` (keywords go to :class:`SimulatedObserver`)."""
    if spec == "terminal":
        return TerminalResponses(protocol)
    if spec == "simulated":
        return SimulatedObserver(protocol, **observer)
    raise ValueError(f"spec: must be 'terminal' or 'simulated', got {spec!r}")


def make_responses(kind: str, protocol: Protocol, display: Display, *, threshold: str | float | None = None,
                   strain: str | None = None, recorded: dict | None = None) -> ResponseSource:
    """A response source from CLI-style options.

    Parameters
    ----------
    kind : {"terminal", "simulated"}
    protocol : Protocol
    display : Display
        The (bare) display of the session; a simulated observer feeling the display's strain
        needs a :class:`~tactilab.experiments.devices.SimulatedDisplay`.
    threshold : str or float, optional
        Strain felt at d' = 1 (dimensionless, > 0).
    strain : {"surface", "display"}, optional
        What the observer feels (default: recorded, else surface).
    recorded : dict, optional
        The observer configuration recorded with the session (resume); options override it.
    """
    if kind != "simulated":
        return responses_from_spec(kind, protocol)
    from tactilab.data_schemas.units import to_si

    config = dict(recorded or {})
    source = strain if strain is not None else config.pop("strain", "surface")
    config.pop("strain", None)
    if threshold is not None:
        value = to_si(threshold, "dimensionless", name="threshold")
        if value <= 0:
            raise ValueError(f"threshold: must be a strain > 0, got {threshold!r}; e.g. 2e-3")
        config["threshold_strain"] = value
    if source == "display":
        if not callable(getattr(display, "steady_drive", None)):
            raise ValueError("strain: 'display' needs a SimulatedDisplay (a display whose strain is computed); "
                             "use strain='surface' with a real display")
        config["display"] = display
    elif source == "contact":
        raise ValueError("strain: 'contact' is read through a receptor hypothesis; name one (the command line's "
                         "--observer, e.g. zx@1mm) and give the protocol a [finger] table")
    elif source != "surface":
        raise ValueError(
            f"strain: must be 'surface' or 'display', got {source!r}"
            + ("; the session's observer used a custom strain function: resume it from Python"
               if source == "custom" else "")
        )
    return responses_from_spec(kind, protocol, **config)


def next_session_path(folder: str | Path, subject: str, task: str) -> tuple[Path, str]:
    """The first free ``sub-<subject>_ses-<NN>_task-<task>.sqlite`` in ``folder``, and its label."""
    folder = Path(folder)
    for number in range(1, 1000):
        label = f"{number:02d}"
        path = folder / f"sub-{subject}_ses-{label}_task-{task}.sqlite"
        if not path.exists():
            return path, label
    raise ValueError(f"folder: {folder} already holds 999 sessions of sub-{subject}; use another folder")

"""Does the display play every stimulus a protocol plans as commanded? Checked before a session starts.

Every planned stimulus (each level of a procedure, the bounds of a staircase, each candidate of
an adaptive design, merged with ``[stimulus]`` as a trial merges them) is rendered for the
display (:func:`~tactilab.experiments.devices.render_drive`) and limited as the runner's safety
layer limits it (:func:`~tactilab.experiments.devices.limit_drive`). A stimulus the display
would clip, slew-limit or duty-limit is not the stimulus the protocol names: an observer would
feel another one, and a model fitted to the commanded one would be fitted to the wrong stimulus.

``clipped="refuse"`` (the default of a protocol) refuses the protocol, naming the first such
stimulus and the limit; ``"drop"`` leaves such stimuli out (levels of constant stimuli or psi,
candidates of an adaptive design; a staircase's bounds are refused, as it may command any level
between them) and counts them; ``"allow"`` lets the safety layer limit them at run time (a
safety test's choice, recorded as interventions).

:func:`design_display` is the model of what the display renders that an adaptive design predicts
from (a :class:`~tactilab.experiments.devices.SimulatedDisplay` of the session's description):
a session on a real display (UDP) gets one too, built from the description alone, so a resume
rebuilds the same model from the recorded description.
"""

from __future__ import annotations

import warnings

from tactilab.data_schemas.experiment import CLIPPED, check_clipped  # noqa: F401 - CLIPPED is this part's too

from ..devices import SimulatedDisplay, limit_drive, render_drive, resolve_command


def _label(stimulus) -> str:
    return (f"{stimulus.surface} amplitude {stimulus.amplitude_m * 1e6:.4g} um, pitch {stimulus.pitch_m * 1e3:.4g} mm, "
            f"speed {stimulus.speed_m_per_s * 1e3:.4g} mm/s")


def clipped_stimuli(protocol, description) -> list[tuple[str, dict]]:
    """``(where, intervention)`` for every planned stimulus the display would limit (first limit
    that acts: kind, limit, unit, requested and applied at the worst sample)."""
    return [(where, hit) for _, where, hit in _limited(protocol, description)]


def _limited(protocol, description) -> list[tuple[int, str, dict]]:
    """``(index in planned_fields, where, intervention)`` for each planned stimulus the display limits."""
    from tactilab.data_schemas.experiment import Stimulus

    out = []
    for i, (where, fields) in enumerate(protocol.procedure.planned_fields()):
        stimulus = Stimulus.model_validate({**protocol.stimulus.model_dump(), **fields})
        frames = render_drive(description, **stimulus.model_dump())
        _, interventions = limit_drive(frames, stimulus.frame_rate_hz, description)
        if interventions:
            out.append((i, f"{where} ({_label(stimulus)})", interventions[0]))
    return out


def drop_clipped(protocol, description):
    """The protocol without the planned stimuli the display would limit (``clipped="drop"``).

    Returns
    -------
    protocol : Protocol
        The protocol to run: the limited levels (or design candidates) removed, everything else
        as given.
    dropped : list of str
        Each dropped stimulus (where it is planned, the stimulus, the limit that acts), in plan order.

    Raises
    ------
    ValueError
        The procedure cannot drop planned stimuli (a staircase's bounds), or none would be left.
    """
    bad = _limited(protocol, description)
    if not bad:
        return protocol, []
    procedure = protocol.procedure.without_planned({i for i, _, _ in bad})
    kept = type(protocol).model_validate({**protocol.model_dump(), "procedure": procedure.model_dump()})
    return kept, [f"{where}: {hit['kind']} at {hit['limit']:.4g} {hit['unit']}" for _, where, hit in bad]


def check_display_limits(protocol, description, clipped: str = "refuse") -> int:
    """Refuse a protocol whose planned stimuli the display would limit (``clipped="refuse"``).

    Returns the number of planned stimuli the display limits (0 when refused nothing; under
    ``"drop"`` and ``"allow"`` nothing is refused, see :func:`drop_clipped` for dropping them).

    Raises
    ------
    ValueError
        ``clipped`` is not one of ``CLIPPED`` (refuse, drop, allow), or it is ``"refuse"`` and a planned stimulus
        would be limited: the message names the stimulus, the limit and the count.
    """
    check_clipped(clipped, "clipped")
    bad = clipped_stimuli(protocol, description)
    if bad and clipped == "refuse":
        where, hit = bad[0]
        raise ValueError(
            f"protocol: {where} exceeds the display's limits: {hit['kind']} at {hit['limit']:.4g} {hit['unit']} "
            f"(requested {abs(hit['requested']):.4g} {hit['unit']}); {len(bad)} of {len(protocol.procedure.planned_fields())} "
            "planned stimuli would be limited; lower the levels or candidates, or pick a display that plays them "
            "(clipped='drop' leaves them out; clipped='allow' lets the safety layer limit them, a safety test's choice)")
    return len(bad)


def plan_for_display(protocol, description, clipped: str | None = None):
    """The protocol a session runs on this display, and the record of what ``clipped`` did.

    Parameters
    ----------
    protocol : Protocol
        The protocol as loaded.
    description : DisplayDescription
        The display's limits.
    clipped : {"refuse", "drop", "allow"}, optional
        Overrides the protocol's ``clipped`` (a command-line option does).

    Returns
    -------
    protocol : Protocol
        The protocol to run (under ``"drop"``: without the stimuli the display would limit).
    record : dict
        ``policy``, ``n_planned`` (planned stimuli as loaded) and ``dropped`` (one line per
        dropped stimulus), for the session's metadata. A drop is also warned with its count.

    Raises
    ------
    ValueError
        As :func:`check_display_limits` and :func:`drop_clipped` raise.
    """
    clipped = protocol.clipped if clipped is None else clipped
    n_planned = len(protocol.procedure.planned_fields())
    check_display_limits(protocol, description, clipped)
    dropped: list[str] = []
    if clipped == "drop":
        protocol, dropped = drop_clipped(protocol, description)
        if dropped:
            warnings.warn(f"clipped='drop': dropped {len(dropped)} of {n_planned} planned stimuli the display would "
                          f"limit (first: {dropped[0]}); the session runs the other {n_planned - len(dropped)}",
                          UserWarning, stacklevel=4)
    return protocol, {"policy": clipped, "n_planned": n_planned, "dropped": dropped}



class RenderedStimuli:
    """What a session's display renders for a design candidate, limits included.

    A candidate is merged with the protocol's ``[stimulus]`` as a trial merges it (its
    ``fields`` replace those of ``base``), then rendered and limited by ``display``
    (:meth:`SimulatedDisplay.steady_drive`); ``strain`` is the display's. It is the ``display``
    of ``TransductionModel(source="display")`` for the design's hypotheses.

    Parameters
    ----------
    display : SimulatedDisplay
    base : Stimulus
        The protocol's ``[stimulus]``.
    fields : tuple of str
        The stimulus fields a candidate sets (surface, amplitude_m, pitch_m and its listed fields).
    """

    def __init__(self, display: SimulatedDisplay, base, fields: tuple[str, ...]) -> None:
        self.display, self.base, self.fields = display, base, tuple(fields)

    def played(self, stimulus):
        """The stimulus a trial plays for the candidate ``stimulus`` (validated, SI)."""
        return type(self.base).model_validate({**self.base.model_dump(),
                                               **{k: getattr(stimulus, k) for k in self.fields}})

    def steady_drive(self, stimulus):
        """The frames the display plays for the candidate between its ramps (Pa or m), shape (n, n_tractors)."""
        return self.display.steady_drive(self.played(stimulus))

    def strain(self, frames, depth_m: float):
        """``eps_xx, eps_xz`` under each row at ``depth_m`` (m), as :meth:`SimulatedDisplay.strain`."""
        return self.display.strain(frames, depth_m=depth_m)


def design_display(description, protocol):
    """The model of what the display renders for a protocol's design, from the description alone.

    It renders and limits each candidate as the runner does (merged with ``[stimulus]``; the
    default receptor depth and skin modulus of :func:`~tactilab.experiments.devices.render_drive`),
    so a design's predictions use the stimulus the display actually plays.

    Parameters
    ----------
    description : DisplayDescription
        The session's display (recorded in its metadata).
    protocol : Protocol

    Returns
    -------
    RenderedStimuli or None
        ``None`` for a display commanded in deflection: its strain needs the tractors'
        stiffness (Pa/m), which a description does not hold; designs then predict from the
        ideal surface.
    """
    if resolve_command(description) != "traction":
        return None
    fields = tuple(dict.fromkeys(("surface", "amplitude_m", "pitch_m",
                                  *getattr(protocol.procedure, "candidates", {}))))
    return RenderedStimuli(SimulatedDisplay(description, realtime=False), protocol.stimulus, fields)

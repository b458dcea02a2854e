"""Does the display play every stimulus a protocol plans as commanded? Checked before a session starts.

Every planned stimulus (each level of a procedure, the bounds of a staircase, each candidate of
an adaptive design, merged with ``[stimulus]`` as a trial merges them) is rendered for the
display (:func:`~tactilab.experiments.devices.render_drive`) and limited as the runner's safety
layer limits it (:func:`~tactilab.experiments.devices.limit_drive`). A stimulus the display
would clip, slew-limit or duty-limit is not the stimulus the protocol names: an observer would
feel another one, and a model fitted to the commanded one would be fitted to the wrong stimulus.

``clipped="refuse"`` (the default of a session) refuses the protocol, naming the first such
stimulus and the limit; ``"allow"`` lets the safety layer limit it at run time (a safety test's
choice, recorded as interventions).
"""

from __future__ import annotations

from ..devices import limit_drive, render_drive

CLIPPED = ("refuse", "allow")


def _label(stimulus) -> str:
    return (f"{stimulus.surface} amplitude {stimulus.amplitude_m * 1e6:.4g} um, pitch {stimulus.pitch_m * 1e3:.4g} mm, "
            f"speed {stimulus.speed_m_per_s * 1e3:.4g} mm/s")


def clipped_stimuli(protocol, description) -> list[tuple[str, dict]]:
    """``(where, intervention)`` for every planned stimulus the display would limit (first limit
    that acts: kind, limit, unit, requested and applied at the worst sample)."""
    out = []
    for where, fields in protocol.procedure.planned_fields():
        from tactilab.data_schemas.experiment import Stimulus

        stimulus = Stimulus.model_validate({**protocol.stimulus.model_dump(), **fields})
        frames = render_drive(description, **stimulus.model_dump())
        _, interventions = limit_drive(frames, stimulus.frame_rate_hz, description)
        if interventions:
            out.append((f"{where} ({_label(stimulus)})", interventions[0]))
    return out


def check_display_limits(protocol, description, clipped: str = "refuse") -> int:
    """Refuse a protocol whose planned stimuli the display would limit (``clipped="refuse"``).

    Returns the number of planned stimuli the display limits (0 when refused nothing).

    Raises
    ------
    ValueError
        ``clipped`` is not one of :data:`CLIPPED`, or it is ``"refuse"`` and a planned stimulus
        would be limited: the message names the stimulus, the limit and the count.
    """
    if clipped not in CLIPPED:
        raise ValueError(f"clipped: must be one of {CLIPPED}, got {clipped!r}")
    bad = clipped_stimuli(protocol, description)
    if bad and clipped == "refuse":
        where, hit = bad[0]
        raise ValueError(
            f"protocol: {where} exceeds the display's limits: {hit['kind']} at {hit['limit']:.4g} {hit['unit']} "
            f"(requested {abs(hit['requested']):.4g} {hit['unit']}); {len(bad)} of {len(protocol.procedure.planned_fields())} "
            "planned stimuli would be limited; lower the levels or candidates, or pick a display that plays them "
            "(clipped='allow' lets the safety layer limit them, a safety test's choice)")
    return len(bad)

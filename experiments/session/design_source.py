"""What a session's adaptive design predicts from: the display's rendering, the finger's contact, or the surface.

A model-discrimination design predicts each hypothesis's response from the strain of the stimulus
the subject feels (:func:`~tactilab.experiments.modelling.design.from_config`). A session picks the
source in this order, from its display's description and its protocol alone:

- ``"display"``: a display commanded in traction renders each candidate, limits included
  (:func:`~.display_check.design_display`; ``TransductionModel(source="display")``);
- ``"contact"``: otherwise, a protocol with a ``[finger]`` table (its gratings are physical,
  pressed by that finger) predicts through the solved contact of that finger (the design builds
  ``tactilab.experiments.modelling.FingerContact`` from the table; ``TransductionModel(source="contact")``);
- ``"surface"``: otherwise, the ideal surface (the sliding-sinusoid formula).

The session's metadata records the choice as ``design_strain``; a resume rebuilds the same source
from the recorded description and protocol (:func:`recorded_design_source`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

#: the strain sources a session's design may record, in the order they are tried
DESIGN_STRAINS = ("display", "contact", "surface")


@dataclass(frozen=True)
class DesignSource:
    """The strain source of a session's design.

    Attributes
    ----------
    strain : {"display", "contact", "surface"}
        Recorded in the session's metadata as ``design_strain``.
    display : RenderedStimuli or None
        The rendered stimuli (``strain == "display"``).
    finger : FingerConfig or None
        The protocol's ``[finger]`` table (``strain == "contact"``).
    """

    strain: str
    display: Any = None
    finger: Any = None

    def keywords(self) -> dict[str, Any]:
        """``make_procedure``'s ``display`` and ``finger`` keywords."""
        return {"display": self.display, "finger": self.finger}


def design_source(description, protocol) -> DesignSource:
    """The source a new session's design predicts from (see the module's order).

    Parameters
    ----------
    description : DisplayDescription
        The session's display.
    protocol : Protocol
    """
    from .display_check import design_display

    rendered = design_display(description, protocol)
    if rendered is not None:
        return DesignSource("display", display=rendered)
    if getattr(protocol, "finger", None) is not None:
        return DesignSource("contact", finger=protocol.finger)
    return DesignSource("surface")


def recorded_design_source(meta: dict[str, Any], protocol, description) -> DesignSource:
    """The source a recorded session's design predicted from, rebuilt from its metadata.

    Parameters
    ----------
    meta : dict
        The session's metadata (``design_strain``; sessions recorded before it was kept predicted
        from the ideal surface).
    protocol : Protocol
        The recorded protocol (its ``[finger]`` for ``"contact"``).
    description : DisplayDescription or None
        The recorded display description (for ``"display"``).

    Raises
    ------
    ValueError
        ``design_strain`` is not one of :data:`DESIGN_STRAINS`, or names a source the recorded
        session lacks (the metadata was edited).
    """
    strain = meta.get("design_strain", "surface")
    if strain not in DESIGN_STRAINS:
        raise ValueError(f"session: design_strain {str(strain)[:40]!r} is not one of {DESIGN_STRAINS}; the metadata "
                         "was edited")
    if strain == "display" and description is not None:
        from .display_check import design_display

        return DesignSource("display", display=design_display(description, protocol))
    if strain == "contact":
        if getattr(protocol, "finger", None) is None:
            raise ValueError("session: design_strain 'contact' but the recorded protocol has no [finger] table; the "
                             "metadata was edited")
        return DesignSource("contact", finger=protocol.finger)
    return DesignSource("surface")

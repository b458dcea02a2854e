"""A simulated observer that reads any receptor hypothesis, recorded so that a resume rebuilds it.

:meth:`SimulatedObserver.from_model` makes an observer whose drive is a
:class:`~.models.TransductionModel`'s statistic, but records its strain source as ``custom``
(a function a session file cannot hold). :func:`hypothesis_observer` records the hypothesis,
the statistic and the source instead (``hypothesis``, ``statistic``, ``strain`` in its
``config``), so ``tactilab experiment resume`` rebuilds the same observer from the session file.
The threshold is in the readout units of the hypothesis and statistic (tensor strain, as
``TransductionModel.statistic_of`` computes it): the same unit as ``power --threshold``.
"""

from __future__ import annotations

from ..session import SimulatedObserver
from .models import TransductionModel


class HypothesisObserver(SimulatedObserver):
    """A :class:`SimulatedObserver` reading a TransductionModel; its ``config`` names the model."""

    def __init__(self, protocol, model: TransductionModel, **kwargs):
        super().__init__(protocol, strain_fn=model.statistic_of, **kwargs)
        self.model = model

    @property
    def config(self) -> dict:
        return {**super().config, "strain": self.model.source, "hypothesis": str(self.model.hypothesis),
                "statistic": self.model.statistic}


def hypothesis_observer(protocol, hypothesis: str, *, threshold_strain: float, statistic: str = "peak",
                        source: str = "surface", display=None, seed: int | None = None, exponent: float = 1.0,
                        lapse: float = 0.0) -> HypothesisObserver:
    """An observer whose drive is ``(statistic of the hypothesis's readout / threshold_strain) ** exponent``.

    Parameters
    ----------
    protocol : Protocol
    hypothesis : str
        A receptor hypothesis, e.g. ``"zx@2mm"`` (``ReceptorHypothesis.parse``).
    threshold_strain : float
        Readout (tensor strain, dimensionless) felt at d' = 1, in the units of the hypothesis and
        statistic.
    statistic : {"peak", "rms"}
    source : {"surface", "display", "contact"}
        The ideal surface's strain, what the simulated ``display`` renders (clipping included), or
        a physical grating pressed by the protocol's ``[finger]`` through the solved contact
        (:class:`~.contact_stimulus.FingerContact`; a resume rebuilds it from the protocol).
    display : SimulatedDisplay, optional
        Needed for ``source="display"``.
    seed, exponent, lapse
        As :class:`SimulatedObserver` (seed default: the protocol's).
    """
    contact = None
    if source == "contact":
        if getattr(protocol, "finger", None) is None:
            raise ValueError("source: 'contact' needs the finger that presses the gratings: add a [finger] table to "
                             "the protocol (finger_radius_m, normal_force_n, friction, young_modulus_pa)")
        from .contact_stimulus import FingerContact

        contact = FingerContact.from_config(protocol.finger)
    model = TransductionModel(hypothesis, statistic=statistic, source=source, display=display, contact=contact)
    return HypothesisObserver(protocol, model, seed=seed, threshold_strain=threshold_strain, exponent=exponent,
                              lapse=lapse)

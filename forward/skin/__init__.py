"""Skin models beyond the homogeneous elastic half-space: this package is the skin room's one door.

Forward code outside this package imports from here, never from the modules inside (a test
enforces it). The skin models here keep the faces of :class:`tactilab.forward.halfspace.HalfSpace`
(``stress`` / ``strain`` / ``operator``) and provide ``surface_compliance(kx, ky)`` so that
:func:`tactilab.forward.contact.solve_contact` takes them. SI units; the theory is in
``docs/theory.md``.
"""

from tactilab.core import attach

#: public name -> module of the skin room that defines it (loaded on first use)
_EXPORTS: dict[str, str] = {
    # layered skin (structure)
    "Layer": "layered",
    "LayeredHalfSpace": "layered",
    "ViscoelasticLayeredHalfSpace": "layered_viscoelastic",
    "tractor_phi_psi": "line_loads",
    "tangential_line_strain": "line_loads",
    "receptive_field": "receptive",
    "ReceptiveField": "receptive",
    # viscoelastic skin (time): the material, the half-space, its contact
    "Prony": "prony",
    "ViscoelasticHalfSpace": "viscoelastic",
    "TimeFieldResult": "time_field",
    "HereditaryIntegral": "hereditary",
    "HistoryOperator": "viscoelastic_operator",
    "solve_viscoelastic_contact": "viscoelastic_contact",
    "ViscoelasticContactHistory": "viscoelastic_contact",
    "skin_from_material": "materials",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS)

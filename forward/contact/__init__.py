"""Contact mechanics of the skin against a rigid surface: this package is the contact room's one door.

Forward code outside this package imports from here, never from the modules inside (a test
enforces it). Inside:

- ``hertz``: the Hertz and Cattaneo--Mindlin closed forms (:class:`HertzContact`,
  :func:`interfacial_traction`, :func:`stick_radius`, :class:`ContactLoad`);
- ``compliance``: the surface compliance of the skin per wavenumber and the operators that map
  surface tractions to surface displacements on a grid (:class:`ContactCompliance`), and
  ``coarse_stiffness``, the two-level approximation of the periodic stiffness that preconditions
  the normal solver on periodic grids, and ``single_correction``, its float32 correction of the
  displacement after a step that clips many nodes;
- ``solve``: the contact solver :func:`solve_contact` and its result :class:`ContactSolution`;
- ``linearised``: the derivative of a solved normal contact at its contact set
  (:class:`ContactLinearisation`, the inversions' Jacobian);
- ``tangential``: partial slip and stuck contact under a given pressure (:func:`solve_tangential`,
  :class:`TangentialSolution`), on the quadratic program of ``friction_qp``;
- ``periodic_forms``: the closed forms of periodic cells, Westergaard's sinusoid and the periodic
  flat punch, with their harmonics and fields at depth (:class:`WestergaardContact`,
  :class:`PeriodicFlatPunch`, :func:`harmonic_field`);
- ``validity``: the sensor error of the cheap texture models against the solved contact
  (:func:`interface_model_errors`, :func:`linear_pressure`, :func:`modulation_pressure`,
  :func:`full_contact_pressure`).

Conventions (docs/theory.md section 1): tractions act on the skin, ``p`` pushes into it, heights
are positive towards the skin, ``uz`` is positive into the skin; SI units.
"""

from tactilab.core import attach

#: public name -> module of the contact room that defines it (loaded on first use)
_EXPORTS = {
    "CONDITIONS": "hertz",
    "ContactLoad": "hertz",
    "HertzContact": "hertz",
    "interfacial_traction": "hertz",
    "stick_radius": "hertz",
    "stuck_shape": "hertz",
    "ContactCompliance": "compliance",
    "ContactSolution": "solution",
    "ContactLinearisation": "linearised",
    "solve_contact": "solve",
    "METHODS": "solve",
    "memory_estimate": "inputs",
    "memory_limit": "inputs",
    "solve_tangential": "tangential",
    "WestergaardContact": "periodic_forms",
    "PeriodicFlatPunch": "periodic_forms",
    "harmonic_field": "periodic_forms",
    "interface_model_errors": "validity",
    "linear_pressure": "validity",
    "modulation_pressure": "validity",
    "full_contact_pressure": "validity",
    "TangentialSolution": "tangential",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS)

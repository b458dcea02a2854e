"""Skin material: a linear, isotropic, elastic half-space (Young's modulus E, Poisson's ratio nu).

Convention: ``young_modulus_pa`` is Young's modulus E in Pa (not the shear modulus, not the
plane-strain modulus); ``poisson_ratio`` is nu. Skin is nearly incompressible, so nu = 0.5 is
allowed exactly and is the default: code built on this record must treat it as a stable limit
(no division by 1 - 2 nu).
"""

from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator

from tactilab.core import rules

from .base import Record, positive


def _poisson_ratio(nu: float) -> float:
    """nu in (-1, 0.5]: the ground floor's rule (:func:`tactilab.core.rules.poisson_ratio`), the solver's too."""
    return rules.poisson_ratio(nu, "poisson_ratio")


class SkinMaterial(Record):
    """Elastic constants of the skin half-space.

    Parameters
    ----------
    young_modulus_pa : float, Pa
        Young's modulus E, > 0 (fingertip skin: about 1 to 4 MPa, docs/theory.md 4b).
    poisson_ratio : float
        Poisson's ratio nu in (-1, 0.5]; 0.5 (incompressible) is the default.
    name : str
        Free label, e.g. ``"fingertip"`` or ``"silicone phantom"``.
    """

    young_modulus_pa: Annotated[float, positive(
        "a stiffness", "give Young's modulus E in Pa, e.g. 1e6 for 1 MPa")]
    poisson_ratio: Annotated[float, AfterValidator(_poisson_ratio)] = 0.5
    name: str = ""

    @property
    def shear_modulus_pa(self) -> float:
        """Shear modulus G = E / (2 (1 + nu)), Pa."""
        return self.young_modulus_pa / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def plane_strain_modulus_pa(self) -> float:
        """Plane-strain (contact) modulus E* = E / (1 - nu^2), Pa."""
        return self.young_modulus_pa / (1.0 - self.poisson_ratio**2)

    @property
    def is_incompressible(self) -> bool:
        """True when nu is exactly 0.5."""
        return self.poisson_ratio == 0.5

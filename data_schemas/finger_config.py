"""The finger of a protocol (``[finger]``): what presses a physical grating, for contact-source models.

A protocol whose stimuli are physical gratings (not a display's virtual surface) names the finger
that presses them: ``TransductionModel(source="contact")`` and the simulated observer with
``--observer-strain contact`` solve the contact of this finger on each stimulus
(``tactilab.experiments.modelling.FingerContact``). Quantities are SI; a file may carry unit
suffixes (``finger_radius_m = "10mm"``, ``normal_force_n = "0.5N"``, ``young_modulus_pa = "1MPa"``).
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field, model_validator

from tactilab.core import rules

from .experiment_procedures import Length, _Model, _quantity

Force = Annotated[float, _quantity("force")]
Pressure = Annotated[float, _quantity("pressure")]


class FingerConfig(_Model):
    """A fingertip pressing a grating: radius, normal force, friction, skin."""

    finger_radius_m: Length = Field(10e-3, description="fingertip radius of curvature R, m (> 0)")
    normal_force_n: Force = Field(0.5, description="normal force F, N (> 0)")
    friction: float = Field(0.5, description="Coulomb coefficient mu (>= 0) of the sliding finger")
    young_modulus_pa: Pressure = Field(1e6, description="skin Young's modulus E, Pa (> 0)")
    poisson_ratio: float = Field(0.5, description="skin Poisson's ratio nu in (-1, 0.5]")

    @model_validator(mode="after")
    def _check(self) -> FingerConfig:
        rules.positive(self.finger_radius_m, "finger_radius_m", "m")
        rules.positive(self.normal_force_n, "normal_force_n", "N")
        rules.finite(self.friction, "friction", "")
        if self.friction < 0:
            raise ValueError(f"friction: must be a Coulomb coefficient >= 0, got {self.friction!r}; e.g. 0.5")
        rules.young_modulus(self.young_modulus_pa, "young_modulus_pa")
        rules.poisson_ratio(self.poisson_ratio, "poisson_ratio")
        return self

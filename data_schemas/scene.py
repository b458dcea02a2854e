"""Scenes: a finger (or a display) touching a surface, sensed by sensors in the skin.

Frames. The surface is described in the WORLD frame. Sensor positions and display tractor
positions are in the FINGER frame, whose origin is the centre of contact. During a scan the
finger moves along +x: at time t (s from the scan start) the contact centre is at world
x = ``scan.start_position_m + scan.speed_m_per_s * t`` (and y = 0), so a surface point at world
x_w lies at finger-frame x = x_w - that position.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import model_validator

from .base import Record, finite, in_range, non_negative, positive
from .display import DisplayDescription
from .material import SkinMaterial
from .sensors import SensorArray
from .surface import Surface


class Contact(Record):
    """The finger pressing the skin on a surface, and the interface law.

    Parameters
    ----------
    normal_force_n : float, N
        Total normal force of the finger on the surface, > 0.
    finger_radius_m : float, m
        Radius of curvature of the fingertip (Hertz-like contact), > 0.
    friction_coefficient : float
        Dynamic (sliding) friction coefficient mu_d >= 0; while sliding the tangential
        traction is mu_d times the local pressure. 0 is a frictionless contact.
    adhesion : float in [0, 1]
        Blend between the two limiting contact conditions: 0 frictionless indentation, 1 a
        fully adhesive (no-slip) contact, values between mix the two.
    fingerprint_period_m : float or None, m
        Period of the fingerprint ridges (a regular square-wave pattern on the skin, about
        0.5 mm), or None for smooth skin.
    """

    normal_force_n: Annotated[float, positive("the finger presses on the surface",
                                              "give the normal force in N, e.g. 0.8")]
    finger_radius_m: Annotated[float, positive("a radius of curvature")]
    friction_coefficient: Annotated[float, non_negative("a friction coefficient")] = 0.0
    adhesion: Annotated[float, in_range(0.0, 1.0, reason="0 frictionless, 1 fully adhesive")] = 0.0
    fingerprint_period_m: Annotated[float, positive("the ridge period")] | None = None


class Scan(Record):
    """How the finger moves over the surface and how the sensors are sampled.

    Parameters
    ----------
    speed_m_per_s : float, m/s
        Scanning speed along +x, >= 0 (0 for a static press).
    duration_s : float, s
        Length of the recording, > 0.
    sampling_rate_hz : float, Hz
        Sensor sampling rate, > 0; ``duration_s * sampling_rate_hz`` must give >= 1 sample.
    start_position_m : float, m
        World x of the contact centre at t = 0.
    """

    speed_m_per_s: Annotated[float, non_negative("the finger moves along +x",
                                                 "give the speed in m/s; set start_position_m to scan from the other side")]
    duration_s: Annotated[float, positive("the length of the recording")]
    sampling_rate_hz: Annotated[float, positive("samples per second")]
    start_position_m: Annotated[float, finite()] = 0.0

    @model_validator(mode="after")
    def _at_least_one_sample(self) -> Scan:
        if self.n_samples < 1:
            raise ValueError(
                f"duration_s * sampling_rate_hz must give at least 1 sample, got {self.duration_s!r} s x "
                f"{self.sampling_rate_hz!r} Hz; record for longer or sample faster"
            )
        return self

    @property
    def n_samples(self) -> int:
        """Number of samples, ``floor(duration_s * sampling_rate_hz + 1e-9)``."""
        return int(np.floor(self.duration_s * self.sampling_rate_hz + 1e-9))

    @property
    def times_s(self) -> np.ndarray:
        """Sample times from the scan start, shape (n_samples,), s."""
        return np.arange(self.n_samples) / self.sampling_rate_hz

    @property
    def positions_m(self) -> np.ndarray:
        """World x of the contact centre at each sample, shape (n_samples,), m."""
        return self.start_position_m + self.speed_m_per_s * self.times_s

    @property
    def distance_m(self) -> float:
        """Distance travelled during the scan, m."""
        return self.speed_m_per_s * self.duration_s


class Scene(Record):
    """Everything a forward simulation needs: skin, surface, contact, sensors, scan, display.

    Parameters
    ----------
    name : str
        Short identifier.
    description : str
        Free text: what the scene shows and where its numbers come from.
    material : SkinMaterial
        The skin.
    surface : Surface
        The touched surface; with a ``display``, the VIRTUAL surface it renders.
    contact : Contact or None
        The finger on the surface; required unless a ``display`` drives the skin.
    sensors : SensorArray
        Sensors in the skin (finger frame).
    scan : Scan
        Motion and sampling.
    display : DisplayDescription or None
        A laterotactile display in contact with the skin, rendering ``surface``.
    """

    name: str = ""
    description: str = ""
    material: SkinMaterial
    surface: Surface
    contact: Contact | None = None
    sensors: SensorArray
    scan: Scan
    display: DisplayDescription | None = None

    @model_validator(mode="after")
    def _something_touches(self) -> Scene:
        if self.contact is None and self.display is None:
            raise ValueError(
                "contact and display are both missing (nothing touches the skin); give a contact "
                "(finger on the surface) or a display (rendering the surface)"
            )
        return self

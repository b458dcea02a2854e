"""Scenes: a finger (or a display) touching a surface, sensed by sensors in the skin.

Frames. The surface is described in the WORLD frame. Sensor positions and display tractor
positions are in the FINGER frame, whose origin is the centre of contact. During a scan the
finger moves along +x: at time t (s from the scan start) the contact centre is at world
x = ``scan.start_position_m + scan.speed_m_per_s * t`` (and y = 0), so a surface point at world
x_w lies at finger-frame x = x_w - that position.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import model_validator

from .base import Record, finite, in_range, non_negative, positive
from .display import DisplayDescription
from .material import SkinMaterial
from .sensors import SensorArray
from .surface import Surface


#: the interface models a scene may ask for (docs/scenes.md, "Interface models")
CONTACT_MODELS = ("auto", "exact", "linear", "modulation")


class Contact(Record):
    """The finger pressing the skin on a surface, the interface law and the interface model.

    Parameters
    ----------
    normal_force_n : float or None, N
        Total normal force of the finger on the surface, > 0. With ``finger_radius_m``; None for a
        periodic cell (``mean_pressure_pa``).
    finger_radius_m : float or None, m
        Radius of curvature of the fingertip (Hertz-like contact), > 0; None for a periodic cell.
    mean_pressure_pa : float or None, Pa
        A periodic cell in place of a finger: the nominally flat skin pressed on one period of the
        surface at this mean pressure (> 0). Give it OR ``normal_force_n`` and ``finger_radius_m``.
    friction_coefficient : float
        Dynamic (sliding) friction coefficient mu_d >= 0; while sliding the tangential
        traction is mu_d times the local pressure. 0 is a frictionless contact.
    adhesion : float in [0, 1]
        The modulation model's blend between sliding (0) and the fully adhesive (no-slip) shape
        (1) of the same total tangential force mu F. The exact model reads it as Q / (mu F) of a
        partial-slip press when the finger does not move (speed 0); a moving finger slides.
    fingerprint_period_m : float or None, m
        Period of the fingerprint ridges (a regular square-wave pattern on the skin, about
        0.5 mm), or None for smooth skin.
    fingerprint_height_m : float or None, m
        Height of the ridges over the grooves (> 0, about 10-50 um): the exact and linear models
        add them to the gap; needs ``fingerprint_period_m``.
    model : {"auto", "exact", "linear", "modulation"}
        The interface model: ``"exact"`` solves every frame's contact, ``"linear"`` superposes the
        finger's pressure and the texture's full-contact pressure (clipped at 0), ``"modulation"``
        multiplies the finger's stress by 1 + h / h_ref (docs/theory.md 4b); ``"auto"`` picks the
        cheapest that meets ``tol`` and says why.
    tol : float
        The scene's accepted error of the sensor signal, in (0, 1): max over the scan of |error| /
        max |signal|, per sensor and component.
    """

    normal_force_n: Annotated[float, positive("the finger presses on the surface",
                                              "give the normal force in N, e.g. 0.8")] | None = None
    finger_radius_m: Annotated[float, positive("a radius of curvature")] | None = None
    mean_pressure_pa: Annotated[float, positive("a periodic cell is pressed at a mean pressure",
                                                "give it in Pa, e.g. \"10kPa\"")] | None = None
    friction_coefficient: Annotated[float, non_negative("a friction coefficient")] = 0.0
    adhesion: Annotated[float, in_range(0.0, 1.0, reason="0 frictionless, 1 fully adhesive")] = 0.0
    fingerprint_period_m: Annotated[float, positive("the ridge period")] | None = None
    fingerprint_height_m: Annotated[float, positive("the ridges stand out of the grooves",
                                                    "give it in m, e.g. \"20um\"")] | None = None
    model: Literal["auto", "exact", "linear", "modulation"] = "auto"
    tol: Annotated[float, in_range(0.0, 1.0, low_open=True, high_open=True,
                                   reason="a relative error of the sensor signal, e.g. 1e-2")] = 1e-2

    @model_validator(mode="after")
    def _finger_or_cell(self) -> Contact:
        finger = (self.normal_force_n is not None, self.finger_radius_m is not None)
        if self.mean_pressure_pa is not None and any(finger):
            raise ValueError(
                f"mean_pressure = {self.mean_pressure_pa!r} Pa makes a periodic cell without a finger, but "
                f"normal_force = {self.normal_force_n!r} N / finger_radius = {self.finger_radius_m!r} m are given "
                "too; keep mean_pressure or the finger (normal_force and finger_radius)")
        if self.mean_pressure_pa is None and not all(finger):
            missing = [n for n, ok in zip(("normal_force", "finger_radius"), finger) if not ok]
            raise ValueError(f"{' and '.join(missing)} missing: a finger needs normal_force (N) and finger_radius "
                             "(m); or give mean_pressure (Pa) for a periodic cell")
        if self.fingerprint_height_m is not None and self.fingerprint_period_m is None:
            raise ValueError(f"fingerprint_height = {self.fingerprint_height_m!r} m needs fingerprint_period "
                             "(the ridges' spacing, e.g. \"0.5mm\"); add it or drop fingerprint_height")
        return self

    @property
    def periodic(self) -> bool:
        """True for a periodic cell (``mean_pressure_pa`` given), False for a finger."""
        return self.mean_pressure_pa is not None


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
    onset_s : float, s
        The tangential load ramps from 0 to mu F over the first ``onset_s`` of the scan, in partial
        slip (exact model; the others scale the sliding traction); 0 (default) slides from t = 0.
    """

    speed_m_per_s: Annotated[float, non_negative("the finger moves along +x",
                                                 "give the speed in m/s; set start_position_m to scan from the other side")]
    duration_s: Annotated[float, positive("the length of the recording")]
    sampling_rate_hz: Annotated[float, positive("samples per second")]
    start_position_m: Annotated[float, finite()] = 0.0
    onset_s: Annotated[float, non_negative("the tangential load's ramp", "give it in s, e.g. \"20ms\"")] = 0.0

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
    def slip_ratios(self) -> np.ndarray:
        """Q / (mu F) at each sample, shape (n_samples,): ``t / onset_s`` during the onset, then 1."""
        if self.onset_s == 0:
            return np.ones(self.n_samples)
        return np.minimum(self.times_s / self.onset_s, 1.0)

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

"""The stimulus of a psychophysics trial: a virtual surface scanned at a speed.

:class:`Stimulus` sits below the protocol (:mod:`tactilab.data_schemas.experiment`) and the
adaptive design's configuration (:mod:`tactilab.data_schemas.design_config`), which both use it.
Quantities are SI; files may carry unit suffixes (``"20um"``, ``"40mm/s"``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from tactilab.core import rules

from .experiment_procedures import Frequency, Length, Speed, Time, _Model

#: The pitches a stimulus may have, m (the drive's strain gain overflows far outside; usual: 1 um to 200 mm).
PITCH_RANGE_M = (1e-7, 100.0)
#: the highest drive frame rate a protocol may ask for, Hz (tactile displays refresh at 1-10 kHz)
MAX_FRAME_RATE_HZ = 100_000.0


class Stimulus(_Model):
    """A virtual surface H(x) scanned at a speed, and how the display's tractors render it.

    Each tractor at position x_n follows H(x_n + V t) (a travelling wave, docs/theory.md 4a).
    """

    surface: Literal["sinusoid", "square"] = "sinusoid"
    amplitude_m: Length = Field(description="virtual surface height amplitude A, m (>= 0)")
    pitch_m: Length = Field(description="virtual surface period p, m (> 0)")
    speed_m_per_s: Speed = Field(description="scanning speed V, m/s (sign = direction)")
    duration_s: Time = Field(0.5, description="stimulus duration, s (> 0, <= 60)")
    ramp_s: Time = Field(0.02, description="raised-cosine onset/offset ramp, s (>= 0)")
    phase_rad: float = Field(0.0, description="phase of H at x = 0, t = 0, rad")
    frame_rate_hz: Frequency = Field(1000.0, description="drive frame rate, Hz (> 0, <= 100 kHz)")

    @model_validator(mode="after")
    def _check(self) -> Stimulus:
        rules.finite(self.amplitude_m, "amplitude_m", "m")
        if self.amplitude_m < 0:
            raise ValueError(f"amplitude_m: must be >= 0 m, got {self.amplitude_m!r}; give e.g. '20um'")
        rules.positive(self.pitch_m, "pitch_m", "m")
        if not PITCH_RANGE_M[0] <= self.pitch_m <= PITCH_RANGE_M[1]:
            raise ValueError(f"pitch_m: must lie in [{PITCH_RANGE_M[0]:g}, {PITCH_RANGE_M[1]:g}] m (a grating "
                             f"pitch), got {self.pitch_m!r} m; check its unit, e.g. '2mm'")
        rules.finite(self.speed_m_per_s, "speed_m_per_s", "m/s")
        rules.finite(self.phase_rad, "phase_rad", "rad")
        rules.positive(self.duration_s, "duration_s", "s")
        if self.duration_s > 60:
            raise ValueError(f"duration_s: must be <= 60 s, got {self.duration_s!r}; split long stimuli")
        rules.finite(self.ramp_s, "ramp_s", "s")
        if self.ramp_s < 0 or 2 * self.ramp_s > self.duration_s:
            raise ValueError(
                f"ramp_s: must lie in [0, duration_s / 2] = [0, {self.duration_s / 2!r}] s, got "
                f"{self.ramp_s!r}; shorten the ramp or lengthen the stimulus"
            )
        rules.positive(self.frame_rate_hz, "frame_rate_hz", "Hz")
        if self.frame_rate_hz > MAX_FRAME_RATE_HZ:  # a typo ('1e9Hz') must not reach the renderer
            raise ValueError(f"frame_rate_hz: must be <= {MAX_FRAME_RATE_HZ:g} Hz (no tactile display refreshes "
                             f"faster), got {self.frame_rate_hz!r} Hz; give the display's rate, e.g. '1kHz'")
        if self.frame_rate_hz * self.duration_s < 2:
            raise ValueError(
                f"frame_rate_hz: {self.frame_rate_hz!r} Hz gives fewer than 2 frames in "
                f"{self.duration_s!r} s; raise the frame rate (default 1 kHz)"
            )
        return self

    def with_level(self, parameter: str, level: float) -> Stimulus:
        """Return a copy with ``parameter`` set to ``level`` (SI), validated."""
        return Stimulus.model_validate({**self.model_dump(), parameter: level})

"""Tactile display drivers: the common interface and the travelling-wave drive.

A laterotactile display is an array of tractors (rows across the scanning direction y, columns
along it, x) that push the skin sideways. A :class:`Display` takes a block of frames, one
commanded value per tractor per frame, and plays them at a fixed frame rate:

- ``load(frames, frame_rate_hz)``: ``frames`` has shape ``(n_frames, n_tractors)``; tractor
  ``i = row * n_columns + column`` (row-major). The values are lateral tractions in Pa, or
  lateral deflections in m, as the display's ``command`` says.
- ``play()`` streams them and returns a :class:`PlaybackReport`;
- ``stop()`` ends playback at the next frame boundary (safe to call from another thread or a
  signal handler);
- ``zero()`` sets every output to zero at once (the safe state).

Subclasses implement ``_play`` and ``_zero`` only; validation lives here (template method).
The base class refuses frames that break the description's amplitude or slew-rate limits, so a
bare driver never streams them; :class:`tactilab.experiments.devices.safety.SafeDisplay` instead
*limits* any drive (and enforces the duty limit too) and reports each intervention.

:func:`render_drive` turns a virtual surface into frames (docs/theory.md 4a): each tractor at
position x_n follows the height of the virtual surface as the display scans it,
``q_n(t) = gain * H(x_n + V t) * envelope(t)``.
"""

from __future__ import annotations

import abc
import math
import threading
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from tactilab.core import rules
from tactilab.core.memory import MEMORY_LIMIT_BYTES, check_memory

from .display_limits import check_frames, limit_violations, resolve_command
from .display_strain import strain_gain_line_load

__all__ = [
    "Display", "DisplayError", "PlaybackReport", "render_drive", "virtual_height",
    "DEFAULT_DEPTH_M", "DEFAULT_YOUNG_MODULUS_PA",
]

#: Receptor depth at which the drive's strain is matched to the virtual surface's, m
#: (docs/theory.md 1: receptors sit 0.5 to 3 mm deep; 1 mm is a mid value).
DEFAULT_DEPTH_M = 1.0e-3
#: Skin Young's modulus used to convert strain to traction when none is given, Pa
#: (order of magnitude of in-vivo fingertip skin; the traction gain is proportional to it).
DEFAULT_YOUNG_MODULUS_PA = 1.0e6


class DisplayError(RuntimeError):
    """A display could not do what was asked (no device answer, nothing loaded, ...).

    Attributes
    ----------
    frames_sent : int or None
        For an error during ``play()``: the frames sent before it (count), so the session reports
        what the display actually played; None where unknown or not during playback.
    """

    frames_sent: int | None = None


@dataclass(frozen=True)
class PlaybackReport:
    """What one ``play()`` did.

    Attributes
    ----------
    frames_sent : int
        Frames handed to the outputs (sent on the wire, or applied by a simulation).
    late : int
        Frames sent more than half a frame period after their scheduled time.
    missing : int
        Frames the device did not acknowledge as applied (no ACK, or an ACK with another
        status); 0 for a simulation.
    acked : int
        Frames acknowledged as applied (equal to ``frames_sent`` for a simulation).
    interventions : int
        Safety interventions (events) during load and play; 0 for a bare driver.
    stopped : bool
        ``True`` if ``stop()`` ended playback before the last frame.
    duration_s : float
        Wall time from the first to the last frame sent, s.
    late_acks : int
        Acknowledgements that arrived after the driver's acknowledgement timeout.
    send_intervals_s : ndarray, shape (frames_sent - 1,)
        Intervals between consecutive frame sends, s (empty for non-real-time playback).
    ack_rtt_s : ndarray, shape (acked,)
        Delay of each acknowledgement, s: from the frame's due time to its ACK's arrival (UDP,
        frames sent ahead of time), empty when there are none.
    rejected : int
        Frames acknowledged with a status other than ``applied`` (stale, disarmed, ...);
        ``missing - rejected`` frames got no acknowledgement at all.
    stale : int
        Frames acknowledged ``stale``: the device had already applied a newer sequence number
        (another sender is ahead: an alarm).
    skipped : int
        Frames not sent because their due time had passed by more than half a period before the
        host could send them (the host never sends a burst of late frames).
    foreign : int
        Frames the device applied that this host did not send, since its previous look at the
        device's ``frames_applied`` counter (another process drove the display); 0 for a display
        without such a counter.
    """

    frames_sent: int
    late: int
    missing: int
    acked: int
    interventions: int = 0
    stopped: bool = False
    duration_s: float = 0.0
    late_acks: int = 0
    send_intervals_s: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    ack_rtt_s: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    rejected: int = 0
    stale: int = 0
    skipped: int = 0
    foreign: int = 0

    @property
    def unacknowledged(self) -> int:
        """Frames that got no acknowledgement at all."""
        return self.missing - self.rejected

    def with_interventions(self, n: int) -> PlaybackReport:
        """Return a copy with ``interventions`` set to ``n``."""
        return PlaybackReport(**{**self.__dict__, "interventions": int(n)})


class Display(abc.ABC):
    """A tactile display driver: load frames, play, stop, zero.

    Parameters
    ----------
    description : DisplayDescription
        Geometry and limits of the display (``tactilab.data_schemas.display``).
    command : {"traction", "deflection"}, optional
        What the frames are: lateral traction in Pa or deflection in m. Default: traction
        when the description has ``max_traction_pa``, else deflection.
    """

    def __init__(self, description, command: str | None = None) -> None:
        self.description = description
        self.command = resolve_command(description, command)
        self._frames: np.ndarray | None = None
        self._frame_rate_hz: float | None = None
        self._stop = threading.Event()

    @property
    def frames(self) -> np.ndarray | None:
        """The loaded frames, shape (n_frames, n_tractors), read-only; ``None`` before ``load``."""
        return self._frames

    @property
    def frame_rate_hz(self) -> float | None:
        """The loaded frame rate, Hz; ``None`` before ``load``."""
        return self._frame_rate_hz

    def load(self, frames: np.ndarray, frame_rate_hz: float) -> None:
        """Load a block of frames to play.

        Parameters
        ----------
        frames : ndarray, shape (n_frames, n_tractors)
            Commanded lateral traction (Pa) or deflection (m) per tractor and frame, starting
            from rest (the outputs are zero before the first frame).
        frame_rate_hz : float
            Frames per second, Hz.

        Raises
        ------
        ValueError
            If the shape or values are invalid, or the frames break the amplitude, slew-rate
            or duty limits of the description (wrap the display in ``SafeDisplay`` to have
            them limited instead).
        """
        array, rate = check_frames(frames, frame_rate_hz, self.description)
        bad = limit_violations(array, rate, self.description, command=self.command,
                               tolerance=2.0**-22)
        if bad:
            first = bad[0]
            raise ValueError(
                f"frames: {len(bad)} (kind, tractor) pairs break the limits of display "
                f"{self.description.display_id!r}; e.g. {first['kind']} {first['value']:.6g} > "
                f"{first['limit']:.6g} at tractor {first['tractor']}, frame {first['frame']}; "
                "wrap the display in tactilab.experiments.devices.safety.SafeDisplay to limit the drive"
            )
        array.flags.writeable = False
        self._frames, self._frame_rate_hz = array, rate
        self._load(array, rate)

    def play(self) -> PlaybackReport:
        """Play the loaded frames at the loaded rate and report what happened.

        Raises
        ------
        DisplayError
            If nothing was loaded.
        """
        if self._frames is None:
            raise DisplayError("play: no frames loaded; call load(frames, frame_rate_hz) first")
        self._stop.clear()
        return self._play(self._frames, self._frame_rate_hz)

    def stop(self) -> None:
        """Ask playback to end at the next frame boundary (thread- and signal-safe)."""
        self._stop.set()

    def zero(self) -> None:
        """Set every output to zero now (the safe state)."""
        self._zero()

    def audit(self) -> int:
        """Zero the outputs and count the frames the device applied that this host did not send
        since its previous look (from the device's ``frames_applied`` counter).

        The runner asks after each response, before the trial is scored: a display that another
        process drove between stimuli, or while the subject answered, faults the trial. A display
        without such a counter (a simulation) answers 0.
        """
        self.zero()
        return 0

    @property
    def onset_delay_s(self) -> float:
        """How long after ``play()`` is called the first frame is due, s (0: at once; a display that
        sends frames ahead of their due times, such as UDP, says how far)."""
        return 0.0

    @property
    def stop_requested(self) -> bool:
        """Whether ``stop()`` was called since playback started."""
        return self._stop.is_set()

    def close(self) -> None:
        """Release resources (sockets, files). The base class holds none."""

    def __enter__(self) -> Display:
        return self

    def __exit__(self, *exc_info) -> None:
        """Leave a ``with`` block: zero the outputs (best effort), then close."""
        try:
            self.zero()
        finally:
            self.close()

    def _load(self, frames: np.ndarray, frame_rate_hz: float) -> None:
        """Hook for subclasses that prepare a loaded block (default: nothing)."""

    @abc.abstractmethod
    def _play(self, frames: np.ndarray, frame_rate_hz: float) -> PlaybackReport:
        """Stream ``frames``; return the report. Check ``self.stop_requested`` between frames."""

    @abc.abstractmethod
    def _zero(self) -> None:
        """Set the outputs to zero."""


def virtual_height(x_m: np.ndarray, *, surface: Literal["sinusoid", "square"], amplitude_m: float,
                   pitch_m: float, phase_rad: float = 0.0) -> np.ndarray:
    """Height of the virtual surface H(x), m: ``A sin(2 pi x / p + phase)`` or its sign (square).

    Raises
    ------
    ValueError
        If ``surface`` is not ``"sinusoid"`` or ``"square"``, or a value is NaN or inf
        (``pitch_m`` must also be > 0).
    """
    x_m = np.asarray(x_m, dtype=float)
    if not np.all(np.isfinite(x_m)):
        raise ValueError("x_m: positions must be finite (no NaN or inf), in m")
    for name, value, unit in (("amplitude_m", amplitude_m, "m"), ("phase_rad", phase_rad, "rad")):
        if isinstance(value, bool) or not math.isfinite(float(value)):
            raise ValueError(f"{name}: must be a finite number in {unit}, got {value!r}")
    pitch_m = rules.positive(pitch_m, "pitch_m", "m")
    argument = 2 * np.pi * x_m / pitch_m + phase_rad
    if surface == "sinusoid":
        return amplitude_m * np.sin(argument)
    if surface == "square":
        return amplitude_m * np.sign(np.sin(argument))
    raise ValueError(f"surface: must be 'sinusoid' or 'square', got {surface!r}; pick one of them")


def render_drive(description, *, amplitude_m: float, pitch_m: float, speed_m_per_s: float,
                 duration_s: float, frame_rate_hz: float, surface: str = "sinusoid",
                 phase_rad: float = 0.0, ramp_s: float = 0.02,
                 depth_m: float = DEFAULT_DEPTH_M,
                 young_modulus_pa: float = DEFAULT_YOUNG_MODULUS_PA,
                 gain: float | None = None, command: str | None = None) -> np.ndarray:
    """Frames that render a virtual surface scanned at speed V (docs/theory.md 4a).

    Each tractor at position ``x_n`` (its column's centre, x along the scan) follows the height
    of the virtual surface as the display scans it::

        command_n(t) = gain * H(x_n + V t) * envelope(t),   t = k / frame_rate_hz

    with a raised-cosine onset and offset ``envelope`` of length ``ramp_s`` (so the drive
    starts and ends at rest). All rows get the same drive. Keywords match
    :class:`tactilab.data_schemas.experiment.Stimulus`, so
    ``render_drive(desc, **stimulus.model_dump())`` works.

    The gain (when ``gain`` is None):

    - traction displays: Pa per m of virtual height, chosen so that the root-mean-square
      strain (Frobenius norm of the deviatoric strain tensor) that the tractor array produces
      at ``depth_m``, over the skin under the array and over one period of the scan, equals
      that of the real surface sliding on the skin, ``2 (2 pi)^2 A Z / p^2 exp(-2 pi Z / p)``
      squared (docs/theory.md 4a). The array's strain is the superposition of Flamant tangential
      loads spread over each tractor's width (nu = 1/2, plane strain,
      :func:`tactilab.forward.tractors.tractor_row_strain`); a line load is traction times the
      tractor width along x. The traction is proportional to ``young_modulus_pa``. At
      ``p = 4 d`` this RMS match is the one behind the sqrt(2) of
      :func:`tactilab.forward.synthesis.matching_line_load`, which it generalises to any
      pitch and any array.
    - deflection displays: 1 m of lateral deflection per m of virtual height.

    Parameters
    ----------
    description : DisplayDescription
        Display geometry and limits.
    amplitude_m, pitch_m : float
        Virtual surface amplitude A (>= 0) and period p (> 0), m.
    speed_m_per_s : float
        Scanning speed V, m/s (the sign sets the direction).
    duration_s : float
        Stimulus duration, s (> 0).
    frame_rate_hz : float
        Frame rate, Hz (> 0).
    surface : {"sinusoid", "square"}
        Shape of H.
    phase_rad : float
        Phase of H at x = 0, t = 0, rad.
    ramp_s : float
        Raised-cosine onset and offset, s (0 <= ramp_s <= duration_s / 2).
    depth_m : float
        Receptor depth Z used to match strains, m (> 0).
    young_modulus_pa : float
        Skin Young's modulus E, Pa (> 0).
    gain : float, optional
        Override: command units (Pa or m) per m of virtual height.
    command : {"traction", "deflection"}, optional
        What the frames are (default: see :func:`resolve_command`).

    Returns
    -------
    ndarray, shape (n_frames, n_tractors)
        ``n_frames = max(2, round(duration_s * frame_rate_hz))``; Pa or m per the description.
        The drive is NOT limited here; play it through ``SafeDisplay``.

    Raises
    ------
    ValueError
        If a parameter is out of range (each message names it).
    """
    amplitude = float(amplitude_m)
    if not (math.isfinite(amplitude) and amplitude >= 0):
        raise ValueError(f"amplitude_m: must be a finite number >= 0 m, got {amplitude_m!r}; give e.g. 20e-6")
    pitch = rules.positive(pitch_m, "pitch_m", "m")
    speed = float(speed_m_per_s)
    if not math.isfinite(speed):
        raise ValueError(f"speed_m_per_s: must be finite (m/s), got {speed_m_per_s!r}; give e.g. 0.04")
    duration = rules.positive(duration_s, "duration_s", "s")
    rate = rules.positive(frame_rate_hz, "frame_rate_hz", "Hz")
    ramp = float(ramp_s)
    if not (math.isfinite(ramp) and 0 <= 2 * ramp <= duration):
        raise ValueError(
            f"ramp_s: must lie in [0, duration_s / 2] = [0, {duration / 2!r}] s, got {ramp_s!r}; "
            "shorten the ramp"
        )
    if not math.isfinite(float(phase_rad)):
        raise ValueError(f"phase_rad: must be finite (rad), got {phase_rad!r}; give e.g. 0.0")
    depth = rules.depth(depth_m, "depth_m")
    modulus = rules.young_modulus(young_modulus_pa, "young_modulus_pa")
    if gain is not None and not math.isfinite(float(gain)):
        raise ValueError(f"gain: must be finite, got {gain!r}; give a number or None for the default")

    n_frames = max(2, int(round(duration * rate)))
    # the memory rule, before any frame exists (a few arrays of this size are alive at once); it names
    # the largest frame rate that fits at this duration
    frame_bytes = 4 * 8 * int(description.n_tractors)
    fits_hz = MEMORY_LIMIT_BYTES // frame_bytes / duration
    check_memory(frame_bytes * n_frames, "frame_rate_hz",
                 f"the drive ({n_frames} frames = {rate!r} Hz x {duration!r} s, x {description.n_tractors} tractors)",
                 f"give frame_rate_hz at most {fits_hz:.6g} Hz at duration_s = {duration!r} s, or a shorter duration_s")
    t = np.arange(n_frames) / rate
    command = resolve_command(description, command)
    x_columns = np.asarray(description.tractor_x_m, dtype=float)
    heights = virtual_height(x_columns[None, :] + speed * t[:, None], surface=surface,
                             amplitude_m=amplitude, pitch_m=pitch, phase_rad=float(phase_rad))
    if gain is None:
        if command == "deflection":
            gain = 1.0
        else:
            line_gain = strain_gain_line_load(x_columns, float(description.pitch_x_m), pitch_m=pitch,
                                              depth_m=depth, young_modulus_pa=modulus,
                                              footprint_m=float(description.tractor_width_m))
            gain = line_gain / float(description.tractor_width_m)
    envelope = np.ones(n_frames)
    n_ramp = int(round(ramp * rate))
    if n_ramp > 0:
        # The first and last frames are exactly 0: the drive leaves and returns to rest.
        rise = 0.5 - 0.5 * np.cos(np.pi * np.arange(n_ramp) / n_ramp)
        envelope[:n_ramp] = rise
        envelope[n_frames - n_ramp:] = rise[::-1]
    per_column = float(gain) * heights * envelope[:, None]
    return np.tile(per_column, (1, int(description.rows)))

"""A simulated laterotactile display: plays frames and computes the strain they produce.

:class:`SimulatedDisplay` keeps what it played (its "outputs") and computes the strain at
receptor depth with the plane-strain tractor model of docs/theory.md 4a
(:func:`tactilab.forward.tractors.tractor_row_strain`): each row of tractors is a row of
Flamant tangential loads, uniform over each tractor's contact width, on an incompressible
half-space (nu = 1/2); the line load is the commanded traction times that width. Rows are independent
plane problems (a row's strain is evaluated under that row). Strains use the TENSOR shear
``eps_xz`` (engineering ``gamma_zx = 2 eps_xz``); ``eps_zz = -eps_xx``.

For 2-D arrays of short tractors, :meth:`SimulatedDisplay.strain_3d` gives the full 3-D answer:
each tractor a rectangular patch of uniform traction on a half-space, the Cerruti point-force
solution integrated over it (:func:`tactilab.forward.tractor_display.display_patch_strain_3d`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from tactilab.core import rules
from tactilab.forward.tractor_display import display_patch_strain_3d

from .display import DEFAULT_DEPTH_M, DEFAULT_YOUNG_MODULUS_PA, Display, PlaybackReport, render_drive
from .display_strain import row_strain
from .safety import limit_drive

__all__ = ["SimulatedDisplay"]


class SimulatedDisplay(Display):
    """A display that exists only in software; it plays frames and reports the skin strain.

    Parameters
    ----------
    description : DisplayDescription
        Geometry and limits.
    command : {"traction", "deflection"}, optional
        What the frames are (default: traction when the description has a traction limit).
    depth_m : float
        Receptor depth Z at which strain is computed, m (> 0).
    young_modulus_pa : float
        Skin Young's modulus E, Pa (> 0); nu = 1/2.
    tractor_stiffness_pa_per_m : float, optional
        Traction per unit deflection, Pa/m; required to compute strain for deflection commands.
    x_m : ndarray, shape (n_points,), optional
        Where along x to compute strain, m. Default: from half a column pitch before the first
        column to half after the last, every ``min(depth_m, pitch_x_m) / 4``.
    realtime : bool
        ``True``: play at the frame rate (sleeping between frames). ``False``: play at once
        (tests and simulated sessions); the report's timings are then empty.

    Attributes
    ----------
    outputs : ndarray, shape (n_tractors,)
        The commands now applied (Pa or m).
    played : ndarray, shape (n_played, n_tractors)
        The frames applied by the last ``play()``.
    zero_times : list of float
        ``time.monotonic()`` of each ``zero()``.
    """

    def __init__(self, description, *, command: str | None = None,
                 depth_m: float = DEFAULT_DEPTH_M, young_modulus_pa: float = DEFAULT_YOUNG_MODULUS_PA,
                 tractor_stiffness_pa_per_m: float | None = None, x_m=None,
                 realtime: bool = False) -> None:
        super().__init__(description, command)
        self.depth_m = rules.depth(depth_m, "depth_m")
        self.young_modulus_pa = rules.young_modulus(young_modulus_pa, "young_modulus_pa")
        self.tractor_stiffness_pa_per_m = (None if tractor_stiffness_pa_per_m is None else
                                           rules.positive(tractor_stiffness_pa_per_m,
                                                          "tractor_stiffness_pa_per_m", "Pa/m"))
        if self.command == "deflection" and self.tractor_stiffness_pa_per_m is None:
            raise ValueError(
                "tractor_stiffness_pa_per_m: required for a display commanded in deflection "
                "(strain needs the traction), got None; give the tractors' traction per metre of "
                "deflection in Pa/m, or command traction"
            )
        if x_m is None:
            columns = np.asarray(description.tractor_x_m, dtype=float)
            half = description.pitch_x_m / 2
            spacing = min(self.depth_m, description.pitch_x_m) / 4
            n = int(math.ceil((columns[-1] - columns[0] + 2 * half) / spacing)) + 1
            x_m = np.linspace(columns[0] - half, columns[-1] + half, n)
        x = np.asarray(x_m, dtype=float)
        if x.ndim != 1 or x.size < 1 or not np.all(np.isfinite(x)):
            raise ValueError(f"x_m: must be a non-empty 1-D array of finite positions in m, got shape "
                             f"{x.shape}; give e.g. np.linspace(-6e-3, 6e-3, 97)")
        self.x_m = x
        self.realtime = bool(realtime)
        self.outputs = np.zeros(description.n_tractors)
        self.played = np.zeros((0, description.n_tractors))
        self.zero_times: list[float] = []

    def _play(self, frames: np.ndarray, frame_rate_hz: float) -> PlaybackReport:
        n = frames.shape[0]
        period_ns = 1e9 / frame_rate_hz
        sent_ns = np.zeros(n, dtype=np.int64)
        start = time.perf_counter_ns()
        sent = 0
        for k in range(n):
            if self.stop_requested:
                break
            if self.realtime:
                delay = (start + k * period_ns - time.perf_counter_ns()) / 1e9
                if delay > 0:
                    time.sleep(delay)
            self.outputs = frames[k].copy()
            sent_ns[k] = time.perf_counter_ns()
            sent += 1
        self.played = frames[:sent].copy()
        if not self.realtime:
            return PlaybackReport(frames_sent=sent, late=0, missing=0, acked=sent,
                                  stopped=sent < n)
        times = sent_ns[:sent]
        lateness = times - (start + np.arange(sent) * period_ns)
        return PlaybackReport(
            frames_sent=sent, late=int(np.count_nonzero(lateness > period_ns / 2)), missing=0,
            acked=sent, stopped=sent < n,
            duration_s=float(times[-1] - times[0]) / 1e9 if sent else 0.0,
            send_intervals_s=np.diff(times) / 1e9,
        )

    def _zero(self) -> None:
        self.outputs = np.zeros(self.description.n_tractors)
        self.zero_times.append(time.monotonic())

    def line_loads(self, frames=None) -> np.ndarray:
        """Tangential line loads per tractor, N/m, shape (n_frames, rows, columns).

        ``frames`` defaults to the frames played last.
        """
        f = self.played if frames is None else np.asarray(frames, dtype=float)
        traction = f if self.command == "traction" else f * self.tractor_stiffness_pa_per_m
        rows, columns = self.description.rows, self.description.columns
        return traction.reshape(-1, rows, columns) * self.description.tractor_width_m

    def steady_drive(self, stimulus) -> np.ndarray:
        """The frames this display plays for ``stimulus`` between its onset and offset ramps.

        The drive is rendered (:func:`~.display.render_drive`) and limited exactly as the
        runner's safety layer limits it (:func:`~.safety.limit_drive`); the frames of the ramps
        are dropped (all frames are kept when the ramps cover the whole stimulus).

        Parameters
        ----------
        stimulus : Stimulus
            What is commanded (SI): amplitude, pitch, speed, duration, ramp, frame rate.

        Returns
        -------
        ndarray, shape (n_steady, n_tractors)
            Commands in Pa (traction) or m (deflection).
        """
        frames = render_drive(self.description, **stimulus.model_dump(), depth_m=self.depth_m,
                              young_modulus_pa=self.young_modulus_pa)
        applied, _ = limit_drive(frames, stimulus.frame_rate_hz, self.description, self.command)
        ramp = int(round(stimulus.ramp_s * stimulus.frame_rate_hz))
        return applied[ramp:len(applied) - ramp] if len(applied) > 2 * ramp else applied

    def strain(self, frames=None, depth_m: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Strain under each row, for the frames played last (or ``frames``).

        Parameters
        ----------
        frames : ndarray, shape (n_frames, n_tractors), optional
            Default: the frames played last.
        depth_m : float, optional
            Depth Z at which strain is computed, m (> 0); default ``self.depth_m``.

        Returns
        -------
        eps_xx, eps_xz : ndarray, shape (n_frames, rows, n_points)
            Normal strain along x (``eps_zz = -eps_xx``) and TENSOR shear strain
            (``gamma_zx = 2 eps_xz``) at the points ``self.x_m``, dimensionless.
        """
        depth = self.depth_m if depth_m is None else rules.depth(depth_m, "depth_m")
        q = self.line_loads(frames)
        return row_strain(self.x_m, self.description.tractor_x_m, q, depth,
                          self.young_modulus_pa, self.description.tractor_width_m)

    def strain_3d(self, frames=None, points_m=None) -> np.ndarray:
        """Strain in the 3-D half-space under the tractor patches (Cerruti, nu = 1/2).

        Parameters
        ----------
        frames : ndarray, shape (n_frames, n_tractors), optional
            Default: the frames played last.
        points_m : ndarray, shape (n_points, 3), optional
            Points (x, y, z) in m, z > 0. Default: ``x_m`` under each row's centre line at
            ``depth_m``, row by row (``rows * len(x_m)`` points).

        Returns
        -------
        ndarray, shape (n_frames, n_points, 6)
            Voigt strain (xx, yy, zz, yz, zx, xy) with TENSOR shear.
        """
        if points_m is None:
            x, y = np.meshgrid(self.x_m, self.description.tractor_y_m)
            points_m = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, self.depth_m)])
        f = self.played if frames is None else np.asarray(frames, dtype=float)
        traction = f if self.command == "traction" else f * self.tractor_stiffness_pa_per_m
        rows, columns = self.description.rows, self.description.columns
        return display_patch_strain_3d(self.description, points_m, traction.reshape(-1, rows, columns),
                                       self.young_modulus_pa, 0.5)

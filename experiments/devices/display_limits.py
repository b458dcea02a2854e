"""Display limits: which quantity a display is commanded in, its per-tractor limits, and checks.

The limits come from :class:`tactilab.data_schemas.display.DisplayDescription`: the full scale
(``max_traction_pa`` or ``max_deflection_m``), the slew rate (``max_slew_rate_per_s``, in full
scales per second) and the duty cycle (``max_duty_cycle``, the largest fraction of a block's
frames in which a tractor is non-zero). :func:`limit_violations` lists where a block breaks them
(the drivers refuse such blocks; :mod:`tactilab.experiments.devices.safety` limits them instead).
"""

from __future__ import annotations

import math

import numpy as np

from tactilab.core import rules

__all__ = ["resolve_command", "limits", "check_frames", "limit_violations"]


def resolve_command(description, command: str | None = None) -> str:
    """The quantity a display is commanded in: ``"traction"`` (Pa) or ``"deflection"`` (m).

    ``None`` picks traction when the description has ``max_traction_pa``, else deflection.

    Raises
    ------
    ValueError
        If ``command`` is another word, or the description has no limit for it.
    """
    if command is None:
        command = "traction" if description.max_traction_pa is not None else "deflection"
    if command not in ("traction", "deflection"):
        raise ValueError(f"command: must be 'traction' or 'deflection', got {command!r}; pick one of the two")
    description.full_scale(command)  # raises ValueError naming the missing limit
    return command


def limits(description, command: str | None = None) -> dict:
    """Per-tractor limits of a display, arrays of shape (n_tractors,).

    Returns a dict with ``amplitude`` (full scale, Pa or m), ``step`` (largest change per frame
    at the display's own refresh rate ``description.frame_rate_hz``, whatever rate a block is
    played at, so slower blocks are limited at least as tightly; ``inf`` without a slew limit),
    ``duty`` (largest fraction of non-zero frames in one block), ``unit`` and ``command``.
    """
    command = resolve_command(description, command)
    n = int(description.n_tractors)
    full = float(description.full_scale(command))
    rate = float(description.frame_rate_hz)
    slew = description.max_slew_rate_per_s
    step = np.inf if slew is None else float(slew) * full / rate
    return {
        "amplitude": np.full(n, full),
        "step": np.full(n, step),
        "duty": float(description.max_duty_cycle),
        "unit": "m" if command == "deflection" else "Pa",
        "command": command,
    }


def check_frame_rate(frame_rate_hz, description) -> float:
    """Return ``frame_rate_hz`` (Hz) as a float if the display can apply frames at that rate.

    Raises
    ------
    ValueError
        If it is not a finite number > 0 Hz, or exceeds ``description.frame_rate_hz``.
    """
    rate = rules.positive(frame_rate_hz, "frame_rate_hz", "Hz", fix="give e.g. 1000.0")
    if rate > float(description.frame_rate_hz) * (1 + 1e-12):
        raise ValueError(
            f"frame_rate_hz: {rate!r} Hz exceeds the refresh rate of display "
            f"{description.display_id!r}, {description.frame_rate_hz!r} Hz (it could not apply the "
            "frames); render the stimulus at that rate or lower"
        )
    return rate


def check_frames(frames, frame_rate_hz, description, *, name: str = "frames") -> tuple[np.ndarray, float]:
    """Validate a frame block against a description's shape; return (float64 copy, rate).

    Raises
    ------
    ValueError
        If ``frames`` is not a finite 2-D array with one column per tractor and at least one
        row, or ``frame_rate_hz`` is not a finite positive number no higher than the display's
        refresh rate ``description.frame_rate_hz``.
    """
    rate = check_frame_rate(frame_rate_hz, description)
    array = np.array(frames, dtype=float)
    n = int(description.n_tractors)
    if array.ndim != 2 or array.shape[1] != n or array.shape[0] < 1:
        raise ValueError(
            f"{name}: must have shape (n_frames >= 1, n_tractors = {n}) for display "
            f"{description.display_id!r}, got shape {array.shape}; give one row per frame and one "
            "column per tractor (row-major: row * n_columns + column)"
        )
    bad = ~np.isfinite(array)
    if bad.any():
        frame, tractor = (int(i) for i in np.argwhere(bad)[0])
        raise ValueError(
            f"{name}: must be finite, got {float(array[frame, tractor])!r} at frame {frame}, tractor "
            f"{tractor} ({int(bad.sum())} non-finite values); fix the drive that produced it"
        )
    return array, rate


def limit_violations(frames, frame_rate_hz: float, description, *, command: str | None = None,
                     initial=None, tolerance: float = 0.0) -> list[dict]:
    """List where a frame block breaks the description's amplitude, slew-rate or duty limits.

    Parameters
    ----------
    frames : array_like, shape (n_frames, n_tractors)
        Commanded values (Pa or m, per ``command``).
    frame_rate_hz : float
        Frame rate of the block, Hz (at most the display's). The slew limit per frame is
        ``max_slew_rate_per_s * full_scale / description.frame_rate_hz``, as in
        ``DisplayDescription.check_commands``.
    description : DisplayDescription
        The display and its limits.
    command : {"traction", "deflection"}, optional
        What the values are (default: see :func:`resolve_command`).
    initial : array_like, shape (n_tractors,), optional
        Outputs before the first frame (default zero: a display starts from rest).
    tolerance : float
        Slack on the amplitude and slew limits, as a fraction of full scale (e.g. ``2**-23``
        for the float32 rounding of the wire format).

    Returns
    -------
    list of dict
        One dict per (kind, tractor) that breaks a limit: ``kind`` (``"amplitude"``,
        ``"slew"`` or ``"duty"``), ``tractor``, ``frame`` (the worst; -1 for duty), ``value``
        and ``limit``. Empty when the block is within limits.
    """
    array, rate = check_frames(frames, frame_rate_hz, description)
    lim = limits(description, command)
    start = np.zeros(array.shape[1]) if initial is None else np.asarray(initial, dtype=float)
    slack = tolerance * lim["amplitude"]
    out = []
    jumps = np.abs(np.diff(np.vstack([start, array]), axis=0))
    for kind, values, limit in (
        ("amplitude", np.abs(array), lim["amplitude"]),
        ("slew", jumps, lim["step"]),
    ):
        excess = values - limit - slack
        for tractor in np.flatnonzero((excess > 0).any(axis=0)):
            frame = int(np.argmax(excess[:, tractor]))
            out.append({"kind": kind, "tractor": int(tractor), "frame": frame,
                        "value": float(values[frame, tractor]), "limit": float(limit[tractor])})
    on = np.count_nonzero(array, axis=0)
    allowed = math.floor(lim["duty"] * array.shape[0] * (1 + 1e-12))
    for tractor in np.flatnonzero(on > allowed):
        out.append({"kind": "duty", "tractor": int(tractor), "frame": -1,
                    "value": float(on[tractor] / array.shape[0]), "limit": lim["duty"]})
    return out

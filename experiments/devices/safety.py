"""A safety layer that no stimulus can bypass: :class:`SafeDisplay`.

``SafeDisplay(display, on_event)`` wraps any :class:`~tactilab.experiments.devices.display.Display`.
Every block of frames it is given is *limited* before the wrapped display ever sees it:

1. **amplitude**: ``|command| <= full scale`` (``max_traction_pa`` or ``max_deflection_m``);
2. **slew rate**: ``|command[k] - command[k-1]| <= max_slew_rate_per_s * full_scale /
   description.frame_rate_hz`` (the display's refresh rate; a block may be played at that rate
   or slower), starting from rest (a block starts at zero);
3. **rest at the end**: the block ends at zero (the last frame is 0, reached within the slew
   limit), so the display is at rest between blocks;
4. **duty**: at most ``floor(max_duty_cycle * n_frames)`` frames of a block are non-zero per
   tractor. The limiter keeps a reserve: a tractor is forced to ramp down (at the slew limit)
   as soon as continuing would leave too few frames to reach zero within its budget.

The limits hold exactly for the float32 values of the wire format: the limiter works with
margins of ``2**-22`` of full scale, larger than float32 rounding.

The wrapped display is zeroed on any exception during ``load`` or ``play``, on Ctrl-C
(SIGINT) and on SIGTERM, SIGHUP, SIGQUIT and SIGUSR1 (:data:`STOP_SIGNALS`); the signal
handlers are installed only while playing (from the main thread) and the previous ones are
restored afterwards, then the signal is re-delivered to them (so SIGINT still raises
``KeyboardInterrupt`` and an un-handled SIGTERM still ends the process, after the display is at
zero). SIGKILL and power loss cannot be caught: only the device's watchdog covers them.

Every intervention is reported to ``on_event`` as a dict with the keys ``kind``, ``tractor``,
``frame``, ``requested``, ``applied``, ``time`` (UTC, ISO 8601), ``monotonic_s``, ``limit``,
``unit``, ``n_frames`` and ``display_id``. Limiting events are aggregated per kind and block
(each event is committed durably by the runner, so a clipped 60-tractor drive gives one
event, not 60): ``frame`` is the first frame limited, ``n_frames`` how many were,
``tractors`` which, and ``tractor``, ``requested`` / ``applied`` are taken at the sample where
they differed most (``worst_frame``). Zeroing events have ``tractor = None`` (all tractors), ``applied = 0.0``
and ``frame`` the number of frames sent so far when known.
"""

from __future__ import annotations

import math
import signal
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime

import numpy as np

from .display import Display, PlaybackReport
from .display_limits import check_frames, limits

__all__ = ["SafeDisplay", "PlaybackInterrupted", "limit_drive", "MARGIN", "STOP_SIGNALS"]

#: Margin, as a fraction of full scale, kept inside the amplitude and slew limits so that
#: float32 rounding on the wire (at most 2**-24 relative) can never cross them.
MARGIN = 2.0**-22

#: The stop signals: each zeroes the display at once (SIGKILL and power loss cannot be caught:
#: only the device's own watchdog covers them).
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT", "SIGUSR1")
                     if hasattr(signal, name))
_SIGNAL_KIND = {sig: "zero_on_" + signal.Signals(sig).name.lower() for sig in STOP_SIGNALS}


class PlaybackInterrupted(RuntimeError):
    """Playback ended by a signal whose previous handler did not raise; the display is at zero."""


def _now() -> tuple[str, float]:
    return datetime.now(UTC).isoformat(timespec="microseconds"), time.monotonic()


def limit_drive(frames: np.ndarray, frame_rate_hz: float, description, command: str | None = None
                ) -> tuple[np.ndarray, list[dict]]:
    """Limit a block of frames to the description's limits; list the interventions.

    Parameters
    ----------
    frames : ndarray, shape (n_frames, n_tractors)
        Requested commands (Pa or m).
    frame_rate_hz : float
        Frame rate, Hz.
    description : DisplayDescription
        The display and its limits.
    command : {"traction", "deflection"}, optional
        What the values are.

    Returns
    -------
    applied : ndarray, shape (n_frames, n_tractors)
        float32-representable float64 values within every limit (module docstring).
    interventions : list of dict
        One per kind of limit that acted: ``kind`` in ``"amplitude_clip"``, ``"slew_limit"``,
        ``"end_at_rest"``, ``"duty_limit"``; ``tractor`` and ``worst_frame`` (where requested
        and applied differ most), ``frame`` (the first frame limited), ``n_frames`` (frames
        with any tractor limited), ``n_samples`` ((frame, tractor) pairs limited),
        ``tractors`` (those limited), ``requested`` and ``applied`` (at the worst sample),
        ``limit``, ``unit``.
    """
    requested, _ = check_frames(frames, frame_rate_hz, description)
    lim = limits(description, command)
    n_frames, n_tractors = requested.shape
    full, step = lim["amplitude"], lim["step"]
    # Internal limits sit a margin inside the true ones (see MARGIN).
    amp_in = full * (1 - MARGIN)
    step_in = np.where(np.isfinite(step), step * (1 - 1e-8) - 2 * MARGIN * full, np.inf)
    step_in = np.where(step_in > 0, step_in, step / 2)
    allowed = math.floor(lim["duty"] * n_frames * (1 + 1e-12))

    ideal = np.zeros(n_tractors)  # the exact (float64) track the invariants hold on
    on_count = np.zeros(n_tractors, dtype=np.int64)
    applied = np.empty_like(requested)
    flags = {k: np.zeros(requested.shape, dtype=bool)
             for k in ("amplitude_clip", "slew_limit", "end_at_rest", "duty_limit")}
    for k in range(n_frames):
        prev = ideal
        want = requested[k]
        flags["amplitude_clip"][k] = np.abs(want) > full
        c = np.clip(want, -amp_in, amp_in)
        flags["slew_limit"][k] = np.abs(c - prev) > step
        c = np.clip(c, prev - step_in, prev + step_in)
        rest = np.zeros(n_tractors) if k == n_frames - 1 else step_in * (n_frames - 1 - k)
        flags["end_at_rest"][k] = np.abs(c) > rest * (1 + 1e-12) + MARGIN * full
        c = np.clip(c, -rest, rest)
        # Frames still needed, this one included, to bring c back to rest at the slew limit.
        needed = np.where(c != 0, np.maximum(1, np.ceil(np.abs(c) / step_in - 1e-9)), 0)
        over = on_count + needed > allowed
        if over.any():
            down = np.where(np.abs(prev) <= step_in * (1 + 1e-9), 0.0,
                            prev - np.sign(prev) * np.minimum(step_in, np.abs(prev)))
            down = np.clip(down, -rest, rest)
            flags["duty_limit"][k] = over & (c != down)
            c = np.where(over, down, c)
        ideal = c
        on_count += c != 0
        applied[k] = c.astype(np.float32)
    limit = {"amplitude_clip": full, "slew_limit": step * float(description.frame_rate_hz),
             "end_at_rest": np.zeros(n_tractors), "duty_limit": np.full(n_tractors, lim["duty"])}
    unit = {"amplitude_clip": lim["unit"], "slew_limit": lim["unit"] + "/s",
            "end_at_rest": lim["unit"], "duty_limit": "fraction of frames"}
    events = []
    for kind, mask in flags.items():
        if not mask.any():
            continue
        # One event per kind and block (the runner commits each event durably): the worst
        # (frame, tractor) sample, plus where and how often the limit acted.
        diff = np.where(mask, np.abs(requested - applied), -1.0)
        worst, tractor = (int(i) for i in np.unravel_index(int(np.argmax(diff)), diff.shape))
        events.append({
            "kind": kind, "tractor": tractor, "frame": int(np.flatnonzero(mask.any(axis=1))[0]),
            "worst_frame": worst, "n_frames": int(np.count_nonzero(mask.any(axis=1))),
            "n_samples": int(np.count_nonzero(mask)),
            "tractors": [int(t) for t in np.flatnonzero(mask.any(axis=0))],
            "requested": float(requested[worst, tractor]),
            "applied": float(applied[worst, tractor]),
            "limit": float(limit[kind][tractor]),
            "unit": unit[kind],
        })
    return applied, events


class SafeDisplay(Display):
    """Wrap a display so that nothing it plays can break the description's limits.

    Parameters
    ----------
    display : Display
        The driver to protect (simulated, UDP, ...). Its description and command are used.
    on_event : callable(dict) -> None
        Called once per intervention event (see the module docstring), synchronously, before
        the limited frames are handed to ``display`` (for limiting events) or right after the
        display was zeroed (for zeroing events). The runner records these durably.

    Notes
    -----
    ``stop()`` ends playback and zeroes the display. ``zero()`` is the emergency action and is
    exempt from the slew limit (it must be immediate).
    """

    def __init__(self, display: Display, on_event: Callable[[dict], None]) -> None:
        if not isinstance(display, Display):
            raise TypeError(
                f"display: must be a tactilab Display (simulated, udp, ...), got {type(display).__name__}; "
                "wrap a driver instance"
            )
        if not callable(on_event):
            raise TypeError(f"on_event: must be callable(dict), got {type(on_event).__name__}; "
                            "pass e.g. events.append")
        super().__init__(display.description, display.command)
        self.display = display
        self.on_event = on_event
        self._n_interventions = 0
        self._zeroing = False
        self._pending_signal: int | None = None

    # ----- events -----------------------------------------------------------------------
    def _emit(self, event: dict) -> None:
        stamp, mono = _now()
        event = {**event, "time": stamp, "monotonic_s": mono,
                 "display_id": self.description.display_id}
        self._n_interventions += 1
        self.on_event(event)

    def _zero_and_report(self, kind: str, frame: int | None, detail: str = "") -> None:
        self._zeroing = True  # a second Ctrl-C must not interrupt the zeroing itself
        try:
            self.display.stop()
            self.display.zero()
        finally:
            self._zeroing = False
            event = {"kind": kind, "tractor": None, "frame": frame, "requested": None,
                     "applied": 0.0, "limit": None, "unit": "m" if self.display.command == "deflection" else "Pa",
                     "n_frames": 0}
            if detail:
                event["detail"] = detail
            self._emit(event)

    # ----- Display interface ------------------------------------------------------------
    def load(self, frames: np.ndarray, frame_rate_hz: float) -> None:
        """Limit ``frames`` (see the module docstring), report interventions, load the result.

        Raises
        ------
        ValueError
            If the frames are not a finite (n_frames, n_tractors) block, or the rate is not
            positive or exceeds the display's refresh rate; the display is zeroed first.
        """
        self._n_interventions = 0
        try:
            applied, events = limit_drive(frames, frame_rate_hz, self.description, self.command)
            for event in events:
                self._emit(event)
            applied.flags.writeable = False
            self._frames, self._frame_rate_hz = applied, float(frame_rate_hz)
            self.display.load(applied, frame_rate_hz)
        except BaseException as err:
            self._zero_and_report("zero_on_exception", None, f"{type(err).__name__}: {err}")
            raise

    def _play(self, frames: np.ndarray, frame_rate_hz: float) -> PlaybackReport:
        installed = self._install_handlers()
        self._pending_signal = None
        try:
            report = self.display.play()
        except _SignalStop as stop:
            self._zero_and_report(_SIGNAL_KIND[stop.signum], None)
            self._restore_handlers(installed)
            installed = {}
            signal.raise_signal(stop.signum)  # the previous handler decides what happens next
            raise PlaybackInterrupted(
                f"playback stopped by {signal.Signals(stop.signum).name}; display "
                f"{self.description.display_id!r} zeroed"
            ) from None
        except BaseException as err:
            self._zero_and_report("zero_on_exception", None, f"{type(err).__name__}: {err}")
            raise
        finally:
            self._restore_handlers(installed)
            pending, self._pending_signal = self._pending_signal, None
            if pending is not None:  # a signal that came while zeroing: deliver it now
                signal.raise_signal(pending)
        if report.stopped:
            self._zero_and_report("zero_on_stop", report.frames_sent)
        return report.with_interventions(self._n_interventions)

    def stop(self) -> None:
        """End playback at the next frame boundary; the display is then zeroed."""
        super().stop()
        self.display.stop()

    def _zero(self) -> None:
        self.display.zero()

    @property
    def onset_delay_s(self) -> float:
        """The wrapped display's :attr:`~tactilab.experiments.devices.Display.onset_delay_s`."""
        return self.display.onset_delay_s

    def audit(self) -> int:
        """The wrapped display's :meth:`~tactilab.experiments.devices.Display.audit`."""
        return self.display.audit()

    def close(self) -> None:
        """Close the wrapped display."""
        self.display.close()

    # ----- signals ----------------------------------------------------------------------
    def _install_handlers(self) -> dict:
        if threading.current_thread() is not threading.main_thread():
            return {}  # Python delivers signals to the main thread only

        def handler(signum, _frame):
            if self._zeroing:  # already stopping: remember it, let the zeroing finish
                self._pending_signal = signum
                return
            raise _SignalStop(signum)

        return {sig: signal.signal(sig, handler) for sig in _SIGNAL_KIND}

    @staticmethod
    def _restore_handlers(installed: dict) -> None:
        for sig, previous in installed.items():
            # None: the previous handler was not installed from Python; the default is safest.
            signal.signal(sig, signal.SIG_DFL if previous is None else previous)


class _SignalStop(BaseException):
    """Raised by the temporary signal handler to unwind playback at once."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum

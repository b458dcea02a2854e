"""A device emulator on loopback: acknowledges frames, counts late and missing ones, records
everything it receives, and zeroes its outputs when frames stop (watchdog).

It is the reference device of ``docs/udp-frame-format.md`` (version 3; the logic is in
:mod:`tactilab.experiments.devices.emulator_device`):

- pairing: it holds a 32-byte pairing key (``pairing_key``; ``--pairing-key FILE``). An ARM
  is accepted only when its tag verifies under that key, its host nonce was never seen and no
  session is live; the device answers ARMED (its own nonce, tagged with the key over the
  host's nonce: proof to the host that it is the paired device), zeroes its outputs and pins
  the sender's (ip, port). Every other ARM, and every datagram from a sender without a
  session, gets the same untagged ``refused`` (an intruder cannot tell busy from idle, nor a
  wrong key from busy); counted and logged. Older versions are refused (``bad_version``);
- every message of the session must carry a valid MAC under the session key (``bad_mac``) and a
  seq above the last one (``stale``: replays and resets);
- states: ``disarmed`` (no session, outputs 0), ``idle`` (armed, outputs 0), ``streaming`` (a
  FRAME was accepted), ``tripped`` (the watchdog ended the session; its messages are answered
  ``disarmed``, a new ARM is accepted);
- ZERO: outputs 0 at once, FIFO emptied, state ``idle``, ACK status ``zeroed``; DISARM: the
  same, and the session ends (``released``);
- FRAME: accepted into a FIFO when of the expected count, finite (``non_finite``), due at most
  one FIFO's worth of ticks ahead (``bad_due``) and the FIFO has room (``overflow``), and
  acknowledged ``applied`` when its tick applies it: at its due time on the device's clock, one
  frame per tick (the last value held when the FIFO is empty; ticks are a fixed timer, never
  less than one period apart), so a burst of frames from the host never becomes an output
  burst. Each applied frame is clamped to the description's full scale and to one slew step
  per tick (``limits``), and every clamp is recorded;
- watchdog: while armed, no valid message for ``watchdog_s`` after the last message or the due
  time of the last accepted frame, whichever is later -> outputs 0, the session ends (state
  ``tripped``), the zeroing time recorded. With the host dead, the outputs are zero at most
  the host's lookahead plus ``watchdog_s`` after its last message.

A frame is late when the tick that applied it came more than ``late_after_s`` after its due
time. Missing frames are gaps in the sequence numbers.

It binds to 127.0.0.1 only (loopback), stops after ``max_seconds`` or on SIGTERM / SIGINT, and
writes a JSON-lines record (one line per applied frame, clamp or event; flushed at once, frame lines
while more frames wait at least every 20 ms) that
:func:`read_record` loads.
"""

from __future__ import annotations

import json
import math
import pathlib
import signal
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tactilab.data_schemas.display import DisplayDescription

from .emulator_device import DEFAULT_TICK_HZ, LOOPBACK, Device
from .link import KEY_SIZE, MAX_VALUES

__all__ = ["LOOPBACK", "DEFAULT_TICK_HZ", "EmulatorSummary", "emulate", "read_record"]


@dataclass
class EmulatorSummary:
    """Counts of one emulator run."""

    port: int
    frames_applied: int = 0
    late: int = 0
    missing: int = 0
    stale: int = 0
    rejected: int = 0
    zero_commands: int = 0
    watchdog_trips: int = 0
    clamps: int = 0
    sessions: int = 0
    foreign: int = 0
    refused_arms: int = 0
    bad_mac: int = 0
    duration_s: float = 0.0


#: the longest time the emulator counts (its clock is in integer ns), s
MAX_SECONDS = 1e7


def _seconds(value, name: str, *, allow_none: bool = False) -> float | None:
    if value is None and allow_none:
        return None
    number = math.nan if isinstance(value, bool) or value is None else float(value)
    if not (math.isfinite(number) and number > 0):
        raise ValueError(f"{name}: must be a finite number of seconds > 0, got {value!r}; give e.g. 0.05")
    if number > MAX_SECONDS:  # the emulator counts in integer ns; 1e300 s overflowed to inf there
        raise ValueError(f"{name}: must be at most {MAX_SECONDS:g} s (about 4 months), got {value!r}; "
                         "give e.g. 60 and restart the emulator for longer runs")
    return number


def emulate(port: int = 0, *, watchdog_s: float = 0.05, record: str | pathlib.Path | None = None,
            max_seconds: float = 60.0, n_tractors: int | None = None, late_after_s: float = 1e-3,
            log: Callable[[str], None] = print, stop: threading.Event | None = None,
            handle_signals: bool = True, limits=None, fifo_frames: int = 1000,
            pairing_key: bytes | None = None) -> EmulatorSummary:
    """Run the emulator until ``max_seconds`` pass, ``stop`` is set, or SIGTERM / SIGINT.

    Parameters
    ----------
    port : int
        UDP port on 127.0.0.1 (0: any free port; the port is logged as
        ``listening on udp://127.0.0.1:PORT``).
    watchdog_s : float
        Zero the outputs when no valid message arrived for this long after the last message or
        the due time of the last accepted frame, whichever is later, while armed, s.
    record : path, optional
        JSON-lines file to write every message and event to.
    max_seconds : float
        Stop after this long, s (the emulator never runs unbounded).
    n_tractors : int, optional
        Expected values per FRAME; other counts are refused (status ``bad_count``). Default:
        the count of the first FRAME after each ZERO.
    late_after_s : float
        A frame applied more than this after its due time is late, s.
    log : callable(str)
        Where to print events (the CLI passes ``print`` with flush).
    stop : threading.Event, optional
        Set it to stop the emulator (in-process use).
    handle_signals : bool
        Install SIGTERM / SIGINT handlers that stop the loop (main thread only).
    limits : DisplayDescription or path, optional
        The display description (or its JSON file): its ``frame_rate_hz`` sets the device tick,
        and every applied frame is clamped to ``+-full scale`` and to one slew step per tick
        (``max_slew_rate_per_s * full_scale / frame_rate_hz``); each clamp is recorded. Its
        tractor count is expected unless ``n_tractors`` is given. Without it the device ticks at
        1 kHz and clamps nothing (it still refuses NaN and infinite values).
    fifo_frames : int
        Capacity of the FIFO of accepted frames (>= 1, < 65536); a FRAME that finds it full is
        refused with status ``overflow``, one due more than this many ticks ahead ``bad_due``.
    pairing_key : bytes
        The 32-byte pairing key its hosts hold (:func:`~.pairing.read_pairing_key` reads a key
        file); required.

    Returns
    -------
    EmulatorSummary

    Raises
    ------
    ValueError
        If a parameter is out of range.
    """
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port < 65536:
        raise ValueError(f"port: must be an integer in 0..65535 (0: any free port), got {port!r}; give e.g. 9000")
    watchdog_s = _seconds(watchdog_s, "watchdog_s")
    max_seconds = _seconds(max_seconds, "max_seconds")
    late_after_s = _seconds(late_after_s, "late_after_s")
    if n_tractors is not None and (isinstance(n_tractors, bool) or not isinstance(n_tractors, int)
                                   or n_tractors < 1):
        raise ValueError(f"n_tractors: must be an integer >= 1, got {n_tractors!r}; give the display's tractor count")
    if n_tractors is not None and n_tractors > MAX_VALUES:  # the size rule: no FRAME can carry more (64 KiB datagram)
        raise ValueError(f"n_tractors: a FRAME carries at most {MAX_VALUES} values (the UDP datagram limit), got "
                         f"{n_tractors}; give at most {MAX_VALUES}, the display's tractor count")
    if isinstance(fifo_frames, bool) or not isinstance(fifo_frames, int) or not 1 <= fifo_frames < 2**16:
        raise ValueError(f"fifo_frames: must be an integer in 1..65535, got {fifo_frames!r}; give e.g. 1000")
    if not isinstance(pairing_key, (bytes, bytearray)) or len(pairing_key) != KEY_SIZE:
        got = f"{len(pairing_key)} bytes" if isinstance(pairing_key, (bytes, bytearray)) else repr(pairing_key)
        raise ValueError(f"pairing_key: the emulator needs the {KEY_SIZE}-byte pairing key its hosts hold, got {got}; "
                         "give --pairing-key FILE (create one with `tactilab device pair FILE`)")
    if limits is not None and not isinstance(limits, DisplayDescription):
        try:
            limits = DisplayDescription.load(limits)
        except (OSError, ValueError) as exc:
            raise ValueError(f"limits: cannot read the display description {str(limits)!r} ({' '.join(str(exc).split())[:200]}); "
                             "give a DisplayDescription JSON file") from None
    if limits is not None and n_tractors is None:
        n_tractors = int(limits.n_tractors)
    stop = stop or threading.Event()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    previous = {}
    out = open(record, "w", encoding="utf-8") if record is not None else None  # noqa: SIM115
    try:
        sock.bind((LOOPBACK, port))
        summary = EmulatorSummary(port=sock.getsockname()[1])
        if handle_signals and threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGTERM, signal.SIGINT):
                previous[sig] = signal.signal(sig, lambda signum, frame: stop.set())
        Device(sock, summary, watchdog_s, max_seconds, n_tractors, late_after_s, log, out, stop,
                limits, fifo_frames, bytes(pairing_key)).run()
        return summary
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        sock.close()
        if out is not None:
            out.close()


def read_record(path: str | pathlib.Path) -> dict:
    """Load an emulator record.

    Returns
    -------
    dict
        ``streams``: one dict per stream (the frames between two ZEROs or a watchdog trip) with
        ``values`` (ndarray (n_frames, n_tractors), the applied outputs, float32 exact),
        ``seq``, ``arrival_ns`` (when each frame was received), ``applied_ns`` (when the tick
        applied it), ``tick_ns`` (the tick's scheduled time on the device's timer) and ``due_ns``
        (the frame's due time) (ndarrays (n_frames,), device clock, ns); ``n_frames``: frames in
        all streams; ``events``:
        every non-frame entry, in order; ``clamps``: the clamp entries; ``summary``: the final
        counts (None if the emulator was killed).

    Raises
    ------
    OSError
        If the file cannot be read.
    ValueError
        If a line is not JSON.
    """
    streams, events, current = [], [], []
    summary = None

    def close_stream() -> None:
        if current:
            streams.append({"values": np.array([e["values"] for e in current], dtype=float),
                            "seq": np.array([e["seq"] for e in current], dtype=np.int64),
                            "arrival_ns": np.array([e.get("rx_ns", e["t_ns"]) for e in current], dtype=np.int64),
                            "applied_ns": np.array([e["t_ns"] for e in current], dtype=np.int64),
                            "tick_ns": np.array([e.get("tick_ns", e["t_ns"]) for e in current], dtype=np.int64),
                            "due_ns": np.array([e.get("due_ns", e["t_ns"]) for e in current], dtype=np.int64)})
            current.clear()

    with open(path, encoding="utf-8") as handle:
        for number, line in enumerate(handle, start=1):
            try:
                entry = json.loads(line)
            except json.JSONDecodeError as err:
                raise ValueError(f"{path}: line {number} is not JSON ({err}); is it an emulator record?") from None
            if entry["type"] == "frame":
                current.append(entry)
                continue
            events.append(entry)
            if entry["type"] in ("zero", "watchdog", "arm", "disarm"):
                close_stream()
            if entry["type"] == "summary":
                summary = entry
    close_stream()
    return {"streams": streams, "n_frames": sum(len(s["seq"]) for s in streams), "events": events,
            "clamps": [e for e in events if e["type"] == "clamp"], "summary": summary}

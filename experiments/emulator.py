"""A device emulator on loopback: acknowledges frames, counts late and missing ones, records
everything it receives, and zeroes its outputs when frames stop (watchdog).

It implements the device side of ``docs/udp-frame-format.md``:

- states: ``idle`` (outputs 0, watchdog off), ``streaming`` (a FRAME was applied; the
  watchdog runs), ``tripped`` (the watchdog zeroed the outputs; FRAMEs are refused with
  status ``disarmed`` until a ZERO);
- ZERO: outputs 0 at once, FIFO emptied, state ``idle``, ACK status ``zeroed``;
- FRAME: accepted into a FIFO when newer than the last one (serial-number order), of the
  expected count and finite (NaN or inf: status ``non_finite``; FIFO full: ``overflow``), and
  acknowledged ``applied`` when its tick applies it. The device applies the oldest accepted frame on each of its OWN ticks
  (one frame per tick, the last value held when the FIFO is empty; a tick never comes less
  than one period after the previous one), so a burst of late frames from the host never
  becomes an output burst. Each applied frame is clamped to the description's full scale and
  to one slew step per tick (``limits``), and every clamp is recorded;
- watchdog: in ``streaming``, no valid FRAME or ZERO for ``watchdog_s`` -> outputs 0,
  state ``tripped``, the zeroing time recorded.

Lateness is judged from the host's timestamps, so no clock sharing is needed: a frame is late
when its transit ``arrival - timestamp`` exceeds the smallest transit seen in the stream by more
than ``late_after_s``. Missing frames are gaps in the sequence numbers.

It binds to 127.0.0.1 only (loopback), stops after ``max_seconds`` or on SIGTERM / SIGINT, and
writes a JSON-lines record (one line per applied frame, clamp or event, flushed at once) that
:func:`read_record` loads.
"""

from __future__ import annotations

import collections
import json
import math
import pathlib
import select
import signal
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from tactilab.data_schemas.display import DisplayDescription

from .udp import ACK, FRAME, STATUS_CODE, ZERO, FLAG_WATCHDOG_TRIPPED, FrameFormatError, decode, encode

__all__ = ["LOOPBACK", "EmulatorSummary", "emulate", "read_record"]

#: The only address the emulator ever binds to.
LOOPBACK = "127.0.0.1"
_SEQ_MOD = 2**32


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
    duration_s: float = 0.0


_MAX_SECONDS = 1e7
#: The device tick without a display description (``limits``), Hz.
DEFAULT_TICK_HZ = 1000.0


def _seconds(value, name: str, *, allow_none: bool = False) -> float | None:
    if value is None and allow_none:
        return None
    number = math.nan if isinstance(value, bool) or value is None else float(value)
    if not (math.isfinite(number) and number > 0):
        raise ValueError(f"{name}: must be a finite number of seconds > 0, got {value!r}; give e.g. 0.05")
    if number > _MAX_SECONDS:  # the emulator counts in integer ns; 1e300 s overflowed to inf there
        raise ValueError(f"{name}: must be at most {_MAX_SECONDS:g} s (about 4 months), got {value!r}; "
                         "give e.g. 60 and restart the emulator for longer runs")
    return number


def emulate(port: int = 0, *, watchdog_s: float = 0.05, record: str | pathlib.Path | None = None,
            max_seconds: float = 60.0, n_tractors: int | None = None, late_after_s: float = 1e-3,
            log: Callable[[str], None] = print, stop: threading.Event | None = None,
            handle_signals: bool = True, limits=None, fifo_frames: int = 1000) -> EmulatorSummary:
    """Run the emulator until ``max_seconds`` pass, ``stop`` is set, or SIGTERM / SIGINT.

    Parameters
    ----------
    port : int
        UDP port on 127.0.0.1 (0: any free port; the port is logged as
        ``listening on udp://127.0.0.1:PORT``).
    watchdog_s : float
        Zero the outputs when no valid FRAME or ZERO arrived for this long while streaming, s.
    record : path, optional
        JSON-lines file to write every message and event to.
    max_seconds : float
        Stop after this long, s (the emulator never runs unbounded).
    n_tractors : int, optional
        Expected values per FRAME; other counts are refused (status ``bad_count``). Default:
        the count of the first FRAME after each ZERO.
    late_after_s : float
        Transit delay beyond the stream's smallest that makes a frame late, s.
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
        Capacity of the FIFO of accepted frames (>= 1); a FRAME that finds it full is refused
        with status ``overflow``.

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
    if isinstance(fifo_frames, bool) or not isinstance(fifo_frames, int) or fifo_frames < 1:
        raise ValueError(f"fifo_frames: must be an integer >= 1, got {fifo_frames!r}; give e.g. 1000")
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
        _Device(sock, summary, watchdog_s, max_seconds, n_tractors, late_after_s, log, out, stop,
                limits, fifo_frames).run()
        return summary
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        sock.close()
        if out is not None:
            out.close()


class _Device:
    """The device logic: a FIFO of accepted FRAMEs applied one per tick, clamped per tick."""

    def __init__(self, sock, summary, watchdog_s, max_seconds, n_tractors, late_after_s, log, out, stop,
                 limits=None, fifo_frames: int = 1000):
        self.sock, self.summary, self.log, self.out, self.stop = sock, summary, log, out, stop
        self.watchdog_ns = int(watchdog_s * 1e9)
        self.max_ns = int(max_seconds * 1e9)
        self.late_ns = int(late_after_s * 1e9)
        self.n_tractors = n_tractors  # None: learned from the first FRAME of each stream
        self.stream_tractors = n_tractors
        self.state = "idle"
        self.outputs = np.zeros(n_tractors or 0, dtype=np.float32)
        self.last_seq: int | None = None
        self.last_valid_ns = 0
        self.min_transit: int | None = None
        self.tripped_flag = False
        self.fifo: collections.deque = collections.deque()
        self.fifo_frames = fifo_frames
        rate = float(limits.frame_rate_hz) if limits is not None else DEFAULT_TICK_HZ
        self.period_ns = int(round(1e9 / rate))
        self.next_tick_ns = 0
        self.full, self.step, self.unit = math.inf, math.inf, None
        if limits is not None:
            kind = "traction" if limits.max_traction_pa is not None else "deflection"
            self.full = float(limits.full_scale(kind))
            self.unit = "Pa" if kind == "traction" else "m"
            if limits.max_slew_rate_per_s is not None:
                self.step = float(limits.max_slew_rate_per_s) * self.full / rate

    def write(self, entry: dict) -> None:
        if self.out is not None:
            self.out.write(json.dumps(entry) + "\n")
            self.out.flush()

    def run(self) -> None:
        start = time.monotonic_ns()
        self.write({"type": "start", "t_ns": start, "port": self.summary.port,
                    "watchdog_s": self.watchdog_ns / 1e9, "n_tractors": self.n_tractors,
                    "tick_ns": self.period_ns, "full_scale": None if math.isinf(self.full) else self.full,
                    "max_step": None if math.isinf(self.step) else self.step, "unit": self.unit})
        self.log(f"listening on udp://{LOOPBACK}:{self.summary.port} (watchdog "
                 f"{self.watchdog_ns / 1e6:g} ms, tick {self.period_ns / 1e6:g} ms, stops after "
                 f"{self.max_ns / 1e9:g} s or on SIGTERM)")
        end = start + self.max_ns
        while not self.stop.is_set():
            now = time.monotonic_ns()
            if now >= end:
                break
            wake = end
            if self.state == "streaming":
                deadline = self.last_valid_ns + self.watchdog_ns
                if now >= deadline:
                    self.trip(now, deadline)
                    continue
                wake = min(wake, deadline)
            if self.fifo:
                if now >= self.next_tick_ns:
                    self.tick(now)
                    continue
                wake = min(wake, self.next_tick_ns)
            # sleep until the next event (a tick is never early; a late one delays the next)
            timeout = (wake - now) / 1e9
            readable, _, _ = select.select([self.sock], [], [], min(max(timeout, 0.0), 0.1))
            if readable:
                data, sender = self.sock.recvfrom(65536)
                self.handle(data, sender, time.monotonic_ns())
        self.summary.duration_s = (time.monotonic_ns() - start) / 1e9
        self.write({"type": "summary", "t_ns": time.monotonic_ns(), **asdict(self.summary)})
        self.log("summary: " + ", ".join(f"{k} {v}" for k, v in asdict(self.summary).items()))

    def tick(self, now: int) -> None:
        """Apply the oldest accepted FRAME, clamped to the limits and to one step per tick."""
        seq, values, rx_ns, ts_ns, late, sender = self.fifo.popleft()
        requested = values.astype(float)
        target = np.clip(requested, -self.full, self.full)
        self._clamped("amplitude", seq, now, requested, target, self.full)
        previous = self.outputs.astype(float) if self.outputs.size == target.size else np.zeros(target.size)
        applied = np.clip(target, previous - self.step, previous + self.step)
        self._clamped("slew", seq, now, target, applied, self.step)
        self.outputs = applied.astype(np.float32)
        # the next tick comes one period after THIS one, never earlier: a late tick never makes
        # the next step come sooner, so one step per tick is also the real-time slew limit
        self.next_tick_ns = now + self.period_ns
        self.summary.frames_applied += 1
        self.write({"type": "frame", "t_ns": now, "rx_ns": rx_ns, "seq": seq, "ts_ns": ts_ns, "late": late,
                    "values": [float(v) for v in self.outputs]})
        flags = FLAG_WATCHDOG_TRIPPED if self.tripped_flag else 0
        self.sock.sendto(encode(ACK, seq, ts_ns, status=STATUS_CODE["applied"], flags=flags,
                                frames_applied=self.summary.frames_applied), sender)

    def _clamped(self, kind: str, seq: int, now: int, wanted: np.ndarray, got: np.ndarray, limit: float) -> None:
        changed = wanted != got
        if not changed.any():
            return
        worst = int(np.argmax(np.abs(wanted - got)))
        self.summary.clamps += 1
        self.write({"type": "clamp", "t_ns": now, "seq": seq, "kind": kind,
                    "tractors": [int(t) for t in np.flatnonzero(changed)], "tractor": worst,
                    "requested": float(wanted[worst]), "applied": float(got[worst]), "limit": limit,
                    "unit": self.unit if kind == "amplitude" else f"{self.unit} per tick"})

    def trip(self, now: int, deadline: int) -> None:
        self.outputs[:] = 0
        dropped = len(self.fifo)
        self.fifo.clear()
        self.state = "tripped"
        self.tripped_flag = True
        self.summary.watchdog_trips += 1
        entry = {"type": "watchdog", "t_ns": now, "last_valid_ns": self.last_valid_ns,
                 "deadline_ns": deadline, "late_by_ns": now - deadline, "dropped": dropped}
        self.write(entry)
        self.log(f"watchdog: no frame for {(now - self.last_valid_ns) / 1e6:.1f} ms "
                 f"(limit {self.watchdog_ns / 1e6:g} ms); outputs zeroed")

    def reply(self, sender, message, status: str) -> None:
        flags = FLAG_WATCHDOG_TRIPPED if self.tripped_flag else 0
        self.sock.sendto(encode(ACK, message.seq, message.timestamp_ns, status=STATUS_CODE[status],
                                flags=flags, frames_applied=self.summary.frames_applied), sender)

    def refuse(self, sender, message, arrival: int, status: str, reason: str) -> None:
        self.summary.rejected += 1
        self.write({"type": "rejected", "t_ns": arrival, "seq": message.seq, "reason": reason})
        self.reply(sender, message, status)

    def handle(self, data: bytes, sender, arrival: int) -> None:
        try:
            message = decode(data)
        except FrameFormatError as err:
            self.summary.rejected += 1
            self.write({"type": "rejected", "t_ns": arrival, "reason": str(err)})
            return
        if message.kind == ZERO:
            self.outputs[:] = 0  # at once, exempt from the per-tick step: the safe state
            self.fifo.clear()
            self.state, self.last_seq, self.min_transit = "idle", None, None
            self.stream_tractors = self.n_tractors
            self.tripped_flag = False
            self.last_valid_ns = arrival
            self.summary.zero_commands += 1
            self.write({"type": "zero", "t_ns": arrival, "seq": message.seq, "ts_ns": message.timestamp_ns})
            self.reply(sender, message, "zeroed")
            return
        if message.kind != FRAME:
            self.refuse(sender, message, arrival, "bad_message", f"unexpected type {message.kind}")
            return
        expected = self.stream_tractors if self.stream_tractors is not None else message.values.size
        if message.values.size != expected:
            self.refuse(sender, message, arrival, "bad_count", f"{message.values.size} values, expected {expected}")
            return
        if self.state == "tripped":
            self.refuse(sender, message, arrival, "disarmed", "disarmed")
            return
        if not np.all(np.isfinite(message.values)):
            self.refuse(sender, message, arrival, "non_finite", "NaN or infinite values")
            return
        if self.last_seq is not None:
            gap = (message.seq - self.last_seq) % _SEQ_MOD
            if gap == 0 or gap >= 2**31:
                self.summary.stale += 1
                self.write({"type": "stale", "t_ns": arrival, "seq": message.seq})
                self.reply(sender, message, "stale")
                return
        if len(self.fifo) >= self.fifo_frames:
            self.refuse(sender, message, arrival, "overflow", f"FIFO full ({self.fifo_frames} frames)")
            return
        if self.last_seq is not None:
            self.summary.missing += gap - 1
        transit = arrival - message.timestamp_ns
        self.min_transit = transit if self.min_transit is None else min(self.min_transit, transit)
        late = transit - self.min_transit > self.late_ns
        self.summary.late += int(late)
        self.stream_tractors = expected
        if self.outputs.size != expected:
            self.outputs = np.zeros(expected, dtype=np.float32)
        self.fifo.append((message.seq, message.values.copy(), arrival, message.timestamp_ns, bool(late), sender))
        self.state, self.last_seq, self.last_valid_ns = "streaming", message.seq, arrival
        # acknowledged `applied` by the tick that applies it


def read_record(path: str | pathlib.Path) -> dict:
    """Load an emulator record.

    Returns
    -------
    dict
        ``streams``: one dict per stream (the frames between two ZEROs or a watchdog trip) with
        ``values`` (ndarray (n_frames, n_tractors), the applied outputs, float32 exact),
        ``seq``, ``arrival_ns`` (when each frame was received) and ``applied_ns`` (the tick that
        applied it) (ndarrays (n_frames,)); ``n_frames``: frames in all streams; ``events``:
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
                            "applied_ns": np.array([e["t_ns"] for e in current], dtype=np.int64)})
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
            if entry["type"] in ("zero", "watchdog"):
                close_stream()
            if entry["type"] == "summary":
                summary = entry
    close_stream()
    return {"streams": streams, "n_frames": sum(len(s["seq"]) for s in streams), "events": events,
            "clamps": [e for e in events if e["type"] == "clamp"], "summary": summary}

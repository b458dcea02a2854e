"""A device emulator on loopback: acknowledges frames, counts late and missing ones, records
everything it receives, and zeroes its outputs when frames stop (watchdog).

It implements the device side of ``docs/udp-frame-format.md``:

- states: ``idle`` (outputs 0, watchdog off), ``streaming`` (a FRAME was applied; the
  watchdog runs), ``tripped`` (the watchdog zeroed the outputs; FRAMEs are refused with
  status ``disarmed`` until a ZERO);
- ZERO: outputs 0, state ``idle``, ACK status ``zeroed``;
- FRAME: applied when newer than the last one (serial-number order) and of the expected
  count; ACK status ``applied``;
- watchdog: in ``streaming``, no valid FRAME or ZERO for ``watchdog_s`` -> outputs 0,
  state ``tripped``, the zeroing time recorded.

Lateness is judged from the host's timestamps, so no clock sharing is needed: a frame is late
when its transit ``arrival - timestamp`` exceeds the smallest transit seen in the stream by more
than ``late_after_s``. Missing frames are gaps in the sequence numbers.

It binds to 127.0.0.1 only (loopback), stops after ``max_seconds`` or on SIGTERM / SIGINT, and
writes a JSON-lines record (one line per message or event, flushed at once) that
:func:`read_record` loads.
"""

from __future__ import annotations

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
    duration_s: float = 0.0


_MAX_SECONDS = 1e7


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
            handle_signals: bool = True) -> EmulatorSummary:
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
        _Device(sock, summary, watchdog_s, max_seconds, n_tractors, late_after_s, log, out, stop).run()
        return summary
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        sock.close()
        if out is not None:
            out.close()


class _Device:
    def __init__(self, sock, summary, watchdog_s, max_seconds, n_tractors, late_after_s, log, out, stop):
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

    def write(self, entry: dict) -> None:
        if self.out is not None:
            self.out.write(json.dumps(entry) + "\n")
            self.out.flush()

    def run(self) -> None:
        start = time.monotonic_ns()
        self.write({"type": "start", "t_ns": start, "port": self.summary.port,
                    "watchdog_s": self.watchdog_ns / 1e9, "n_tractors": self.n_tractors})
        self.log(f"listening on udp://{LOOPBACK}:{self.summary.port} (watchdog "
                 f"{self.watchdog_ns / 1e6:g} ms, stops after {self.max_ns / 1e9:g} s or on SIGTERM)")
        while not self.stop.is_set():
            now = time.monotonic_ns()
            end = start + self.max_ns
            if now >= end:
                break
            wake = end
            if self.state == "streaming":
                deadline = self.last_valid_ns + self.watchdog_ns
                if now >= deadline:
                    self.trip(now, deadline)
                    continue
                wake = min(wake, deadline)
            timeout = min((wake - now) / 1e9, 0.1)  # 0.1 s: notice stop() promptly
            readable, _, _ = select.select([self.sock], [], [], max(timeout, 0.0))
            if readable:
                data, sender = self.sock.recvfrom(65536)
                self.handle(data, sender, time.monotonic_ns())
        self.summary.duration_s = (time.monotonic_ns() - start) / 1e9
        self.write({"type": "summary", "t_ns": time.monotonic_ns(), **asdict(self.summary)})
        self.log("summary: " + ", ".join(f"{k} {v}" for k, v in asdict(self.summary).items()))

    def trip(self, now: int, deadline: int) -> None:
        self.outputs[:] = 0
        self.state = "tripped"
        self.tripped_flag = True
        self.summary.watchdog_trips += 1
        entry = {"type": "watchdog", "t_ns": now, "last_valid_ns": self.last_valid_ns,
                 "deadline_ns": deadline, "late_by_ns": now - deadline}
        self.write(entry)
        self.log(f"watchdog: no frame for {(now - self.last_valid_ns) / 1e6:.1f} ms "
                 f"(limit {self.watchdog_ns / 1e6:g} ms); outputs zeroed")

    def reply(self, sender, message, status: str) -> None:
        flags = FLAG_WATCHDOG_TRIPPED if self.tripped_flag else 0
        self.sock.sendto(encode(ACK, message.seq, message.timestamp_ns, status=STATUS_CODE[status],
                                flags=flags, frames_applied=self.summary.frames_applied), sender)

    def handle(self, data: bytes, sender, arrival: int) -> None:
        try:
            message = decode(data)
        except FrameFormatError as err:
            self.summary.rejected += 1
            self.write({"type": "rejected", "t_ns": arrival, "reason": str(err)})
            return
        if message.kind == ZERO:
            self.outputs[:] = 0
            self.state, self.last_seq, self.min_transit = "idle", None, None
            self.stream_tractors = self.n_tractors
            self.tripped_flag = False
            self.last_valid_ns = arrival
            self.summary.zero_commands += 1
            self.write({"type": "zero", "t_ns": arrival, "seq": message.seq, "ts_ns": message.timestamp_ns})
            self.reply(sender, message, "zeroed")
            return
        if message.kind != FRAME:
            self.summary.rejected += 1
            self.write({"type": "rejected", "t_ns": arrival, "reason": f"unexpected type {message.kind}"})
            self.reply(sender, message, "bad_message")
            return
        expected = self.stream_tractors if self.stream_tractors is not None else message.values.size
        if message.values.size != expected:
            self.summary.rejected += 1
            self.write({"type": "rejected", "t_ns": arrival, "seq": message.seq,
                        "reason": f"{message.values.size} values, expected {expected}"})
            self.reply(sender, message, "bad_count")
            return
        if self.state == "tripped":
            self.summary.rejected += 1
            self.write({"type": "rejected", "t_ns": arrival, "seq": message.seq, "reason": "disarmed"})
            self.reply(sender, message, "disarmed")
            return
        if self.last_seq is not None:
            gap = (message.seq - self.last_seq) % _SEQ_MOD
            if gap == 0 or gap >= 2**31:
                self.summary.stale += 1
                self.write({"type": "stale", "t_ns": arrival, "seq": message.seq})
                self.reply(sender, message, "stale")
                return
            self.summary.missing += gap - 1
        transit = arrival - message.timestamp_ns
        self.min_transit = transit if self.min_transit is None else min(self.min_transit, transit)
        late = transit - self.min_transit > self.late_ns
        self.summary.late += int(late)
        self.stream_tractors = expected
        self.outputs = message.values.copy()
        self.state, self.last_seq, self.last_valid_ns = "streaming", message.seq, arrival
        self.summary.frames_applied += 1
        self.write({"type": "frame", "t_ns": arrival, "seq": message.seq, "ts_ns": message.timestamp_ns,
                    "late": late, "values": [float(v) for v in message.values]})
        self.reply(sender, message, "applied")


def read_record(path: str | pathlib.Path) -> dict:
    """Load an emulator record.

    Returns
    -------
    dict
        ``streams``: one dict per stream (the frames between two ZEROs or a watchdog trip) with
        ``values`` (ndarray (n_frames, n_tractors), the applied FRAME values, float32 exact),
        ``seq`` and ``arrival_ns`` (ndarrays (n_frames,)); ``n_frames``: frames in all streams;
        ``events``: every non-frame entry, in order; ``summary``: the final counts (None if
        the emulator was killed).

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
                            "arrival_ns": np.array([e["t_ns"] for e in current], dtype=np.int64)})
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
            "summary": summary}

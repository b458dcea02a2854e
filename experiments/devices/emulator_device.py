"""The emulator's device logic: the device side of docs/udp-frame-format.md (version 3).

:class:`Device` owns the socket loop of :func:`tactilab.experiments.devices.emulator.emulate`:
the paired ARM (pairing key, fresh nonces, the pinned address), MAC and seq checks, the FIFO of
accepted frames applied on the device's tick at their due times with the per-tick clamps, the
watchdog, and the JSON-lines record. Every refusal to a sender without a link session is the
same datagram (``refused``, untagged, counters zero), whatever the reason.
"""

from __future__ import annotations

import collections
import json
import math
import os
import select
import socket
import struct
import time
from dataclasses import asdict

import numpy as np

from .link import (ACK, ARM, ARMED, DISARM, FLAG_WATCHDOG_TRIPPED, FRAME, NONCE_SIZE, STATUS_CODE, VERSION, ZERO,
                   FrameFormatError, decode, encode, peek, session_key)

__all__ = ["Device", "LOOPBACK", "DEFAULT_TICK_HZ", "NONCE_MEMORY"]

#: The only address the emulator ever binds to.
LOOPBACK = "127.0.0.1"
#: The device tick without a display description (``limits``), Hz.
DEFAULT_TICK_HZ = 1000.0
#: How many host nonces of accepted ARMs the device remembers (a replayed ARM is refused).
NONCE_MEMORY = 4096


class Device:
    """The device logic: paired link sessions and a FIFO of FRAMEs applied at their due times, one per tick."""

    def __init__(self, sock, summary, watchdog_s, max_seconds, n_tractors, late_after_s, log, out, stop,
                 limits=None, fifo_frames: int = 1000, pairing_key: bytes = b""):
        self.sock, self.summary, self.log, self.out, self.stop = sock, summary, log, out, stop
        self.pairing_key = pairing_key
        self.watchdog_ns = int(watchdog_s * 1e9)
        self.max_ns = int(max_seconds * 1e9)
        self.late_ns = int(late_after_s * 1e9)
        self.n_tractors = n_tractors  # None: learned from the first FRAME of each stream
        self.stream_tractors = n_tractors
        self.state = "disarmed"  # no link session until an ARM
        self.key: bytes | None = None  # the session key
        self.pin: tuple | None = None  # (ip, port) of the host that armed the session
        self.arm_seq, self.host_nonce, self.armed_data = 0, b"", b""
        self.nonces: collections.deque = collections.deque(maxlen=NONCE_MEMORY)
        self.foreign_seen: set = set()
        self.outputs = np.zeros(n_tractors or 0, dtype=np.float32)
        self.last_seq = 0
        self.last_valid_ns = self.last_due_ns = self.last_tick_ns = 0
        self.tripped_flag = False
        self.fifo: collections.deque = collections.deque()
        self.fifo_frames = fifo_frames
        self.flushed_ns = 0
        rate = float(limits.frame_rate_hz) if limits is not None else DEFAULT_TICK_HZ
        self.period_ns = int(round(1e9 / rate))
        self.max_ahead_ns = fifo_frames * self.period_ns  # a frame due later than this is refused
        self.full, self.step, self.unit = math.inf, math.inf, None
        if limits is not None:
            kind = "traction" if limits.max_traction_pa is not None else "deflection"
            self.full = float(limits.full_scale(kind))
            self.unit = "Pa" if kind == "traction" else "m"
            if limits.max_slew_rate_per_s is not None:
                self.step = float(limits.max_slew_rate_per_s) * self.full / rate

    def write(self, entry: dict, flush: bool = True) -> None:
        """One record line; flushed at once, except frame lines while more frames wait in the FIFO,
        flushed at least every 20 ms (far cheaper on a busy host)."""
        if self.out is not None:
            self.out.write(json.dumps(entry) + "\n")
            now = time.monotonic_ns()
            if flush or now - self.flushed_ns > 20_000_000:
                self.out.flush()
                self.flushed_ns = now

    def run(self) -> None:
        start = time.monotonic_ns()
        self.write({"type": "start", "t_ns": start, "port": self.summary.port, "frame_format_version": VERSION,
                    "watchdog_s": self.watchdog_ns / 1e9, "n_tractors": self.n_tractors,
                    "tick_ns": self.period_ns, "full_scale": None if math.isinf(self.full) else self.full,
                    "max_step": None if math.isinf(self.step) else self.step, "unit": self.unit})
        self.log(f"listening on udp://{LOOPBACK}:{self.summary.port} (frame format {VERSION}, paired; watchdog "
                 f"{self.watchdog_ns / 1e6:g} ms, tick {self.period_ns / 1e6:g} ms, stops after "
                 f"{self.max_ns / 1e9:g} s or on SIGTERM)")
        end = start + self.max_ns
        stamped = _kernel_timestamps(self.sock)
        while not self.stop.is_set():
            # first every datagram already received, at its arrival time: a wake-up the operating
            # system delayed never trips the watchdog on messages that came in time
            self.drain(stamped)
            now = time.monotonic_ns()
            if now >= end:
                break
            wake = end
            if self.state in ("idle", "streaming"):  # the watchdog runs while a session is armed
                deadline = self.deadline()
                if now >= deadline:
                    self.trip(now, deadline)
                    continue
                wake = min(wake, deadline)
            if self.fifo:
                due = self.next_tick()
                if now >= due:
                    self.tick(now, due)
                    continue
                wake = min(wake, due)
            # sleep until the next event (a tick is never early) or a datagram (drained above)
            select.select([self.sock], [], [], min(max((wake - now) / 1e9, 0.0), 0.1))
        self.summary.duration_s = (time.monotonic_ns() - start) / 1e9
        self.write({"type": "summary", "t_ns": time.monotonic_ns(), **asdict(self.summary)})
        self.log("summary: " + ", ".join(f"{k} {v}" for k, v in asdict(self.summary).items()))

    def drain(self, stamped: bool) -> None:
        """Handle every datagram waiting in the socket, each at its arrival time (the kernel's receive
        time stamp where the system gives one, else now)."""
        while select.select([self.sock], [], [], 0)[0]:
            if stamped:
                data, ancillary, _, sender = self.sock.recvmsg(65536, socket.CMSG_SPACE(16))
                arrival = _arrival_ns(ancillary)
            else:
                data, sender = self.sock.recvfrom(65536)
                arrival = time.monotonic_ns()
            self.handle(data, sender, arrival)

    def deadline(self) -> int:
        """The watchdog's deadline: W after the last valid message or the due time of the last
        accepted frame, whichever is later (frames sent ahead keep the session until they are due)."""
        return max(self.last_valid_ns, self.last_due_ns) + self.watchdog_ns

    def next_tick(self) -> int:
        """When the oldest frame is applied: its due time, and never less than one period after the
        previous tick's scheduled time (the tick is a fixed timer: a late wake-up does not shift it)."""
        return max(self.fifo[0][4], self.last_tick_ns + self.period_ns)

    def tick(self, now: int, scheduled: int) -> None:
        """Apply the oldest accepted FRAME, clamped to the limits and to one step per tick."""
        seq, values, rx_ns, ts_ns, due_ns, sender = self.fifo.popleft()
        requested = values.astype(float)
        target = np.clip(requested, -self.full, self.full)
        self._clamped("amplitude", seq, now, requested, target, self.full)
        previous = self.outputs.astype(float) if self.outputs.size == target.size else np.zeros(target.size)
        applied = np.clip(target, previous - self.step, previous + self.step)
        self._clamped("slew", seq, now, target, applied, self.step)
        self.outputs = applied.astype(np.float32)
        self.last_tick_ns = scheduled
        late = now - due_ns > self.late_ns
        self.summary.late += int(late)
        self.summary.frames_applied += 1
        self.write({"type": "frame", "t_ns": now, "tick_ns": scheduled, "due_ns": due_ns, "rx_ns": rx_ns, "seq": seq,
                    "ts_ns": ts_ns, "late": late, "values": self.outputs.tolist()}, flush=not self.fifo)
        self.reply(sender, (seq, ts_ns), "applied")

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
        was = self.state
        self.state = "tripped"  # the session ends (a new ARM is accepted); its messages are answered `disarmed`
        self.tripped_flag = True
        self.summary.watchdog_trips += 1
        self.write({"type": "watchdog", "t_ns": now, "last_valid_ns": self.last_valid_ns,
                    "last_due_ns": self.last_due_ns, "deadline_ns": deadline, "late_by_ns": now - deadline,
                    "dropped": dropped, "state": was})
        self.log(f"watchdog: no frame for {(now - self.last_valid_ns) / 1e6:.1f} ms "
                 f"(limit {self.watchdog_ns / 1e6:g} ms after the last message or due time); outputs zeroed")

    def reply(self, sender, message, status: str) -> None:
        """ACK ``message`` (a Message, or a (seq, timestamp) pair) with ``status``, tagged with the session key."""
        seq, stamp = (message.seq, message.timestamp_ns) if hasattr(message, "seq") else message
        flags = FLAG_WATCHDOG_TRIPPED if self.tripped_flag else 0
        self.sock.sendto(encode(ACK, seq, stamp, status=STATUS_CODE[status], flags=flags, key=self.key,
                                frames_applied=self.summary.frames_applied, device_ns=time.monotonic_ns()), sender)

    def refuse(self, sender, header, arrival: int, status: str, reason: str) -> None:
        """An untagged refusal: status only (flags and counters 0: nothing about the device's state)."""
        self.summary.rejected += 1
        self.write({"type": "rejected", "t_ns": arrival, "seq": header[2], "status": status, "reason": reason,
                    "from": f"{sender[0]}:{sender[1]}"})
        self.sock.sendto(encode(ACK, header[2], header[3], status=STATUS_CODE[status]), sender)

    def refuse_tagged(self, sender, message, arrival: int, status: str, reason: str) -> None:
        self.summary.rejected += 1
        self.write({"type": "rejected", "t_ns": arrival, "seq": message.seq, "status": status, "reason": reason,
                    "from": f"{sender[0]}:{sender[1]}"})
        self.reply(sender, message, status)

    def handle(self, data: bytes, sender, arrival: int) -> None:
        """One datagram: version, ARM, address pin, tag, seq, then the message (docs/udp-frame-format.md)."""
        header = peek(data)
        if header is None:
            return  # not this format: no answer
        if header[0] != VERSION:
            self.refuse(sender, header, arrival, "bad_version",
                        f"version: {header[0]} is refused; host and device must speak version {VERSION}")
            return
        live = self.state in ("idle", "streaming")
        ours = self.key is not None and sender == self.pin
        if header[1] == ARM:
            self.arm(data, header, sender, arrival, live)
            return
        if not ours:  # the same answer whether the device is armed by another host or idle
            if live:
                self.summary.foreign += 1
                if sender not in self.foreign_seen:
                    self.foreign_seen.add(sender)
                    self.log(f"refused: datagram from {sender[0]}:{sender[1]}; the link is armed by "
                             f"{self.pin[0]}:{self.pin[1]}")
            self.refuse(sender, header, arrival, "refused", "no link session for this sender: ARM first")
            return
        try:
            message = decode(data, key=self.key)
        except FrameFormatError as err:
            self.refuse(sender, header, arrival, "bad_message", str(err))
            return
        if not message.authentic:
            self.summary.bad_mac += 1
            self.refuse(sender, header, arrival, "bad_mac", "tag does not verify under the session key")
            return
        if message.seq <= self.last_seq:  # replayed, reordered or a reset: never newer
            self.summary.stale += 1
            self.write({"type": "stale", "t_ns": arrival, "seq": message.seq, "last_seq": self.last_seq})
            self.reply(sender, message, "stale")
            return
        if self.state == "tripped":  # the session ended; the device stays at zero
            self.last_seq = message.seq
            self.refuse_tagged(sender, message, arrival, "disarmed", "disarmed (watchdog)")
            if message.kind == DISARM:
                self.key = self.pin = None
                self.state = "disarmed"
            return
        if message.kind in (ZERO, DISARM):
            self.outputs[:] = 0  # at once, exempt from the per-tick step: the safe state
            self.fifo.clear()
            self.state, self.last_seq, self.last_due_ns = "idle", message.seq, 0
            self.stream_tractors = self.n_tractors
            self.last_valid_ns = arrival
            if message.kind == ZERO:
                self.summary.zero_commands += 1
                self.write({"type": "zero", "t_ns": arrival, "seq": message.seq, "ts_ns": message.timestamp_ns})
                self.reply(sender, message, "zeroed")
            else:
                self.write({"type": "disarm", "t_ns": arrival, "seq": message.seq})
                self.reply(sender, message, "released")
                self.key = self.pin = None
                self.state = "disarmed"
            return
        if message.kind != FRAME:
            self.refuse_tagged(sender, message, arrival, "bad_message", f"unexpected type {message.kind}")
            return
        self.frame(message, sender, arrival)

    def arm(self, data: bytes, header, sender, arrival: int, live: bool) -> None:
        """ARM: a new session if its tag verifies under the pairing key, its host nonce is new and no
        session is live; the ARM that opened the live session is answered again; all else ``refused``."""
        try:
            message = decode(data, key=self.pairing_key)  # the tag is checked whatever the state
        except FrameFormatError:
            message = None
        repeat = (live and message is not None and message.authentic and sender == self.pin
                  and message.nonce == self.host_nonce and message.seq == self.arm_seq)
        if repeat:  # its ARMED was lost: the same answer again
            self.sock.sendto(self.armed_data, sender)
            return
        fresh = message is not None and message.authentic and message.nonce not in self.nonces
        if live or not fresh:
            self.summary.refused_arms += 1
            why = ("a session is live" if live else "malformed" if message is None else
                   "tag does not verify under the pairing key" if not message.authentic else "replayed host nonce")
            self.refuse(sender, header, arrival, "refused", f"ARM refused ({why})")
            return
        self.nonces.append(message.nonce)
        device_nonce = os.urandom(NONCE_SIZE)
        self.key = session_key(self.pairing_key, message.nonce, device_nonce)
        self.pin, self.host_nonce = sender, message.nonce
        self.arm_seq = self.last_seq = message.seq
        self.outputs[:] = 0
        self.fifo.clear()
        self.state, self.tripped_flag, self.last_due_ns = "idle", False, 0
        self.stream_tractors = self.n_tractors
        self.last_valid_ns = arrival
        self.summary.sessions += 1
        self.foreign_seen = set()
        self.write({"type": "arm", "t_ns": arrival, "seq": message.seq, "from": f"{sender[0]}:{sender[1]}"})
        self.armed_data = encode(ARMED, message.seq, message.timestamp_ns, key=self.pairing_key, nonce=device_nonce,
                                 host_nonce=message.nonce, watchdog_us=min(self.watchdog_ns // 1000, 2**32 - 1),
                                 n_tractors=self.n_tractors or 0, fifo_frames=min(self.fifo_frames, 2**16 - 1),
                                 frames_applied=self.summary.frames_applied, device_ns=time.monotonic_ns())
        self.sock.sendto(self.armed_data, sender)

    def frame(self, message, sender, arrival: int) -> None:
        """A FRAME of the live session with a newer seq: checked, then queued for its due time."""
        expected = self.stream_tractors if self.stream_tractors is not None else message.values.size
        if message.values.size != expected:
            self.refuse_tagged(sender, message, arrival, "bad_count",
                               f"{message.values.size} values, expected {expected}")
            return
        if not np.all(np.isfinite(message.values)):
            self.refuse_tagged(sender, message, arrival, "non_finite", "NaN or infinite values")
            return
        if message.due_ns > arrival + self.max_ahead_ns:
            self.refuse_tagged(sender, message, arrival, "bad_due", f"due {(message.due_ns - arrival) / 1e6:.1f} ms "
                               f"ahead, more than the FIFO's {self.max_ahead_ns / 1e6:g} ms")
            return
        if len(self.fifo) >= self.fifo_frames:
            self.refuse_tagged(sender, message, arrival, "overflow", f"FIFO full ({self.fifo_frames} frames)")
            return
        self.summary.missing += message.seq - self.last_seq - 1
        self.stream_tractors = expected
        if self.outputs.size != expected:
            self.outputs = np.zeros(expected, dtype=np.float32)
        self.fifo.append((message.seq, message.values.copy(), arrival, message.timestamp_ns, message.due_ns, sender))
        self.state, self.last_seq, self.last_valid_ns = "streaming", message.seq, arrival
        self.last_due_ns = max(self.last_due_ns, message.due_ns)
        # acknowledged `applied` by the tick that applies it


def _kernel_timestamps(sock) -> bool:
    """Ask the kernel to stamp each received datagram (Linux ``SO_TIMESTAMPNS``); False where it cannot."""
    option = getattr(socket, "SO_TIMESTAMPNS", None)
    if option is None:
        return False
    try:
        sock.setsockopt(socket.SOL_SOCKET, option, 1)
    except OSError:
        return False
    return True


def _arrival_ns(ancillary) -> int:
    """A datagram's kernel receive time (CLOCK_REALTIME) on this process's monotonic clock, ns."""
    for level, kind, data in ancillary:
        if level == socket.SOL_SOCKET and kind == socket.SO_TIMESTAMPNS and len(data) >= 16:
            seconds, nanoseconds = struct.unpack("qq", data[:16])
            now_mono, now_real = time.monotonic_ns(), time.time_ns()
            return min(now_mono, seconds * 1_000_000_000 + nanoseconds - (now_real - now_mono))
    return time.monotonic_ns()


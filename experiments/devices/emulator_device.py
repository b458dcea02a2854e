"""The emulator's device logic: the device side of docs/udp-frame-format.md (version 2).

:class:`Device` owns the socket loop of :func:`tactilab.experiments.devices.emulator.emulate`: link
sessions (ARM, the pinned address, MAC and seq checks), the FIFO of accepted frames applied one
per tick with the per-tick clamps, the watchdog, and the JSON-lines record.
"""

from __future__ import annotations

import collections
import json
import math
import os
import select
import time
from dataclasses import asdict

import numpy as np

from .link import (ACK, ARM, ARMED, DISARM, FLAG_WATCHDOG_TRIPPED, FRAME, NO_NONCE, NONCE_SIZE, STATUS_CODE,
                   VERSION, ZERO, FrameFormatError, decode, encode, peek)

__all__ = ["Device", "LOOPBACK", "DEFAULT_TICK_HZ"]

#: The only address the emulator ever binds to.
LOOPBACK = "127.0.0.1"
#: The device tick without a display description (``limits``), Hz.
DEFAULT_TICK_HZ = 1000.0


class Device:
    """The device logic: a FIFO of accepted FRAMEs applied one per tick, clamped per tick."""

    def __init__(self, sock, summary, watchdog_s, max_seconds, n_tractors, late_after_s, log, out, stop,
                 limits=None, fifo_frames: int = 1000):
        self.sock, self.summary, self.log, self.out, self.stop = sock, summary, log, out, stop
        self.watchdog_ns = int(watchdog_s * 1e9)
        self.max_ns = int(max_seconds * 1e9)
        self.late_ns = int(late_after_s * 1e9)
        self.n_tractors = n_tractors  # None: learned from the first FRAME of each stream
        self.stream_tractors = n_tractors
        self.state = "disarmed"  # no link session until an ARM
        self.key: bytes | None = None
        self.nonce: bytes | None = None
        self.pin: tuple | None = None  # (ip, port) of the host that armed the session
        self.arm_seq = 0
        self.foreign_seen: set = set()
        self.outputs = np.zeros(n_tractors or 0, dtype=np.float32)
        self.last_seq = 0
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
            if self.state in ("idle", "streaming"):  # the watchdog runs while a session is armed
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
        self.sock.sendto(encode(ACK, seq, ts_ns, status=STATUS_CODE["applied"], flags=flags, key=self.key,
                                nonce=self.nonce, frames_applied=self.summary.frames_applied), sender)

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
        entry = {"type": "watchdog", "t_ns": now, "last_valid_ns": self.last_valid_ns,
                 "deadline_ns": deadline, "late_by_ns": now - deadline, "dropped": dropped, "state": was}
        self.write(entry)
        self.log(f"watchdog: no frame for {(now - self.last_valid_ns) / 1e6:.1f} ms "
                 f"(limit {self.watchdog_ns / 1e6:g} ms); outputs zeroed")

    def reply(self, sender, message, status: str, *, tagged: bool = True) -> None:
        """ACK ``message`` (a Message, or peek's (version, kind, seq, stamp)) with ``status``; tagged with
        the session key when ``tagged`` and a session exists, else with the all-zero tag."""
        seq, stamp = (message.seq, message.timestamp_ns) if hasattr(message, "seq") else message[2:4]
        flags = FLAG_WATCHDOG_TRIPPED if self.tripped_flag else 0
        key, nonce = (self.key, self.nonce) if tagged and self.key is not None else (None, NO_NONCE)
        self.sock.sendto(encode(ACK, seq, stamp, status=STATUS_CODE[status], flags=flags, key=key, nonce=nonce,
                                frames_applied=self.summary.frames_applied), sender)

    def refuse(self, sender, message, arrival: int, status: str, reason: str, *, tagged: bool = True) -> None:
        self.summary.rejected += 1
        seq = getattr(message, "seq", None) if message is not None and hasattr(message, "seq") else (
            message[2] if message is not None else None)
        self.write({"type": "rejected", "t_ns": arrival, "seq": seq, "status": status, "reason": reason,
                    "from": f"{sender[0]}:{sender[1]}"})
        if message is not None:
            self.reply(sender, message, status, tagged=tagged)

    def handle(self, data: bytes, sender, arrival: int) -> None:
        """One datagram: address pin, tag, seq, then the message (docs/udp-frame-format.md, device rules)."""
        live = self.state in ("idle", "streaming")
        header = peek(data)
        if live and sender != self.pin:  # the link is pinned to the host that armed it
            self.summary.foreign += 1
            kind = header[1] if header else None
            if kind == ARM:
                self.summary.refused_arms += 1
            if sender not in self.foreign_seen:
                self.foreign_seen.add(sender)
                self.log(f"refused: datagram from {sender[0]}:{sender[1]}; the link is armed by "
                         f"{self.pin[0]}:{self.pin[1]}")
            self.refuse(sender, header, arrival, "busy" if kind == ARM else "foreign",
                        f"from {sender[0]}:{sender[1]}, not the armed host {self.pin[0]}:{self.pin[1]}", tagged=False)
            return
        ours = self.key is not None and sender == self.pin
        try:
            message = decode(data, key=self.key if ours else None, nonce=self.nonce if ours else NO_NONCE)
        except FrameFormatError as err:
            status = "bad_version" if header and header[0] != VERSION else "bad_message"
            self.refuse(sender, header, arrival, status, str(err), tagged=False)
            return
        if message.kind == ARM:
            self.arm(message, sender, arrival)
            return
        if not ours:
            self.refuse(sender, message, arrival, "not_armed", "no link session: ARM first", tagged=False)
            return
        if not message.authentic:
            self.summary.bad_mac += 1
            self.refuse(sender, message, arrival, "bad_mac", "tag does not verify under the session key and nonce",
                        tagged=False)
            return
        if message.seq <= self.last_seq:  # replayed, reordered or a reset: never newer
            self.summary.stale += 1
            self.write({"type": "stale", "t_ns": arrival, "seq": message.seq, "last_seq": self.last_seq})
            self.reply(sender, message, "stale")
            return
        if self.state == "tripped":  # the session ended; the device stays at zero
            self.last_seq = message.seq
            self.refuse(sender, message, arrival, "disarmed", "disarmed (watchdog)")
            if message.kind == DISARM:
                self.key = self.nonce = self.pin = None
                self.state = "disarmed"
            return
        if message.kind in (ZERO, DISARM):
            self.outputs[:] = 0  # at once, exempt from the per-tick step: the safe state
            self.fifo.clear()
            self.state, self.min_transit, self.last_seq = "idle", None, message.seq
            self.stream_tractors = self.n_tractors
            self.last_valid_ns = arrival
            if message.kind == ZERO:
                self.summary.zero_commands += 1
                self.write({"type": "zero", "t_ns": arrival, "seq": message.seq, "ts_ns": message.timestamp_ns})
                self.reply(sender, message, "zeroed")
            else:
                self.write({"type": "disarm", "t_ns": arrival, "seq": message.seq})
                self.reply(sender, message, "released")
                self.key = self.nonce = self.pin = None
                self.state = "disarmed"
            return
        if message.kind != FRAME:
            self.refuse(sender, message, arrival, "bad_message", f"unexpected type {message.kind}")
            return
        self.frame(message, sender, arrival)

    def arm(self, message, sender, arrival: int) -> None:
        """ARM: a new session (fresh nonce, this sender pinned, outputs zero), unless one is live."""
        if self.state in ("idle", "streaming"):  # from the pinned host (others were refused above)
            if message.key == self.key and message.seq == self.arm_seq:  # its ARMED was lost: answer again
                self.armed_reply(message, sender)
                return
            self.summary.refused_arms += 1
            self.refuse(sender, message, arrival, "busy", "already armed: DISARM first", tagged=False)
            return
        if not message.authentic:
            self.refuse(sender, message, arrival, "bad_mac", "ARM tag does not verify under its key", tagged=False)
            return
        self.key, self.nonce, self.pin = message.key, os.urandom(NONCE_SIZE), sender
        self.arm_seq = self.last_seq = message.seq
        self.outputs[:] = 0
        self.fifo.clear()
        self.state, self.min_transit, self.tripped_flag = "idle", None, False
        self.stream_tractors = self.n_tractors
        self.last_valid_ns = arrival
        self.summary.sessions += 1
        self.foreign_seen = set()
        self.write({"type": "arm", "t_ns": arrival, "seq": message.seq, "from": f"{sender[0]}:{sender[1]}"})
        self.armed_reply(message, sender)

    def armed_reply(self, message, sender) -> None:
        self.sock.sendto(encode(ARMED, message.seq, message.timestamp_ns, key=self.key, nonce=self.nonce,
                                watchdog_us=min(self.watchdog_ns // 1000, 2**32 - 1),
                                n_tractors=self.n_tractors or 0), sender)

    def frame(self, message, sender, arrival: int) -> None:
        """A FRAME of the live session with a newer seq: checked, then queued for the tick."""
        expected = self.stream_tractors if self.stream_tractors is not None else message.values.size
        if message.values.size != expected:
            self.refuse(sender, message, arrival, "bad_count", f"{message.values.size} values, expected {expected}")
            return
        if not np.all(np.isfinite(message.values)):
            self.refuse(sender, message, arrival, "non_finite", "NaN or infinite values")
            return
        if len(self.fifo) >= self.fifo_frames:
            self.refuse(sender, message, arrival, "overflow", f"FIFO full ({self.fifo_frames} frames)")
            return
        self.summary.missing += message.seq - self.last_seq - 1
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

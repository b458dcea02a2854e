"""Network driver for real displays: frames over UDP at a fixed rate, each one acknowledged.

The wire format is specified in ``docs/udp-frame-format.md`` (firmware implements it from
there); :func:`encode` / :func:`decode` are its reference implementation. In short, every
datagram is a 20-byte little-endian header, a payload and a CRC32::

    offset  size  field
    0       4     magic  b"TLDF"
    4       1     version (1)
    5       1     message type: 1 FRAME, 2 ZERO, 3 ACK
    6       2     count: number of float32 values (FRAME), else 0
    8       4     seq, uint32 (wraps)
    12      8     timestamp_ns, uint64: the host's monotonic clock at sending (echoed in ACKs)
    20      4*count values, float32 (FRAME), or 8 bytes (ACK: status u8, flags u8,
                  reserved u16, frames_applied u32), or nothing (ZERO)
    end-4   4     CRC32 (zlib / IEEE 802.3) of every byte before it

:class:`UdpDisplay` sends ZERO (which must be acknowledged: the device is there and at rest),
streams the frames with precise pacing (sleep, then busy-wait the last ``busy_wait_s`` on
``perf_counter_ns``), collects the ACKs as they come, and sends ZERO at the end. It sends
ZERO (without waiting) on any error.
"""

from __future__ import annotations

import math
import select
import socket
import struct
import time
import zlib
from dataclasses import dataclass
from urllib.parse import urlparse

import numpy as np

from .display import Display, DisplayError, PlaybackReport

__all__ = ["UdpDisplay", "Message", "encode", "decode", "FrameFormatError", "MAGIC", "VERSION",
           "FRAME", "ZERO", "ACK", "STATUS", "FLAG_WATCHDOG_TRIPPED", "parse_udp_url"]

MAGIC = b"TLDF"
VERSION = 1
#: Message kinds of the display UDP frame format (docs/udp-frame-format.md)
FRAME, ZERO, ACK = 1, 2, 3
HEADER = struct.Struct("<4sBBHIQ")  # 20 bytes
ACK_BODY = struct.Struct("<BBHI")  # 8 bytes
CRC = struct.Struct("<I")
#: ACK status codes (docs/udp-frame-format.md).
STATUS = {0: "applied", 1: "zeroed", 2: "bad_crc", 3: "bad_count", 4: "stale", 5: "disarmed",
          6: "bad_message", 7: "non_finite", 8: "overflow"}
STATUS_CODE = {name: code for code, name in STATUS.items()}
FLAG_WATCHDOG_TRIPPED = 0x01
MAX_VALUES = 16000  # keeps a FRAME under the 64 KiB UDP datagram limit
_SEQ_MOD = 2**32


class FrameFormatError(ValueError):
    """A datagram that is not a valid message of this format."""


@dataclass(frozen=True)
class Message:
    """One decoded datagram. ``values`` is float32 (FRAME) or empty; ACK fields are 0 otherwise."""

    kind: int
    seq: int
    timestamp_ns: int
    values: np.ndarray
    status: int = 0
    flags: int = 0
    frames_applied: int = 0


def encode(kind: int, seq: int, timestamp_ns: int, values=None, *, status: int = 0, flags: int = 0,
           frames_applied: int = 0) -> bytes:
    """Encode one message (see the module docstring for the layout).

    Raises
    ------
    FrameFormatError
        If ``kind`` is unknown, values are given for a non-FRAME message or are too many.
    """
    if kind not in (FRAME, ZERO, ACK):
        raise FrameFormatError(f"kind: must be FRAME (1), ZERO (2) or ACK (3), got {kind!r}")
    payload = b""
    count = 0
    if kind == FRAME:
        array = np.ascontiguousarray(values if values is not None else [], dtype="<f4").ravel()
        if array.size > MAX_VALUES:
            raise FrameFormatError(f"values: at most {MAX_VALUES} per FRAME, got {array.size}; "
                                   "split the display into several devices")
        payload, count = array.tobytes(), array.size
    elif values is not None and len(values):
        raise FrameFormatError(f"values: only FRAME messages carry values, got {len(values)} for type {kind}")
    if kind == ACK:
        payload = ACK_BODY.pack(status, flags, 0, frames_applied % _SEQ_MOD)
    body = HEADER.pack(MAGIC, VERSION, kind, count, seq % _SEQ_MOD, timestamp_ns % 2**64) + payload
    return body + CRC.pack(zlib.crc32(body))


def decode(data: bytes) -> Message:
    """Decode and check one datagram.

    Raises
    ------
    FrameFormatError
        On a short datagram, wrong magic or version, bad CRC, unknown type, or a length that
        does not match the count.
    """
    if len(data) < HEADER.size + CRC.size:
        raise FrameFormatError(f"datagram: {len(data)} bytes, shorter than the {HEADER.size + CRC.size}-byte minimum")
    magic, version, kind, count, seq, stamp = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise FrameFormatError(f"magic: expected {MAGIC!r}, got {magic!r}")
    if (CRC.unpack_from(data, len(data) - CRC.size)[0]) != zlib.crc32(data[:-CRC.size]):
        raise FrameFormatError("crc: CRC32 mismatch (corrupted datagram)")
    if version != VERSION:
        raise FrameFormatError(f"version: expected {VERSION}, got {version}")
    payload = data[HEADER.size:-CRC.size]
    if kind == FRAME:
        if len(payload) != 4 * count:
            raise FrameFormatError(f"count: header says {count} values, payload holds {len(payload)} bytes")
        return Message(FRAME, seq, stamp, np.frombuffer(payload, dtype="<f4"))
    if kind == ZERO and not payload and count == 0:
        return Message(ZERO, seq, stamp, np.zeros(0, dtype="<f4"))
    if kind == ACK and len(payload) == ACK_BODY.size and count == 0:
        status, flags, _, applied = ACK_BODY.unpack(payload)
        return Message(ACK, seq, stamp, np.zeros(0, dtype="<f4"), status, flags, applied)
    raise FrameFormatError(f"type: message type {kind} with count {count} and a {len(payload)}-byte payload is not valid")


def _step_per_frame(description, command: str) -> float:
    """The largest change of one output per frame at the display's refresh rate (inf: no limit),
    less a margin of ``2**-21`` of full scale so that float32 rounding never crosses it."""
    if description.max_slew_rate_per_s is None:
        return math.inf
    full = float(description.full_scale(command))
    return float(description.max_slew_rate_per_s) * full / float(description.frame_rate_hz) - 2.0**-21 * full


def parse_udp_url(url: str) -> tuple[str, int]:
    """``"udp://HOST:PORT"`` -> ``(host, port)``.

    Raises
    ------
    ValueError
        If the scheme is not udp or the host or port is missing or out of range.
    """
    parsed = urlparse(url)
    try:
        port = parsed.port
    except ValueError:
        port = None
    if parsed.scheme != "udp" or not parsed.hostname or port is None or not 0 < port < 65536:
        raise ValueError(f"url: expected udp://HOST:PORT with a port in 1..65535, got {url!r}; "
                         "e.g. udp://127.0.0.1:9000")
    return parsed.hostname, port


class UdpDisplay(Display):
    """Stream frames to a display over UDP (docs/udp-frame-format.md).

    Parameters
    ----------
    description : DisplayDescription
        The display; ``n_tractors`` values per FRAME.
    host, port : str, int
        The device's address (``127.0.0.1`` and the port of ``tactilab device emulate`` for
        the emulator).
    command : {"traction", "deflection"}, optional
        What the values are (Pa or m).
    ack_timeout_s : float
        An ACK later than this after its frame counts as late; after the last frame the driver
        waits this long for outstanding ACKs; ZERO is retried after this long, s (> 0).
    busy_wait_s : float
        The last part of each frame period spent busy-waiting instead of sleeping, s (>= 0).
    zero_retries : int
        ZERO attempts before :meth:`zero` gives up (>= 1).
    max_skipped_fraction : float
        A frame due more than half a period ago is skipped, never sent late in a burst; after a
        skip every value sent is re-limited to one slew step from the previous one. When more
        than this fraction of a stimulus's frames were skipped, playback stops (the trial aborts;
        the report says ``stopped`` and ``skipped``). In [0, 1].
    """

    def __init__(self, description, host: str = "127.0.0.1", port: int = 9000, *,
                 command: str | None = None, ack_timeout_s: float = 0.05, busy_wait_s: float = 1e-3,
                 zero_retries: int = 3, max_skipped_fraction: float = 0.01) -> None:
        super().__init__(description, command)
        if isinstance(port, bool) or not isinstance(port, int) or not 0 < port < 65536:
            raise ValueError(f"port: must be an integer in 1..65535, got {port!r}; give the device's UDP port")
        for name, value, low in (("ack_timeout_s", ack_timeout_s, 0.0), ("busy_wait_s", busy_wait_s, None)):
            number = float(value)
            if not math.isfinite(number) or (number <= low if low is not None else number < 0):
                rule = "> 0" if low is not None else ">= 0"
                raise ValueError(f"{name}: must be a finite number {rule} s, got {value!r}; give e.g. 0.05")
        if isinstance(zero_retries, bool) or not isinstance(zero_retries, int) or zero_retries < 1:
            raise ValueError(f"zero_retries: must be an integer >= 1, got {zero_retries!r}; give e.g. 3")
        if not (isinstance(max_skipped_fraction, (int, float)) and 0 <= max_skipped_fraction <= 1):
            raise ValueError(f"max_skipped_fraction: must be a number in [0, 1], got {max_skipped_fraction!r}; "
                             "give e.g. 0.01")
        self.max_skipped_fraction = float(max_skipped_fraction)
        if description.n_tractors > MAX_VALUES:
            raise ValueError(f"description: {description.n_tractors} tractors exceed the {MAX_VALUES} values "
                             "a FRAME can carry; split the display")
        self.address = (host, port)
        self.ack_timeout_s = float(ack_timeout_s)
        self.busy_wait_s = float(busy_wait_s)
        self.zero_retries = zero_retries
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setblocking(False)
        self._sock.connect(self.address)  # only datagrams from the device reach us
        self._seq = 0
        self.last_ack: Message | None = None

    @classmethod
    def from_url(cls, url: str, description, **kwargs) -> UdpDisplay:
        """Build from ``"udp://HOST:PORT"`` (see :func:`parse_udp_url`)."""
        host, port = parse_udp_url(url)
        return cls(description, host, port, **kwargs)

    @property
    def url(self) -> str:
        """``udp://HOST:PORT`` of the device."""
        return f"udp://{self.address[0]}:{self.address[1]}"

    def close(self) -> None:
        """Close the socket."""
        self._sock.close()

    def _next_seq(self) -> int:
        seq = self._seq
        self._seq = (self._seq + 1) % _SEQ_MOD
        return seq

    def _send(self, kind: int, values=None) -> tuple[int, int]:
        seq, now = self._next_seq(), time.perf_counter_ns()
        self._sock.send(encode(kind, seq, now, values))
        return seq, now

    def _receive(self) -> list[tuple[Message, int]]:
        """Drain the socket without blocking; return (ACK, arrival ns) pairs."""
        out = []
        while True:
            try:
                data = self._sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                return out
            except ConnectionRefusedError as err:  # ICMP port unreachable: nobody listens
                raise DisplayError(f"{self.url}: connection refused; is the device (or `tactilab device "
                                   f"emulate --port {self.address[1]}`) running?") from err
            arrival = time.perf_counter_ns()
            try:
                message = decode(data)
            except FrameFormatError:
                continue  # a corrupted ACK is a missing ACK
            if message.kind == ACK:
                out.append((message, arrival))

    def _zero(self) -> None:
        for _ in range(self.zero_retries):
            seq, _ = self._send(ZERO)
            deadline = time.perf_counter() + self.ack_timeout_s
            while (remaining := deadline - time.perf_counter()) > 0:
                select.select([self._sock], [], [], remaining)
                for message, _ in self._receive():
                    if message.seq == seq:
                        self.last_ack = message
                        return
        raise DisplayError(
            f"{self.url}: no acknowledgement of ZERO after {self.zero_retries} tries of "
            f"{self.ack_timeout_s * 1e3:.0f} ms; is the device (or `tactilab device emulate --port "
            f"{self.address[1]}`) running? The device's watchdog zeroes it when frames stop"
        )

    def _play(self, frames: np.ndarray, frame_rate_hz: float) -> PlaybackReport:
        self._zero()  # the device answers, is at rest and armed
        n = frames.shape[0]
        wire = frames.astype("<f4")
        period_ns = 1e9 / frame_rate_hz
        busy_ns = self.busy_wait_s * 1e9
        sent_ns = np.zeros(n, dtype=np.int64)
        ack_ns = np.zeros(n, dtype=np.int64)
        status = np.full(n, -1, dtype=np.int64)
        seq0 = self._seq
        sent = 0

        def collect() -> None:
            for message, arrival in self._receive():
                index = (message.seq - seq0) % _SEQ_MOD
                if index < sent and ack_ns[index] == 0:
                    ack_ns[index], status[index] = arrival, message.status
                    self.last_ack = message
                    if message.status == STATUS_CODE["disarmed"]:
                        raise DisplayError(
                            f"{self.url}: the device's watchdog tripped during playback (frame {index}); "
                            "frames arrived too late. It stays at zero until the next play"
                        )
                    if message.status in (STATUS_CODE["bad_count"], STATUS_CODE["bad_message"]):
                        raise DisplayError(
                            f"{self.url}: the device rejected frame {index} ({STATUS[message.status]}); "
                            f"does it have {self.description.n_tractors} tractors like display "
                            f"{self.description.display_id!r}? Check the device's configuration"
                        )

        # frames more than half a period late are skipped, never sent in a burst; after a skip the
        # values sent are re-limited to one slew step per frame sent (the device clamps per tick)
        step = _step_per_frame(self.description, self.command)
        allowed_skips = int(self.max_skipped_fraction * n)
        frame_of = np.zeros(n, dtype=np.int64)
        skipped, diverged = 0, False
        last = np.zeros(wire.shape[1], dtype="<f4")
        try:
            start = time.perf_counter_ns() + period_ns
            k = 0
            while k < n:
                if self.stop_requested:
                    break
                target = start + k * period_ns
                while (remaining := target - time.perf_counter_ns()) > busy_ns:
                    readable, _, _ = select.select([self._sock], [], [], (remaining - busy_ns) / 1e9)
                    if readable:
                        collect()
                while time.perf_counter_ns() < target:
                    time.sleep(0)  # busy-wait, but let other threads (an in-process device) run
                late_by = time.perf_counter_ns() - target
                if sent == 0 and skipped == 0:
                    start += late_by  # the schedule starts with the first frame actually sent
                    target, late_by = target + late_by, 0
                if late_by > period_ns / 2:
                    ahead = min(n, k + int(math.ceil((late_by - period_ns / 2) / period_ns)))
                    skipped += ahead - k
                    k, diverged = ahead, True
                    if skipped > allowed_skips:
                        break  # the trial aborts: reported as stopped, with the skipped frames
                    continue
                values = wire[k]
                if diverged:
                    values = (last + np.clip(values.astype(float) - last, -step, step)).astype("<f4")
                self._sock.send(encode(FRAME, self._next_seq(), time.perf_counter_ns(), values))
                sent_ns[sent], frame_of[sent] = time.perf_counter_ns(), k
                last = values
                sent += 1
                k += 1
                collect()
            # the device acknowledges a frame when its tick applies it: wait while they come
            deadline = time.perf_counter_ns() + self.ack_timeout_s * 1e9
            while np.any(ack_ns[:sent] == 0) and (remaining := deadline - time.perf_counter_ns()) > 0:
                readable, _, _ = select.select([self._sock], [], [], remaining / 1e9)
                if readable:
                    before = np.count_nonzero(ack_ns[:sent])
                    collect()
                    if np.count_nonzero(ack_ns[:sent]) > before:
                        deadline = time.perf_counter_ns() + self.ack_timeout_s * 1e9
        except BaseException:
            try:
                self._send(ZERO)  # best effort, no wait: the caller may be unwinding a signal
            except OSError:
                pass
            raise
        self._zero()
        times = sent_ns[:sent]
        acked = ack_ns[:sent] > 0
        rtt_s = (ack_ns[:sent][acked] - times[acked]) / 1e9
        lateness = times - (start + frame_of[:sent] * period_ns)
        return PlaybackReport(
            frames_sent=sent,
            late=int(np.count_nonzero(lateness > period_ns / 2)),
            missing=int(sent - np.count_nonzero(status[:sent] == STATUS_CODE["applied"])),
            acked=int(np.count_nonzero(status[:sent] == STATUS_CODE["applied"])),
            stopped=sent + skipped < n,
            duration_s=float(times[-1] - times[0]) / 1e9 if sent else 0.0,
            late_acks=int(np.count_nonzero(rtt_s > self.ack_timeout_s)),
            send_intervals_s=np.diff(times) / 1e9,
            ack_rtt_s=rtt_s,
            rejected=int(np.count_nonzero((status[:sent] >= 0) & (status[:sent] != STATUS_CODE["applied"]))),
            stale=int(np.count_nonzero(status[:sent] == STATUS_CODE["stale"])),
            skipped=skipped,
        )

"""Network driver for real displays: frames over UDP at a fixed rate, each one acknowledged.

The wire format, version 2, is specified in ``docs/udp-frame-format.md`` (firmware implements it
from there) and implemented in :mod:`tactilab.experiments.devices.link` (:func:`encode` /
:func:`decode`, re-exported here): a 20-byte header, a payload and a 16-byte HMAC-SHA256 tag.

:class:`UdpDisplay` opens one authenticated link session per stimulus: ARM with a fresh random
32-byte key (the device answers ARMED with its own random nonce, zeroes its outputs and pins
this socket's address), then the FRAMEs with precise pacing (sleep, then busy-wait the last
``busy_wait_s`` on ``perf_counter_ns``), collecting the ACKs as they come, then ZERO and DISARM.
It sends ZERO and DISARM (without waiting) on any error. Only ACKs whose tag verifies count as
``applied`` or ``zeroed``; a refusal counts even untagged (it only ever stops the host).
"""

from __future__ import annotations

import math
import secrets
import select
import socket
import time
from urllib.parse import urlparse

import numpy as np

from .display import Display, DisplayError, PlaybackReport
from .link import (ACK, ARM, ARMED, DISARM, FLAG_WATCHDOG_TRIPPED, FRAME, KEY_SIZE, MAGIC, MAX_VALUES, REFUSALS,
                   STATUS, STATUS_CODE, VERSION, ZERO, FrameFormatError, Message, decode, encode)

__all__ = ["UdpDisplay", "Message", "encode", "decode", "FrameFormatError", "MAGIC", "VERSION",
           "FRAME", "ZERO", "ACK", "ARM", "ARMED", "DISARM", "STATUS", "STATUS_CODE", "FLAG_WATCHDOG_TRIPPED",
           "parse_udp_url"]

#: A host starts a new link session's seq from 0 once its counter passed this (seq never wraps).
_SEQ_RESTART = 2**31


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
    """Stream frames to a display over UDP (docs/udp-frame-format.md, version 2).

    Each ``play()`` is one authenticated link session: ARM with a fresh random key (the device
    answers ARMED with its nonce and pins this socket's address), the FRAMEs, ZERO, DISARM.
    ``zero()`` outside playback is ARM, ZERO, DISARM. A device armed by another host refuses the
    ARM (``busy``): :class:`DisplayError`.

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
        Attempts of each ARM, ZERO and DISARM exchange before giving up (>= 1).
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
        self._session: tuple[bytes, bytes] | None = None  # (key, device nonce) of the open link session
        self.last_ack: Message | None = None
        #: The device's watchdog time from its last ARMED, s (None before the first ARM).
        self.device_watchdog_s: float | None = None
        # the device's frames_applied at this host's last look, and the frames sent since: any
        # other increase is frames another process made the device apply (FRAME's ACKs carry it)
        self._applied_base: int | None = None
        self._own_sent = 0
        #: frames the device applied that this host did not send, over this display's life
        self.foreign_frames = 0

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
        """End an open link session (best effort, no wait) and close the socket."""
        if self._session is not None and self._sock.fileno() >= 0:
            self._abandon()
        self._sock.close()

    def _next_seq(self) -> int:
        seq = self._seq
        self._seq += 1
        return seq

    def _sealed(self, kind: int, values=None) -> tuple[bytes, int]:
        """A message of the open session, tagged with its key and the device's nonce, and its seq."""
        key, nonce = self._session
        seq = self._next_seq()
        return encode(kind, seq, time.perf_counter_ns(), values, key=key, nonce=nonce), seq

    def _abandon(self) -> None:
        """ZERO and DISARM without waiting (unwinding an error or a signal), forget the session."""
        try:
            for kind in (ZERO, DISARM):
                self._sock.send(self._sealed(kind)[0])
        except OSError:
            pass
        self._session = None

    def _receive(self, key: bytes | None = None, nonce: bytes | None = None) -> list[tuple[Message, int]]:
        """Drain the socket without blocking; return (answer, arrival ns) pairs: ACKs and ARMEDs whose
        tag verifies under the session (or the given) key, and refusals, tagged or not."""
        if key is None and self._session is not None:
            key, nonce = self._session
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
                message = decode(data, key=key, nonce=nonce if nonce is not None else bytes(16))
            except FrameFormatError:
                continue  # a corrupted answer is a missing answer
            if message.kind in (ACK, ARMED) and (message.authentic or
                                                 (message.kind == ACK and message.status in REFUSALS)):
                out.append((message, arrival))

    def _exchange(self, what: str, make, key: bytes | None = None) -> Message:
        """Send ``make() -> (datagram, seq)`` and wait for the answer to that seq, retrying."""
        sent: set[int] = set()
        for _ in range(self.zero_retries):
            data, seq = make()
            self._sock.send(data)
            sent.add(seq)  # a late answer to an earlier try counts too (a busy device answers late)
            deadline = time.perf_counter() + self.ack_timeout_s
            while (remaining := deadline - time.perf_counter()) > 0:
                select.select([self._sock], [], [], remaining)
                for message, _ in self._receive(key):
                    if message.seq in sent:
                        self.last_ack = message
                        return message
        raise DisplayError(
            f"{self.url}: no acknowledgement of {what} after {self.zero_retries} tries of "
            f"{self.ack_timeout_s * 1e3:.0f} ms; is the device (or `tactilab device emulate --port "
            f"{self.address[1]}`) running and does it speak frame format version {VERSION}? The device's "
            "watchdog zeroes it when frames stop"
        )

    def _arm(self) -> None:
        """Open a link session: ARM with a fresh key; the device zeroes, pins us and sends its nonce."""
        if self._seq > _SEQ_RESTART:
            self._seq = 0  # a new session may start anywhere; seq never wraps within one
        key, seq = secrets.token_bytes(KEY_SIZE), self._next_seq()
        data = encode(ARM, seq, time.perf_counter_ns(), key=key)  # retries repeat it byte for byte
        answer = self._exchange("ARM", lambda: (data, seq), key=key)
        if answer.kind != ARMED:
            status = STATUS.get(answer.status, str(answer.status))
            hint = ("another host holds the device's link session (it is released when that host disarms or "
                    "the device's watchdog trips); is another runner driving this display?" if status == "busy"
                    else "see docs/udp-frame-format.md")
            raise DisplayError(f"{self.url}: the device refused ARM ({status}); {hint}")
        self._session = (key, answer.nonce)
        self.device_watchdog_s = answer.watchdog_us / 1e6
        if answer.n_tractors and answer.n_tractors != self.description.n_tractors:
            self._abandon()
            raise DisplayError(f"{self.url}: the device has {answer.n_tractors} tractors, display "
                               f"{self.description.display_id!r} has {self.description.n_tractors}; check the "
                               "device's configuration or give its display description")

    def _look(self, counter: int) -> int:
        """Compare the device's ``frames_applied`` with the frames this host sent since its last
        look; return (and count) the excess: frames another process made the device apply."""
        foreign = 0
        if self._applied_base is not None:
            foreign = max(0, (counter - self._applied_base) % 2**32 - self._own_sent)
        self._applied_base, self._own_sent = counter, 0
        self.foreign_frames += foreign
        return foreign

    def _close_session(self) -> int:
        """ZERO (acknowledged: the outputs are zero) and DISARM (best effort) the open session;
        returns the foreign frames the ZERO's acknowledgement reveals (see :meth:`audit`)."""
        foreign = 0
        try:
            answer = self._exchange("ZERO", lambda: self._sealed(ZERO))
            if answer.status != STATUS_CODE["zeroed"] and answer.status not in (STATUS_CODE["disarmed"],):
                raise DisplayError(f"{self.url}: the device refused ZERO ({STATUS.get(answer.status)}); its "
                                   "watchdog zeroes it when frames stop; see docs/udp-frame-format.md")
            if answer.authentic:  # the counter of a tagged answer only: nobody else can fake it
                foreign = self._look(answer.frames_applied)
            try:
                self._exchange("DISARM", lambda: self._sealed(DISARM))
            except DisplayError:
                pass  # the outputs are zero; the device's watchdog ends the session
        except BaseException:
            if self._session is not None:
                self._abandon()
            raise
        self._session = None
        return foreign

    def _zero(self) -> None:
        self.audit()

    def audit(self) -> int:
        """ARM, ZERO, DISARM; return the frames the device applied that this host did not send
        since its previous look (the ZERO's acknowledgement carries the device's
        ``frames_applied``; the first look only sets the baseline)."""
        if self._session is None:
            self._arm()  # ARM zeroes the outputs
        return self._close_session()

    def _play(self, frames: np.ndarray, frame_rate_hz: float) -> PlaybackReport:
        self._arm()  # the device answers, is at rest and pins this socket for the session
        key, nonce = self._session
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
                index = message.seq - seq0
                if 0 <= index < sent and ack_ns[index] == 0:
                    ack_ns[index], status[index] = arrival, message.status
                    self.last_ack = message
                    if message.status == STATUS_CODE["disarmed"]:
                        self._session = None  # the device ended it; its outputs are zero
                        raise DisplayError(
                            f"{self.url}: the device's watchdog tripped during playback (frame {index}); "
                            "frames arrived too late. It stays at zero until the next play"
                        )
                    if message.status in (STATUS_CODE["not_armed"], STATUS_CODE["foreign"], STATUS_CODE["bad_mac"]):
                        raise DisplayError(
                            f"{self.url}: the device refused frame {index} ({STATUS[message.status]}): the link "
                            "session was lost (did the device restart?); see docs/udp-frame-format.md"
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
                self._sock.send(encode(FRAME, self._next_seq(), time.perf_counter_ns(), values, key=key,
                                       nonce=nonce))
                self._own_sent += 1
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
        except BaseException as exc:
            if isinstance(exc, DisplayError) and exc.frames_sent is None:
                exc.frames_sent = sent  # the session reports the frames the device was sent before the loss
            if self._session is not None:
                self._abandon()  # ZERO and DISARM, no wait: the caller may be unwinding a signal
            raise
        foreign = self._close_session()
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
            foreign=foreign,
        )

"""Network driver for real displays: frames over UDP, sent ahead of their due times, each one acknowledged.

The wire format, version 3, is specified in ``docs/udp-frame-format.md`` (firmware implements it
from there) and implemented in :mod:`tactilab.experiments.devices.link` (:func:`encode` /
:func:`decode`, re-exported here); the host's end of the paired link (ARM, keep-alive, DISARM,
the device's clock, the ``frames_applied`` look) is :mod:`tactilab.experiments.devices.udp_link`.

:class:`UdpDisplay` arms the device once, at its first use, with the pairing key the display
description names, keeps the link armed between stimuli (keep-alive ZEROs) and disarms it on
``close()``. Each stimulus starts and ends with an acknowledged ZERO; its FRAMEs go into the
device's FIFO up to ``lookahead_s`` ahead of their due times on the device's clock, so host
jitter up to the lookahead skips nothing. Only ACKs whose tag verifies count as ``applied`` or
``zeroed``; a refusal counts even untagged (it only ever stops the host).
"""

from __future__ import annotations

import math
import select
import time
from urllib.parse import urlparse

import numpy as np

from .display import Display, DisplayError, PlaybackReport
from .link import (ACK, ARM, ARMED, DISARM, FLAG_WATCHDOG_TRIPPED, FRAME, KEY_SIZE, MAGIC, MAX_VALUES, STATUS,
                   STATUS_CODE, VERSION, ZERO, FrameFormatError, Message, decode, encode)
from .udp_link import HostLink

__all__ = ["UdpDisplay", "Message", "encode", "decode", "FrameFormatError", "MAGIC", "VERSION",
           "FRAME", "ZERO", "ACK", "ARM", "ARMED", "DISARM", "STATUS", "STATUS_CODE", "FLAG_WATCHDOG_TRIPPED",
           "parse_udp_url"]

#: ACK statuses that end playback at once: the link or the display's configuration is wrong.
_LINK_LOST = {STATUS_CODE[s] for s in ("refused", "bad_mac", "bad_version")}
_MISCONFIGURED = {STATUS_CODE[s] for s in ("bad_count", "bad_message", "bad_due", "overflow")}


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
    """Stream frames to a paired display over UDP (docs/udp-frame-format.md, version 3).

    The link is armed once (at the first ``zero()``, ``audit()`` or ``play()``), kept alive
    between stimuli and disarmed by ``close()``. A device armed by another host, or holding
    another pairing key, refuses the ARM (the same answer for both): :class:`DisplayError`.

    Parameters
    ----------
    description : DisplayDescription
        The display: ``n_tractors`` values per FRAME, ``lookahead_s``, and (unless
        ``pairing_key`` is given) ``pairing_key_file``.
    host, port : str, int
        The device's address (``127.0.0.1`` and the port of ``tactilab device emulate`` for
        the emulator).
    command : {"traction", "deflection"}, optional
        What the values are (Pa or m).
    ack_timeout_s : float
        How long one try of an exchange waits (ARM, ZERO, DISARM; each is tried ``zero_retries``
        times), and how long after a frame's due time its ACK may come before it counts as late,
        s (> 0; default 0.2: a device process on a busy host may answer that late).
    zero_retries : int
        Attempts of each ARM, ZERO and DISARM exchange before giving up (>= 1).
    max_skipped_fraction : float
        A frame the host could not send before half a period after its due time is skipped,
        never sent late in a burst; after a skip every value sent is re-limited to one slew step
        from the previous one. When more than this fraction of a stimulus's frames were
        skipped, playback stops (the trial aborts; the report says ``stopped`` and ``skipped``).
        In [0, 1].
    pairing_key : bytes, optional
        The 32-byte pairing key; default: read from the description's ``pairing_key_file``
        (:func:`~.pairing.read_pairing_key`: owner-only permissions, exactly 32 bytes).
    """

    def __init__(self, description, host: str = "127.0.0.1", port: int = 9000, *,
                 command: str | None = None, ack_timeout_s: float = 0.2, zero_retries: int = 3,
                 max_skipped_fraction: float = 0.01, pairing_key: bytes | None = None) -> None:
        super().__init__(description, command)
        if isinstance(port, bool) or not isinstance(port, int) or not 0 < port < 65536:
            raise ValueError(f"port: must be an integer in 1..65535, got {port!r}; give the device's UDP port")
        number = float(ack_timeout_s)
        if not (math.isfinite(number) and number > 0):
            raise ValueError(f"ack_timeout_s: must be a finite number > 0 s, got {ack_timeout_s!r}; give e.g. 0.05")
        if isinstance(zero_retries, bool) or not isinstance(zero_retries, int) or zero_retries < 1:
            raise ValueError(f"zero_retries: must be an integer >= 1, got {zero_retries!r}; give e.g. 3")
        if not (isinstance(max_skipped_fraction, (int, float)) and 0 <= max_skipped_fraction <= 1):
            raise ValueError(f"max_skipped_fraction: must be a number in [0, 1], got {max_skipped_fraction!r}; "
                             "give e.g. 0.01")
        if description.n_tractors > MAX_VALUES:
            raise ValueError(f"description: {description.n_tractors} tractors exceed the {MAX_VALUES} values "
                             "a FRAME can carry; split the display")
        if pairing_key is None:
            from .pairing import description_pairing_key

            pairing_key = description_pairing_key(description)
        elif not isinstance(pairing_key, (bytes, bytearray)) or len(pairing_key) != KEY_SIZE:
            raise ValueError(f"pairing_key: must be {KEY_SIZE} bytes (the key shared with the device), got "
                             f"{pairing_key!r:.40}; read it with tactilab.experiments.devices.pairing.read_pairing_key")
        self.max_skipped_fraction = float(max_skipped_fraction)
        self.lookahead_s = float(description.lookahead_s)
        self.address = (host, port)
        self.ack_timeout_s = float(ack_timeout_s)
        self.zero_retries = zero_retries
        self.link = HostLink(self.address, bytes(pairing_key), ack_timeout_s=self.ack_timeout_s,
                             retries=zero_retries, url=self.url)

    @classmethod
    def from_url(cls, url: str, description, **kwargs) -> UdpDisplay:
        """Build from ``"udp://HOST:PORT"`` (see :func:`parse_udp_url`)."""
        host, port = parse_udp_url(url)
        return cls(description, host, port, **kwargs)

    @property
    def url(self) -> str:
        """``udp://HOST:PORT`` of the device."""
        return f"udp://{self.address[0]}:{self.address[1]}"

    @property
    def onset_delay_s(self) -> float:
        """The first frame of a ``play()`` is due this long after the call: the lookahead, s."""
        return self.lookahead_s

    @property
    def device_watchdog_s(self) -> float | None:
        """The device's watchdog time from its ARMED, s (None before the first ARM)."""
        return self.link.watchdog_s

    @property
    def foreign_frames(self) -> int:
        """Frames the device applied that this host did not send, over this display's life."""
        return self.link.foreign_frames

    @property
    def last_ack(self) -> Message | None:
        """The last answer of an exchange."""
        return self.link.last_ack

    def close(self) -> None:
        """Disarm the link (the device's outputs go to zero) and close the socket."""
        self.link.close()

    def _zero(self) -> None:
        with self.link.lock:  # what this look finds is kept for the next audit() or play() report
            self.link.zero()

    def audit(self) -> int:
        """An acknowledged ZERO on the armed link (armed first if needed); return the frames the device
        applied that this host did not send since its previous look (the first look sets the baseline)."""
        with self.link.lock:
            self.link.zero()
            return self.link.found()

    def _check_device(self, frame_rate_hz: float) -> None:
        link = self.link
        if link.n_tractors and link.n_tractors != self.description.n_tractors:
            raise DisplayError(f"{self.url}: the device has {link.n_tractors} tractors, display "
                               f"{self.description.display_id!r} has {self.description.n_tractors}; check the "
                               "device's configuration or give its display description")
        ahead = int(math.ceil(self.lookahead_s * frame_rate_hz)) + 2
        if link.fifo_frames and ahead > link.fifo_frames:
            raise DisplayError(f"{self.url}: lookahead_s {self.lookahead_s:g} s at {frame_rate_hz:g} Hz needs {ahead} "
                               f"frames in the device's FIFO, which holds {link.fifo_frames}; lower the description's "
                               "lookahead_s")

    def _play(self, frames: np.ndarray, frame_rate_hz: float) -> PlaybackReport:
        link = self.link
        with link.lock:  # the keep-alive pauses: the stream keeps the link alive
            for attempt in range(3):
                link.zero()  # the link is armed, the outputs at rest, a fresh clock sample taken
                self._check_device(frame_rate_hz)
                try:
                    return self._stream(frames.astype("<f4"), frame_rate_hz, link.clock_offset_ns())
                except _EndedBeforeOnset:
                    # the device's watchdog ended the link between the opening ZERO and the first frame
                    # (this host was descheduled): it answered before the first frame was due, so nothing
                    # was applied, and the stimulus starts again on a new link
                    if attempt == 2:
                        raise DisplayError(f"{self.url}: the device's watchdog ended the link before the stimulus "
                                           "began, three times; this host is descheduled for longer than the "
                                           "device's watchdog time (a busy machine?)") from None

    def _stream(self, wire: np.ndarray, frame_rate_hz: float, offset_ns: int) -> PlaybackReport:
        link, n = self.link, wire.shape[0]
        period_ns = 1e9 / frame_rate_hz
        ahead_ns = self.lookahead_s * 1e9
        sent_ns, ack_ns = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
        due_ns, applied_ns = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
        status = np.full(n, -1, dtype=np.int64)
        seq0, sent = link.seq, 0

        def collect() -> None:
            for message, arrival in link.receive():
                index = message.seq - seq0
                if not (0 <= index < sent and ack_ns[index] == 0):
                    continue
                ack_ns[index], status[index], applied_ns[index] = arrival, message.status, message.device_ns
                link.last_ack = message
                if message.status == STATUS_CODE["disarmed"]:
                    link.lost = "the device's watchdog ended the link during playback"
                    if message.authentic and message.device_ns < first_due:  # before the onset: nothing applied
                        link.own_sent -= sent
                        raise _EndedBeforeOnset
                    raise DisplayError(f"{self.url}: the device's watchdog tripped during playback (frame {index}); "
                                       "frames arrived too late. It stays at zero; the next use arms it again")
                if message.status in _LINK_LOST:
                    link.lost = f"the device answered {STATUS[message.status]}"
                    raise DisplayError(f"{self.url}: the device refused frame {index} ({STATUS[message.status]}): the "
                                       "link session was lost (did the device restart?); see docs/udp-frame-format.md")
                if message.status in _MISCONFIGURED:
                    raise DisplayError(f"{self.url}: the device rejected frame {index} ({STATUS[message.status]}); "
                                       f"does it have {self.description.n_tractors} tractors like display "
                                       f"{self.description.display_id!r}, and room for lookahead_s "
                                       f"{self.lookahead_s:g} s of frames? Check the device's configuration")

        # a frame that cannot leave before half a period after its due time is skipped, never sent
        # in a burst; after a skip the values sent are re-limited to one slew step per frame sent
        step = _step_per_frame(self.description, self.command)
        allowed_skips = int(self.max_skipped_fraction * n)
        frame_of = np.zeros(n, dtype=np.int64)
        skipped, diverged = 0, False
        last = np.zeros(wire.shape[1], dtype="<f4")
        start = time.perf_counter_ns() + ahead_ns  # frame k is due at start + k period (host clock)
        first_due = int(round(start + offset_ns))  # frame 0's, on the device's clock
        # frames go out in batches of a fifth of the lookahead: few wake-ups, each frame still sent at
        # least 4/5 of the lookahead ahead of its due time
        batch = max(1, int(self.lookahead_s * frame_rate_hz / 5))
        try:
            k = 0
            while k < n:
                if self.stop_requested:
                    break
                now = time.perf_counter_ns()
                late_by = now - (start + k * period_ns)
                if late_by > period_ns / 2:
                    ahead = min(n, k + int(math.ceil((late_by - period_ns / 2) / period_ns)))
                    skipped += ahead - k
                    k, diverged = ahead, True
                    if skipped > allowed_skips:
                        break  # the trial aborts: reported as stopped, with the skipped frames
                    continue
                last_due = min(n - 1, int((now + ahead_ns - start) // period_ns))
                while k <= last_due:  # every frame whose due time is within the lookahead
                    values = wire[k]
                    if diverged:
                        values = (last + np.clip(values.astype(float) - last, -step, step)).astype("<f4")
                    due = start + k * period_ns
                    data, _ = link.sealed(FRAME, values, due_ns=max(0, int(round(due + offset_ns))))
                    link.sock.send(data)
                    link.own_sent += 1
                    sent_ns[sent], due_ns[sent], frame_of[sent] = time.perf_counter_ns(), int(due), k
                    last, sent, k = values, sent + 1, k + 1
                collect()
                # sleep until the next batch enters the lookahead, collecting ACKs meanwhile
                send_at = start + (k + batch - 1) * period_ns - ahead_ns
                while k < n and (wait_ns := send_at - time.perf_counter_ns()) > 0 and not self.stop_requested:
                    readable, _, _ = select.select([link.sock], [], [], wait_ns / 1e9)
                    if readable:
                        collect()
            # stopped: no wait, the ZERO below drops the frames still in the device's FIFO
            sent_whole = not (self.stop_requested or skipped > allowed_skips)
            # the device acknowledges a frame when its tick applies it, at its due time: wait for them
            patience_ns = self.ack_timeout_s * 1e9
            end = (int(due_ns[sent - 1]) if sent else time.perf_counter_ns()) + patience_ns
            while sent_whole and np.any(ack_ns[:sent] == 0) and (remaining := max(end, 0) - time.perf_counter_ns()) > 0:
                readable, _, _ = select.select([link.sock], [], [], remaining / 1e9)
                if readable:
                    before = np.count_nonzero(ack_ns[:sent])
                    collect()
                    if np.count_nonzero(ack_ns[:sent]) > before:
                        end = max(end, time.perf_counter_ns() + patience_ns)
        except _EndedBeforeOnset:
            raise
        except BaseException as exc:
            if isinstance(exc, DisplayError) and exc.frames_sent is None:
                exc.frames_sent = sent  # the session reports the frames the device was sent before the loss
            link.send_zero()  # no wait: the caller may be unwinding a signal; it zeroes again
            raise
        link.own_sent -= int(np.count_nonzero((status[:sent] >= 0) & (status[:sent] != STATUS_CODE["applied"])))
        link.zero()  # acknowledged: the outputs are at rest, the counter looked at
        return self._report(sent, skipped, n, start, period_ns, offset_ns, sent_ns, ack_ns, due_ns, applied_ns,
                            status, frame_of)

    def _report(self, sent, skipped, n, start, period_ns, offset_ns, sent_ns, ack_ns, due_ns, applied_ns, status,
                frame_of) -> PlaybackReport:
        times, acked = sent_ns[:sent], status[:sent] == STATUS_CODE["applied"]
        # when the device applied each frame (its clock, from the ACK) relative to the frame's due time
        lateness = applied_ns[:sent][acked] - (due_ns[:sent][acked] + offset_ns)
        ack_delay_s = (ack_ns[:sent][acked] - due_ns[:sent][acked]) / 1e9
        return PlaybackReport(
            frames_sent=sent,
            late=int(np.count_nonzero(lateness > period_ns / 2)),
            missing=int(sent - np.count_nonzero(acked)),
            acked=int(np.count_nonzero(acked)),
            stopped=sent + skipped < n,
            duration_s=float(due_ns[sent - 1] - due_ns[0]) / 1e9 if sent else 0.0,
            late_acks=int(np.count_nonzero(ack_delay_s > self.ack_timeout_s)),
            send_intervals_s=np.diff(times) / 1e9,
            ack_rtt_s=ack_delay_s,
            rejected=int(np.count_nonzero((status[:sent] >= 0) & (status[:sent] != STATUS_CODE["applied"]))),
            stale=int(np.count_nonzero(status[:sent] == STATUS_CODE["stale"])),
            skipped=skipped,
            foreign=self.link.found(),
        )


class _EndedBeforeOnset(Exception):
    """The device's watchdog ended the link before the stimulus's first frame was due."""

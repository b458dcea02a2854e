"""The host's end of the paired display link (docs/udp-frame-format.md, version 3), held for a whole session.

:class:`HostLink` arms the device once (ARM with a fresh host nonce, tagged with the pairing
key; the device proves it holds the same key in its ARMED), keeps the link alive between
stimuli with ZERO messages from a background thread (every quarter of the device's watchdog
time), and disarms it on :meth:`HostLink.close`. It estimates the device's clock from the
acknowledged exchanges (for the FRAMEs' due times) and compares the device's ``frames_applied``
counter with the frames it sent (foreign frames). :class:`RawLink` is a bare blocking link for
tests and firmware bring-up.
"""

from __future__ import annotations

import collections
import secrets
import select
import socket
import threading
import time

from .display import DisplayError
from .link import (ACK, ARM, ARMED, DISARM, REFUSALS, STATUS, STATUS_CODE, VERSION, ZERO, FrameFormatError, Message,
                   decode, encode, peek, session_key)

__all__ = ["HostLink", "RawLink", "ARM_PATIENCE_S"]

#: How long a host repeats an ARM the device refuses (a previous host's session ends by its watchdog), s.
ARM_PATIENCE_S = 1.0
#: A host starts a new link session's seq from 0 once its counter passed this (seq never wraps).
_SEQ_RESTART = 2**31


class HostLink:
    """One host's paired link to one device.

    Parameters
    ----------
    address : (str, int)
        The device's IPv4 address and UDP port.
    pairing_key : bytes
        The 32-byte key shared with the device.
    ack_timeout_s : float
        How long one try of an exchange waits for its answer, s.
    retries : int
        Tries of each exchange (ARM, ZERO, DISARM).
    url : str
        ``udp://HOST:PORT``, for messages.
    """

    def __init__(self, address: tuple[str, int], pairing_key: bytes, *, ack_timeout_s: float, retries: int,
                 url: str) -> None:
        self.address, self.pairing_key, self.url = address, pairing_key, url
        self.ack_timeout_s, self.retries = ack_timeout_s, retries
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.sock.connect(address)  # only datagrams from the device reach us
        #: one user of the socket at a time: the caller (exchanges, playback) or the keep-alive thread
        self.lock = threading.Lock()
        self.seq = 0
        self.key: bytes | None = None  # the session key of the armed link
        self.watchdog_s: float | None = None  # the device's, from its ARMED
        self.fifo_frames = 0
        self.n_tractors = 0
        self.last_ack: Message | None = None
        self.lost: str | None = None  # why the keep-alive found the link gone (re-armed at the next use)
        self.rearms = 0  # ARMs after the first (a link lost between stimuli)
        self._samples: collections.deque = collections.deque(maxlen=16)  # (rtt_ns, device - host offset ns)
        self._applied_base: int | None = None
        self.own_sent = 0
        self._found = 0  # foreign frames found since the caller last asked
        self.foreign_frames = 0
        self._stop = threading.Event()
        self._keeper: threading.Thread | None = None

    # ----- messages ---------------------------------------------------------------------
    def next_seq(self) -> int:
        seq = self.seq
        self.seq += 1
        return seq

    def sealed(self, kind: int, values=None, due_ns: int = 0) -> tuple[bytes, int]:
        """A message of the armed link, tagged with its session key, and its seq."""
        seq = self.next_seq()
        return encode(kind, seq, time.perf_counter_ns(), values, key=self.key, due_ns=due_ns), seq

    def receive(self, key: bytes | None = None, host_nonce: bytes = b"") -> list[tuple[Message, int]]:
        """Drain the socket without blocking: (answer, arrival ns) pairs of ACKs and ARMEDs whose tag
        verifies under the session (or the given) key, and refusals, tagged or not.

        Raises
        ------
        DisplayError
            Nobody listens at the address, or the device speaks an older version of the format.
        """
        out = []
        while True:
            try:
                data = self.sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                return out
            except ConnectionRefusedError as err:  # ICMP port unreachable: nobody listens
                raise DisplayError(f"{self.url}: connection refused; is the device (or `tactilab device emulate "
                                   f"--port {self.address[1]} --pairing-key FILE`) running?") from err
            arrival = time.perf_counter_ns()
            header = peek(data)
            if header is not None and header[0] in (1, 2):
                raise DisplayError(f"{self.url}: the device speaks frame format version {header[0]}; this host speaks "
                                   f"version {VERSION} (a paired ARM, due times): update the device's firmware "
                                   "(docs/udp-frame-format.md)")
            try:
                message = decode(data, key=key if key is not None else self.key, host_nonce=host_nonce)
            except FrameFormatError:
                continue  # a corrupted answer is a missing answer
            if message.kind in (ACK, ARMED) and (message.authentic or
                                                 (message.kind == ACK and message.status in REFUSALS)):
                out.append((message, arrival))

    def exchange(self, what: str, make, *, key: bytes | None = None, host_nonce: bytes = b"",
                 patience_s: float = 0.0) -> Message:
        """Send ``make() -> (datagram, seq)`` and wait for the answer to that seq, retrying; an untagged
        ``refused`` is tried again for ``patience_s``. An authentic answer gives a clock sample."""
        sent: dict[int, int] = {}
        refused_until = time.perf_counter() + patience_s
        tries = 0
        while True:
            data, seq = make()
            start = time.perf_counter_ns()
            self.sock.send(data)
            sent.setdefault(seq, start)  # a late answer to an earlier try counts too
            tries += 1
            deadline = time.perf_counter() + self.ack_timeout_s
            answer = None
            while answer is None and (remaining := deadline - time.perf_counter()) > 0:
                select.select([self.sock], [], [], remaining)
                for message, arrival in self.receive(key, host_nonce):
                    if message.seq in sent and answer is None:
                        answer = message
                        if message.authentic:
                            self._sample(sent[message.seq], arrival, message.device_ns)
            if answer is not None and not (answer.status == STATUS_CODE["refused"] and not answer.authentic
                                           and time.perf_counter() < refused_until):
                self.last_ack = answer
                return answer
            if answer is None and tries >= self.retries:
                raise DisplayError(
                    f"{self.url}: no acknowledgement of {what} after {tries} tries of {self.ack_timeout_s * 1e3:.0f} "
                    f"ms; is the device (or `tactilab device emulate --port {self.address[1]} --pairing-key FILE`) "
                    f"running and does it speak frame format version {VERSION}? The device's watchdog zeroes it "
                    "when frames stop")
            if answer is not None:
                time.sleep(min(0.02, self.ack_timeout_s))  # refused: wait for a previous host's watchdog

    def _sample(self, sent_ns: int, arrival_ns: int, device_ns: int) -> None:
        self._samples.append((arrival_ns - sent_ns, device_ns - (sent_ns + arrival_ns) // 2))

    def clock_offset_ns(self) -> int:
        """The device's clock minus this host's ``perf_counter_ns``, from the quickest recent round trip."""
        return min(self._samples)[1]

    # ----- the link session ---------------------------------------------------------------
    def arm(self) -> None:
        """ARM with a fresh host nonce; the device proves the pairing key in its ARMED, zeroes and pins us."""
        if self.seq > _SEQ_RESTART:
            self.seq = 0  # a new session may start anywhere; seq never wraps within one
        nonce, seq = secrets.token_bytes(16), self.next_seq()
        data = encode(ARM, seq, time.perf_counter_ns(), key=self.pairing_key, nonce=nonce)  # tries repeat it
        answer = self.exchange("ARM", lambda: (data, seq), key=self.pairing_key, host_nonce=nonce,
                               patience_s=ARM_PATIENCE_S)
        if answer.kind != ARMED:
            status = STATUS.get(answer.status, str(answer.status))
            hint = ("either another host holds the device's link (a run still armed is released by the device's "
                    "watchdog), or this host's pairing key is not the device's (check the description's "
                    "pairing_key_file and the device's key); the device answers both alike, by design"
                    if status == "refused" else "see docs/udp-frame-format.md")
            raise DisplayError(f"{self.url}: the device refused ARM ({status}); {hint}")
        if self.key is not None or self.lost is not None:
            self.rearms += 1
        self.key = session_key(self.pairing_key, nonce, answer.nonce)
        self.watchdog_s, self.fifo_frames, self.n_tractors = answer.watchdog_us / 1e6, answer.fifo_frames, \
            answer.n_tractors
        self.lost = None
        self.look(answer.frames_applied)
        if self._keeper is None:
            self._keeper = threading.Thread(target=self._keep_alive, name="tactilab-link-keepalive", daemon=True)
            self._keeper.start()

    def look(self, counter: int) -> None:
        """Compare the device's ``frames_applied`` with the frames this host sent since its last look;
        the excess is frames another process made the device apply (counted in ``foreign_frames``)."""
        if self._applied_base is not None:
            foreign = max(0, (counter - self._applied_base) % 2**32 - self.own_sent)
            self._found += foreign
            self.foreign_frames += foreign
        self._applied_base, self.own_sent = counter, 0

    def found(self) -> int:
        """Foreign frames found since the previous call."""
        found, self._found = self._found, 0
        return found

    def zero(self) -> None:
        """An acknowledged ZERO on the armed link (armed again first if it was lost); looks at the counter.

        Call with :attr:`lock` held. Raises :class:`DisplayError` when the device refuses it."""
        for attempt in range(2):
            if self.key is None or self.lost is not None:
                self.arm()  # ARM zeroes the outputs too
            answer = self.exchange("ZERO", lambda: self.sealed(ZERO))
            if answer.status == STATUS_CODE["zeroed"] and answer.authentic:
                self.look(answer.frames_applied)
                return
            if answer.status in (STATUS_CODE["disarmed"], STATUS_CODE["refused"]) and attempt == 0:
                # the device's watchdog ended the link (outputs zero): arm again; its ARMED's counter
                # tells whether anything was applied meanwhile
                self.lost = f"the device answered {STATUS[answer.status]}"
                continue
            raise DisplayError(f"{self.url}: the device refused ZERO ({STATUS.get(answer.status)}); its watchdog "
                               "zeroes it when frames stop; see docs/udp-frame-format.md")

    def send_zero(self) -> None:
        """ZERO without waiting (unwinding an error or a signal); the link stays armed."""
        if self.key is not None:
            try:
                self.sock.send(self.sealed(ZERO)[0])
            except OSError:
                pass

    def _keep_alive(self) -> None:
        """Every quarter of the watchdog time, a ZERO while no one else uses the link; a link the device
        ended (its watchdog tripped: this process was descheduled for longer than W) is armed again."""
        while not self._stop.wait(min(max((self.watchdog_s or 0.2) / 4, 1e-3), 0.25)):
            if not self.lock.acquire(blocking=False):
                continue  # playback or an exchange holds the link: their messages keep it alive
            try:
                if self.key is None or self.sock.fileno() < 0:
                    continue
                if self.lost is not None:
                    self.arm()  # outputs were at zero; the ARMED's counter is looked at
                    continue
                data, seq = self.sealed(ZERO)
                start = time.perf_counter_ns()
                self.sock.send(data)
                deadline = time.perf_counter() + min(self.ack_timeout_s, (self.watchdog_s or 0.2) / 8)
                answered = False
                while not answered and (remaining := deadline - time.perf_counter()) > 0:
                    select.select([self.sock], [], [], remaining)
                    for message, arrival in self.receive():
                        answered |= message.seq == seq
                        if message.status == STATUS_CODE["zeroed"] and message.authentic:
                            self.look(message.frames_applied)
                            if message.seq == seq:
                                self._sample(start, arrival, message.device_ns)
                        elif message.status in REFUSALS:
                            self.lost = f"the device answered {STATUS.get(message.status)} between stimuli"
            except (OSError, DisplayError) as exc:  # the next use arms again, and says why it cannot
                self.lost, self.key = f"keep-alive failed: {exc}", None
            finally:
                self.lock.release()

    def close(self) -> None:
        """Stop the keep-alive, DISARM (best effort: the outputs go to zero) and close the socket."""
        self._stop.set()
        if self._keeper is not None:
            self._keeper.join(timeout=5)
        with self.lock:
            if self.key is not None and self.lost is None and self.sock.fileno() >= 0:
                try:
                    self.exchange("DISARM", lambda: self.sealed(DISARM))
                except (DisplayError, OSError):
                    try:  # no answer: say it once more without waiting; the watchdog ends it anyway
                        self.sock.send(self.sealed(DISARM)[0])
                    except OSError:
                        pass
            self.key = None
            self.sock.close()


class RawLink:
    """A bare blocking host of one link session, message by message: for tests and firmware bring-up
    (a real host uses :class:`tactilab.experiments.devices.udp.UdpDisplay`).

    Parameters
    ----------
    port : int
        The device's UDP port.
    pairing_key : bytes
        The 32-byte pairing key (a wrong one is refused like any other intruder).
    host : str
        The device's IPv4 address.
    bind : str
        The local address to send from (e.g. ``127.0.0.2``: another loopback address).
    timeout_s : float
        How long :meth:`recv` waits, s.
    """

    def __init__(self, port: int, pairing_key: bytes, host: str = "127.0.0.1", *, bind: str = "127.0.0.1",
                 timeout_s: float = 5.0):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((bind, 0))
        self.sock.settimeout(timeout_s)
        self.sock.connect((host, port))
        self.pairing_key = pairing_key
        self.key: bytes | None = None
        self.seq = 0

    def message(self, kind: int, values=None, *, seq: int | None = None, due_ns: int = 0) -> bytes:
        """The next message of the session (seq one above the last, unless given), tagged."""
        self.seq = self.seq + 1 if seq is None else seq
        return encode(kind, self.seq, time.monotonic_ns(), values, key=self.key, due_ns=due_ns)

    def send(self, data: bytes) -> None:
        """Send one datagram as it is."""
        self.sock.send(data)

    def recv(self) -> Message:
        """The next answer, its tag checked under the session's key."""
        return decode(self.sock.recv(65536), key=self.key)

    def ask(self, kind: int, values=None, *, seq: int | None = None, due_ns: int = 0) -> Message:
        """Send the next message and return the answer."""
        self.send(self.message(kind, values, seq=seq, due_ns=due_ns))
        return self.recv()

    def arm(self, nonce: bytes | None = None, *, seq: int | None = None) -> Message:
        """ARM with ``nonce`` (default: a fresh random one); on an authentic ARMED the session is open."""
        nonce = secrets.token_bytes(16) if nonce is None else nonce
        self.seq = self.seq + 1 if seq is None else seq
        self.send(encode(ARM, self.seq, time.monotonic_ns(), key=self.pairing_key, nonce=nonce))
        answer = decode(self.sock.recv(65536), key=self.pairing_key, host_nonce=nonce)
        if answer.kind == ARMED and answer.authentic:
            self.key = session_key(self.pairing_key, nonce, answer.nonce)
        return answer

    def close(self) -> None:
        """Close the socket."""
        self.sock.close()

"""The display link's wire format, version 2: authenticated frames (docs/udp-frame-format.md).

Every datagram is a 20-byte little-endian header, a payload and a 16-byte tag::

    offset  size  field
    0       4     magic  b"TLDF"
    4       1     version (2)
    5       1     type: 1 FRAME, 2 ZERO, 3 ACK, 4 ARM, 5 ARMED, 6 DISARM
    6       2     count: number of float32 values (FRAME), else 0
    8       4     seq, uint32, strictly increasing within a link session (never wraps)
    12      8     timestamp_ns, uint64: the host's monotonic clock at sending (echoed in ACKs)
    20      P     payload: FRAME 4*count float32; ACK 8 bytes (status u8, flags u8,
                  reserved u16, frames_applied u32); ARM the 32-byte session key; ARMED
                  24 bytes (device nonce 16, watchdog_us u32, n_tractors u16, reserved u16);
                  ZERO and DISARM nothing
    20+P    16    tag: the first 16 bytes of HMAC-SHA256(key, nonce || bytes 0 .. 20+P-1)

A link session begins with the host's ARM, which carries a fresh random key; the device answers
ARMED with a fresh random nonce and pins the host's address. Every later message of the session
is tagged with that key over the nonce and its own bytes (ARM itself with an all-zero nonce), so
a message of an earlier session never verifies. Refusals the device cannot authenticate carry
an all-zero tag. :func:`encode` / :func:`decode` are the reference implementation.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
import socket
import struct
import time
from dataclasses import dataclass

import numpy as np

__all__ = ["Message", "encode", "decode", "peek", "FrameFormatError", "MAGIC", "VERSION", "FRAME", "ZERO",
           "ACK", "ARM", "ARMED", "DISARM", "STATUS", "STATUS_CODE", "REFUSALS", "FLAG_WATCHDOG_TRIPPED",
           "KEY_SIZE", "NONCE_SIZE", "TAG_SIZE", "NO_NONCE", "MAX_VALUES", "MAX_SEQ", "RawLink"]

MAGIC = b"TLDF"
VERSION = 2
#: Message types of the display frame format (docs/udp-frame-format.md)
FRAME, ZERO, ACK, ARM, ARMED, DISARM = 1, 2, 3, 4, 5, 6
KINDS = {FRAME: "FRAME", ZERO: "ZERO", ACK: "ACK", ARM: "ARM", ARMED: "ARMED", DISARM: "DISARM"}
HEADER = struct.Struct("<4sBBHIQ")  # 20 bytes
ACK_BODY = struct.Struct("<BBHI")  # 8 bytes
ARMED_BODY = struct.Struct("<16sIHH")  # 24 bytes
KEY_SIZE, NONCE_SIZE, TAG_SIZE = 32, 16, 16
#: The nonce in the MAC input of ARM (the device has not chosen its nonce yet).
NO_NONCE = bytes(NONCE_SIZE)
#: ACK status codes (docs/udp-frame-format.md).
STATUS = {0: "applied", 1: "zeroed", 2: "bad_mac", 3: "bad_count", 4: "stale", 5: "disarmed",
          6: "bad_message", 7: "non_finite", 8: "overflow", 9: "released", 10: "busy", 11: "not_armed",
          12: "foreign", 13: "bad_version"}
STATUS_CODE = {name: code for code, name in STATUS.items()}
#: Statuses that refuse a message: a host may act on them without a valid tag (they only stop it).
REFUSALS = frozenset(code for code, name in STATUS.items() if name not in ("applied", "zeroed", "released"))
FLAG_WATCHDOG_TRIPPED = 0x01
MAX_VALUES = 16000  # keeps a FRAME under the 64 KiB UDP datagram limit
#: The largest seq; a host re-arms (a new link session) before reaching it.
MAX_SEQ = 2**32 - 1
_UNTAGGED = bytes(TAG_SIZE)


class FrameFormatError(ValueError):
    """A datagram that is not a valid message of this format."""


@dataclass(frozen=True)
class Message:
    """One decoded datagram.

    ``values`` is float32 (FRAME) or empty; ACK fields are 0 otherwise; ``key`` is the session
    key an ARM carries; ``nonce``, ``watchdog_us`` and ``n_tractors`` come from an ARMED;
    ``authentic`` says whether the tag verified (for an ARM: under the key it carries, which
    proves integrity only).
    """

    kind: int
    seq: int
    timestamp_ns: int
    values: np.ndarray
    status: int = 0
    flags: int = 0
    frames_applied: int = 0
    authentic: bool = False
    key: bytes = b""
    nonce: bytes = b""
    watchdog_us: int = 0
    n_tractors: int = 0


def mac(key: bytes, nonce: bytes, body: bytes) -> bytes:
    """The 16-byte tag: HMAC-SHA256(key, nonce || body) truncated to its first 16 bytes."""
    return hmac.new(key, nonce + body, hashlib.sha256).digest()[:TAG_SIZE]


def _check_secret(value, size: int, name: str) -> bytes:
    if not isinstance(value, (bytes, bytearray)) or len(value) != size:
        got = f"{len(value)} bytes" if isinstance(value, (bytes, bytearray)) else type(value).__name__
        raise FrameFormatError(f"{name}: must be {size} bytes, got {got}; use secrets.token_bytes({size})")
    return bytes(value)


def encode(kind: int, seq: int, timestamp_ns: int, values=None, *, key: bytes | None = None,
           nonce: bytes = NO_NONCE, status: int = 0, flags: int = 0, frames_applied: int = 0,
           watchdog_us: int = 0, n_tractors: int = 0) -> bytes:
    """Encode and tag one message (see the module docstring for the layout).

    ``key`` is the session key (ARM carries it as its payload); without it the tag is all
    zero, which only a refusal ACK may use. ``nonce`` is the device's nonce of the session
    (ARM: ignored, the all-zero nonce is used).

    Raises
    ------
    FrameFormatError
        If ``kind`` is unknown, ``seq`` is out of range, values are given for a non-FRAME
        message or are too many, or a key or nonce has the wrong size.
    """
    if kind not in KINDS:
        raise FrameFormatError(f"kind: must be one of {sorted(KINDS)} ({', '.join(KINDS.values())}), got {kind!r}")
    if isinstance(seq, bool) or not isinstance(seq, int) or not 0 <= seq <= MAX_SEQ:
        raise FrameFormatError(f"seq: must be an integer in 0..{MAX_SEQ} (it never wraps; re-arm first), got {seq!r}")
    if kind != FRAME and values is not None and len(values):
        raise FrameFormatError(f"values: only FRAME messages carry values, got {len(values)} for type {kind}")
    if key is not None:
        key = _check_secret(key, KEY_SIZE, "key")
    elif kind in (ARM, ARMED):
        raise FrameFormatError(f"key: {KINDS[kind]} needs the session key (32 bytes)")
    nonce = NO_NONCE if kind == ARM else _check_secret(nonce, NONCE_SIZE, "nonce")
    payload, count = b"", 0
    if kind == FRAME:
        array = np.ascontiguousarray(values if values is not None else [], dtype="<f4").ravel()
        if array.size > MAX_VALUES:
            raise FrameFormatError(f"values: at most {MAX_VALUES} per FRAME, got {array.size}; "
                                   "split the display into several devices")
        payload, count = array.tobytes(), array.size
    elif kind == ACK:
        payload = ACK_BODY.pack(status, flags, 0, frames_applied % 2**32)
    elif kind == ARM:
        payload = key
    elif kind == ARMED:
        payload = ARMED_BODY.pack(nonce, watchdog_us, n_tractors, 0)
    body = HEADER.pack(MAGIC, VERSION, kind, count, seq, timestamp_ns % 2**64) + payload
    return body + (mac(key, nonce, body) if key is not None else _UNTAGGED)


def peek(data: bytes) -> tuple[int, int, int, int] | None:
    """``(version, kind, seq, timestamp_ns)`` of any datagram with this format's magic (also
    version 1), or None: enough to answer a refusal."""
    if len(data) < HEADER.size or data[:4] != MAGIC:
        return None
    _, version, kind, _, seq, stamp = HEADER.unpack_from(data)
    return version, kind, seq, stamp


def decode(data: bytes, *, key: bytes | None = None, nonce: bytes = NO_NONCE) -> Message:
    """Decode one datagram and verify its tag under ``key`` and ``nonce`` (constant time).

    A bad tag is not an error here: ``Message.authentic`` is False (the caller refuses it).

    Raises
    ------
    FrameFormatError
        On a short datagram, wrong magic, version 1 or another version, unknown type, or a
        length that does not match the type and count.
    """
    if len(data) >= HEADER.size:
        magic, version = data[:4], data[4]
        if magic != MAGIC:
            raise FrameFormatError(f"magic: expected {MAGIC!r}, got {magic!r}")
        if version == 1:
            raise FrameFormatError("version: 1 is refused (unauthenticated CRC frames); host and device must speak "
                                   "version 2 of docs/udp-frame-format.md (ARM key exchange, a MAC on every frame)")
        if version != VERSION:
            raise FrameFormatError(f"version: expected {VERSION}, got {version}")
    if len(data) < HEADER.size + TAG_SIZE:
        raise FrameFormatError(f"datagram: {len(data)} bytes, shorter than the {HEADER.size + TAG_SIZE}-byte minimum")
    _, _, kind, count, seq, stamp = HEADER.unpack_from(data)
    body, tag = data[:-TAG_SIZE], data[-TAG_SIZE:]
    payload = body[HEADER.size:]
    sizes = {ZERO: 0, DISARM: 0, ACK: ACK_BODY.size, ARM: KEY_SIZE, ARMED: ARMED_BODY.size}
    if kind == FRAME:
        if len(payload) != 4 * count:
            raise FrameFormatError(f"count: header says {count} values, payload holds {len(payload)} bytes")
    elif kind not in sizes or count != 0 or len(payload) != sizes[kind]:
        raise FrameFormatError(f"type: message type {kind} with count {count} and a {len(payload)}-byte payload "
                               "is not valid")
    fields: dict = {}
    if kind == ARM:
        key, nonce = bytes(payload), NO_NONCE
        fields["key"] = key
    elif kind == ARMED:
        nonce, fields["watchdog_us"], fields["n_tractors"], _ = ARMED_BODY.unpack(payload)
        fields["nonce"] = nonce
    elif kind == ACK:
        fields["status"], fields["flags"], _, fields["frames_applied"] = ACK_BODY.unpack(payload)
    authentic = key is not None and len(key) == KEY_SIZE and len(nonce) == NONCE_SIZE and \
        hmac.compare_digest(tag, mac(key, nonce, body))
    values = np.frombuffer(payload, dtype="<f4") if kind == FRAME else np.zeros(0, dtype="<f4")
    return Message(kind, seq, stamp, values, authentic=authentic, **fields)


class RawLink:
    """A bare blocking host of one link session, message by message: for tests and firmware bring-up
    (a real host uses :class:`tactilab.experiments.devices.udp.UdpDisplay`).

    Parameters
    ----------
    port : int
        The device's UDP port.
    host : str
        The device's IPv4 address.
    bind : str
        The local address to send from (e.g. ``127.0.0.2``: another loopback address).
    timeout_s : float
        How long :meth:`recv` waits, s.
    """

    def __init__(self, port: int, host: str = "127.0.0.1", *, bind: str = "127.0.0.1", timeout_s: float = 5.0):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((bind, 0))
        self.sock.settimeout(timeout_s)
        self.sock.connect((host, port))
        self.key: bytes | None = None
        self.nonce = NO_NONCE
        self.seq = 0

    def message(self, kind: int, values=None, *, seq: int | None = None) -> bytes:
        """The next message of the session (seq one above the last, unless given), tagged."""
        self.seq = self.seq + 1 if seq is None else seq
        return encode(kind, self.seq, time.monotonic_ns(), values, key=self.key, nonce=self.nonce)

    def send(self, data: bytes) -> None:
        """Send one datagram as it is."""
        self.sock.send(data)

    def recv(self) -> Message:
        """The next answer, its tag checked under the session's key and nonce."""
        return decode(self.sock.recv(65536), key=self.key, nonce=self.nonce)

    def ask(self, kind: int, values=None, *, seq: int | None = None) -> Message:
        """Send the next message and return the answer."""
        self.send(self.message(kind, values, seq=seq))
        return self.recv()

    def arm(self, key: bytes | None = None, *, seq: int | None = None) -> Message:
        """ARM with ``key`` (default: a fresh random one); on an authentic ARMED the session is open."""
        key = secrets.token_bytes(KEY_SIZE) if key is None else key
        self.seq = self.seq + 1 if seq is None else seq
        self.send(encode(ARM, self.seq, time.monotonic_ns(), key=key))
        answer = decode(self.sock.recv(65536), key=key)
        if answer.kind == ARMED and answer.authentic:
            self.key, self.nonce = key, answer.nonce
        return answer

    def close(self) -> None:
        """Close the socket."""
        self.sock.close()

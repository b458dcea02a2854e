"""The display link's wire format, version 3: paired, authenticated, with due times (docs/udp-frame-format.md).

Every datagram is a 20-byte little-endian header, a payload and a 16-byte tag::

    offset  size  field
    0       4     magic  b"TLDF"
    4       1     version (3)
    5       1     type: 1 FRAME, 2 ZERO, 3 ACK, 4 ARM, 5 ARMED, 6 DISARM
    6       2     count: number of float32 values (FRAME), else 0
    8       4     seq, uint32, strictly increasing within a link session (never wraps)
    12      8     timestamp_ns, uint64: the sender's monotonic clock at sending (echoed in ACKs)
    20      P     payload: FRAME due_ns u64 (device clock) + 4*count float32; ACK 16 bytes
                  (status u8, flags u8, reserved u16, frames_applied u32, device_ns u64); ARM the
                  16-byte host nonce; ARMED 40 bytes (device nonce 16, watchdog_us u32,
                  n_tractors u16, fifo_frames u16, frames_applied u32, reserved u32, device_ns
                  u64); ZERO and DISARM nothing
    20+P    16    tag: the first 16 bytes of an HMAC-SHA256 (below)

Host and device share a 32-byte pairing key P. ARM is tagged with P; ARMED with P over the host's
nonce and its own bytes (so only the paired device can answer this very ARM); every later message
of the link session with the session key ``K = HMAC-SHA256(P, "TLDF3 session" || host nonce ||
device nonce)``, which nobody without P can compute. Refusals carry an all-zero tag.
:func:`encode` / :func:`decode` are the reference implementation.
"""

from __future__ import annotations

import hashlib
import hmac
import struct
from dataclasses import dataclass

import numpy as np

__all__ = ["Message", "encode", "decode", "peek", "session_key", "FrameFormatError", "MAGIC", "VERSION", "FRAME",
           "ZERO", "ACK", "ARM", "ARMED", "DISARM", "STATUS", "STATUS_CODE", "REFUSALS", "FLAG_WATCHDOG_TRIPPED",
           "KEY_SIZE", "NONCE_SIZE", "TAG_SIZE", "MAX_VALUES", "MAX_SEQ"]

MAGIC = b"TLDF"
VERSION = 3
#: Message types of the display frame format (docs/udp-frame-format.md)
FRAME, ZERO, ACK, ARM, ARMED, DISARM = 1, 2, 3, 4, 5, 6
KINDS = {FRAME: "FRAME", ZERO: "ZERO", ACK: "ACK", ARM: "ARM", ARMED: "ARMED", DISARM: "DISARM"}
HEADER = struct.Struct("<4sBBHIQ")  # 20 bytes
DUE = struct.Struct("<Q")  # 8 bytes before a FRAME's values
ACK_BODY = struct.Struct("<BBHIQ")  # 16 bytes
ARMED_BODY = struct.Struct("<16sIHHIIQ")  # 40 bytes
KEY_SIZE, NONCE_SIZE, TAG_SIZE = 32, 16, 16
#: ACK status codes (docs/udp-frame-format.md).
STATUS = {0: "applied", 1: "zeroed", 2: "bad_mac", 3: "bad_count", 4: "stale", 5: "disarmed",
          6: "bad_message", 7: "non_finite", 8: "overflow", 9: "released", 10: "refused", 11: "bad_version",
          12: "bad_due"}
STATUS_CODE = {name: code for code, name in STATUS.items()}
#: Statuses that refuse a message: a host may act on them without a valid tag (they only stop it).
REFUSALS = frozenset(code for code, name in STATUS.items() if name not in ("applied", "zeroed", "released"))
FLAG_WATCHDOG_TRIPPED = 0x01
MAX_VALUES = 16000  # keeps a FRAME under the 64 KiB UDP datagram limit
#: The largest seq; a host re-arms (a new link session) before reaching it.
MAX_SEQ = 2**32 - 1
_UNTAGGED = bytes(TAG_SIZE)
_SESSION_LABEL = b"TLDF3 session"
_SIZES = {ZERO: 0, DISARM: 0, ACK: ACK_BODY.size, ARM: NONCE_SIZE, ARMED: ARMED_BODY.size}


class FrameFormatError(ValueError):
    """A datagram that is not a valid message of this format."""


@dataclass(frozen=True)
class Message:
    """One decoded datagram.

    ``values`` is float32 (FRAME) or empty and ``due_ns`` the FRAME's due time on the device's
    clock; ACK fields are 0 otherwise; ``nonce`` is the host nonce of an ARM or the device nonce
    of an ARMED; ``watchdog_us``, ``n_tractors`` and ``fifo_frames`` come from an ARMED;
    ``frames_applied`` and ``device_ns`` (the device's clock when it answered) from an ACK or
    an ARMED; ``authentic`` says whether the tag verified under the key given to :func:`decode`.
    """

    kind: int
    seq: int
    timestamp_ns: int
    values: np.ndarray
    status: int = 0
    flags: int = 0
    frames_applied: int = 0
    authentic: bool = False
    nonce: bytes = b""
    watchdog_us: int = 0
    n_tractors: int = 0
    fifo_frames: int = 0
    device_ns: int = 0
    due_ns: int = 0


def mac(key: bytes, prefix: bytes, body: bytes) -> bytes:
    """The 16-byte tag: HMAC-SHA256(key, prefix || body) truncated to its first 16 bytes."""
    return hmac.new(key, prefix + body, hashlib.sha256).digest()[:TAG_SIZE]


def _secret(value, size: int, name: str) -> bytes:
    if not isinstance(value, (bytes, bytearray)) or len(value) != size:
        got = f"{len(value)} bytes" if isinstance(value, (bytes, bytearray)) else type(value).__name__
        raise FrameFormatError(f"{name}: must be {size} bytes, got {got}; use secrets.token_bytes({size})")
    return bytes(value)


def session_key(pairing_key: bytes, host_nonce: bytes, device_nonce: bytes) -> bytes:
    """The 32-byte key of one link session: HMAC-SHA256(P, "TLDF3 session" || host nonce || device nonce)."""
    pairing_key = _secret(pairing_key, KEY_SIZE, "pairing_key")
    material = _secret(host_nonce, NONCE_SIZE, "host_nonce") + _secret(device_nonce, NONCE_SIZE, "device_nonce")
    return hmac.new(pairing_key, _SESSION_LABEL + material, hashlib.sha256).digest()


def _check_int(value, bits: int, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < 2**bits:
        raise FrameFormatError(f"{name}: must be an integer in 0..{2**bits - 1}, got {value!r}")
    return int(value)


def encode(kind: int, seq: int, timestamp_ns: int, values=None, *, key: bytes | None = None, nonce: bytes = b"",
           status: int = 0, flags: int = 0, frames_applied: int = 0, due_ns: int = 0, device_ns: int = 0,
           watchdog_us: int = 0, n_tractors: int = 0, fifo_frames: int = 0, host_nonce: bytes = b"") -> bytes:
    """Encode and tag one message (see the module docstring for the layout).

    ``key`` is the pairing key for ARM and ARMED, the session key otherwise; without it the tag
    is all zero, which only a refusal ACK may use. ``nonce`` is the ARM's host nonce or the
    ARMED's device nonce; an ARMED also needs ``host_nonce`` (the ARM's, covered by its tag).

    Raises
    ------
    FrameFormatError
        If ``kind`` is unknown, ``seq`` is out of range, values are given for a non-FRAME
        message or are too many, or a key or nonce is missing or has the wrong size.
    """
    if kind not in KINDS:
        raise FrameFormatError(f"kind: must be one of {sorted(KINDS)} ({', '.join(KINDS.values())}), got {kind!r}")
    if isinstance(seq, bool) or not isinstance(seq, int) or not 0 <= seq <= MAX_SEQ:
        raise FrameFormatError(f"seq: must be an integer in 0..{MAX_SEQ} (it never wraps; re-arm first), got {seq!r}")
    if kind != FRAME and values is not None and len(values):
        raise FrameFormatError(f"values: only FRAME messages carry values, got {len(values)} for type {kind}")
    if key is not None:
        key = _secret(key, KEY_SIZE, "key")
    elif kind in (ARM, ARMED):
        raise FrameFormatError(f"key: {KINDS[kind]} needs the 32-byte pairing key")
    payload, count, prefix = b"", 0, b""
    if kind == FRAME:
        array = np.ascontiguousarray(values if values is not None else [], dtype="<f4").ravel()
        if array.size > MAX_VALUES:
            raise FrameFormatError(f"values: at most {MAX_VALUES} per FRAME, got {array.size}; "
                                   "split the display into several devices")
        payload, count = DUE.pack(_check_int(due_ns, 64, "due_ns")) + array.tobytes(), array.size
    elif kind == ACK:
        payload = ACK_BODY.pack(status, flags, 0, frames_applied % 2**32, device_ns % 2**64)
    elif kind == ARM:
        payload = _secret(nonce, NONCE_SIZE, "nonce")
    elif kind == ARMED:
        prefix = _secret(host_nonce, NONCE_SIZE, "host_nonce")
        payload = ARMED_BODY.pack(_secret(nonce, NONCE_SIZE, "nonce"), watchdog_us, n_tractors, fifo_frames,
                                  frames_applied % 2**32, 0, device_ns % 2**64)
    body = HEADER.pack(MAGIC, VERSION, kind, count, seq, timestamp_ns % 2**64) + payload
    return body + (mac(key, prefix, body) if key is not None else _UNTAGGED)


def peek(data: bytes) -> tuple[int, int, int, int] | None:
    """``(version, kind, seq, timestamp_ns)`` of any datagram with this format's magic (also an
    older version), or None: enough to answer a refusal."""
    if len(data) < HEADER.size or data[:4] != MAGIC:
        return None
    _, version, kind, _, seq, stamp = HEADER.unpack_from(data)
    return version, kind, seq, stamp


def decode(data: bytes, *, key: bytes | None = None, host_nonce: bytes = b"") -> Message:
    """Decode one datagram and verify its tag under ``key`` in constant time.

    ``key`` is the pairing key for ARM and ARMED (an ARMED also needs the ``host_nonce`` of the
    ARM it answers), the session key otherwise. A bad tag is not an error here:
    ``Message.authentic`` is False (the caller refuses it).

    Raises
    ------
    FrameFormatError
        On a short datagram, wrong magic, an older or unknown version, unknown type, or a
        length that does not match the type and count.
    """
    if len(data) >= HEADER.size:
        magic, version = data[:4], data[4]
        if magic != MAGIC:
            raise FrameFormatError(f"magic: expected {MAGIC!r}, got {magic!r}")
        if version in (1, 2):
            raise FrameFormatError(f"version: {version} is refused; host and device must speak version {VERSION} of "
                                   "docs/udp-frame-format.md (a paired ARM, one armed link per session, due times)")
        if version != VERSION:
            raise FrameFormatError(f"version: expected {VERSION}, got {version}")
    if len(data) < HEADER.size + TAG_SIZE:
        raise FrameFormatError(f"datagram: {len(data)} bytes, shorter than the {HEADER.size + TAG_SIZE}-byte minimum")
    _, _, kind, count, seq, stamp = HEADER.unpack_from(data)
    body, tag = data[:-TAG_SIZE], data[-TAG_SIZE:]
    payload = body[HEADER.size:]
    if kind == FRAME:
        if len(payload) != DUE.size + 4 * count:
            raise FrameFormatError(f"count: header says {count} values, payload holds {len(payload)} bytes "
                                   f"(a FRAME carries an {DUE.size}-byte due time, then the values)")
    elif kind not in _SIZES or count != 0 or len(payload) != _SIZES[kind]:
        raise FrameFormatError(f"type: message type {kind} with count {count} and a {len(payload)}-byte payload "
                               "is not valid")
    fields: dict = {}
    prefix = b""
    if kind == ARM:
        fields["nonce"] = bytes(payload)
    elif kind == ARMED:
        (fields["nonce"], fields["watchdog_us"], fields["n_tractors"], fields["fifo_frames"],
         fields["frames_applied"], _, fields["device_ns"]) = ARMED_BODY.unpack(payload)
        prefix = host_nonce
    elif kind == ACK:
        fields["status"], fields["flags"], _, fields["frames_applied"], fields["device_ns"] = ACK_BODY.unpack(payload)
    elif kind == FRAME:
        fields["due_ns"] = DUE.unpack_from(payload)[0]
    authentic = (key is not None and len(key) == KEY_SIZE and (kind != ARMED or len(prefix) == NONCE_SIZE)
                 and hmac.compare_digest(tag, mac(key, prefix, body)))
    values = np.frombuffer(payload, dtype="<f4", offset=DUE.size) if kind == FRAME else np.zeros(0, dtype="<f4")
    return Message(kind, seq, stamp, values, authentic=authentic, **fields)

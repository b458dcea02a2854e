"""The paired display link (frame format version 3, docs/udp-frame-format.md): only a host with the
pairing key arms the device, the address is pinned after ARM, every message carries a MAC under the
session key, seq never goes back, every refused ARM gets the same answer, and versions 1 and 2 are
refused. The emulator is the reference device; each test drives it with raw datagrams or the real
host, UdpDisplay."""

from __future__ import annotations

import struct
import subprocess
import sys
import threading
import time
import zlib

import numpy as np
import pytest
from udp_pairing import KEY, WRONG_KEY, emulator_thread

from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.display import DisplayError
from tactilab.experiments.devices.emulator import emulate, read_record
from tactilab.experiments.devices.link import (
    ACK, ARM, ARMED, DISARM, FRAME, STATUS, STATUS_CODE, ZERO, FrameFormatError, decode, encode, session_key)
from tactilab.experiments.devices import display_fault
from tactilab.experiments.devices.udp import UdpDisplay
from tactilab.experiments.devices.udp_link import RawLink

DESC = DisplayDescription.braille_row(n_tractors=2)


@pytest.fixture
def device(tmp_path):
    """The emulator in a thread with DESC's limits (watchdog 30 s: no session expires while a test
    waits for a subprocess on a loaded machine); yields (port, finish() -> summary, record, logs)."""
    record = tmp_path / "link.jsonl"
    port, finish, logs = emulator_thread(watchdog_s=30.0, record=record, limits=DESC)
    yield port, finish, record, logs
    finish()


def test_a_second_sender_on_another_loopback_address_is_refused_and_the_trial_is_unaffected(device, monkeypatch):
    """While the host streams, a sender on 127.0.0.2 tries ARM (under the right key too: it may have
    stolen it), ZERO and a 20-times-the-limit FRAME of a session of its own making, over and over:
    each gets the same untagged `refused`, counted and logged; the host's frames are all applied,
    bit for bit, and nothing had to be clamped."""
    port, finish, record, logs = device
    armed, done, answers = threading.Event(), threading.Event(), []
    attacker = RawLink(port, KEY, bind="127.0.0.2", timeout_s=1.0)
    attacker.key = bytes(range(32))  # a session key of its own making

    def attack():
        armed.wait(10)
        while not done.is_set():
            for data in (encode(ARM, 1, 0, key=KEY, nonce=bytes(16)), attacker.message(ZERO),
                         attacker.message(FRAME, [20 * DESC.max_traction_pa, 0.0])):
                attacker.send(data)
                answers.append(attacker.recv())
            time.sleep(0.002)

    from tactilab.experiments.devices.udp_link import HostLink

    real_zero = HostLink.zero

    def zero_then_signal(self):  # the attack starts once the host's link is armed
        real_zero(self)
        armed.set()

    monkeypatch.setattr(HostLink, "zero", zero_then_signal)
    thread = threading.Thread(target=attack, daemon=True)
    thread.start()
    frames = np.outer(np.sin(np.linspace(0, np.pi, 300)), [0.5, -0.5]) * DESC.max_traction_pa
    display = UdpDisplay(DESC, "127.0.0.1", port, max_skipped_fraction=1.0, pairing_key=KEY)
    display.load(frames, 1000.0)
    report = display.play()
    done.set()
    thread.join(timeout=10)
    display.close()
    attacker.close()
    summary = finish()
    assert len(answers) >= 3 and {STATUS[a.status] for a in answers} == {"refused"}
    assert not any(a.authentic or a.frames_applied or a.flags or a.device_ns for a in answers)
    assert report.acked == report.frames_sent and report.rejected == 0 and report.stale == 0
    assert display_fault(report) is None
    assert summary.foreign == 2 * len(answers) // 3 and summary.refused_arms == len(answers) // 3
    assert summary.clamps == 0 and summary.sessions == 1  # one armed link, from the first use to close()
    rec = read_record(record)
    applied = rec["streams"][0]
    assert len(applied["seq"]) == report.acked == 300
    np.testing.assert_array_equal(applied["values"], frames.astype(np.float32))
    foreign = [e for e in rec["events"] if e["type"] == "rejected" and e["from"].startswith("127.0.0.2:")]
    assert len(foreign) == len(answers)
    assert any(line.startswith("refused: datagram from 127.0.0.2:") for line in logs)


def _answer(link: RawLink, data: bytes) -> bytes:
    link.send(data)
    return link.sock.recv(65536)


def test_every_refused_arm_gets_the_same_answer(device):
    """An intruder cannot tell a busy device from an idle one, nor a wrong key from a busy device: a
    wrong key (idle and busy), the right key from another address while busy, a replayed ARM, a
    truncated ARM and a FRAME without a session all get byte-identical answers (given the same seq
    and timestamp, which every answer echoes)."""
    port, finish, _, _ = device
    probe = RawLink(port, WRONG_KEY, bind="127.0.0.2")
    wrong = encode(ARM, 7, 99, key=WRONG_KEY, nonce=bytes(range(16)))
    idle_wrong_key = _answer(probe, wrong)
    host = RawLink(port, KEY)
    nonce = bytes(range(100, 116))
    assert host.arm(nonce, seq=7).kind == ARMED
    busy_wrong_key = _answer(probe, wrong)
    busy_right_key = _answer(probe, encode(ARM, 7, 99, key=KEY, nonce=bytes(range(50, 66))))
    busy_frame = _answer(probe, encode(FRAME, 7, 99, [1.0, 1.0], key=bytes(32)))
    assert host.ask(DISARM).status == STATUS_CODE["released"]
    idle_replay = _answer(probe, encode(ARM, 7, 99, key=KEY, nonce=nonce))  # the host's ARM, replayed
    idle_truncated = _answer(probe, encode(ARM, 7, 99, key=KEY, nonce=bytes(16))[:-1])
    idle_frame = _answer(probe, encode(FRAME, 7, 99, [1.0, 1.0], key=bytes(32)))
    answers = {idle_wrong_key, busy_wrong_key, busy_right_key, busy_frame, idle_replay, idle_truncated, idle_frame}
    assert len(answers) == 1
    refusal = decode(answers.pop())
    assert (refusal.kind, STATUS[refusal.status], refusal.authentic) == (ACK, "refused", False)
    assert (refusal.flags, refusal.frames_applied, refusal.device_ns) == (0, 0, 0)
    probe.close()
    host.close()
    summary = finish()
    assert summary.sessions == 1 and summary.refused_arms == 5


def test_the_armed_answer_proves_the_device_holds_the_key(device):
    """ARMED is tagged with the pairing key over the host's nonce: it verifies for that ARM only."""
    port, finish, _, _ = device
    link = RawLink(port, KEY)
    nonce = bytes(range(16))
    link.send(encode(ARM, 1, 5, key=KEY, nonce=nonce))
    data = link.sock.recv(65536)
    assert decode(data, key=KEY, host_nonce=nonce).authentic
    assert not decode(data, key=KEY, host_nonce=bytes(16)).authentic  # an old ARMED for another ARM
    assert not decode(data, key=WRONG_KEY, host_nonce=nonce).authentic  # a device without the key
    link.close()
    finish()


def test_a_host_with_the_wrong_key_is_refused_with_a_clear_error(device):
    port, finish, _, _ = device
    display = UdpDisplay(DESC, "127.0.0.1", port, pairing_key=WRONG_KEY, ack_timeout_s=0.05)
    with pytest.raises(DisplayError, match=r"refused ARM \(refused\); either another host holds the device's link.*"
                                           r"or this host's pairing key is not the device's"):
        display.zero()
    display.close()
    assert finish().sessions == 0


def test_a_replayed_frame_of_an_earlier_session_is_refused(device):
    """Even when a host restarts seq, a new session has a new key: an old frame fails its MAC;
    within a session, the replay is stale."""
    port, finish, record, _ = device
    link = RawLink(port, KEY)
    assert link.arm(seq=1).kind == ARMED
    old = link.message(FRAME, [100.0, -100.0], seq=5)
    link.send(old)
    assert link.recv().status == STATUS_CODE["applied"]
    link.send(old)  # the same session: not newer
    assert link.recv().status == STATUS_CODE["stale"]
    assert link.ask(DISARM).status == STATUS_CODE["released"]
    assert link.arm(seq=1).kind == ARMED  # seq from 1 again: only the nonces differ
    link.send(old)  # seq 5 > 1, but the tag was made with the old session key
    answer = link.recv()
    assert (answer.status, answer.authentic) == (STATUS_CODE["bad_mac"], False)
    link.close()
    summary = finish()
    assert (summary.frames_applied, summary.bad_mac, summary.stale, summary.sessions) == (1, 1, 1, 2)
    assert read_record(record)["n_frames"] == 1


@pytest.mark.parametrize("forge", ["wrong key", "flipped value", "truncated tag", "no tag"])
def test_a_frame_with_a_bad_mac_is_refused(device, forge):
    port, finish, record, _ = device
    link = RawLink(port, KEY)
    assert link.arm().kind == ARMED
    good = link.message(FRAME, [1.0, 2.0])
    data = {"wrong key": encode(FRAME, link.seq, 0, [1.0, 2.0], key=bytes(32)),
            "flipped value": good[:28] + bytes([good[28] ^ 0x40]) + good[29:],
            "truncated tag": good[:-8] + bytes(8),
            "no tag": encode(FRAME, link.seq, 0, [1.0, 2.0])}[forge]
    link.send(data)
    answer = link.recv()
    assert (answer.status, answer.authentic) == (STATUS_CODE["bad_mac"], False)
    assert link.ask(FRAME, [3.0, 4.0]).status == STATUS_CODE["applied"]  # the session goes on
    link.close()
    summary = finish()
    assert summary.bad_mac == 1 and summary.frames_applied == 1
    stream = read_record(record)["streams"][-1]
    np.testing.assert_array_equal(stream["values"], [[3.0, 4.0]])


def test_a_sequence_reset_is_refused(device):
    """seq only grows within a session: not after a ZERO, not ever."""
    port, finish, record, _ = device
    link = RawLink(port, KEY)
    assert link.arm(seq=1).kind == ARMED
    assert link.ask(FRAME, [1.0, 1.0], seq=10).status == STATUS_CODE["applied"]
    assert link.ask(ZERO, seq=11).status == STATUS_CODE["zeroed"]
    for seq in (1, 11, 2):  # a reset, a repeat, a reset
        assert link.ask(FRAME, [5.0, 5.0], seq=seq).status == STATUS_CODE["stale"]
    assert link.ask(FRAME, [2.0, 2.0], seq=12).status == STATUS_CODE["applied"]
    link.close()
    summary = finish()
    assert summary.stale == 3 and summary.frames_applied == 2
    values = np.vstack([s["values"] for s in read_record(record)["streams"]])
    assert not np.any(values == 5.0)


CLIENT = """
import sys
from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.display import DisplayError
from tactilab.experiments.devices.udp import UdpDisplay
display = UdpDisplay(DisplayDescription.braille_row(n_tractors=2), "127.0.0.1", int(sys.argv[1]),
                     pairing_key=bytes(range(32)), ack_timeout_s=0.05)
try:
    display.zero()
    print("armed")
except DisplayError as err:
    print(err)
display.close()
"""


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_an_arm_from_another_process_while_armed_is_refused(device):
    """Even a process holding the pairing key cannot arm a device whose link is armed; it can once the
    holder disarms."""
    port, finish, record, _ = device
    holder = RawLink(port, KEY)
    assert holder.arm().kind == ARMED
    other = subprocess.run([sys.executable, "-c", CLIENT, str(port)], capture_output=True, text=True, timeout=60)
    assert "refused ARM (refused)" in other.stdout and "another host holds" in other.stdout, other
    again = holder.arm()  # a second ARM from the holder itself is refused too
    assert (again.kind, again.status) == (ACK, STATUS_CODE["refused"])
    assert holder.ask(FRAME, [1.0, 1.0]).status == STATUS_CODE["applied"]  # the holder's session is intact
    assert holder.ask(DISARM).status == STATUS_CODE["released"]
    other = subprocess.run([sys.executable, "-c", CLIENT, str(port)], capture_output=True, text=True, timeout=60)
    assert other.stdout.strip() == "armed", other  # released: another host with the key may arm now
    holder.close()
    summary = finish()
    assert summary.refused_arms >= 2 and summary.sessions == 2


V1_ZERO = b"TLDF\x01\x02\x00\x00" + struct.pack("<IQ", 1, 0)
V1_ZERO += struct.pack("<I", zlib.crc32(V1_ZERO))
V2_ARM = struct.pack("<4sBBHIQ", b"TLDF", 2, ARM, 0, 1, 0) + bytes(32) + bytes(16)


def test_versions_1_and_2_are_refused_with_a_clear_reason(device):
    port, finish, record, _ = device
    link = RawLink(port, KEY)
    v1_frame = b"TLDF\x01\x01\x02\x00" + struct.pack("<IQ2f", 5, 1_000_000, 1.5, -2.0)
    for data in (V1_ZERO, v1_frame + struct.pack("<I", zlib.crc32(v1_frame)), V2_ARM):
        link.send(data)
        answer = link.recv()
        assert (answer.status, answer.authentic) == (STATUS_CODE["bad_version"], False)
    with pytest.raises(FrameFormatError, match="version: 1 is refused.*version 3"):
        decode(V1_ZERO)
    with pytest.raises(FrameFormatError, match="version: 2 is refused.*version 3"):
        decode(V2_ARM)
    link.close()
    summary = finish()
    assert summary.rejected == 3 and summary.frames_applied == 0 and summary.sessions == 0
    reasons = [e["reason"] for e in read_record(record)["events"] if e["type"] == "rejected"]
    assert reasons[0].startswith("version: 1 is refused") and reasons[2].startswith("version: 2 is refused")


def test_a_device_that_speaks_version_2_is_a_clear_error():
    """A version-2 device answers a version-3 ARM in its own version: the host names both versions."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as old_device:
        old_device.bind(("127.0.0.1", 0))
        display = UdpDisplay(DESC, "127.0.0.1", old_device.getsockname()[1], ack_timeout_s=2.0, pairing_key=KEY)
        outcome = {}
        thread = threading.Thread(target=lambda: outcome.update(error=pytest.raises(DisplayError, display.zero)))
        thread.start()
        data, sender = old_device.recvfrom(65536)
        seq, stamp = struct.unpack_from("<IQ", data, 8)
        old_device.sendto(struct.pack("<4sBBHIQ", b"TLDF", 2, ACK, 0, seq, stamp) + bytes([13]) + bytes(7 + 16), sender)
        thread.join()
        display.close()
    assert "the device speaks frame format version 2; this host speaks version 3" in str(outcome["error"].value)


def test_a_silent_device_is_a_clear_error():
    """A device that drops the datagrams (another version, or none): the host says which version it needs."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as old_device:
        old_device.bind(("127.0.0.1", 0))
        display = UdpDisplay(DESC, "127.0.0.1", old_device.getsockname()[1], ack_timeout_s=0.01, zero_retries=2,
                             pairing_key=KEY)
        with pytest.raises(DisplayError, match="no acknowledgement of ARM.*frame format version 3"):
            display.zero()
        display.close()


class RefusingDevice:
    """Arms like a paired device, then answers messages of type ``kind`` with an untagged refusal of
    ``status`` (a device that restarted, or a link that lost its session)."""

    def __init__(self, kind: int, status: str) -> None:
        import socket

        self.kind, self.status = kind, status
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        key, nonce = None, bytes(range(16))
        while not self.stop.is_set():
            try:
                data, sender = self.sock.recvfrom(65536)
            except TimeoutError:
                continue
            message = decode(data, key=KEY if data[5] == ARM else key)
            if message.kind == self.kind:
                self.sock.sendto(encode(ACK, message.seq, message.timestamp_ns, status=STATUS_CODE[self.status]),
                                 sender)
            elif message.kind == ARM:
                key = session_key(KEY, message.nonce, nonce)
                self.sock.sendto(encode(ARMED, message.seq, message.timestamp_ns, key=KEY, nonce=nonce,
                                        host_nonce=message.nonce, fifo_frames=1000), sender)
            else:
                status = {ZERO: "zeroed", DISARM: "released", FRAME: "applied"}[message.kind]
                self.sock.sendto(encode(ACK, message.seq, message.timestamp_ns, status=STATUS_CODE[status], key=key,
                                        device_ns=time.perf_counter_ns()), sender)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()
        self.sock.close()


@pytest.mark.parametrize("kind,status,match", [
    (FRAME, "refused", r"refused frame 0 \(refused\): the link session was lost"),
    (FRAME, "bad_mac", r"refused frame 0 \(bad_mac\): the link session was lost"),
    (FRAME, "bad_due", r"rejected frame 0 \(bad_due\).*room for lookahead_s"),
    (ARM, "bad_version", r"refused ARM \(bad_version\); see docs/udp-frame-format.md"),
    (ZERO, "bad_message", r"refused ZERO \(bad_message\)"),
])
def test_the_host_stops_on_a_refusal_even_untagged(kind, status, match):
    """A refusal needs no tag to stop the host (it can only make it stop); success always needs one."""
    device = RefusingDevice(kind, status)
    try:
        display = UdpDisplay(DESC, "127.0.0.1", device.port, ack_timeout_s=0.2, pairing_key=KEY)
        display.load(np.zeros((20, 2)), 1000.0)
        with pytest.raises(DisplayError, match=match):
            display.play()
        display.close()
    finally:
        device.close()


def test_untagged_success_is_never_taken():
    """An ARMED or `applied` without a valid tag is ignored: the host times out instead of trusting it."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as forger:
        forger.bind(("127.0.0.1", 0))
        forger.settimeout(2)
        display = UdpDisplay(DESC, "127.0.0.1", forger.getsockname()[1], ack_timeout_s=0.05, zero_retries=1,
                             pairing_key=KEY)
        outcome = {}
        thread = threading.Thread(target=lambda: outcome.update(error=pytest.raises(DisplayError, display.zero)))
        thread.start()
        data, sender = forger.recvfrom(65536)
        arm = decode(data)
        forged = encode(ARMED, arm.seq, arm.timestamp_ns, key=WRONG_KEY, nonce=bytes(16), host_nonce=arm.nonce)
        forger.sendto(forged, sender)  # tagged under another pairing key: not the paired device
        thread.join()
        display.close()
    assert "no acknowledgement of ARM" in str(outcome["error"].value)


def test_cli_emulate_json_prints_one_summary_object(tmp_path, capsys):
    import json

    from udp_pairing import key_file

    from tactilab.cli.main import main as cli_main

    assert cli_main(["device", "emulate", "--port", "0", "--max-seconds", "200ms", "--json", "--pairing-key",
                     str(key_file(tmp_path)), "--record", str(tmp_path / "r.jsonl")]) == 0
    out, err = capsys.readouterr()
    summary = json.loads(out)  # stdout is exactly one JSON object
    assert summary["frame_format_version"] == 3 and summary["sessions"] == 0 and summary["foreign"] == 0
    assert summary["watchdog_s"] == 0.05 and summary["record"] == str(tmp_path / "r.jsonl")
    assert err.startswith("listening on udp://127.0.0.1:")


def test_a_tripped_watchdog_releases_the_pin_to_another_host_with_the_key(tmp_path):
    """A host that goes silent holds the device only for the watchdog time: then another address with
    the pairing key may arm, and the old host's messages are refused."""
    stop, logs = threading.Event(), []
    thread = threading.Thread(target=emulate, kwargs=dict(port=0, watchdog_s=0.5, max_seconds=60, log=logs.append,
                                                          stop=stop, handle_signals=False, pairing_key=KEY),
                              daemon=True)
    thread.start()
    while not logs:
        time.sleep(0.005)
    port = int(logs[0].split(":")[2].split()[0])
    first, second = RawLink(port, KEY), RawLink(port, KEY, bind="127.0.0.2")
    try:
        assert first.arm().kind == ARMED
        assert second.arm().status == STATUS_CODE["refused"]  # armed: refused
        while not any(line.startswith("watchdog:") for line in logs):  # count events, not time
            time.sleep(0.01)
        assert second.arm().kind == ARMED  # the trip ended the first session
        assert second.ask(FRAME, [1.0, 1.0]).status == STATUS_CODE["applied"]
        assert first.ask(FRAME, [1.0, 1.0]).status == STATUS_CODE["refused"]  # the old host is now foreign
    finally:
        first.close()
        second.close()
        stop.set()
        thread.join(timeout=10)

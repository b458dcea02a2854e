"""The authenticated display link (frame format version 2, docs/udp-frame-format.md): the address
is pinned after ARM, every message carries a MAC over the device's nonce, seq never goes back,
a second ARM is refused while armed, and version 1 is refused. The emulator is the reference
device; each test drives it with raw datagrams or the real host, UdpDisplay."""

from __future__ import annotations

import struct
import subprocess
import sys
import threading
import time
import zlib

import numpy as np
import pytest

from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.display import DisplayError
from tactilab.experiments.devices.emulator import emulate, read_record
from tactilab.experiments.devices.link import (
    ARM, ARMED, DISARM, FRAME, STATUS, STATUS_CODE, ZERO, FrameFormatError, RawLink, decode, encode)
from tactilab.experiments.devices import display_fault
from tactilab.experiments.devices.udp import UdpDisplay

DESC = DisplayDescription.braille_row(n_tractors=2)


@pytest.fixture
def device(tmp_path):
    """The emulator in a thread with DESC's limits (watchdog 30 s: no session expires while a test
    waits for a subprocess on a loaded machine); yields (port, finish() -> summary, record, logs)."""
    stop, logs, record, result = threading.Event(), [], tmp_path / "link.jsonl", {}
    thread = threading.Thread(target=lambda: result.update(summary=emulate(
        0, watchdog_s=30.0, record=record, max_seconds=120, log=logs.append, stop=stop, handle_signals=False,
        limits=DESC)), daemon=True)
    thread.start()
    while not logs:
        assert thread.is_alive(), "the emulator ended before listening"
        time.sleep(0.005)

    def finish():
        stop.set()
        thread.join(timeout=10)
        return result["summary"]

    yield int(logs[0].split(":")[2].split()[0]), finish, record, logs
    finish()


def test_a_second_sender_on_another_loopback_address_is_refused_and_the_trial_is_unaffected(device, monkeypatch):
    """While the host streams, a sender on 127.0.0.2 tries ARM, ZERO and a 20-times-the-limit FRAME of
    its own session, over and over: each is refused (`busy` / `foreign`, untagged), counted and
    logged; the host's frames are all applied, bit for bit, and nothing had to be clamped."""
    port, finish, record, logs = device
    armed, done, answers = threading.Event(), threading.Event(), []
    attacker = RawLink(port, bind="127.0.0.2", timeout_s=1.0)
    attacker.key, attacker.nonce = bytes(range(32)), bytes(16)  # a session of its own making

    def attack():
        armed.wait(10)
        while not done.is_set():
            for data in (encode(ARM, 1, 0, key=bytes(32)), attacker.message(ZERO),
                         attacker.message(FRAME, [20 * DESC.max_traction_pa, 0.0])):
                attacker.send(data)
                answers.append(attacker.recv())
            time.sleep(0.002)

    real_arm, real_close = UdpDisplay._arm, UdpDisplay._close_session

    def arm_then_signal(self):
        real_arm(self)
        armed.set()

    def stop_attack_then_close(self):  # the attack runs exactly while the host's session is open
        done.set()
        thread.join(timeout=10)
        real_close(self)

    monkeypatch.setattr(UdpDisplay, "_arm", arm_then_signal)
    monkeypatch.setattr(UdpDisplay, "_close_session", stop_attack_then_close)
    thread = threading.Thread(target=attack, daemon=True)
    thread.start()
    frames = np.outer(np.sin(np.linspace(0, np.pi, 300)), [0.5, -0.5]) * DESC.max_traction_pa
    with UdpDisplay(DESC, "127.0.0.1", port, max_skipped_fraction=1.0) as display:
        display.load(frames, 1000.0)
        report = display.play()
    attacker.close()
    summary = finish()
    assert len(answers) >= 3 and {STATUS[a.status] for a in answers} == {"busy", "foreign"}
    assert not any(a.authentic for a in answers)
    assert report.acked == report.frames_sent and report.rejected == 0 and report.stale == 0
    assert display_fault(report) is None or report.skipped > 0  # a loaded machine may skip, never mis-apply
    assert summary.foreign == len(answers) and summary.refused_arms == len(answers) // 3
    assert summary.clamps == 0 and summary.sessions == 2  # the host's play and its zero() on leaving
    rec = read_record(record)
    applied = rec["streams"][0]
    assert len(applied["seq"]) == report.acked
    if report.skipped == 0:
        np.testing.assert_array_equal(applied["values"], frames.astype(np.float32))
    assert np.abs(applied["values"]).max() <= DESC.max_traction_pa
    foreign = [e for e in rec["events"] if e["type"] == "rejected" and e["from"].startswith("127.0.0.2:")]
    assert len(foreign) == len(answers)
    assert any(line.startswith("refused: datagram from 127.0.0.2:") for line in logs)


def test_a_replayed_frame_of_an_earlier_session_is_refused(device):
    """Even when a host reuses its key and restarts seq, the device's fresh nonce makes an old frame
    fail its MAC; within a session, the replay is stale."""
    port, finish, record, _ = device
    link = RawLink(port)
    key = bytes(range(32))
    assert link.arm(key, seq=1).kind == ARMED
    old = link.message(FRAME, [100.0, -100.0], seq=5)
    link.send(old)
    assert link.recv().status == STATUS_CODE["applied"]
    link.send(old)  # the same session: not newer
    assert link.recv().status == STATUS_CODE["stale"]
    assert link.ask(DISARM).status == STATUS_CODE["released"]
    assert link.arm(key, seq=1).kind == ARMED  # the same key, seq from 1 again: only the nonce differs
    link.send(old)  # seq 5 > 1, but the tag was made with the old nonce
    answer = link.recv()
    assert (answer.status, answer.authentic) == (STATUS_CODE["bad_mac"], False)
    link.close()
    summary = finish()
    assert (summary.frames_applied, summary.bad_mac, summary.stale, summary.sessions) == (1, 1, 1, 2)
    assert read_record(record)["n_frames"] == 1


@pytest.mark.parametrize("forge", ["wrong key", "flipped value", "truncated tag", "no tag"])
def test_a_frame_with_a_bad_mac_is_refused(device, forge):
    port, finish, record, _ = device
    link = RawLink(port)
    assert link.arm().kind == ARMED
    good = link.message(FRAME, [1.0, 2.0])
    data = {"wrong key": encode(FRAME, link.seq, 0, [1.0, 2.0], key=bytes(32), nonce=link.nonce),
            "flipped value": good[:20] + bytes([good[20] ^ 0x40]) + good[21:],
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
    """seq only grows within a session: not after a ZERO (version 1 forgot it there), not ever."""
    port, finish, record, _ = device
    link = RawLink(port)
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
display = UdpDisplay(DisplayDescription.braille_row(n_tractors=2), "127.0.0.1", int(sys.argv[1]))
try:
    display.zero()
    print("armed")
except DisplayError as err:
    print(err)
display.close()
"""


def test_an_arm_from_another_process_while_armed_is_refused(device):
    port, finish, record, _ = device
    holder = RawLink(port)
    assert holder.arm().kind == ARMED
    other = subprocess.run([sys.executable, "-c", CLIENT, str(port)], capture_output=True, text=True, timeout=60)
    assert "refused ARM (busy)" in other.stdout and "another host holds" in other.stdout, other
    again = holder.arm()  # a second ARM from the holder itself is refused too
    assert (again.kind, again.status) == (3, STATUS_CODE["busy"])
    assert holder.ask(FRAME, [1.0, 1.0]).status == STATUS_CODE["applied"]  # the holder's session is intact
    assert holder.ask(DISARM).status == STATUS_CODE["released"]
    other = subprocess.run([sys.executable, "-c", CLIENT, str(port)], capture_output=True, text=True, timeout=60)
    assert other.stdout.strip() == "armed", other  # released: another host may arm now
    holder.close()
    summary = finish()
    assert summary.refused_arms == 2 and summary.sessions == 2


V1_ZERO = b"TLDF\x01\x02\x00\x00" + struct.pack("<IQ", 1, 0)
V1_ZERO += struct.pack("<I", zlib.crc32(V1_ZERO))


def test_version_1_frames_are_refused_with_a_clear_reason(device):
    port, finish, record, _ = device
    link = RawLink(port)
    v1_frame = b"TLDF\x01\x01\x02\x00" + struct.pack("<IQ2f", 5, 1_000_000, 1.5, -2.0)
    for data in (V1_ZERO, v1_frame + struct.pack("<I", zlib.crc32(v1_frame))):
        link.send(data)
        answer = link.recv()
        assert (answer.status, answer.authentic) == (STATUS_CODE["bad_version"], False)
    with pytest.raises(FrameFormatError, match="version: 1 is refused.*version 2"):
        decode(V1_ZERO)
    link.close()
    summary = finish()
    assert summary.rejected == 2 and summary.frames_applied == 0 and summary.zero_commands == 0
    reasons = [e["reason"] for e in read_record(record)["events"] if e["type"] == "rejected"]
    assert len(reasons) == 2 and all("version: 1 is refused" in r for r in reasons)


def test_a_device_that_speaks_version_1_is_a_clear_error():
    """A version-1 device drops version-2 datagrams: the host says which version it needs."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as old_device:
        old_device.bind(("127.0.0.1", 0))
        display = UdpDisplay(DESC, "127.0.0.1", old_device.getsockname()[1], ack_timeout_s=0.01, zero_retries=2)
        with pytest.raises(DisplayError, match="no acknowledgement of ARM.*frame format version 2"):
            display.zero()
        display.close()


class RefusingDevice:
    """Arms like a device, then answers ``refuse`` messages of type ``kind`` with an untagged
    refusal of ``status`` (a device that restarted, or a link that lost its session)."""

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
            message = decode(data, key=key, nonce=nonce)
            if message.kind == self.kind:
                self.sock.sendto(encode(3, message.seq, message.timestamp_ns, status=STATUS_CODE[self.status]), sender)
            elif message.kind == ARM:
                key = message.key
                self.sock.sendto(encode(ARMED, message.seq, message.timestamp_ns, key=key, nonce=nonce), sender)
            else:
                status = {ZERO: "zeroed", DISARM: "released", FRAME: "applied"}[message.kind]
                self.sock.sendto(encode(3, message.seq, message.timestamp_ns, status=STATUS_CODE[status], key=key,
                                        nonce=nonce), sender)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()
        self.sock.close()


@pytest.mark.parametrize("kind,status,match", [
    (FRAME, "not_armed", r"refused frame 0 \(not_armed\): the link session was lost"),
    (FRAME, "foreign", r"refused frame 0 \(foreign\): the link session was lost"),
    (FRAME, "bad_mac", r"refused frame 0 \(bad_mac\): the link session was lost"),
    (ARM, "bad_version", r"refused ARM \(bad_version\); see docs/udp-frame-format.md"),
    (ZERO, "bad_message", r"refused ZERO \(bad_message\)"),
])
def test_the_host_stops_on_a_refusal_even_untagged(kind, status, match):
    """A refusal needs no tag to stop the host (it can only make it stop); success always needs one."""
    device = RefusingDevice(kind, status)
    try:
        display = UdpDisplay(DESC, "127.0.0.1", device.port, ack_timeout_s=0.2)
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
        display = UdpDisplay(DESC, "127.0.0.1", forger.getsockname()[1], ack_timeout_s=0.05, zero_retries=1)
        outcome = {}
        thread = threading.Thread(target=lambda: outcome.update(error=pytest.raises(DisplayError, display.zero)))
        thread.start()
        data, sender = forger.recvfrom(65536)
        arm = decode(data)
        forged = bytearray(encode(ARMED, arm.seq, arm.timestamp_ns, key=bytes(32), nonce=bytes(16)))
        forger.sendto(bytes(forged), sender)  # tagged under another key
        thread.join()
        display.close()
    assert "no acknowledgement of ARM" in str(outcome["error"].value)


def test_cli_emulate_json_prints_one_summary_object(tmp_path, capsys):
    import json

    from tactilab.cli.main import main as cli_main

    assert cli_main(["device", "emulate", "--port", "0", "--max-seconds", "200ms", "--json",
                     "--record", str(tmp_path / "r.jsonl")]) == 0
    out, err = capsys.readouterr()
    summary = json.loads(out)  # stdout is exactly one JSON object
    assert summary["frame_format_version"] == 2 and summary["sessions"] == 0 and summary["foreign"] == 0
    assert summary["watchdog_s"] == 0.05 and summary["record"] == str(tmp_path / "r.jsonl")
    assert err.startswith("listening on udp://127.0.0.1:")


def test_a_tripped_watchdog_releases_the_pin_to_another_host(tmp_path):
    """A host that goes silent holds the device only for the watchdog time: then another address may
    arm, and the old host's messages are refused as foreign."""
    stop, logs = threading.Event(), []
    thread = threading.Thread(target=emulate, kwargs=dict(port=0, watchdog_s=0.5, max_seconds=60, log=logs.append,
                                                          stop=stop, handle_signals=False), daemon=True)
    thread.start()
    while not logs:
        time.sleep(0.005)
    port = int(logs[0].split(":")[2].split()[0])
    first, second = RawLink(port), RawLink(port, bind="127.0.0.2")
    try:
        assert first.arm().kind == ARMED
        assert second.arm().status == STATUS_CODE["busy"]  # armed: refused
        while not any(line.startswith("watchdog:") for line in logs):  # count events, not time
            time.sleep(0.01)
        assert second.arm().kind == ARMED  # the trip ended the first session
        assert second.ask(FRAME, [1.0, 1.0]).status == STATUS_CODE["applied"]
        assert first.ask(FRAME, [1.0, 1.0]).status == STATUS_CODE["foreign"]  # the old host is now foreign
    finally:
        first.close()
        second.close()
        stop.set()
        thread.join(timeout=10)

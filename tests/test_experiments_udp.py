"""UDP frame format, the network driver against the device emulator on loopback, and the watchdog."""

from __future__ import annotations

import hashlib
import hmac
import os
import signal
import socket
import struct
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from udp_pairing import KEY as PAIRING_KEY
from udp_pairing import key_file
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.display import DisplayError, render_drive
from tactilab.experiments.devices.display_limits import limit_violations
from tactilab.experiments.devices.emulator import LOOPBACK, emulate, read_record
from tactilab.experiments.devices.safety import SafeDisplay
from tactilab.experiments.devices.link import ARM, ARMED, DISARM, session_key
from tactilab.experiments.devices.udp_link import RawLink
from tactilab.experiments.devices.udp import (
    ACK,
    FRAME,
    STATUS_CODE,
    ZERO,
    FrameFormatError,
    UdpDisplay,
    decode,
    encode,
    parse_udp_url,
)

EMULATOR = [sys.executable, "-m", "tactilab.cli.main", "device", "emulate", "--port", "0"]


def start_emulator(tmp_path, name, *args):
    record = tmp_path / f"{name}.jsonl"
    key = key_file(tmp_path, name=f"{name}.key")
    proc = subprocess.Popen([*EMULATOR, "--record", str(record), "--pairing-key", str(key), *args],
                            stdout=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert line.startswith("listening on udp://127.0.0.1:"), line
    return proc, int(line.split(":")[2].split()[0]), record


def stop_emulator(proc):
    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=30)
    return out


@pytest.fixture(scope="module")
def emulator(tmp_path_factory):
    proc, port, record = start_emulator(tmp_path_factory.mktemp("emu"), "shared", "--watchdog", "2s",
                                        "--max-seconds", "120s")
    yield port, record
    out = stop_emulator(proc)
    assert proc.returncode == 0 and "summary:" in out


def last_stream(record):
    rec = read_record(record)
    return rec["streams"][-1]["values"], rec


def assert_record_within_limits(values, desc, rate=1000.0, whole_stream=True):
    """The emulator's record proves it: data_schemas' check and our own, on the received float32.

    With frames skipped by a late host (``whole_stream`` False) the duty cycle over the frames
    received says nothing; amplitude and slew must still hold frame to frame."""
    if whole_stream:
        desc.check_commands(values.reshape(-1, desc.rows, desc.columns), "traction")
    assert [v for v in limit_violations(values, rate, desc) if whole_stream or v["kind"] != "duty"] == []


# ----- the frame format ---------------------------------------------------------------------
KEY, NONCE = bytes(range(32)), bytes(range(0xA0, 0xB0))


def _tag(body: bytes, key=KEY, prefix=b"") -> bytes:
    """The documented MAC, computed independently of the encoder."""
    return hmac.new(key, prefix + body, hashlib.sha256).digest()[:16]


def test_frame_layout_matches_the_documented_offsets():
    data = encode(FRAME, 0x01020304, 0x1122334455667788, [1.5, -2.0], key=KEY, due_ns=0x0102030405060708)
    assert data[:4] == b"TLDF" and data[4] == 3 and data[5] == FRAME
    assert struct.unpack_from("<H", data, 6)[0] == 2
    assert struct.unpack_from("<I", data, 8)[0] == 0x01020304
    assert struct.unpack_from("<Q", data, 12)[0] == 0x1122334455667788
    assert struct.unpack_from("<Q", data, 20)[0] == 0x0102030405060708
    assert struct.unpack_from("<2f", data, 28) == (1.5, -2.0)
    assert len(data) == 20 + 8 + 8 + 16 and data[36:] == _tag(data[:36])
    ack = encode(ACK, 7, 99, status=STATUS_CODE["applied"], flags=1, frames_applied=12, device_ns=5, key=KEY)
    assert len(ack) == 52 and struct.unpack_from("<BBHIQ", ack, 20) == (0, 1, 0, 12, 5) and ack[36:] == _tag(ack[:36])
    assert len(encode(ZERO, 3, 4, key=KEY)) == 36
    arm = encode(ARM, 1, 2, key=KEY, nonce=NONCE)
    assert len(arm) == 52 and arm[20:36] == NONCE and arm[36:] == _tag(arm[:36])
    armed = encode(ARMED, 1, 2, key=KEY, nonce=bytes(range(16)), host_nonce=NONCE, watchdog_us=50_000, n_tractors=60,
                   fifo_frames=1000, frames_applied=9, device_ns=77)
    assert len(armed) == 76
    assert struct.unpack_from("<16sIHHIIQ", armed, 20) == (bytes(range(16)), 50_000, 60, 1000, 9, 0, 77)
    assert armed[60:] == _tag(armed[:60], prefix=NONCE)
    refusal = encode(ACK, 7, 99, status=STATUS_CODE["refused"])  # no key: the all-zero tag
    assert refusal[36:] == bytes(16)
    # the session key, computed independently of session_key()
    assert session_key(KEY, NONCE, bytes(16)) == hmac.new(KEY, b"TLDF3 session" + NONCE + bytes(16),
                                                          hashlib.sha256).digest()


def test_roundtrip_of_each_message_type_and_the_tag_check():
    frame = decode(encode(FRAME, 5, 10, np.array([0.1, 2.0]), key=KEY, due_ns=33), key=KEY)
    assert (frame.kind, frame.seq, frame.timestamp_ns, frame.due_ns, frame.authentic) == (FRAME, 5, 10, 33, True)
    np.testing.assert_array_equal(frame.values, np.float32([0.1, 2.0]))
    assert decode(encode(ZERO, 1, 2, key=KEY), key=KEY).authentic
    ack = decode(encode(ACK, 1, 2, status=5, flags=1, frames_applied=9, device_ns=4, key=KEY), key=KEY)
    assert (ack.kind, ack.status, ack.flags, ack.frames_applied, ack.device_ns) == (ACK, 5, 1, 9, 4) and ack.authentic
    arm = decode(encode(ARM, 1, 2, key=KEY, nonce=NONCE), key=KEY)
    assert arm.nonce == NONCE and arm.authentic
    assert not decode(encode(ARM, 1, 2, key=KEY, nonce=NONCE), key=bytes(32)).authentic  # another pairing key
    armed = decode(encode(ARMED, 1, 2, key=KEY, nonce=bytes(16), host_nonce=NONCE, watchdog_us=7, n_tractors=3,
                          fifo_frames=8), key=KEY, host_nonce=NONCE)
    assert (armed.watchdog_us, armed.n_tractors, armed.fifo_frames, armed.authentic) == (7, 3, 8, True)
    data = encode(FRAME, 5, 10, [1.0], key=KEY)
    assert not decode(data, key=bytes(32)).authentic  # another session's key
    assert not decode(data).authentic  # no key: nothing is authentic
    flipped = data[:28] + bytes([data[28] ^ 1]) + data[29:]
    assert not decode(flipped, key=KEY).authentic  # one bit of a value changed
    later = data[:20] + struct.pack("<Q", 1) + data[28:]
    assert not decode(later, key=KEY).authentic  # the due time is covered by the tag too


def _header(version, kind, count=0, seq=1):
    return struct.pack("<4sBBHIQ", b"TLDF", version, kind, count, seq, 2)


@pytest.mark.parametrize("data,match", [
    (b"TLDF", "shorter than the 36-byte minimum"),
    (b"XXXX" + bytes(32), "magic: expected b'TLDF'"),
    (_header(1, 2) + bytes(16), "version: 1 is refused.*version 3"),
    (_header(2, 2) + bytes(16), "version: 2 is refused.*version 3"),
    (_header(9, 2) + bytes(16), "version: expected 3, got 9"),
    (_header(3, 1, 3) + bytes(8 + 4) + bytes(16), "count: header says 3 values"),
    (_header(3, 7) + bytes(16), "type: message type 7"),
    (_header(3, 4) + bytes(16), "type: message type 4 with count 0 and a 0-byte payload"),  # ARM without a nonce
])
def test_decode_rejects(data, match):
    with pytest.raises(FrameFormatError, match=match):
        decode(data)


def test_encode_rejects():
    with pytest.raises(FrameFormatError, match="kind: must be one of"):
        encode(9, 0, 0)
    with pytest.raises(FrameFormatError, match="values: at most 16000 per FRAME"):
        encode(FRAME, 0, 0, np.zeros(16001))
    with pytest.raises(FrameFormatError, match="values: only FRAME messages carry values"):
        encode(ZERO, 0, 0, [1.0])
    with pytest.raises(FrameFormatError, match="seq: must be an integer in 0..4294967295"):
        encode(ZERO, 2**32, 0)
    with pytest.raises(FrameFormatError, match="key: ARM needs the 32-byte pairing key"):
        encode(ARM, 0, 0, nonce=NONCE)
    with pytest.raises(FrameFormatError, match=r"key: must be 32 bytes, got 5 bytes"):
        encode(ZERO, 0, 0, key=b"short")
    with pytest.raises(FrameFormatError, match=r"nonce: must be 16 bytes, got 3 bytes"):
        encode(ARM, 0, 0, key=KEY, nonce=b"abc")
    with pytest.raises(FrameFormatError, match=r"host_nonce: must be 16 bytes, got 0 bytes"):
        encode(ARMED, 0, 0, key=KEY, nonce=NONCE)
    with pytest.raises(FrameFormatError, match=r"due_ns: must be an integer in 0..18446744073709551615, got -1"):
        encode(FRAME, 0, 0, [1.0], key=KEY, due_ns=-1)
    with pytest.raises(FrameFormatError, match=r"pairing_key: must be 32 bytes"):
        session_key(b"x", NONCE, NONCE)


@pytest.mark.parametrize("url", ["tcp://127.0.0.1:9000", "udp://127.0.0.1", "udp://:9000", "udp://h:99999"])
def test_parse_udp_url_rejects(url):
    with pytest.raises(ValueError, match="url: expected udp://HOST:PORT"):
        parse_udp_url(url)


@pytest.mark.parametrize("kwargs,match", [
    ({"port": 0}, "port: must be an integer in 1..65535"),
    ({"port": True}, "port: must be an integer in 1..65535"),
    ({"ack_timeout_s": 0.0}, "ack_timeout_s: must be a finite number > 0"),
    ({"zero_retries": 0}, "zero_retries: must be an integer >= 1"),
    ({"pairing_key": b"short"}, "pairing_key: must be 32 bytes"),
])
def test_udp_display_rejects_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        UdpDisplay(DisplayDescription.braille_row(), **{"pairing_key": PAIRING_KEY, **kwargs})


def test_udp_display_rejects_displays_too_big_for_one_datagram():
    with pytest.raises(ValueError, match="description: 16200 tractors exceed the 16000 values"):
        UdpDisplay(DisplayDescription.braille_row(n_tractors=16200), port=9000, pairing_key=PAIRING_KEY)


# ----- driver <-> emulator ------------------------------------------------------------------
def test_safe_stream_arrives_exactly_and_within_limits(emulator):
    port, record = emulator
    desc = DisplayDescription.stress2()
    events = []
    safe = SafeDisplay(UdpDisplay.from_url(f"udp://127.0.0.1:{port}", desc, max_skipped_fraction=1.0,
                                          pairing_key=PAIRING_KEY), events.append)
    frames = render_drive(desc, amplitude_m=30e-6, pitch_m=2.4e-3, speed_m_per_s=0.04, duration_s=0.15,
                          frame_rate_hz=1000.0)
    safe.load(frames, 1000.0)
    report = safe.play()
    safe.close()
    assert report.frames_sent + report.skipped == 150 and report.acked + report.missing == report.frames_sent
    assert any(e["kind"] == "amplitude_clip" for e in events)  # 30 um needs more than 50 kPa
    received, rec = last_stream(record)
    assert received.shape[0] == report.acked
    if report.skipped == 0:  # bit-exact when the host kept the frame rate (a loaded machine may skip)
        np.testing.assert_array_equal(received, safe.frames.astype(np.float32))
        assert np.all(np.diff(rec["streams"][-1]["seq"]) == 1)
    assert_record_within_limits(received, desc, whole_stream=report.skipped == 0)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(data=st.data(), slew=st.floats(20.0, 3000.0), duty=st.floats(0.1, 1.0), n_frames=st.integers(2, 30),
       scale=st.floats(0.1, 4.0))
@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_random_drives_through_safe_display_never_exceed_limits(emulator, data, slew, duty, n_frames, scale):
    """Hypothesis: whatever the drive, the emulator's record stays within the limits."""
    port, record = emulator
    desc = DisplayDescription.braille_row(n_tractors=6, max_slew_rate_per_s=slew, max_duty_cycle=duty)
    values = data.draw(st.lists(st.floats(-1, 1), min_size=6 * n_frames, max_size=6 * n_frames))
    frames = scale * desc.max_traction_pa * np.array(values).reshape(n_frames, 6)
    safe = SafeDisplay(UdpDisplay(desc, LOOPBACK, port, max_skipped_fraction=1.0, pairing_key=PAIRING_KEY),
                       lambda e: None)
    safe.load(frames, 1000.0)
    report = safe.play()
    safe.close()
    received, rec = last_stream(record)
    assert received.shape[0] == report.frames_sent == n_frames - report.skipped
    assert_record_within_limits(received, desc, whole_stream=report.skipped == 0)
    assert rec["clamps"] == []  # the device never had to clamp


def test_stop_ends_the_stream_and_zeroes(emulator):
    port, record = emulator
    desc = DisplayDescription.braille_row()
    events = []
    safe = SafeDisplay(UdpDisplay(desc, LOOPBACK, port, pairing_key=PAIRING_KEY), events.append)
    safe.load(np.zeros((2000, 10)), 1000.0)
    timer = threading.Timer(0.1, safe.stop)
    timer.start()
    report = safe.play()
    timer.join()
    safe.close()
    assert report.stopped and report.frames_sent < 2000 and events[-1]["kind"] == "zero_on_stop"
    assert [e["type"] for e in read_record(record)["events"]][-2:] == ["zero", "disarm"]


def test_no_device_is_a_clear_error():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as silent:  # bound, never answers
        silent.bind((LOOPBACK, 0))
        display = UdpDisplay(DisplayDescription.braille_row(), LOOPBACK, silent.getsockname()[1],
                             ack_timeout_s=0.01, zero_retries=2, pairing_key=PAIRING_KEY)
        with pytest.raises(DisplayError, match="no acknowledgement of ARM after 2 tries.*version 3"):
            display.zero()
        display.close()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind((LOOPBACK, 0))
        free_port = probe.getsockname()[1]
    display = UdpDisplay(DisplayDescription.braille_row(), LOOPBACK, free_port, ack_timeout_s=0.05,
                         pairing_key=PAIRING_KEY)
    with pytest.raises(DisplayError, match="connection refused; is the device"):
        display.zero()  # nobody listens: loopback answers with ICMP port unreachable
    display.close()


def test_wrong_tractor_count_and_watchdog_trip_raise_and_zero(tmp_path):
    proc, port, record = start_emulator(tmp_path, "strict", "--tractors", "4", "--watchdog", "5ms",
                                        "--max-seconds", "60s")
    try:
        events = []
        safe = SafeDisplay(UdpDisplay(DisplayDescription.braille_row(), LOOPBACK, port, pairing_key=PAIRING_KEY),
                           events.append)
        safe.load(np.zeros((5, 10)), 1000.0)
        with pytest.raises(DisplayError, match=r"the device has 4 tractors, display 'VirtualBrailleRow' has 10"):
            safe.play()
        assert events[-1]["kind"] == "zero_on_exception"
        safe.close()  # its link ends: the device may be armed by the next host
        # 20 Hz frames against a 5 ms watchdog: the device trips, then refuses frames.
        safe = SafeDisplay(UdpDisplay(DisplayDescription.braille_row(n_tractors=4, lookahead_s=0.0), LOOPBACK, port,
                                      ack_timeout_s=0.2, pairing_key=PAIRING_KEY), events.append)
        safe.load(np.zeros((10, 4)), 20.0)
        with pytest.raises(DisplayError, match="watchdog tripped during playback"):
            safe.play()
        assert events[-1]["kind"] == "zero_on_exception"
        safe.close()
    finally:
        out = stop_emulator(proc)
    assert "watchdog: no frame for" in out
    rec = read_record(record)
    assert rec["summary"]["watchdog_trips"] >= 1 and rec["summary"]["rejected"] >= 1
    assert any(e["type"] == "rejected" and e["status"] == "disarmed" for e in rec["events"])


HOST = """
import sys, numpy as np
from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.display import render_drive
from tactilab.experiments.devices.safety import SafeDisplay
from tactilab.experiments.devices.udp import UdpDisplay
desc = DisplayDescription.stress2()
safe = SafeDisplay(UdpDisplay(desc, "127.0.0.1", int(sys.argv[1]), max_skipped_fraction=1.0,
                              pairing_key=bytes(range(32))), print)
safe.load(render_drive(desc, amplitude_m=10e-6, pitch_m=2.4e-3, speed_m_per_s=0.04, duration_s=30.0,
                       frame_rate_hz=1000.0), 1000.0)
print("playing", flush=True)
safe.play()
"""


def _frames_so_far(record) -> int:
    """Frames in a record the emulator is still writing (0 while its last line is half written)."""
    try:
        return read_record(record)["n_frames"]
    except ValueError:  # a torn last line: read again on the next poll
        return 0


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_host_killed_mid_stimulus_emulator_zeroes_within_its_lookahead_and_watchdog(tmp_path):
    proc, port, record = start_emulator(tmp_path, "kill", "--watchdog", "100ms", "--max-seconds", "60s")
    host = subprocess.Popen([sys.executable, "-c", HOST, str(port)], stdout=subprocess.PIPE, text=True)
    try:
        assert host.stdout.readline().strip() == "playing"
        while _frames_so_far(record) < 200:  # mid-stimulus: the drive is non-zero now
            assert host.poll() is None, "the host ended before streaming 200 frames"
            time.sleep(0.02)
        os.kill(host.pid, signal.SIGKILL)
        host.wait(timeout=30)
        line = proc.stdout.readline()
        assert line.startswith("watchdog: no frame for"), line
    finally:
        if host.poll() is None:
            host.kill()
        out = stop_emulator(proc)
    rec = read_record(record)
    trips = [e for e in rec["events"] if e["type"] == "watchdog"]
    assert len(trips) == 1 and rec["summary"]["watchdog_trips"] == 1
    trip = trips[0]
    stream = rec["streams"][-1]
    last_frame_ns = int(stream["arrival_ns"][-1])
    assert np.any(stream["values"][-1] != 0)  # it was killed while driving the skin
    # the last frame received (frames still in the FIFO at the trip are dropped, never applied)
    assert trip["last_valid_ns"] >= last_frame_ns and trip["dropped"] >= 0
    # the stated bound: the watchdog time after the last message or the last frame's due time (at most
    # the lookahead after it), whichever is later, exactly
    assert trip["deadline_ns"] == max(trip["last_valid_ns"], trip["last_due_ns"]) + 100_000_000
    assert trip["t_ns"] >= trip["deadline_ns"] and trip["late_by_ns"] == trip["t_ns"] - trip["deadline_ns"]
    assert rec["events"][-1]["type"] == "summary" and "summary:" in out
    assert_record_within_limits(stream["values"], DisplayDescription.stress2())


# ----- the emulator's device logic, driven by raw datagrams ------------------------------------
@pytest.fixture
def thread_emulator(tmp_path):
    stop, logs = threading.Event(), []
    record = tmp_path / "thread.jsonl"
    result = {}
    thread = threading.Thread(target=lambda: result.update(summary=emulate(
        0, watchdog_s=0.05, record=record, max_seconds=30, n_tractors=2, log=logs.append, stop=stop,
        handle_signals=False, pairing_key=PAIRING_KEY)))
    thread.start()
    while not logs:
        assert thread.is_alive(), "the emulator thread ended before listening"
        time.sleep(0.005)
    port = int(logs[0].split(":")[2].split()[0])
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.settimeout(5)
    sock.connect((LOOPBACK, port))

    def ask(data):
        sock.send(data)
        return decode(sock.recv(1024))

    def finish():
        stop.set()
        thread.join(timeout=10)
        return result["summary"]

    yield ask, sock, finish, record
    finish()
    sock.close()


def test_emulator_statuses_gaps_and_rearming(thread_emulator):
    ask, sock, finish, record = thread_emulator
    port = sock.getpeername()[1]
    link = RawLink(port, PAIRING_KEY)
    try:
        refused = link.ask(ZERO)
        assert (refused.status, refused.authentic) == (STATUS_CODE["refused"], False)  # no session yet
        armed = link.arm()
        assert (armed.kind, armed.authentic, armed.watchdog_us, armed.n_tractors) == (ARMED, True, 50_000, 2)
        assert link.ask(FRAME, [1.0, 2.0]).status == STATUS_CODE["applied"]
        assert link.ask(FRAME, [1.0, 2.0], seq=link.seq).status == STATUS_CODE["stale"]  # the same seq again
        assert link.ask(FRAME, [1.0, 2.0], seq=link.seq + 4).status == STATUS_CODE["applied"]  # 3 missing
        assert link.ask(FRAME, [1.0, 2.0, 3.0]).status == STATUS_CODE["bad_count"]
        assert link.ask(ACK).status == STATUS_CODE["bad_message"]
        corrupted = link.message(ZERO)
        link.send(corrupted[:-1] + bytes([corrupted[-1] ^ 0xFF]))  # a bad tag: refused, untagged
        answer = link.recv()
        assert (answer.status, answer.authentic) == (STATUS_CODE["bad_mac"], False)
        time.sleep(0.2)  # > watchdog: the device zeroes and the session ends
        tripped = link.ask(FRAME, [1.0, 2.0])
        assert tripped.status == STATUS_CODE["disarmed"] and tripped.flags == 1 and tripped.authentic
        assert link.arm().kind == ARMED  # after a trip, a new session
        assert link.ask(FRAME, [0.5, 0.5]).status == STATUS_CODE["applied"]
        assert link.ask(DISARM).status == STATUS_CODE["released"]
        assert link.ask(FRAME, [0.5, 0.5]).status == STATUS_CODE["refused"]
        link.sock.settimeout(0.05)
        with pytest.raises(socket.timeout):
            link.sock.recv(1024)  # nothing else was sent
    finally:
        link.close()
    summary = finish()
    assert (summary.frames_applied, summary.stale, summary.missing, summary.rejected, summary.watchdog_trips,
            summary.sessions, summary.bad_mac, summary.zero_commands) == (3, 1, 3, 6, 1, 2, 1, 0)
    rec = read_record(record)
    assert [e["type"] for e in rec["events"]].count("watchdog") == 1
    assert [len(st_["seq"]) for st_ in rec["streams"]] == [2, 1]  # the watchdog ended the first
    np.testing.assert_array_equal(np.vstack([st_["values"] for st_ in rec["streams"]]),
                                  [[1, 2], [1, 2], [0.5, 0.5]])


@pytest.mark.parametrize("kwargs,match", [
    ({"port": 70000}, r"port: must be an integer in 0..65535"),
    ({"watchdog_s": 0.0}, "watchdog_s: must be a finite number of seconds > 0"),
    ({"max_seconds": float("inf")}, "max_seconds: must be a finite number of seconds > 0"),
    ({"max_seconds": 1e300}, r"max_seconds: must be at most 1e\+07 s .*, got 1e\+300"),
    ({"late_after_s": -1.0}, "late_after_s: must be a finite number of seconds > 0"),
    ({"n_tractors": 0}, "n_tractors: must be an integer >= 1"),
    ({"fifo_frames": 70000}, r"fifo_frames: must be an integer in 1..65535"),
    ({"pairing_key": None}, r"pairing_key: the emulator needs the 32-byte pairing key its hosts hold, got None; "
                            r"give --pairing-key FILE"),
    ({"pairing_key": b"short"}, r"pairing_key: .* got 5 bytes"),
])
def test_emulate_rejects_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        emulate(**{"port": 0, "pairing_key": PAIRING_KEY, **kwargs})


def test_cli_reports_bad_options_in_one_line(capsys, tmp_path):
    assert cli_main(["device", "emulate", "--port", "0", "--watchdog", "0ms", "--max-seconds", "1s",
                     "--pairing-key", "k"]) == 2
    assert "--watchdog: must be finite and > 0 s, got 0.0; give a time with a unit, e.g. 50ms" in capsys.readouterr().err
    assert cli_main(["device", "emulate", "--port", "0", "--max-seconds", "1e300s", "--pairing-key", "k"]) == 2
    assert "--max-seconds: must be at most" in capsys.readouterr().err  # was OverflowError
    key = key_file(tmp_path)
    assert cli_main(["device", "emulate", "--port", "0", "--tractors", "0", "--pairing-key", str(key)]) == 2
    assert "--tractors: must be an integer >= 1" in capsys.readouterr().err
    key.chmod(0o640)
    assert cli_main(["device", "emulate", "--port", "0", "--pairing-key", str(key)]) == 2
    assert f"--pairing-key: {key} may be read or written by its group or others (mode 640)" in capsys.readouterr().err


def test_cli_emulator_stops_on_its_own_after_max_seconds(tmp_path, capsys):
    record = tmp_path / "short.jsonl"
    assert cli_main(["device", "emulate", "--port", "0", "--max-seconds", "0.2s", "--record", str(record),
                     "--pairing-key", str(key_file(tmp_path))]) == 0
    assert "summary: port" in capsys.readouterr().out
    rec = read_record(record)
    assert rec["summary"]["frames_applied"] == 0 and rec["streams"] == [] and rec["n_frames"] == 0


def test_read_record_rejects_non_json(tmp_path):
    path = tmp_path / "bad.jsonl"
    path.write_text("not json\n")
    with pytest.raises(ValueError, match="line 1 is not JSON"):
        read_record(path)


def test_documented_example_bytes_match_the_encoder():
    """docs/udp-frame-format.md's example is what encode() produces (firmware copies it): the ARM, the
    ARMED and a FRAME of the session, with the session key computed independently."""
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[1] / "docs" / "udp-frame-format.md").read_text()
    block = doc.split("Pairing key P = bytes")[1].split("```")[1]
    messages = {}
    for line in block.strip().splitlines():
        if line.startswith(("ARM:", "ARMED:", "FRAME:")):
            name, line = line.split(":", 1)
            messages[name] = ""
        messages[name] += " " + line.strip().split("   ")[0]
    host_nonce, device_nonce = bytes(range(0xA0, 0xB0)), bytes(range(0xB0, 0xC0))
    assert bytes.fromhex(messages["ARM"]) == encode(ARM, 4, 1_000_000, key=KEY, nonce=host_nonce)
    assert bytes.fromhex(messages["ARMED"]) == encode(
        ARMED, 4, 1_000_000, key=KEY, nonce=device_nonce, host_nonce=host_nonce, watchdog_us=50_000, n_tractors=2,
        fifo_frames=1000, frames_applied=0, device_ns=2_000_000)
    session = hmac.new(KEY, b"TLDF3 session" + host_nonce + device_nonce, hashlib.sha256).digest()
    frame = bytes.fromhex(messages["FRAME"])
    assert frame == encode(FRAME, 5, 1_100_000, [1.5, -2.0], key=session, due_ns=2_050_000)
    assert frame[-16:] == _tag(frame[:-16], key=session)
    exec(doc.split("The same in Python")[1].split("```python")[1].split("```")[0], {})  # the page's own check


def test_emulator_can_only_listen_on_loopback():
    import inspect

    assert LOOPBACK == "127.0.0.1"
    assert not {"host", "address", "bind"} & set(inspect.signature(emulate).parameters)

"""A failed trial is never scored: fake devices that answer `stale` or nothing at all."""

from __future__ import annotations

import socket
import threading
import time

import pytest
from udp_pairing import KEY, paired_description

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments import (
    DisplayFault, SessionLog, SimulatedObserver, UdpDisplay, emulate, new_session, resume_session, session_status)
from tactilab.experiments.devices.display import PlaybackReport
from tactilab.experiments.devices import MAX_UNACKED_FRACTION, display_fault
from tactilab.experiments.devices.link import ACK, ARM, ARMED, DISARM, STATUS_CODE, ZERO, decode, encode, session_key

PROTOCOL = {
    "name": "faults", "seed": 3, "iti_s": 0, "task": {"kind": "yes_no"},
    "stimulus": {"amplitude_m": "2um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s",
                 "duration_s": "30ms", "ramp_s": "5ms"},
    "procedure": {"method": "constant_stimuli", "parameter": "amplitude_m", "levels": ["1um", "3um"],
                  "repeats_per_block": 1, "n_blocks": 1}}


class FakeDevice:
    """Speaks frame format 3 (a paired ARM; ZERO and DISARM are answered, tagged); answers FRAMEs with
    ``mode``: 'stale', 'silent' (nothing) or 'applied'."""

    def __init__(self, mode: str) -> None:
        self.mode, self.log = mode, []
        self.key, self.nonce = None, bytes(range(16))
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while not self.stop.is_set():
            try:
                data, sender = self.sock.recvfrom(65536)
            except TimeoutError:
                continue
            message = decode(data, key=KEY if data[5] == ARM else self.key)
            self.log.append(message.kind)
            if message.kind == ARM:
                self.key = session_key(KEY, message.nonce, self.nonce)
                self.sock.sendto(encode(ARMED, message.seq, message.timestamp_ns, key=KEY, nonce=self.nonce,
                                        host_nonce=message.nonce, fifo_frames=1000), sender)
                continue
            assert message.authentic
            status = {ZERO: "zeroed", DISARM: "released"}.get(message.kind, self.mode)
            if status != "silent":
                self.sock.sendto(encode(ACK, message.seq, message.timestamp_ns, status=STATUS_CODE[status],
                                        key=self.key, device_ns=time.perf_counter_ns()), sender)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()
        self.sock.close()


@pytest.mark.parametrize("mode,match,alarm", [
    ("stale", r"ALARM: (\d+) of \1 frames were acknowledged 'stale'", True),
    ("silent", r"(\d+) of \1 frames were never acknowledged", False),
])
def test_a_trial_whose_frames_were_not_applied_is_never_scored(tmp_path, mode, match, alarm):
    protocol = Protocol.model_validate(PROTOCOL)
    description = DisplayDescription.braille_row()
    device = FakeDevice(mode)
    path = tmp_path / "s.sqlite"
    try:
        with UdpDisplay(description, "127.0.0.1", device.port, max_skipped_fraction=1.0, pairing_key=KEY) as display:
            with pytest.raises(DisplayFault, match=match + ".*not scored.*resume"):
                new_session(protocol, path, display, SimulatedObserver(protocol), subject="S01", realtime=False)
    finally:
        device.close()
    assert device.log[-3:] == [ZERO, ZERO, DISARM], "the display is zeroed after the fault, then disarmed"
    log = SessionLog(path)
    try:
        assert log.trials() == []
        faults = log.events("display_fault")
        assert len(faults) == 1 and faults[0]["trial_index"] == 0 and faults[0]["payload"]["alarm"] is alarm
        assert not log.events("response") and log.events("session_failed")
    finally:
        log.close()
    assert session_status(path)["status"] == "failed"
    # resume on a device that applies the frames: the trial is repeated, then scored
    stop = threading.Event()
    ports = []
    emulator = threading.Thread(target=emulate, kwargs=dict(
        port=0, watchdog_s=1.0, max_seconds=30, log=lambda line: ports.append(line), stop=stop,
        handle_signals=False, pairing_key=KEY), daemon=True)
    emulator.start()
    while not ports:
        stop.wait(0.01)
    port = int(ports[0].split(":")[2].split()[0])
    try:
        with UdpDisplay(description, "127.0.0.1", port, max_skipped_fraction=1.0, pairing_key=KEY) as display:
            result = resume_session(path, display, SimulatedObserver(protocol), realtime=False)
    finally:
        stop.set()
        emulator.join()
    assert result.status == "complete"
    log = SessionLog(path)
    try:
        first = log.trials()[0]
        assert (first.attempt, first.repeated, first.frames_missing) == (1, True, 0)
    finally:
        log.close()


def test_the_cli_reports_a_display_fault_in_one_line(tmp_path, capsys):
    device = FakeDevice("stale")
    toml = tmp_path / "p.toml"
    toml.write_text('name = "faults"\nseed = 3\niti_s = 0\n[task]\nkind = "yes_no"\n[stimulus]\n'
                    'amplitude_m = "2um"\npitch_m = "2mm"\nspeed_m_per_s = "40mm/s"\nduration_s = "30ms"\n'
                    'ramp_s = "5ms"\n[procedure]\nmethod = "constant_stimuli"\nparameter = "amplitude_m"\n'
                    'levels = ["1um"]\nrepeats_per_block = 1\nn_blocks = 1\n')
    try:
        code = cli_main(["experiment", "run", str(toml), "--subject", "S01", "--responses", "simulated",
                         "--no-wait", "--quiet", "--out", str(tmp_path), "--display", f"udp://127.0.0.1:{device.port}",
                         "--device", str(paired_description(tmp_path, DisplayDescription.braille_row()))])
    finally:
        device.close()
    err = capsys.readouterr().err
    assert code == 3 and len(err.strip().splitlines()) == 1 and "ALARM" in err and "resume" in err


def test_the_fault_rule_allows_a_small_stated_fraction_of_lost_acknowledgements():
    ok = PlaybackReport(frames_sent=1000, late=0, missing=10, acked=990)
    assert MAX_UNACKED_FRACTION == 0.01 and display_fault(ok) is None
    lost = PlaybackReport(frames_sent=1000, late=0, missing=11, acked=989)
    assert "11 of 1000 frames were never acknowledged" in display_fault(lost)["reason"]
    refused = PlaybackReport(frames_sent=1000, late=0, missing=1, acked=999, rejected=1)
    assert "1 of 1000 frames were refused" in display_fault(refused)["reason"]
    stopped = PlaybackReport(frames_sent=10, late=0, missing=0, acked=10, stopped=True)
    assert "playback stopped after 10 frames" in display_fault(stopped)["reason"]


def test_an_absent_device_is_found_before_any_session_file_exists(tmp_path, capsys):
    """A ZERO round trip comes first: no device, no file (and one line from the command line)."""
    from tactilab.experiments.devices.display import DisplayError

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        free_port = probe.getsockname()[1]
    protocol = Protocol.model_validate(PROTOCOL)
    display = UdpDisplay(DisplayDescription.braille_row(), "127.0.0.1", free_port, pairing_key=KEY)
    try:
        with pytest.raises(DisplayError, match="connection refused"):
            new_session(protocol, tmp_path / "s.sqlite", display, SimulatedObserver(protocol), subject="S01",
                        realtime=False)
    finally:
        display.close()
    assert list(tmp_path.iterdir()) == []
    toml = tmp_path / "p.toml"
    toml.write_text('name = "faults"\nseed = 3\n[task]\nkind = "yes_no"\n[stimulus]\namplitude_m = "2um"\n'
                    'pitch_m = "2mm"\nspeed_m_per_s = "40mm/s"\n[procedure]\nmethod = "constant_stimuli"\n'
                    'parameter = "amplitude_m"\nlevels = ["1um"]\n')
    code = cli_main(["experiment", "run", str(toml), "--subject", "S01", "--responses", "simulated", "--quiet",
                     "--out", str(tmp_path / "out"), "--display", f"udp://127.0.0.1:{free_port}",
                     "--device", str(paired_description(tmp_path, DisplayDescription.braille_row()))])
    err = capsys.readouterr().err
    assert code == 3 and len(err.strip().splitlines()) == 1 and "connection refused" in err
    assert not list((tmp_path / "out").glob("*.sqlite"))

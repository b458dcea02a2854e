"""A local intruder and the one armed link (issue 26, item 1): the host arms the device once per
session with its pairing key and keeps the link armed between stimuli, so an intruder between
stimuli or while the subject answers drives nothing, whatever it tries; should another key holder
drive the device while the link was down, the host's look at ``frames_applied`` faults the trial."""

from __future__ import annotations

import time

import numpy as np
import pytest
from udp_pairing import KEY, WRONG_KEY, emulator_thread

from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments.devices import DisplayFault
from tactilab.experiments.devices.emulator import read_record
from tactilab.experiments.devices.link import ARM, ARMED, DISARM, FRAME, STATUS, encode
from tactilab.experiments.devices.udp import UdpDisplay
from tactilab.experiments.devices.udp_link import HostLink, RawLink
from tactilab.experiments.session import SessionLog, SimulatedObserver, new_session

DESC = DisplayDescription.braille_row(n_tractors=4)
INTRUDER_VALUE = 0.2 * DESC.max_traction_pa
PROTOCOL = Protocol.model_validate({
    "name": "intruder", "seed": 5, "iti_s": 0, "task": {"kind": "2ifc", "interval_gap_s": "50ms"},
    "stimulus": {"amplitude_m": "2um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s", "duration_s": "30ms",
                 "ramp_s": "5ms"},
    "procedure": {"method": "constant_stimuli", "parameter": "amplitude_m", "levels": ["1um", "3um"],
                  "repeats_per_block": 1, "n_blocks": 1}})


@pytest.fixture
def start(tmp_path):
    """``start(watchdog_s=30.0)`` runs the emulator in a thread and returns (port, finish() -> summary,
    record); it is stopped at the end of the test."""
    stops = []

    def run(watchdog_s: float = 30.0):
        record = tmp_path / "link.jsonl"
        port, finish, _ = emulator_thread(watchdog_s=watchdog_s, record=record, limits=DESC)
        stops.append(finish)
        return port, finish, record

    yield run
    for finish in stops:
        finish()


def _intrude(port: int) -> list[str]:
    """Another local process on 127.0.0.2: ARM with a wrong key, ARM with the stolen key, FRAMEs and a
    DISARM of a session it made up; returns the statuses it got."""
    intruder = RawLink(port, WRONG_KEY, bind="127.0.0.2", timeout_s=2.0)
    try:
        answers = [_status(intruder.arm())]
        intruder.pairing_key = KEY
        answers.append(_status(intruder.arm()))
        intruder.key = bytes(32)  # a session key it made up
        for _ in range(3):
            answers.append(_status(intruder.ask(FRAME, [INTRUDER_VALUE] * DESC.n_tractors)))
        answers.append(_status(intruder.ask(DISARM)))
        return answers
    finally:
        intruder.close()


def _status(message) -> str:
    return "armed" if message.kind == ARMED else STATUS[message.status]


@pytest.mark.parametrize("when", ["between the two stimuli", "while the subject answers"])
def test_an_intruder_between_stimuli_cannot_drive_the_display(start, tmp_path, monkeypatch, when):
    """The intruder strikes inside trial 0 (after interval 1's closing ZERO, or during the response):
    every datagram is refused alike, the session completes, and the device applied exactly the
    frames the host sent (the intruder's value never appears)."""
    port, finish, record = start()
    intruded = []
    if when == "between the two stimuli":
        real_zero, count = HostLink.zero, [0]

        def zero_then_intrude(self):  # ZEROs: 1 start-up, 2 interval 1 starts, 3 interval 1 ends
            real_zero(self)
            count[0] += 1
            if count[0] == 3:
                intruded.extend(_intrude(port))

        monkeypatch.setattr(HostLink, "zero", zero_then_intrude)
    else:
        real_collect = SimulatedObserver.collect

        def collect_while_intruding(self, plan):
            if not intruded:
                intruded.extend(_intrude(port))
            return real_collect(self, plan)

        monkeypatch.setattr(SimulatedObserver, "collect", collect_while_intruding)
    path = tmp_path / "s.sqlite"
    with UdpDisplay(DESC, "127.0.0.1", port, max_skipped_fraction=1.0, pairing_key=KEY) as display:
        result = new_session(PROTOCOL, path, display, SimulatedObserver(PROTOCOL), subject="S01", realtime=False)
    assert intruded == ["refused"] * 6
    assert result.status == "complete" and display.foreign_frames == 0
    summary = finish()
    assert summary.sessions == 1 and summary.refused_arms == 2
    rec = read_record(record)
    applied = np.vstack([s["values"] for s in rec["streams"]])
    log = SessionLog(path)
    try:
        trials = log.trials()
    finally:
        log.close()
    assert summary.frames_applied == len(applied) == sum(t.frames_sent for t in trials)
    assert not np.any(applied == np.float32(INTRUDER_VALUE))


def test_frames_the_host_did_not_send_fault_the_trial(start, tmp_path, monkeypatch):
    """A holder of the stolen key arms the device once the host's link is down (no keep-alive: the
    watchdog ends it while the subject answers), makes it apply 7 frames and disarms. The host arms
    again for its look before scoring; the ARMED's counter shows 7 frames it did not send: the
    trial is not scored and the session says why."""
    port, finish, record = start(watchdog_s=0.3)
    monkeypatch.setattr(HostLink, "_keep_alive", lambda self: None)
    real_collect, intruded = SimulatedObserver.collect, []

    def collect_while_a_key_holder_intrudes(self, plan):
        if not intruded:
            thief = RawLink(port, KEY, bind="127.0.0.2", timeout_s=2.0)
            try:
                while thief.arm().kind != ARMED:  # refused while the host's link is armed
                    time.sleep(0.02)
                intruded.extend(_status(thief.ask(FRAME, [INTRUDER_VALUE] * DESC.n_tractors)) for _ in range(7))
                intruded.append(_status(thief.ask(DISARM)))
            finally:
                thief.close()
        return real_collect(self, plan)

    monkeypatch.setattr(SimulatedObserver, "collect", collect_while_a_key_holder_intrudes)
    path = tmp_path / "s.sqlite"
    with UdpDisplay(DESC, "127.0.0.1", port, max_skipped_fraction=1.0, pairing_key=KEY) as display:
        with pytest.raises(DisplayFault, match="the device applied 7 frames this host did not send"):
            new_session(PROTOCOL, path, display, SimulatedObserver(PROTOCOL), subject="S01", realtime=False)
    assert intruded == ["applied"] * 7 + ["released"]
    log = SessionLog(path)
    try:
        trials, faults = log.trials(), log.events("display_fault")
    finally:
        log.close()
    assert trials == [] and len(faults) == 1  # the trial was not scored; the session says why
    assert faults[0]["trial_index"] == 0 and faults[0]["payload"]["alarm"] and faults[0]["payload"]["foreign"] == 7
    assert display.foreign_frames == 7 and display.link.rearms == 1
    summary = finish()
    assert summary.watchdog_trips == 1 and summary.frames_applied == sum(
        len(s["seq"]) for s in read_record(record)["streams"])


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_the_keep_alive_holds_the_link_through_a_long_response_wait(start, tmp_path, monkeypatch):
    """The subject takes 4 watchdog times to answer: the keep-alive ZEROs hold the link, so the device
    never trips and the host never arms again (one link for the whole session)."""
    port, finish, _ = start(watchdog_s=0.25)
    real_collect, waited = SimulatedObserver.collect, []

    def slow_collect(self, plan):
        if not waited:
            waited.append(time.sleep(1.0))
        return real_collect(self, plan)

    monkeypatch.setattr(SimulatedObserver, "collect", slow_collect)
    with UdpDisplay(DESC, "127.0.0.1", port, max_skipped_fraction=1.0, pairing_key=KEY) as display:
        result = new_session(PROTOCOL, tmp_path / "s.sqlite", display, SimulatedObserver(PROTOCOL), subject="S01",
                             realtime=False)
        assert display.device_watchdog_s == 0.25 and display.link.rearms == 0
    summary = finish()
    assert result.status == "complete" and waited
    assert (summary.watchdog_trips, summary.sessions) == (0, 1)
    assert summary.zero_commands >= 4  # the keep-alive's, besides the stimuli's own


def test_arm_refusals_do_not_depend_on_the_key_or_the_state(start):
    """The same ARM datagram under a wrong key is answered identically before and during the host's session."""
    port, finish, _ = start()
    probe = RawLink(port, WRONG_KEY, bind="127.0.0.2")
    arm = encode(ARM, 3, 3, key=WRONG_KEY, nonce=bytes(16))
    probe.send(arm)
    idle = probe.sock.recv(65536)
    with UdpDisplay(DESC, "127.0.0.1", port, pairing_key=KEY) as display:
        display.zero()
        probe.send(arm)
        busy = probe.sock.recv(65536)
    probe.close()
    assert idle == busy
    finish()

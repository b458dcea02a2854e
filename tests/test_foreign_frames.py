"""A local intruder that drives the display between the host's stimuli (issue 26, item 1): the
host compares the device's ``frames_applied`` counter with the frames it sent, before every
scored trial, so no foreign frame lands inside a scored trial: the trial is faulted instead."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments.devices import DisplayFault, display_fault
from tactilab.experiments.devices.emulator import emulate, read_record
from tactilab.experiments.devices.link import ARMED, DISARM, FRAME, STATUS, RawLink
from tactilab.experiments.devices.udp import UdpDisplay
from tactilab.experiments.session import SessionLog, SimulatedObserver, new_session

DESC = DisplayDescription.braille_row(n_tractors=4)
PROTOCOL = Protocol.model_validate({
    "name": "intruder", "seed": 5, "iti_s": 0, "task": {"kind": "2ifc", "interval_gap_s": "50ms"},
    "stimulus": {"amplitude_m": "2um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s", "duration_s": "30ms",
                 "ramp_s": "5ms"},
    "procedure": {"method": "constant_stimuli", "parameter": "amplitude_m", "levels": ["1um", "3um"],
                  "repeats_per_block": 1, "n_blocks": 1}})


@pytest.fixture
def device(tmp_path):
    """The emulator in a thread (watchdog 30 s); yields (port, finish() -> summary, record)."""
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

    yield int(logs[0].split(":")[2].split()[0]), finish, record
    finish()


def _intrude(port: int, n_frames: int) -> list[str]:
    """Another local process: ARM the idle device, make it apply ``n_frames`` frames, DISARM."""
    intruder = RawLink(port, bind="127.0.0.2", timeout_s=2.0)
    try:
        answers = ["armed" if intruder.arm().kind == ARMED else "refused"]
        for _ in range(n_frames):
            answers.append(STATUS[intruder.ask(FRAME, [0.2 * DESC.max_traction_pa] * DESC.n_tractors).status])
        answers.append(STATUS[intruder.ask(DISARM).status])
        return answers
    finally:
        intruder.close()


@pytest.mark.parametrize("when, closes", [("between the two stimuli", 2), ("while the subject answers", 3)])
def test_an_intruder_between_stimuli_faults_the_trial_and_nothing_is_scored(device, tmp_path, monkeypatch,
                                                                            when, closes):
    """Closes of the host's link sessions: 1 the start-up zero, 2 after interval 1, 3 after interval
    2 of trial 0; the intruder strikes right after close ``closes``, inside trial 0."""
    port, finish, record = device
    real_close, count, intruded = UdpDisplay._close_session, [0], []

    def close_then_intrude(self):
        foreign = real_close(self)
        count[0] += 1
        if count[0] == closes:
            intruded.extend(_intrude(port, 7))
        return foreign

    monkeypatch.setattr(UdpDisplay, "_close_session", close_then_intrude)
    path = tmp_path / "s.sqlite"
    with UdpDisplay(DESC, "127.0.0.1", port, max_skipped_fraction=1.0) as display:
        with pytest.raises(DisplayFault, match="the device applied 7 frames this host did not send"):
            new_session(PROTOCOL, path, display, SimulatedObserver(PROTOCOL), subject="S01", realtime=False)
    assert intruded == ["armed"] + ["applied"] * 7 + ["released"]
    log = SessionLog(path)
    try:
        trials, faults = log.trials(), log.events("display_fault")
    finally:
        log.close()
    assert trials == [] and len(faults) == 1  # the trial was not scored; the session says why
    assert faults[0]["trial_index"] == 0 and faults[0]["payload"]["alarm"] and faults[0]["payload"]["foreign"] == 7
    assert display.foreign_frames == 7
    summary = finish()
    assert summary.frames_applied == sum(len(s["seq"]) for s in read_record(record)["streams"])


def test_the_counter_look_needs_no_intruder_to_stay_quiet(device, tmp_path):
    """Without an intruder the looks find nothing: the session completes and every report is clean."""
    port, finish, _ = device
    with UdpDisplay(DESC, "127.0.0.1", port, max_skipped_fraction=1.0) as display:
        display.zero()
        frames = np.zeros((20, DESC.n_tractors))
        display.load(frames, 1000.0)
        report = display.play()
        assert report.foreign == 0 and display.audit() == 0 and display.foreign_frames == 0
        assert display_fault(report) is None or report.skipped
        result = new_session(PROTOCOL, tmp_path / "s.sqlite", display, SimulatedObserver(PROTOCOL), subject="S01",
                             realtime=False)
    assert result.status == "complete" and display.foreign_frames == 0
    assert finish().refused_arms == 0

"""Fuzzed VALID protocols never command anything beyond the display's limits.

Hypothesis draws protocols that pass validation, with amplitudes up to 5 mm (far beyond what
any display renders), any pitch, speed, surface, ramp and duration, and staircase or constant
stimuli levels across that range. Each runs as a real session (runner, recorder, safety layer)
streaming over UDP to the device emulator on loopback; the emulator's record of every frame it
applied is the proof: per stream (between ZEROs) no value exceeds full scale, no step exceeds
the slew limit, no tractor is driven on more than the duty fraction of frames, and every stream
ends at rest. The display description is deliberately tight (slew and duty limits bind).
"""

from __future__ import annotations

import math
import shutil
import tempfile
import threading
from pathlib import Path

import hypothesis.strategies as st
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from udp_pairing import KEY

from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments.devices.display import limit_violations
from tactilab.experiments.devices.emulator import emulate, read_record
from tactilab.experiments.session.recording import SessionLog
from tactilab.experiments.session.responses import SimulatedObserver
from tactilab.experiments.session.runner import new_session
from tactilab.experiments.devices.udp import UdpDisplay

DESCRIPTION = DisplayDescription.braille_row(display_id="FuzzRow", max_slew_rate_per_s=40.0, max_duty_cycle=0.6)


@pytest.fixture(scope="module")
def emulator():
    """The device emulator in a thread on a free loopback port, recording every frame."""
    folder = Path(tempfile.mkdtemp(prefix="tactilab-fuzz-"))
    record = folder / "record.jsonl"
    lines: list[str] = []
    stop = threading.Event()
    thread = threading.Thread(target=emulate, kwargs=dict(
        port=0, watchdog_s=0.5, record=record, max_seconds=120, log=lines.append, stop=stop,
        handle_signals=False, limits=DESCRIPTION, pairing_key=KEY), daemon=True)
    thread.start()
    while not lines:
        stop.wait(0.01)
    port = int(lines[0].split("udp://127.0.0.1:")[1].split()[0])
    yield port, record, folder
    stop.set()
    thread.join(timeout=5)
    shutil.rmtree(folder, ignore_errors=True)


lengths = st.floats(min_value=0.2e-3, max_value=20e-3)
amplitudes = st.floats(min_value=0.0, max_value=5e-3)


@st.composite
def valid_protocols(draw):
    duration = draw(st.floats(min_value=0.01, max_value=0.04))
    stimulus = {
        "surface": draw(st.sampled_from(["sinusoid", "square"])),
        "amplitude_m": draw(amplitudes), "pitch_m": draw(lengths),
        "speed_m_per_s": draw(st.floats(min_value=-0.5, max_value=0.5)),
        "duration_s": duration, "ramp_s": draw(st.floats(min_value=0.0, max_value=duration / 2)),
        "phase_rad": draw(st.floats(min_value=-math.pi, max_value=math.pi)),
    }
    parameter = draw(st.sampled_from(["amplitude_m", "pitch_m"]))
    values = amplitudes.filter(lambda v: v > 0) if parameter == "amplitude_m" else lengths
    if draw(st.booleans()):
        low, high = sorted(draw(st.lists(values, min_size=2, max_size=2, unique=True)))
        procedure = {"method": "staircase", "parameter": parameter, "tracks": [{
            "start": draw(st.floats(min_value=low, max_value=high)), "step_sizes": [draw(st.floats(0.05, 1.0))],
            "min_level": low, "max_level": high, "max_trials": 2, "down": 1}]}
    else:
        procedure = {"method": "constant_stimuli", "parameter": parameter,
                     "levels": draw(st.lists(values, min_size=1, max_size=2)), "repeats_per_block": 1, "n_blocks": 1}
    kind = draw(st.sampled_from(["2ifc", "yes_no"]))
    return Protocol.model_validate({"name": "fuzz", "seed": draw(st.integers(0, 2**32)), "iti_s": 0,
                                    "task": {"kind": kind, "interval_gap_s": 0}, "stimulus": stimulus,
                                    "procedure": procedure})


@settings(max_examples=10, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(protocol=valid_protocols())
@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_fuzzed_valid_protocols_stay_within_the_limits_on_the_wire(protocol, emulator):
    port, record, folder = emulator
    path = Path(tempfile.mkdtemp(dir=folder)) / "s.sqlite"
    display = UdpDisplay(DESCRIPTION, port=port, max_skipped_fraction=1.0, pairing_key=KEY)  # a loaded CI box may skip
    # the emulator (and its record) is shared by all examples: check only this session's streams,
    # against this session's own count of skipped frames
    n_before = len(read_record(record)["streams"])
    try:
        result = new_session(protocol, path, display, SimulatedObserver(protocol), subject="F1", realtime=False,
                             clipped="allow")  # the safety layer is what this test fuzzes
    finally:
        display.close()
    assert result.status == "complete"
    applied = read_record(record)
    assert applied["n_frames"] > 0 and applied["clamps"] == []  # the device never had to clamp
    trials = SessionLog(path).trials()
    skipped = sum(t.frames_skipped for t in trials)  # a loaded machine may skip late frames
    full = DESCRIPTION.max_traction_pa
    for stream in applied["streams"][n_before:]:
        frames = stream["values"]
        assert frames.shape[1] == DESCRIPTION.n_tractors
        violations = limit_violations(frames, DESCRIPTION.frame_rate_hz, DESCRIPTION, tolerance=1e-6)
        assert [v for v in violations if skipped == 0 or v["kind"] != "duty"] == []
        assert np.max(np.abs(frames)) <= full
        if skipped == 0:
            assert np.all(np.count_nonzero(frames, axis=0) <= math.floor(DESCRIPTION.max_duty_cycle * len(frames)))
            assert np.all(frames[-1] == 0)
    sent = sum(t.frames_sent for t in trials)
    assert sent + skipped == sum(round(s.duration_s * s.frame_rate_hz) for t in trials for s in t.stimuli)


def test_an_absurd_amplitude_is_limited_and_every_intervention_logged(emulator, tmp_path):
    """5 mm of virtual height asks for far more than full scale: the wire carries at most full
    scale, and the session log holds the safety interventions (amplitude, slew, duty) of each trial."""
    port, record, _ = emulator
    protocol = Protocol.model_validate({
        "name": "absurd", "seed": 1, "iti_s": 0, "task": {"kind": "yes_no"},
        "stimulus": {"amplitude_m": "5mm", "pitch_m": "2mm", "speed_m_per_s": "40mm/s", "duration_s": "40ms"},
        "procedure": {"method": "constant_stimuli", "parameter": "amplitude_m", "levels": ["5mm"],
                      "repeats_per_block": 2, "n_blocks": 1}})
    before = read_record(record)["n_frames"]
    display = UdpDisplay(DESCRIPTION, port=port, max_skipped_fraction=1.0, pairing_key=KEY)  # a loaded CI box may skip
    try:
        new_session(protocol, tmp_path / "s.sqlite", display, SimulatedObserver(protocol), subject="F2", realtime=False,
                    clipped="allow")
    finally:
        display.close()
    frames = np.vstack([s["values"] for s in read_record(record)["streams"]])[before:]
    peak = np.max(np.abs(frames))
    assert 0 < peak <= DESCRIPTION.max_traction_pa  # the slew and duty limits bind before full scale
    log = SessionLog(tmp_path / "s.sqlite")
    kinds = {e["payload"]["kind"] for e in log.events("safety_intervention")}
    assert {"amplitude_clip", "slew_limit", "duty_limit"} <= kinds, kinds
    assert all(t.safety_interventions > 0 for t in log.trials())

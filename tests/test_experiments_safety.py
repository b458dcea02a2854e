"""SafeDisplay: no drive gets past the limits; zeroing on errors and signals; every event reported."""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.display import Display, PlaybackReport, render_drive
from tactilab.experiments.devices.display_limits import limit_violations, limits
from tactilab.experiments.devices.safety import PlaybackInterrupted, SafeDisplay, limit_drive
from tactilab.experiments.devices.simulated_display import SimulatedDisplay


def as_grid(frames, desc):
    return np.asarray(frames, dtype=np.float32).astype(float).reshape(-1, desc.rows, desc.columns)


def assert_within_limits(frames, desc, rate=1000.0):
    """Two independent checks: data_schemas' check_commands and limit_violations, on float32."""
    wire = np.asarray(frames, dtype=np.float32).astype(float)
    desc.check_commands(as_grid(wire, desc), "traction")
    assert limit_violations(wire, rate, desc) == []
    assert np.all(wire[-1] == 0)  # every block ends at rest


def test_drive_within_limits_passes_unchanged():
    desc = DisplayDescription.stress2()
    frames = render_drive(desc, amplitude_m=2e-6, pitch_m=2.4e-3, speed_m_per_s=0.04, duration_s=0.1,
                          frame_rate_hz=1000.0).astype(np.float32).astype(float)
    applied, events = limit_drive(frames, 1000.0, desc)
    assert events == []
    np.testing.assert_array_equal(applied, frames)


def test_amplitude_clip_reports_one_event_naming_the_tractors():
    desc = DisplayDescription.braille_row()
    frames = render_drive(desc, amplitude_m=40e-6, pitch_m=4.8e-3, speed_m_per_s=0.04, duration_s=0.2,
                          frame_rate_hz=1000.0)
    events = []
    safe = SafeDisplay(SimulatedDisplay(desc), events.append)
    safe.load(frames, 1000.0)
    report = safe.play()
    assert_within_limits(safe.display.played, desc)
    clips = [e for e in events if e["kind"] == "amplitude_clip"]
    assert len(clips) == 1 and clips[0]["tractors"] == list(range(10))
    e = clips[0]
    assert abs(e["requested"]) > desc.max_traction_pa >= abs(e["applied"]) and e["limit"] == desc.max_traction_pa
    assert abs(e["requested"]) == pytest.approx(np.abs(frames).max())  # the worst sample
    assert e["n_samples"] == np.count_nonzero(np.abs(frames) > desc.max_traction_pa)
    assert e["unit"] == "Pa" and e["display_id"] == "VirtualBrailleRow" and e["n_frames"] > 0
    assert set(e) >= {"kind", "tractor", "frame", "requested", "applied", "time", "monotonic_s"}
    assert report.interventions == len(events)


def test_slew_limit_and_end_at_rest():
    desc = DisplayDescription.braille_row(max_slew_rate_per_s=100.0)  # 0.1 full scale per frame
    step = limits(desc)["step"][0]
    frames = np.full((30, 10), 0.8 * desc.max_traction_pa)  # a step from rest that never ends
    applied, events = limit_drive(frames, 1000.0, desc)
    assert_within_limits(applied, desc)
    assert {e["kind"] for e in events} == {"slew_limit", "end_at_rest"}
    assert np.max(np.abs(np.diff(applied[:, 0]))) <= step
    # Up at 0.1 full scale per frame to the requested 0.8 FS, hold, down to rest by frame 29.
    assert applied[:, 0].max() == 0.8 * desc.max_traction_pa
    assert np.count_nonzero(np.diff(applied[:, 0]) > 0) == 8 and np.all(applied[-1] == 0)


def test_duty_limit_ramps_down_within_budget():
    desc = DisplayDescription.braille_row(max_duty_cycle=0.3, max_slew_rate_per_s=250.0)
    frames = np.full((100, 10), 0.9 * desc.max_traction_pa)
    applied, events = limit_drive(frames, 1000.0, desc)
    assert_within_limits(applied, desc)
    on = np.count_nonzero(applied, axis=0)
    assert np.all(on == 30)  # the whole budget is used, not more
    assert any(e["kind"] == "duty_limit" for e in events)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    data=st.data(),
    slew=st.one_of(st.none(), st.floats(1.0, 5000.0)),
    duty=st.floats(0.05, 1.0),
    n_frames=st.integers(1, 60),
    scale=st.floats(0.0, 5.0),
)
def test_random_drives_never_exceed_limits(data, slew, duty, n_frames, scale):
    desc = DisplayDescription.braille_row(n_tractors=4, max_slew_rate_per_s=slew, max_duty_cycle=duty)
    values = data.draw(st.lists(st.floats(-1.0, 1.0), min_size=4 * n_frames, max_size=4 * n_frames))
    frames = scale * desc.max_traction_pa * np.array(values).reshape(n_frames, 4)
    applied, _ = limit_drive(frames, 1000.0, desc)
    assert_within_limits(applied, desc)


class _Scripted(Display):
    """A display whose play runs ``action`` halfway through."""

    def __init__(self, description, action):
        super().__init__(description)
        self.action, self.zeroed = action, 0

    def _play(self, frames, rate):
        for k in range(len(frames)):
            if k == len(frames) // 2:
                self.action(self)
            if self.stop_requested:
                return PlaybackReport(frames_sent=k, late=0, missing=0, acked=k, stopped=True)
        return PlaybackReport(frames_sent=len(frames), late=0, missing=0, acked=len(frames))

    def _zero(self):
        self.zeroed += 1


def _play_with(action):
    events = []
    inner = _Scripted(DisplayDescription.braille_row(), action)
    safe = SafeDisplay(inner, events.append)
    safe.load(np.zeros((10, 10)), 1000.0)
    return safe, inner, events


def test_sigint_zeroes_then_raises_keyboard_interrupt_and_restores_handler():
    # Python's own Ctrl-C handler, as an interactive run has it: a suite started with nohup or '&'
    # inherits SIGINT ignored, and the test must not depend on how it was started
    outer = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        safe, inner, events = _play_with(lambda d: os.kill(os.getpid(), signal.SIGINT))
        with pytest.raises(KeyboardInterrupt):
            safe.play()
        assert inner.zeroed == 1 and [e["kind"] for e in events] == ["zero_on_sigint"]
        assert events[0]["tractor"] is None and events[0]["applied"] == 0.0
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, outer)


def test_sigint_while_ignored_still_zeroes_and_stops_playback():
    """Started with SIGINT ignored (nohup, '&'), Ctrl-C still stops the drive and zeroes the display;
    the ignored signal raises nothing, so play() says what happened."""
    outer = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        safe, inner, events = _play_with(lambda d: os.kill(os.getpid(), signal.SIGINT))
        with pytest.raises(PlaybackInterrupted, match="playback stopped by SIGINT; display 'VirtualBrailleRow' zeroed"):
            safe.play()
        assert inner.zeroed == 1 and [e["kind"] for e in events] == ["zero_on_sigint"]
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, outer)


def test_sigterm_zeroes_and_hands_the_signal_to_the_previous_handler():
    seen = []
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: seen.append(signum))
    try:
        safe, inner, events = _play_with(lambda d: os.kill(os.getpid(), signal.SIGTERM))
        with pytest.raises(PlaybackInterrupted, match="playback stopped by SIGTERM; display 'VirtualBrailleRow' zeroed"):
            safe.play()
        assert inner.zeroed == 1 and [e["kind"] for e in events] == ["zero_on_sigterm"]
        assert seen == [signal.SIGTERM]  # re-delivered after zeroing
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_exception_during_play_zeroes_and_is_reraised():
    def fail(display):
        raise OSError("link down")

    safe, inner, events = _play_with(fail)
    with pytest.raises(OSError, match="link down"):
        safe.play()
    assert inner.zeroed == 1 and events[0]["kind"] == "zero_on_exception"
    assert "OSError: link down" in events[0]["detail"]


def test_stop_zeroes_and_reports():
    safe, inner, events = _play_with(lambda d: d.stop())
    report = safe.play()
    assert report.stopped and report.frames_sent == 5
    assert inner.zeroed == 1 and events[-1]["kind"] == "zero_on_stop" and events[-1]["frame"] == 5


def test_invalid_load_zeroes_and_raises():
    events = []
    inner = _Scripted(DisplayDescription.braille_row(), lambda d: None)
    safe = SafeDisplay(inner, events.append)
    with pytest.raises(ValueError, match="frames: must be finite"):
        safe.load(np.full((3, 10), np.nan), 1000.0)
    assert inner.zeroed == 1 and events[0]["kind"] == "zero_on_exception"


def test_constructor_rejects_non_display_and_non_callable():
    with pytest.raises(TypeError, match="display: must be a tactilab Display"):
        SafeDisplay(object(), print)
    with pytest.raises(TypeError, match="on_event: must be callable"):
        SafeDisplay(SimulatedDisplay(DisplayDescription.braille_row()), None)


def test_a_second_signal_during_zeroing_waits_until_the_display_is_zero():
    """Ctrl-C twice: the first stops playback, the second arrives while zeroing and is held
    until the display is at zero, then delivered (here to a recording handler)."""
    seen = []

    class SlowZero(_Scripted):
        def _zero(self):
            os.kill(os.getpid(), signal.SIGTERM)  # arrives in the middle of zeroing
            self.zeroed += 1

    previous = signal.signal(signal.SIGTERM, lambda signum, frame: seen.append(signum))
    try:
        events = []
        inner = SlowZero(DisplayDescription.braille_row(), lambda d: os.kill(os.getpid(), signal.SIGTERM))
        safe = SafeDisplay(inner, events.append)
        safe.load(np.zeros((10, 10)), 1000.0)
        with pytest.raises(PlaybackInterrupted, match="SIGTERM"):
            safe.play()
        assert inner.zeroed == 1 and [e["kind"] for e in events] == ["zero_on_sigterm"]
        assert seen == [signal.SIGTERM, signal.SIGTERM]  # both reached the previous handler
    finally:
        signal.signal(signal.SIGTERM, previous)

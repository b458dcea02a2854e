"""The host's end of the paired link (experiments/devices/udp_link.py): the device's clock from the
quickest round trip, the keep-alive arming again after the device's watchdog ended the link while
this host was descheduled, and the onset delay a UDP display states."""

from __future__ import annotations

import time

import numpy as np
import pytest
from udp_pairing import KEY, emulator_thread

from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices import DisplayError, SafeDisplay
from tactilab.experiments.devices.udp import UdpDisplay
from tactilab.experiments.devices.udp_link import HostLink

DESC = DisplayDescription.braille_row(n_tractors=2)


def test_the_device_clock_comes_from_the_quickest_round_trip():
    """offset = device time - midpoint of the exchange, taken from the sample with the smallest round trip."""
    link = HostLink(("127.0.0.1", 9), KEY, ack_timeout_s=0.05, retries=1, url="udp://127.0.0.1:9")
    try:
        link._sample(100, 300, 1200)  # round trip 200 ns, offset 1200 - 200 = 1000
        link._sample(1000, 1050, 2030)  # round trip 50 ns, offset 2030 - 1025 = 1005
        link._sample(5000, 5400, 9000)  # round trip 400 ns, offset 3800
        assert link.clock_offset_ns() == 1005
    finally:
        link.close()


def test_the_keep_alive_arms_again_after_a_trip_between_stimuli():
    """The host holds its link busy (a process descheduled for 3 watchdog times): the device zeroes and
    ends the link; the keep-alive finds it ended and arms again at once (the ARMED's counter shows no
    foreign frame), and the next stimulus plays on the new link."""
    port, finish, logs = emulator_thread(watchdog_s=0.3, limits=DESC)
    display = UdpDisplay(DESC, "127.0.0.1", port, pairing_key=KEY, max_skipped_fraction=1.0)
    try:
        display.zero()
        with display.link.lock:  # nothing reaches the device meanwhile
            while not any(line.startswith("watchdog:") for line in logs):
                time.sleep(0.01)
        while display.link.rearms == 0:  # the keep-alive's next rounds: `disarmed`, then ARM
            time.sleep(0.01)
        assert display.audit() == 0 and display.link.lost is None
        display.load(np.zeros((20, 2)), 1000.0)
        report = display.play()
        assert (report.acked, report.foreign) == (20, 0)
    finally:
        display.close()
        summary = finish()
    assert (summary.watchdog_trips, summary.sessions, summary.frames_applied) == (1, 2, 20)


def test_a_udp_display_states_its_onset_delay():
    display = UdpDisplay(DESC.replace(lookahead_s=0.02), port=9, pairing_key=KEY)
    try:
        assert display.onset_delay_s == pytest.approx(0.02)
        assert SafeDisplay(display, lambda e: None).onset_delay_s == pytest.approx(0.02)
    finally:
        display.close()


def test_a_device_fifo_too_small_for_the_lookahead_is_a_clear_error():
    port, finish, _ = emulator_thread(watchdog_s=1.0, limits=DESC, fifo_frames=20)
    display = UdpDisplay(DESC, "127.0.0.1", port, pairing_key=KEY)
    try:
        display.load(np.zeros((5, 2)), 1000.0)
        with pytest.raises(DisplayError, match=r"lookahead_s 0.05 s at 1000 Hz needs 52 frames in the device's FIFO, "
                                               r"which holds 20; lower the description's lookahead_s"):
            display.play()
    finally:
        display.close()
        finish()


def test_a_key_file_that_changes_while_it_is_read_is_refused(tmp_path, monkeypatch):
    import os

    from udp_pairing import key_file

    from tactilab.experiments.devices import read_pairing_key

    path = key_file(tmp_path)
    real_read = os.read
    monkeypatch.setattr(os, "read", lambda fd, n: real_read(fd, n)[:10])  # truncated between stat and read
    with pytest.raises(ValueError, match=r"pairing_key_file: .* changed while it was read; read it again"):
        read_pairing_key(path)


def test_a_link_ended_before_the_onset_starts_the_stimulus_again(monkeypatch):
    """This host is descheduled between a stimulus's opening ZERO and its first frame, long enough for
    the device's watchdog: the device answers `disarmed` before the first frame was due, so nothing of
    the stimulus was applied; the host arms again and plays the whole stimulus on the new link."""
    port, finish, logs = emulator_thread(watchdog_s=0.1, limits=DESC)
    real_check, stalls = UdpDisplay._check_device, []

    def stall_once(self, rate):
        if not stalls:  # the first stimulus only: wait (holding the link) until the device trips
            stalls.append(True)
            while not any(line.startswith("watchdog:") for line in logs):
                time.sleep(0.01)
        real_check(self, rate)

    monkeypatch.setattr(UdpDisplay, "_check_device", stall_once)
    display = UdpDisplay(DESC, "127.0.0.1", port, pairing_key=KEY, max_skipped_fraction=1.0)
    try:
        display.load(np.full((30, 2), 0.0), 1000.0)
        report = display.play()
        assert (report.acked, report.rejected, report.foreign, display.link.rearms) == (30, 0, 0, 1)
    finally:
        display.close()
        summary = finish()
    assert (summary.watchdog_trips, summary.sessions, summary.frames_applied) == (1, 2, 30)


def test_a_link_that_keeps_ending_before_the_onset_is_a_clear_error(monkeypatch):
    from tactilab.experiments.devices import udp

    port, finish, _ = emulator_thread(watchdog_s=1.0, limits=DESC)

    def ended(self, *args):
        raise udp._EndedBeforeOnset

    monkeypatch.setattr(UdpDisplay, "_stream", ended)
    display = UdpDisplay(DESC, "127.0.0.1", port, pairing_key=KEY)
    try:
        display.load(np.zeros((5, 2)), 1000.0)
        with pytest.raises(DisplayError, match=r"the device's watchdog ended the link before the stimulus began, "
                                               r"three times; this host is descheduled"):
            display.play()
    finally:
        display.close()
        finish()

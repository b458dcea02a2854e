"""Safety in real time: the device applies frames on its own tick from a FIFO at their due times,
clamps the change per tick and to full scale (recording every clamp), refuses NaN and inf; a burst
of frames from the host never becomes an output burst, even on a loaded CPU; the host sends frames
ahead of their due times, so a stall shorter than the lookahead skips nothing."""

from __future__ import annotations

import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from udp_pairing import KEY

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.emulator import LOOPBACK, emulate, read_record
from tactilab.experiments.devices.link import ARMED, FRAME, STATUS_CODE
from tactilab.experiments.devices.udp_link import HostLink, RawLink

DESC = DisplayDescription.braille_row(n_tractors=2, max_slew_rate_per_s=100.0)  # 5 kPa per 1 ms tick
FULL = DESC.max_traction_pa
STEP = DESC.max_slew_rate_per_s * FULL / DESC.frame_rate_hz
BUSY = "import time\nend = time.monotonic() + 20\nwhile time.monotonic() < end: pass\n"


@pytest.fixture
def device(tmp_path):
    stop, logs, record = threading.Event(), [], tmp_path / "rt.jsonl"
    thread = threading.Thread(target=emulate, kwargs=dict(
        port=0, watchdog_s=2.0, record=record, max_seconds=60, log=logs.append, stop=stop,
        handle_signals=False, limits=DESC, pairing_key=KEY), daemon=True)
    thread.start()
    while not logs:
        time.sleep(0.005)
    link = RawLink(int(logs[0].split(":")[2].split()[0]), KEY)
    yield link, record
    stop.set()
    thread.join(timeout=10)
    link.close()


def _acks(link, n):
    return [link.recv() for _ in range(n)]


def test_a_burst_is_applied_one_frame_per_tick_within_the_real_time_slew_under_load(device):
    """200 frames sent at once, all due at once (due time 0), each a full slew step from the last,
    while two processes load the CPU: the record shows one frame per tick (ticks never less than a
    period apart on the device's timer, never before they are due) and a change per tick never
    above the limit; nothing was clamped."""
    link, record = device
    load = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(2)]
    try:
        assert link.arm().kind == ARMED
        levels = np.minimum(np.arange(1, 201) * STEP * 0.999, FULL * 0.99)
        for level in levels:
            link.send(link.message(FRAME, [level, -level]))
        acks = _acks(link, 200)
    finally:
        for p in load:
            p.kill()
            p.wait()
    assert all(a.status == STATUS_CODE["applied"] and a.authentic for a in acks)
    rec = read_record(record)
    stream = rec["streams"][-1]
    assert len(stream["seq"]) == 200 and rec["clamps"] == []
    dt = np.diff(stream["tick_ns"]) / 1e9
    assert np.all(dt >= 1 / DESC.frame_rate_hz * (1 - 1e-6))  # ticks are never less than a period apart
    assert np.all(stream["applied_ns"] >= stream["tick_ns"])  # and a tick is never early
    rate = np.abs(np.diff(stream["values"], axis=0)).max(axis=1) / dt
    assert rate.max() <= DESC.max_slew_rate_per_s * FULL * (1 + 1e-6)


def test_the_device_clamps_to_its_limits_records_each_clamp_and_refuses_non_finite(device):
    link, record = device
    assert link.arm().kind == ARMED
    for values in ([np.nan, 0.0], [np.inf, 0.0]):
        assert link.ask(FRAME, values).status == STATUS_CODE["non_finite"]
    assert link.ask(FRAME, [1e12, -1e12]).status == STATUS_CODE["applied"]  # far beyond full scale
    rec = read_record(record)
    kinds = [(c["kind"], c["requested"], c["applied"]) for c in rec["clamps"]]
    assert kinds[0][0] == "amplitude" and abs(kinds[0][1]) == float(np.float32(1e12)) and abs(kinds[0][2]) == FULL
    assert kinds[1][0] == "slew" and abs(kinds[1][2]) == pytest.approx(STEP)
    np.testing.assert_allclose(rec["streams"][-1]["values"][-1], [STEP, -STEP], rtol=1e-6)
    assert rec["events"][0]["max_step"] == pytest.approx(STEP) and rec["events"][0]["full_scale"] == FULL


def test_cli_limits_option(tmp_path, capsys):
    from udp_pairing import key_file

    limits = DESC.save(tmp_path / "d.json")
    record = tmp_path / "r.jsonl"
    key = str(key_file(tmp_path))
    assert cli_main(["device", "emulate", "--port", "0", "--max-seconds", "0.1s", "--limits", str(limits),
                     "--record", str(record), "--pairing-key", key]) == 0
    assert "tick 1 ms" in capsys.readouterr().out and read_record(record)["events"][0]["n_tractors"] == 2
    assert cli_main(["device", "emulate", "--port", "0", "--limits", str(tmp_path / "none.json"),
                     "--pairing-key", key]) == 2
    assert "--limits: cannot read the display description" in capsys.readouterr().err


def _stall_at(monkeypatch, frame: int, seconds: float) -> None:
    """The host's process stalls for ``seconds`` before sealing its ``frame``-th FRAME (a descheduled host)."""
    calls = {"frames": 0}
    real_sealed = HostLink.sealed

    def stalling_sealed(self, kind, *args, **kwargs):
        if kind == FRAME:
            calls["frames"] += 1
            if calls["frames"] == frame:
                time.sleep(seconds)
        return real_sealed(self, kind, *args, **kwargs)

    monkeypatch.setattr(HostLink, "sealed", stalling_sealed)


def _play(port, description, frames):
    from tactilab.experiments import SafeDisplay, UdpDisplay

    safe = SafeDisplay(UdpDisplay(description, LOOPBACK, port, max_skipped_fraction=1.0, pairing_key=KEY),
                       lambda e: None)
    safe.load(frames, 1000.0)
    report = safe.play()
    safe.close()
    return report


def test_a_stall_shorter_than_the_lookahead_skips_nothing(device, monkeypatch):
    """A 20 ms stall of the host mid-stimulus, lookahead 50 ms: the frames due meanwhile were already
    in the device's FIFO; nothing is skipped, every frame is applied, bit for bit, nothing clamped."""
    link, record = device
    _stall_at(monkeypatch, 60, 0.02)  # frame 60 leaves 50 ms ahead of its due time: after the first burst
    frames = np.outer(np.sin(np.linspace(0, np.pi, 200)), [1.0, -1.0]) * FULL
    report = _play(link.sock.getpeername()[1], DESC.replace(lookahead_s=0.05), frames)
    assert (report.skipped, report.frames_sent, report.acked, report.stopped) == (0, 200, 200, False)
    rec = read_record(record)
    assert rec["clamps"] == [] and len(rec["streams"][-1]["seq"]) == 200


def test_frames_are_applied_at_their_due_times(device):
    """The emulator applies each frame at the first tick at or after its due time (never before),
    one period apart on its timer, whatever the order in which they arrived ahead of time."""
    link, record = device
    assert link.arm().kind == ARMED
    due = time.monotonic_ns() + 30_000_000 + np.arange(20) * 2_000_000  # every 2 ms, from 30 ms ahead
    for k, when in enumerate(due):
        link.send(link.message(FRAME, [float(k), 0.0], due_ns=int(when)))
    acks = _acks(link, 20)
    assert all(a.status == STATUS_CODE["applied"] and a.authentic for a in acks)
    stream = read_record(record)["streams"][-1]
    np.testing.assert_array_equal(stream["due_ns"], due)
    np.testing.assert_array_equal(stream["tick_ns"], due)  # each due 2 periods after the last: ticks at due
    assert np.all(stream["applied_ns"] >= due)  # never early
    assert all(a.device_ns >= when for a, when in zip(acks, due))  # the ACK says when, on the device's clock


def test_the_host_skips_late_frames_forward_and_never_bursts(device, monkeypatch):
    """A stall longer than the lookahead (10 ms ahead, a 30 ms stall): the frames due meanwhile are
    skipped (not sent late in a burst), the values after the stall are re-limited to one slew step
    per frame, and the device never has to clamp."""
    link, record = device
    _stall_at(monkeypatch, 30, 0.03)
    frames = np.outer(np.sin(np.linspace(0, np.pi, 200)), [1.0, -1.0]) * FULL
    report = _play(link.sock.getpeername()[1], DESC.replace(lookahead_s=0.01), frames)
    assert report.skipped >= 10 and report.frames_sent + report.skipped == 200
    rec = read_record(record)
    assert rec["clamps"] == []
    values = rec["streams"][-1]["values"]
    assert np.abs(np.diff(values, axis=0)).max() <= STEP * (1 + 1e-6)
    ticks = np.diff(rec["streams"][-1]["tick_ns"])
    assert np.all(ticks >= 1e9 / DESC.frame_rate_hz * (1 - 1e-6))  # no output burst
    with pytest.raises(ValueError, match="max_skipped_fraction: must be a number in \\[0, 1\\]"):
        from tactilab.experiments import UdpDisplay

        UdpDisplay(DESC, LOOPBACK, 9, max_skipped_fraction=2, pairing_key=KEY)

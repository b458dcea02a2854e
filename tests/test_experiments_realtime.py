"""Safety in real time: the device applies frames on its own tick from a FIFO, clamps the change
per tick and to full scale (recording every clamp), refuses NaN and inf; a burst of frames from
the host (or anyone) never becomes an output burst, even on a loaded CPU."""

from __future__ import annotations

import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.emulator import LOOPBACK, emulate, read_record
from tactilab.experiments.devices.link import ARMED, FRAME, STATUS_CODE, RawLink

DESC = DisplayDescription.braille_row(n_tractors=2, max_slew_rate_per_s=100.0)  # 5 kPa per 1 ms tick
FULL = DESC.max_traction_pa
STEP = DESC.max_slew_rate_per_s * FULL / DESC.frame_rate_hz
BUSY = "import time\nend = time.monotonic() + 20\nwhile time.monotonic() < end: pass\n"


@pytest.fixture
def device(tmp_path):
    stop, logs, record = threading.Event(), [], tmp_path / "rt.jsonl"
    thread = threading.Thread(target=emulate, kwargs=dict(
        port=0, watchdog_s=2.0, record=record, max_seconds=60, log=logs.append, stop=stop,
        handle_signals=False, limits=DESC), daemon=True)
    thread.start()
    while not logs:
        time.sleep(0.005)
    link = RawLink(int(logs[0].split(":")[2].split()[0]))
    yield link, record
    stop.set()
    thread.join(timeout=10)
    link.close()


def _acks(link, n):
    return [link.recv() for _ in range(n)]


def test_a_burst_is_applied_one_frame_per_tick_within_the_real_time_slew_under_load(device):
    """200 frames sent at once, each a full slew step from the last, while two processes load the
    CPU: the record shows one frame per tick (never less than a period apart) and a real-time
    change never above the limit; nothing was clamped."""
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
    dt = np.diff(stream["applied_ns"]) / 1e9
    assert np.all(dt >= 1 / DESC.frame_rate_hz * (1 - 1e-6))  # a tick is never early
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
    limits = DESC.save(tmp_path / "d.json")
    record = tmp_path / "r.jsonl"
    assert cli_main(["device", "emulate", "--port", "0", "--max-seconds", "0.1s", "--limits", str(limits),
                     "--record", str(record)]) == 0
    assert "tick 1 ms" in capsys.readouterr().out and read_record(record)["events"][0]["n_tractors"] == 2
    assert cli_main(["device", "emulate", "--port", "0", "--limits", str(tmp_path / "none.json")]) == 2
    assert "--limits: cannot read the display description" in capsys.readouterr().err


def test_the_host_skips_late_frames_forward_and_never_bursts(device, monkeypatch):
    """A 20 ms stall mid-stimulus: the frames due meanwhile are skipped (not sent late in a burst),
    the values after the stall are re-limited to one slew step per frame, and the device never
    has to clamp."""
    from tactilab.experiments import SafeDisplay, UdpDisplay
    from tactilab.experiments.devices import udp

    link, record = device
    port = link.sock.getpeername()[1]
    calls = {"frames": 0}
    real_encode = udp.encode

    def stalling_encode(kind, *args, **kwargs):
        if kind == FRAME:
            calls["frames"] += 1
            if calls["frames"] == 30:
                time.sleep(0.02)
        return real_encode(kind, *args, **kwargs)

    monkeypatch.setattr(udp, "encode", stalling_encode)
    frames = np.outer(np.sin(np.linspace(0, np.pi, 200)), [1.0, -1.0]) * FULL
    safe = SafeDisplay(UdpDisplay(DESC, LOOPBACK, port, max_skipped_fraction=1.0), lambda e: None)
    safe.load(frames, 1000.0)
    report = safe.play()
    safe.close()
    assert report.skipped >= 10 and report.frames_sent + report.skipped == 200
    # no burst: a single short interval happens when the host is preempted between its lateness
    # check and the send (a loaded machine), but never two in a row (three frames within half a period)
    short = report.send_intervals_s < 0.25e-3
    assert not np.any(short[1:] & short[:-1]), report.send_intervals_s
    rec = read_record(record)
    assert rec["clamps"] == []
    values = rec["streams"][-1]["values"]
    assert np.abs(np.diff(values, axis=0)).max() <= STEP * (1 + 1e-6)
    with pytest.raises(ValueError, match="max_skipped_fraction: must be a number in \\[0, 1\\]"):
        UdpDisplay(DESC, LOOPBACK, port, max_skipped_fraction=2)

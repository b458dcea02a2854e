"""Every stop is a safe stop: SIGHUP and SIGQUIT to the real command line, mid-stimulus, zero the
display (the emulator records the host's ZERO, long before its own watchdog) and log the stop."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest
from udp_pairing import key_file, paired_description

from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments import SessionLog

PROTOCOL = """
name = "sig"
seed = 2
iti_s = 0
[task]
kind = "yes_no"
[stimulus]
amplitude_m = "2um"
pitch_m = "2mm"
speed_m_per_s = "40mm/s"
duration_s = "3s"
ramp_s = "5ms"
[procedure]
method = "constant_stimuli"
parameter = "amplitude_m"
levels = ["1um"]
repeats_per_block = 2
n_blocks = 1
"""


def _entries(record):
    try:
        return [json.loads(line) for line in record.read_text().splitlines() if line.strip()]
    except (FileNotFoundError, json.JSONDecodeError):
        return []


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGHUP, signal.SIGQUIT])
def test_sighup_and_sigquit_mid_stimulus_zero_the_display_and_log_the_stop(tmp_path, signum):
    record = tmp_path / "emu.jsonl"
    emulator = subprocess.Popen([sys.executable, "-m", "tactilab.cli.main", "device", "emulate", "--port", "0",
                                 "--record", str(record), "--watchdog", "10s", "--max-seconds", "60s",
                                 "--pairing-key", str(key_file(tmp_path))],
                                stdout=subprocess.PIPE, text=True)
    try:
        port = int(emulator.stdout.readline().split(":")[2].split()[0])
        toml = tmp_path / "p.toml"
        toml.write_text(PROTOCOL)
        runner = subprocess.Popen([sys.executable, "-m", "tactilab.cli.main", "experiment", "run", str(toml),
                                   "--subject", "S01", "--responses", "simulated", "--quiet", "--out", str(tmp_path),
                                   "--display", f"udp://127.0.0.1:{port}", "--max-skipped", "1",
                                   "--device", str(paired_description(tmp_path, DisplayDescription.braille_row()))],
                                  stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 30
        while sum(e["type"] == "frame" for e in _entries(record)) < 50:
            assert time.monotonic() < deadline and runner.poll() is None, runner.communicate()
            time.sleep(0.02)
        runner.send_signal(signum)
        out, err = runner.communicate(timeout=30)
    finally:
        emulator.send_signal(signal.SIGTERM)
        emulator.communicate(timeout=30)
    assert runner.returncode == 130, (out, err)
    entries = _entries(record)
    last_frame = max(i for i, e in enumerate(entries) if e["type"] == "frame")
    after = [e["type"] for e in entries[last_frame + 1:]]
    assert "zero" in after and "watchdog" not in after, after
    assert sum(e["type"] == "frame" for e in entries) < 2900, "the stimulus was cut short"
    log = SessionLog(tmp_path / "sub-S01_ses-01_task-sig.sqlite")
    try:
        events = log.events()
    finally:
        log.close()
    name = signal.Signals(signum).name
    assert events[-1]["kind"] == "session_stopped" and name in events[-1]["payload"]["reason"]
    assert any(e["kind"] == "safety_intervention" and e["payload"]["kind"] == f"zero_on_{name.lower()}"
               for e in events)

"""Frame rate and jitter of the UDP display driver on loopback, and the emulator's watchdog delay.

Starts ``tactilab device emulate`` as a separate process on 127.0.0.1, streams a STReSS2 drive
(60 tractors, float32 frames of 276 bytes: frame format version 2, a 16-byte HMAC-SHA256 tag, one
ARM / ARMED key exchange per stimulus) through ``SafeDisplay(UdpDisplay(...))`` and prints
one table: inter-frame send interval (mean, p50, p99, max, standard deviation), frames the host
sent late (> half a period behind schedule), frames the device never acknowledged, ACK
round-trip p50/p99, frames sent and skipped (a frame due more than half a period ago is skipped,
never sent late in a burst; the measurement allows any fraction), and the emulator's own
late/missing counts. The baseline is the same driver
pacing with ``select`` sleeps only (``busy_wait_s = 0``); "ratio" is the p99 jitter
(|interval - period|) of the baseline over that of each row (> 1: better than the baseline).
The rows are the default busy-wait of 1 ms, 0.2 ms, and the baseline.

It also times the MAC: encoding and tagging one 60-tractor FRAME, and decoding and verifying it,
in microseconds (median of many).

Then it kills (SIGKILL) a host process mid-stimulus and reports how long after the last frame
the emulator zeroed its outputs (watchdog 50 ms).

    python benchmarks/bench_display_udp.py [--frames 3000] [--rate 1000] [--no-kill]
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.display import render_drive
from tactilab.experiments.devices.emulator import read_record
from tactilab.experiments.devices.link import FRAME, decode, encode
from tactilab.experiments.devices.safety import SafeDisplay
from tactilab.experiments.devices.udp import UdpDisplay

EMULATOR = [sys.executable, "-m", "tactilab.cli.main", "device", "emulate", "--port", "0"]

HOST = """
import sys
from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.display import render_drive
from tactilab.experiments.devices.safety import SafeDisplay
from tactilab.experiments.devices.udp import UdpDisplay
desc = DisplayDescription.stress2()
safe = SafeDisplay(UdpDisplay(desc, "127.0.0.1", int(sys.argv[1])), lambda e: None)
safe.load(render_drive(desc, amplitude_m=10e-6, pitch_m=2.4e-3, speed_m_per_s=0.04, duration_s=30.0,
                       frame_rate_hz=1000.0), 1000.0)
print("playing", flush=True)
safe.play()
"""


def start_emulator(record: Path, watchdog: str) -> tuple[subprocess.Popen, int]:
    proc = subprocess.Popen([*EMULATOR, "--record", str(record), "--watchdog", watchdog, "--max-seconds", "300s"],
                            stdout=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    return proc, int(line.split(":")[2].split()[0])


def stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=60)


def stream(port: int, n_frames: int, rate: float, busy_wait_s: float) -> dict:
    desc = DisplayDescription.stress2()
    frames = render_drive(desc, amplitude_m=10e-6, pitch_m=2.4e-3, speed_m_per_s=0.04,
                          duration_s=n_frames / rate, frame_rate_hz=rate)
    # max_skipped_fraction 1: measure the pacing of the whole stream (a trial would abort past 1 %)
    safe = SafeDisplay(UdpDisplay(desc, "127.0.0.1", port, busy_wait_s=busy_wait_s, max_skipped_fraction=1.0),
                       lambda e: None)
    safe.load(frames, rate)
    report = safe.play()
    safe.close()
    iv = report.send_intervals_s * 1e3
    jitter = np.abs(iv - 1e3 / rate)
    rtt = report.ack_rtt_s * 1e3
    return {"n": report.frames_sent, "skipped": report.skipped, "rate": (report.frames_sent - 1) / report.duration_s,
            "mean": iv.mean(), "p50": np.median(iv), "p99": np.percentile(iv, 99), "max": iv.max(),
            "std": iv.std(), "jit99": np.percentile(jitter, 99), "late": report.late,
            "missing": report.missing, "rtt50": np.median(rtt), "rtt99": np.percentile(rtt, 99)}


def kill_test(folder: Path) -> tuple[float, float]:
    record = folder / "kill.jsonl"
    proc, port = start_emulator(record, "50ms")
    host = subprocess.Popen([sys.executable, "-c", HOST, str(port)], stdout=subprocess.PIPE, text=True)
    host.stdout.readline()
    while read_record(record)["n_frames"] < 300:
        time.sleep(0.02)
    os.kill(host.pid, signal.SIGKILL)
    host.wait()
    time.sleep(0.3)
    stop(proc)
    trip = [e for e in read_record(record)["events"] if e["type"] == "watchdog"][0]
    return (trip["t_ns"] - trip["last_valid_ns"]) / 1e6, trip["late_by_ns"] / 1e6


def mac_cost(repeats: int = 20000) -> tuple[float, float, int]:
    """Median µs to encode+tag and to decode+verify one 60-tractor FRAME, and its size in bytes."""
    key, nonce = bytes(range(32)), bytes(range(16))
    values = np.linspace(-1.0, 1.0, 60) * 1e3
    enc, dec = [], []
    for seq in range(repeats):
        t0 = time.perf_counter_ns()
        data = encode(FRAME, seq, t0, values, key=key, nonce=nonce)
        t1 = time.perf_counter_ns()
        assert decode(data, key=key, nonce=nonce).authentic
        dec.append(time.perf_counter_ns() - t1)
        enc.append(t1 - t0)
    return float(np.median(enc)) / 1e3, float(np.median(dec)) / 1e3, len(data)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=3000, help="frames per run (count)")
    parser.add_argument("--rate", type=float, default=1000.0, help="frame rate, Hz")
    parser.add_argument("--no-kill", action="store_true", help="skip the host-killed watchdog measurement")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        record = folder / "stream.jsonl"
        proc, port = start_emulator(record, "1s")
        try:
            rows = {"busy-wait 1 ms": stream(port, args.frames, args.rate, 1e-3),
                    "busy-wait 0.2 ms": stream(port, args.frames, args.rate, 2e-4),
                    "sleep only (baseline)": stream(port, args.frames, args.rate, 0.0)}
        finally:
            stop(proc)
        summary = read_record(record)["summary"]
        print(f"UDP display driver on loopback: {args.frames} frames of 60 tractors at {args.rate:g} Hz, "
              f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}")
        head = (f"{'pacing':<26}{'rate Hz':>9}{'mean ms':>9}{'p50 ms':>8}{'p99 ms':>8}{'max ms':>8}"
                f"{'std ms':>8}{'sent':>6}{'skipped':>8}{'late':>6}{'missing':>8}{'rtt50 ms':>9}{'rtt99 ms':>9}"
                f"{'ratio':>7}")
        print(head)
        print("-" * len(head))
        base = rows["sleep only (baseline)"]["jit99"]
        for name, r in rows.items():
            print(f"{name:<26}{r['rate']:>9.1f}{r['mean']:>9.4f}{r['p50']:>8.4f}{r['p99']:>8.4f}{r['max']:>8.3f}"
                  f"{r['std']:>8.4f}{r['n']:>6d}{r['skipped']:>8d}{r['late']:>6d}{r['missing']:>8d}{r['rtt50']:>9.3f}{r['rtt99']:>9.3f}"
                  f"{base / max(r['jit99'], 1e-9):>7.2f}")
        print(f"emulator (all runs): frames applied {summary['frames_applied']}, late (> 1 ms transit) "
              f"{summary['late']}, missing {summary['missing']}, stale {summary['stale']}, "
              f"rejected {summary['rejected']}, link sessions {summary['sessions']}, foreign {summary['foreign']}")
        enc_us, dec_us, size = mac_cost()
        print(f"MAC (HMAC-SHA256, 16-byte tag): encode+tag {enc_us:.1f} us, decode+verify {dec_us:.1f} us "
              f"per {size}-byte FRAME (median)")
        if not args.no_kill:
            delay, late_by = kill_test(folder)
            print(f"host killed (SIGKILL) mid-stimulus: emulator zeroed {delay:.2f} ms after the last frame "
                  f"(watchdog 50 ms; {late_by:.2f} ms past its deadline)")


if __name__ == "__main__":
    main()

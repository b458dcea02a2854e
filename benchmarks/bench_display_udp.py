"""Frame timing of the UDP display driver on loopback, the MAC's cost, and the emulator's watchdog delay.

Starts ``tactilab device emulate`` as a separate process on 127.0.0.1 with a pairing key,
streams a STReSS2 drive (60 tractors, float32 frames of 284 bytes: frame format version 3, a
due time and a 16-byte HMAC-SHA256 tag, one armed link per run) through
``SafeDisplay(UdpDisplay(...))`` and prints one table: inter-frame send interval (mean, p50,
p99, max, standard deviation), frames applied more than half a period after their due time
(late, from the device's ACKs), frames never acknowledged, the acknowledgement delay after the
due time (p50/p99), frames sent and skipped (a frame the host cannot send before half a period
after its due time is skipped, never sent late in a burst; the measurement allows any
fraction), and the emulator's own counts. The rows: the default lookahead of 50 ms (frames go
into the device's FIFO 50 ms ahead of their due times) and a lookahead of 0 (each frame sent at
its due time, as frame format 2 did).

It also times the MAC: encoding and tagging one 60-tractor FRAME, and decoding and verifying it,
in microseconds (median of many).

Then it kills (SIGKILL) a host process mid-stimulus and reports how long after the host's last
message the emulator zeroed its outputs (watchdog 50 ms, lookahead 50 ms: bound 100 ms).
``benchmarks/bench_udp_jitter.py`` measures the same under heavy CPU load.

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
from tactilab.experiments.devices import create_pairing_key
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
desc = DisplayDescription.load(sys.argv[2])
safe = SafeDisplay(UdpDisplay(desc, "127.0.0.1", int(sys.argv[1]), max_skipped_fraction=1.0), lambda e: None)
safe.load(render_drive(desc, amplitude_m=10e-6, pitch_m=2.4e-3, speed_m_per_s=0.04, duration_s=30.0,
                       frame_rate_hz=1000.0), 1000.0)
print("playing", flush=True)
safe.play()
"""


def paired_stress2(folder: Path, **overrides) -> Path:
    """A STReSS2 description in ``folder`` naming a fresh pairing key there (``display.key``)."""
    if not (folder / "display.key").exists():
        create_pairing_key(folder / "display.key")
    path = folder / "display.json"
    DisplayDescription.stress2(pairing_key_file="display.key", **overrides).save(path)
    return path


def start_emulator(record: Path, watchdog: str, description: Path,
                   niceness: int | None = None) -> tuple[subprocess.Popen, int]:
    """``tactilab device emulate`` with the description's limits and pairing key; (process, port).

    ``niceness``: the emulator's scheduling priority (``os.setpriority``; negative needs root), or None
    to inherit this process's."""
    def priority() -> None:
        if niceness is not None:
            os.setpriority(os.PRIO_PROCESS, 0, niceness)

    proc = subprocess.Popen([*EMULATOR, "--record", str(record), "--watchdog", watchdog, "--max-seconds", "3000s",
                             "--pairing-key", str(description.parent / "display.key"), "--limits", str(description)],
                            stdout=subprocess.PIPE, text=True, preexec_fn=priority)
    line = proc.stdout.readline()
    return proc, int(line.split(":")[2].split()[0])


def stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=60)


def stream(port: int, n_frames: int, rate: float, description: Path, lookahead_s: float) -> dict:
    desc = DisplayDescription.load(description).replace(lookahead_s=lookahead_s)
    frames = render_drive(desc, amplitude_m=10e-6, pitch_m=2.4e-3, speed_m_per_s=0.04,
                          duration_s=n_frames / rate, frame_rate_hz=rate)
    # max_skipped_fraction 1: measure the pacing of the whole stream (a trial would abort past 1 %)
    safe = SafeDisplay(UdpDisplay(desc, "127.0.0.1", port, max_skipped_fraction=1.0), lambda e: None)
    safe.load(frames, rate)
    report = safe.play()
    safe.close()
    iv = report.send_intervals_s * 1e3
    jitter = np.abs(iv - 1e3 / rate)
    rtt = report.ack_rtt_s * 1e3
    return {"n": report.frames_sent, "skipped": report.skipped,
            "mean": iv.mean(), "p50": np.median(iv), "p99": np.percentile(iv, 99), "max": iv.max(),
            "std": iv.std(), "jit99": np.percentile(jitter, 99), "late": report.late,
            "missing": report.missing, "rtt50": np.median(rtt), "rtt99": np.percentile(rtt, 99)}


def kill_test(folder: Path, description: Path) -> tuple[float, float, float]:
    """Kill a streaming host; (ms from its last message to the zeroing, ms past the deadline, ms from the last
    message to the last frame's due time)."""
    record = folder / "kill.jsonl"
    proc, port = start_emulator(record, "50ms", description)
    host = subprocess.Popen([sys.executable, "-c", HOST, str(port), str(description)], stdout=subprocess.PIPE,
                            text=True)
    host.stdout.readline()
    while read_record(record)["n_frames"] < 300:
        time.sleep(0.02)
    os.kill(host.pid, signal.SIGKILL)
    host.wait()
    time.sleep(0.3)
    stop(proc)
    trip = [e for e in read_record(record)["events"] if e["type"] == "watchdog"][0]
    return ((trip["t_ns"] - trip["last_valid_ns"]) / 1e6, trip["late_by_ns"] / 1e6,
            (trip["last_due_ns"] - trip["last_valid_ns"]) / 1e6)


def mac_cost(repeats: int = 20000) -> tuple[float, float, int]:
    """Median µs to encode+tag and to decode+verify one 60-tractor FRAME, and its size in bytes."""
    key = bytes(range(32))
    values = np.linspace(-1.0, 1.0, 60) * 1e3
    enc, dec = [], []
    for seq in range(repeats):
        t0 = time.perf_counter_ns()
        data = encode(FRAME, seq, t0, values, key=key, due_ns=t0)
        t1 = time.perf_counter_ns()
        assert decode(data, key=key).authentic
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
        description = paired_stress2(folder)
        record = folder / "stream.jsonl"
        proc, port = start_emulator(record, "1s", description)
        try:
            rows = {"lookahead 50 ms": stream(port, args.frames, args.rate, description, 0.05),
                    "lookahead 0 (baseline)": stream(port, args.frames, args.rate, description, 0.0)}
        finally:
            stop(proc)
        summary = read_record(record)["summary"]
        print(f"UDP display driver on loopback: {args.frames} frames of 60 tractors at {args.rate:g} Hz, "
              f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}")
        head = (f"{'host':<24}{'mean ms':>9}{'p50 ms':>8}{'p99 ms':>8}{'max ms':>8}{'std ms':>8}{'sent':>6}"
                f"{'skipped':>8}{'late':>6}{'missing':>8}{'ack50 ms':>9}{'ack99 ms':>9}")
        print(head)
        print("-" * len(head))
        for name, r in rows.items():
            print(f"{name:<24}{r['mean']:>9.4f}{r['p50']:>8.4f}{r['p99']:>8.4f}{r['max']:>8.3f}{r['std']:>8.4f}"
                  f"{r['n']:>6d}{r['skipped']:>8d}{r['late']:>6d}{r['missing']:>8d}{r['rtt50']:>9.3f}"
                  f"{r['rtt99']:>9.3f}")
        print(f"emulator (all runs): frames applied {summary['frames_applied']}, late (> 1 ms after due) "
              f"{summary['late']}, missing {summary['missing']}, stale {summary['stale']}, "
              f"rejected {summary['rejected']}, link sessions {summary['sessions']}, foreign {summary['foreign']}")
        enc_us, dec_us, size = mac_cost()
        print(f"MAC (HMAC-SHA256, 16-byte tag): encode+tag {enc_us:.1f} us, decode+verify {dec_us:.1f} us "
              f"per {size}-byte FRAME (median)")
        if not args.no_kill:
            delay, late_by, ahead = kill_test(folder, description)
            print(f"host killed (SIGKILL) mid-stimulus: emulator zeroed {delay:.2f} ms after the host's last message "
                  f"(its last frame was due {ahead:.2f} ms after it; bound lookahead 50 ms + watchdog 50 ms; "
                  f"{late_by:.2f} ms past its deadline)")


if __name__ == "__main__":
    main()

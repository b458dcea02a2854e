"""Jitter-proof playback under heavy CPU load: a real session over UDP with 8 CPU-bound processes.

Starts 8 CPU-bound processes (``while True: pass``) on this machine, the device emulator
(``tactilab device emulate`` with a pairing key, the display's limits, watchdog 50 ms) and a
real session from the command line (``tactilab experiment run ... --display udp://...
--max-skipped 0.01``, a 2IFC protocol of 100 trials: 200 stimuli of 100 ms at 1 kHz on a
STReSS2 description, 200 ms inter-trial intervals, 50 ms gaps, simulated responses). It prints
one table: frames sent, skipped, applied late (from the device's ACKs) and never acknowledged,
the display faults the session logged, the link sessions and watchdog trips the emulator saw,
and the exit status; one row per lookahead (``--lookahead-ms``: the description's default 50 ms,
and 200 ms) and one with a lookahead of 0 (each frame sent at its due time, as frame format 2
did; it stops at its first display fault). Rows print as they finish.

The emulator stands for the device, whose own processor the host's load does not slow: it runs at
``--device-nice`` (default -10, root only; otherwise at 0, which it says), while the session and the
busy processes run at nice 0, so the load lands on the host, as the benchmark means it to.

Then, under the same load, it kills (SIGKILL) a host streaming a long stimulus, three times per
lookahead, and reports how long after the host's last message the emulator zeroed its outputs:
the stated bound is lookahead + watchdog, and the benchmark's criterion that bound plus 20 ms.

    python benchmarks/bench_udp_jitter.py [--trials 100] [--load 8] [--kills 3] [--lookahead-ms 50 200]
                                          [--no-baseline]

It takes a few minutes; say the machine's load (printed) with its figures.
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

from bench_display_udp import HOST, paired_stress2, start_emulator, stop

from tactilab.experiments.devices.emulator import read_record
from tactilab.experiments.session import SessionLog

CLI = [sys.executable, "-m", "tactilab.cli.main"]
BUSY = "while True: pass\n"
PROTOCOL = """name = "jitter"
seed = 7
iti_s = "200ms"
[task]
kind = "2ifc"
interval_gap_s = "50ms"
[stimulus]
amplitude_m = "3um"
pitch_m = "2.4mm"
speed_m_per_s = "40mm/s"
duration_s = "100ms"
ramp_s = "10ms"
[procedure]
method = "constant_stimuli"
parameter = "amplitude_m"
levels = ["1um", "2um", "3um", "4um"]
repeats_per_block = REPEATS
n_blocks = 1
"""
WATCHDOG_S = 0.05
#: the emulator's niceness (``--device-nice``): it stands for the device's own processor, which the
#: host's load does not slow; set by main()
DEVICE_NICE: list[int | None] = [None]


def session_row(folder: Path, lookahead_s: float, trials: int) -> dict:
    """One command-line session against a fresh emulator; the counts of the table's row."""
    run = folder / f"lookahead-{lookahead_s * 1e3:g}ms"
    run.mkdir()
    description = paired_stress2(run, lookahead_s=lookahead_s)
    protocol = run / "p.toml"
    protocol.write_text(PROTOCOL.replace("REPEATS", str(max(1, trials // 4))))
    record = run / "emulator.jsonl"
    proc, port = start_emulator(record, f"{WATCHDOG_S * 1e3:g}ms", description, DEVICE_NICE[0])
    started = time.monotonic()
    try:
        result = subprocess.run([*CLI, "experiment", "run", str(protocol), "--subject", "S01", "--responses",
                                 "simulated", "--quiet", "--out", str(run / "out"), "--device", str(description),
                                 "--display", f"udp://127.0.0.1:{port}", "--max-skipped", "0.01"],
                                capture_output=True, text=True, timeout=3600)
    finally:
        stop(proc)
    wall = time.monotonic() - started
    log = SessionLog(next((run / "out").glob("*.sqlite")))
    try:
        done, faults = log.trials(), log.events("display_fault")
    finally:
        log.close()
    summary = read_record(record)["summary"]
    faulted = [f["payload"] for f in faults]  # the interval that faulted counts too
    return {"stimuli": sum(len(t.stimuli) for t in done) + len(faulted), "trials": len(done),
            "sent": sum(t.frames_sent for t in done) + sum(f.get("frames_sent", 0) for f in faulted),
            "skipped": sum(t.frames_skipped for t in done) + sum(f.get("skipped", 0) for f in faulted),
            "late": sum(t.frames_late for t in done), "missing": sum(t.frames_missing for t in done),
            "faults": len(faults), "fault": faults[0]["payload"]["reason"][:70] if faults else "",
            "sessions": summary["sessions"], "trips": summary["watchdog_trips"], "clamps": summary["clamps"],
            "exit": result.returncode, "wall": wall}


def kill_once(folder: Path, index: int, lookahead_s: float) -> dict:
    """Kill a streaming host mid-stimulus; the emulator's watchdog entry, in ms (``ended``: the host's
    stream had ended by itself before the kill, a display fault under the load)."""
    run = folder / f"kill-{index}-{lookahead_s * 1e3:g}ms"
    run.mkdir()
    description = paired_stress2(run, lookahead_s=lookahead_s)
    record = run / "kill.jsonl"
    proc, port = start_emulator(record, f"{WATCHDOG_S * 1e3:g}ms", description, DEVICE_NICE[0])
    host = subprocess.Popen([sys.executable, "-c", HOST, str(port), str(description)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    ended = ""
    try:
        host.stdout.readline()
        while _frames(record) < 500 and host.poll() is None:
            time.sleep(0.05)
        if host.poll() is None:
            os.kill(host.pid, signal.SIGKILL)
        else:
            ended = host.stderr.read().strip().splitlines()[-1][-90:]
        host.wait()
        while not any(e["type"] == "watchdog" for e in _events(record)):
            time.sleep(0.05)
    finally:
        if host.poll() is None:
            host.kill()
        stop(proc)
    trip = next(e for e in read_record(record)["events"] if e["type"] == "watchdog")
    return {"zeroed": (trip["t_ns"] - trip["last_valid_ns"]) / 1e6, "lookahead": lookahead_s * 1e3,
            "ahead": (trip["last_due_ns"] - trip["last_valid_ns"]) / 1e6, "late_by": trip["late_by_ns"] / 1e6,
            "ended": ended}


def _frames(record: Path) -> int:
    try:
        return read_record(record)["n_frames"]
    except (OSError, ValueError):  # not written yet, or a torn last line
        return 0


def _events(record: Path) -> list:
    try:
        return read_record(record)["events"]
    except (OSError, ValueError):
        return []


def print_row(name: str, r: dict) -> None:
    print(f"{name:<24}{r['stimuli']:>8d}{r['sent']:>8d}{r['skipped']:>8d}{r['late']:>6d}{r['missing']:>8d}"
          f"{r['faults']:>7d}{r['sessions']:>6d}{r['trips']:>6d}{r['clamps']:>7d}{r['exit']:>5d}{r['wall']:>8.1f}"
          + (f"  first fault: {r['fault']}" if r["fault"] else ""), flush=True)


def print_kill(i: int, k: dict) -> None:
    bound = k["lookahead"] + WATCHDOG_S * 1e3
    verdict = "within" if k["zeroed"] <= bound + 20 else "OUTSIDE"
    print(f"host killed (SIGKILL) #{i}, lookahead {k['lookahead']:g} ms: zeroed {k['zeroed']:.2f} ms after its last "
          f"message (last frame due {k['ahead']:.2f} ms after it; {k['late_by']:.2f} ms past the deadline); bound "
          f"{bound:g} ms: {verdict} bound + 20 ms"
          + (f"; the host's stream had already ended: {k['ended']}" if k["ended"] else ""), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=100, help="2IFC trials per session (count; 2 stimuli each)")
    parser.add_argument("--load", type=int, default=8, help="CPU-bound processes started (count)")
    parser.add_argument("--kills", type=int, default=3, help="hosts killed mid-stimulus per lookahead (count)")
    parser.add_argument("--lookahead-ms", type=float, nargs="+", default=[50.0, 200.0],
                        help="lookaheads of the rows, ms (default 50, the description's default, and 200)")
    parser.add_argument("--no-baseline", action="store_true", help="skip the lookahead-0 session")
    parser.add_argument("--device-nice", type=int, default=-10,
                        help="niceness of the emulator, which stands for the device's own processor (default -10: "
                             "the busy processes load the host, not the stand-in device; negative needs root, "
                             "else 0 is used and said)")
    args = parser.parse_args()
    DEVICE_NICE[0] = args.device_nice
    if args.device_nice < 0:
        lower = f"import os; os.setpriority(os.PRIO_PROCESS, 0, {args.device_nice})"
        probe = subprocess.run([sys.executable, "-c", lower], capture_output=True)  # lowering niceness needs root
        if probe.returncode != 0:
            print(f"--device-nice {args.device_nice}: not allowed here (needs root); the emulator runs at nice 0, "
                  "sharing the host's CPUs with the load", flush=True)
            DEVICE_NICE[0] = None
    before = os.getloadavg()[0]
    load = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(args.load)]
    print(f"UDP session under load: {args.load} CPU-bound processes on {os.cpu_count()} CPUs (load average "
          f"{before:.2f} before they started); STReSS2 (60 tractors) at 1 kHz, {args.trials} 2IFC trials of "
          f"2 x 100 ms, --max-skipped 0.01, watchdog {WATCHDOG_S * 1e3:g} ms; the emulator (the device) at nice "
          f"{DEVICE_NICE[0] if DEVICE_NICE[0] is not None else 0}, the host session and the load at nice 0", flush=True)
    head = (f"{'host':<24}{'stimuli':>8}{'sent':>8}{'skipped':>8}{'late':>6}{'missing':>8}{'faults':>7}"
            f"{'links':>6}{'trips':>6}{'clamps':>7}{'exit':>5}{'wall s':>8}")
    print(head)
    print("-" * len(head), flush=True)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            lookaheads = [ms / 1e3 for ms in args.lookahead_ms] + ([] if args.no_baseline else [0.0])
            for lookahead in lookaheads:
                name = f"lookahead {lookahead * 1e3:g} ms" + (" (baseline)" if lookahead == 0 else "")
                print_row(name, session_row(folder, lookahead, args.trials))
            for lookahead in lookaheads[:len(args.lookahead_ms)]:
                for i in range(args.kills):
                    print_kill(i + 1, kill_once(folder, i, lookahead))
            print(f"load average at the end: {os.getloadavg()[0]:.2f}", flush=True)
    finally:
        for process in load:
            process.kill()
            process.wait()


if __name__ == "__main__":
    main()

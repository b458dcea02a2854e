"""``tactilab device emulate``: a display emulator on loopback for the UDP driver."""

from __future__ import annotations

import argparse
import functools
import json
import sys
from dataclasses import asdict


NAME = "device"
HELP = "tactile display devices: create a pairing key, run an emulator of the UDP frame protocol on 127.0.0.1"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="device_command", metavar="ACTION", required=True)
    emu = sub.add_parser(
        "emulate",
        help="acknowledge frames on udp://127.0.0.1:PORT, count late/missing ones, record them, "
             "zero the outputs when frames stop (watchdog)",
        description="Emulate a tactile display on loopback (127.0.0.1 only); see docs/udp-frame-format.md.",
    )
    emu.add_argument("--pairing-key", metavar="FILE", default=None,
                     help="required: the 32-byte pairing key its hosts hold (the file the display description's "
                          "pairing_key_file names; owner-only permissions, e.g. chmod 600); only a host with this key "
                          "can arm it")
    emu.add_argument("--port", type=int, required=True,
                     help="UDP port on 127.0.0.1 (0: any free port, printed at start)")
    emu.add_argument("--watchdog", default="50ms",
                     help="zero the outputs when no frame arrived for this long (time, e.g. 50ms; default 50ms)")
    emu.add_argument("--record", metavar="FILE", default=None,
                     help="write every message and event to FILE (JSON lines; values in the display's units, Pa or m)")
    emu.add_argument("--max-seconds", default="60s",
                     help="stop after this long (time with a unit, e.g. 30s or 500ms; default 60s); SIGTERM also stops it")
    emu.add_argument("--tractors", type=int, default=None,
                     help="expected values per frame (count); default: the count of the first frame")
    emu.add_argument("--limits", metavar="FILE", default=None,
                     help="display description JSON: the device ticks at its frame rate (Hz) and clamps every applied "
                          "frame to its full scale (Pa or m) and slew limit (full scale per s), recording each clamp")
    emu.add_argument("--late-after", default="1ms",
                     help="a frame applied more than this after its due time is late (time; default 1ms)")
    emu.add_argument("--json", action="store_true",
                     help="print one JSON object summarising the run on stdout at the end (counts; duration in s); "
                          "the event lines, 'listening on ...' first, go to stderr")

    pair = sub.add_parser("pair", help="create a pairing key file: 32 random bytes, readable by its owner only",
                          description="Create a pairing key for a UDP display (docs/udp-frame-format.md): name it in "
                                      "the display description's pairing_key_file and give the same file to the "
                                      "device (`tactilab device emulate --pairing-key FILE`). An existing file is "
                                      "never overwritten.")
    pair.add_argument("path", help="the key file to create (mode 600)")


#: library parameter -> the flag that sets it
_FLAGS = {"port": "--port", "watchdog_s": "--watchdog", "max_seconds": "--max-seconds",
          "late_after_s": "--late-after", "n_tractors": "--tractors", "limits": "--limits"}


def _time_option(text: str, flag: str, example: str) -> float:
    """A time option in s, > 0 and within the emulator's clock; the fix is a time WITH a unit
    (the library's own messages speak of seconds to Python callers)."""
    from tactilab.core import rules
    from tactilab.data_schemas.units import to_si
    from tactilab.experiments.devices import MAX_SECONDS

    value = rules.positive(to_si(text, "time", name=flag), flag, "s", fix=f"give a time with a unit, e.g. {example}")
    if value > MAX_SECONDS:
        raise ValueError(f"{flag}: must be at most {MAX_SECONDS:g} s (about 4 months), got {text!r}; give e.g. "
                         f"{example} (restart the emulator for longer runs)")
    return value


def run(args: argparse.Namespace) -> int:
    from tactilab.experiments.devices import create_pairing_key, emulate, read_pairing_key

    if args.device_command == "pair":
        path = create_pairing_key(args.path)
        print(f"pairing key written to {path} (32 random bytes, mode 600); name it in the display description "
              "(\"pairing_key_file\") and give it to the device")
        return 0
    watchdog = _time_option(args.watchdog, "--watchdog", "50ms")
    max_seconds = _time_option(args.max_seconds, "--max-seconds", "60s")
    late_after = _time_option(args.late_after, "--late-after", "1ms")
    if args.pairing_key is None:
        raise ValueError("--pairing-key: required; the emulator holds the pairing key its hosts hold (frame format 3): "
                         "create one with `tactilab device pair FILE`, name it in the display description's "
                         "pairing_key_file and give it here")
    key = read_pairing_key(args.pairing_key, "--pairing-key")
    log = functools.partial(print, flush=True, file=sys.stderr if args.json else sys.stdout)
    try:
        summary = emulate(args.port, watchdog_s=watchdog, record=args.record, max_seconds=max_seconds,
                          n_tractors=args.tractors, late_after_s=late_after, log=log, limits=args.limits,
                          pairing_key=key)
    except ValueError as exc:
        text = str(exc)
        for parameter, flag in _FLAGS.items():
            if text.startswith(parameter + ":"):
                raise ValueError(flag + text[len(parameter):]) from None
        raise
    if args.json:
        print(json.dumps({"command": "device emulate", "frame_format_version": 3, **asdict(summary),
                          "watchdog_s": watchdog, "record": args.record, "limits": args.limits}), flush=True)
    return 0

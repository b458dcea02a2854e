"""Subjects see only what they should: with terminal responses the prompt is on its own line and
the running estimate never reaches the subject's screen.

Oracle: the bytes a pseudo-terminal's master side reads are exactly what the subject's screen
shows; a typist thread answers each prompt as a subject would.
"""

from __future__ import annotations

import fcntl
import io
import os
import pty
import re
import select
import struct
import sys
import termios
import threading
import tomllib

import pytest

from tactilab.cli.main import main
from tactilab.data_schemas import DisplayDescription, Protocol
from tactilab.experiments import SimulatedDisplay
from tactilab.experiments.session import TerminalResponses, new_session

PROTOCOL = """
name = "screen"
seed = 2
iti_s = 0
[task]
kind = "2ifc"
[stimulus]
amplitude_m = "5um"
pitch_m = "2mm"
speed_m_per_s = "40mm/s"
duration_s = "20ms"
ramp_s = "5ms"
[procedure]
method = "staircase"
parameter = "amplitude_m"
[[procedure.tracks]]
start = "6um"
step_sizes = [0.1]
min_level = "1um"
max_level = "10um"
max_trials = 4
"""

PROMPT = b"Which interval held the stimulus?  [1] 1  [2] 2  ([q] quits)"
LEAKS = (b"threshold", b"estimate:", b"P(", b"trial/s", b"it/s", b"procedure's running", b"summary ---")


@pytest.fixture
def screen():
    """The subject's terminal: (master fd, its input file, its output file, what it shows, start typist)."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))  # a screen 80 columns wide
    tty_in = os.fdopen(slave, "r", closefd=False)
    tty_out = os.fdopen(os.dup(slave), "w")
    shown, stop, threads = bytearray(), threading.Event(), []

    def typist(key: bytes) -> None:
        """Answer every prompt with ``key``, as a subject would, while recording the screen."""
        answered = 0
        while not stop.is_set():
            ready, _, _ = select.select([master], [], [], 0.02)
            if ready:
                shown.extend(os.read(master, 65536))
            if shown.count(b"([q] quits)") > answered:
                answered += 1
                os.write(master, key)

    def start(key: bytes = b"1") -> None:
        threads.append(threading.Thread(target=typist, args=(key,), daemon=True))
        threads[-1].start()

    def finish() -> bytes:
        stop.set()
        for t in threads:
            t.join(timeout=2)
        while select.select([master], [], [], 0.05)[0]:  # what is left on the screen
            shown.extend(os.read(master, 65536))
        return bytes(shown)

    yield master, tty_in, tty_out, start, finish
    stop.set()
    tty_out.close()
    tty_in.close()
    os.close(slave)
    os.close(master)


def _lines(shown: bytes) -> list[bytes]:
    return [line for line in re.split(rb"\r\n|\n|\r", shown) if line.strip()]


def test_the_prompt_is_on_its_own_line_and_no_estimate_reaches_the_subject(screen, tmp_path, monkeypatch):
    master, tty_in, tty_out, start, finish = screen
    protocol = Protocol.model_validate(tomllib.loads(PROTOCOL))
    monkeypatch.setattr(sys, "stderr", tty_out)  # experimenter and subject share one terminal
    responses = TerminalResponses(protocol, stdin=tty_in, stdout=tty_out)
    start()
    try:
        result = new_session(protocol, tmp_path / "s.sqlite", SimulatedDisplay(DisplayDescription.braille_row(),
                             realtime=False), responses, subject="S01", realtime=False, progress=True)
    finally:
        responses.close()
        shown = finish()
    assert result.status == "complete" and result.n_completed == 4
    prompts = [line for line in _lines(shown) if b"Which interval" in line]
    assert prompts == [PROMPT] * 4  # each prompt alone on its line: no bar drawn before it
    assert not [leak for leak in LEAKS if leak in shown], shown
    assert b"progress: not shown on the subject's screen; follow it with `tactilab experiment status" in shown


def test_the_bar_with_the_estimate_goes_to_a_separate_experimenter_stream(screen, tmp_path, monkeypatch):
    master, tty_in, tty_out, start, finish = screen
    protocol = Protocol.model_validate(tomllib.loads(PROTOCOL))
    experimenter = io.StringIO()  # standard error redirected (a second terminal, a log file)
    monkeypatch.setattr(sys, "stderr", experimenter)
    responses = TerminalResponses(protocol, stdin=tty_in, stdout=tty_out)
    start()
    try:
        new_session(protocol, tmp_path / "s.sqlite", SimulatedDisplay(DisplayDescription.braille_row(),
                    realtime=False), responses, subject="S01", realtime=False, progress=True)
    finally:
        responses.close()
        shown = finish()
    assert "sub-S01 ses-01" in experimenter.getvalue() and "4/4" in experimenter.getvalue()
    assert "estimate" in experimenter.getvalue() or "threshold" in experimenter.getvalue()
    assert [line for line in _lines(shown) if b"Which interval" in line] == [PROMPT] * 4
    assert not [leak for leak in LEAKS if leak in shown]
    assert not responses.on_screen(experimenter) and responses.on_screen(tty_out)


def test_a_stopped_session_shows_no_estimate_or_summary_to_the_subject(screen, tmp_path, monkeypatch):
    """The subject quits at the first prompt: the session will be resumed with them, so the CLI's
    end lines on their screen name the session and how to resume, never the estimate."""
    master, tty_in, tty_out, start, finish = screen
    (tmp_path / "p.toml").write_text(PROTOCOL)
    monkeypatch.setattr(sys, "stdin", tty_in)
    monkeypatch.setattr(sys, "stdout", tty_out)
    monkeypatch.setattr(sys, "stderr", tty_out)
    start(b"q")
    try:
        code = main(["experiment", "run", str(tmp_path / "p.toml"), "--subject", "S01", "--no-wait",
                     "--out", str(tmp_path / "out")])
        tty_out.flush()
    finally:
        shown = finish()
    assert code == 130
    assert b"interrupted after 0 trials; running estimate and summary not shown on the subject's screen" in shown
    assert b"resume with: tactilab experiment resume" in shown
    assert not [leak for leak in LEAKS if leak in shown], shown

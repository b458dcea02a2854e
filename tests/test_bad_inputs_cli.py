"""Bad inputs through the real command line: each gives exactly one line on stderr (never a
traceback), a non-zero exit status, and names the file or option and the fix."""

from __future__ import annotations

import re
import shutil
import socket
import sqlite3
import threading
from pathlib import Path

import pytest
from udp_pairing import KEY, paired_description

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.emulator import emulate, read_record

PROTOCOL = """name = "bad"
seed = 3
iti_s = 0
[task]
kind = "yes_no"
PROMPT
[stimulus]
amplitude_m = "2um"
pitch_m = PITCH
speed_m_per_s = "40mm/s"
duration_s = "30ms"
ramp_s = "5ms"
[procedure]
method = "constant_stimuli"
parameter = PARAMETER
levels = ["1um", "3um"]
repeats_per_block = REPEATS
n_blocks = BLOCKS
"""


def _protocol(folder: Path, name: str, *, pitch='"2mm"', parameter='"amplitude_m"', repeats="1", blocks="1",
              prompt="", tail="") -> Path:
    path = folder / f"{name}.toml"
    path.write_text(PROTOCOL.replace("PITCH", pitch).replace("PARAMETER", parameter).replace("REPEATS", repeats)
                    .replace("BLOCKS", blocks).replace("PROMPT", prompt) + tail)
    return path


def _simulated(folder: Path) -> list[str]:
    return ["--responses", "simulated", "--no-wait", "--quiet", "--out", str(folder / "out")]


@pytest.fixture(scope="module")
def session(tmp_path_factory) -> Path:
    """One complete session made by the command line, to damage in several ways."""
    folder = tmp_path_factory.mktemp("good")
    assert cli_main(["experiment", "run", str(_protocol(folder, "good")), "--subject", "S01",
                     *_simulated(folder)]) == 0
    return next((folder / "out").glob("*.sqlite"))


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def device_absent(tmp_path, session):
    port = _free_port()
    return (["experiment", "run", str(_protocol(tmp_path, "p")), "--subject", "S01", *_simulated(tmp_path),
             "--display", f"udp://127.0.0.1:{port}",
             "--device", str(paired_description(tmp_path, DisplayDescription.braille_row()))], [f"udp://127.0.0.1:{port}", "connection refused",
                                                       f"tactilab device emulate --port {port}"])


def torn_session(tmp_path, session):
    torn = tmp_path / "torn.sqlite"
    data = session.read_bytes()
    torn.write_bytes(data[: len(data) // 2])
    return ["experiment", "status", str(torn)], [str(torn), "give the .sqlite file"]


def foreign_sqlite(tmp_path, session):
    foreign = tmp_path / "foreign.sqlite"
    connection = sqlite3.connect(foreign)
    connection.execute("CREATE TABLE results (x)")
    connection.commit()
    connection.close()
    return ["experiment", "export", str(foreign), "--out", str(tmp_path / "x")], [str(foreign), "not a tactilab session"]


def _without(tmp_path, session, key):
    path = tmp_path / f"no-{key}.sqlite"
    shutil.copy(session, path)
    connection = sqlite3.connect(path)
    connection.execute("DELETE FROM meta WHERE key = ?", (key,))
    connection.commit()
    connection.close()
    return path


def missing_meta_status(tmp_path, session):
    path = _without(tmp_path, session, "package_version")
    return ["experiment", "status", str(path)], [str(path), "lacks the metadata ['package_version']", "restore it"]


def missing_meta_export(tmp_path, session):
    path = _without(tmp_path, session, "protocol")
    return (["experiment", "export", str(path), "--out", str(tmp_path / "x")],
            [str(path), "lacks the metadata ['protocol']", "restore it"])


def deeply_nested_toml(tmp_path, session):
    path = tmp_path / "deep.toml"
    path.write_text("a = " + "[" * 100_000 + "]" * 100_000 + "\n")
    return ["experiment", "run", str(path), "--subject", "S01", *_simulated(tmp_path)], [str(path), "nested too deeply",
                                                                                          "fix the file"]


def empty_parameter(tmp_path, session):
    path = _protocol(tmp_path, "p", parameter="[]")
    return (["experiment", "run", str(path), "--subject", "S01", *_simulated(tmp_path)],
            [str(path), "parameter: must be one of", "name the stimulus field"])


def _pitch(value):
    def case(tmp_path, session):
        path = _protocol(tmp_path, "p", pitch=value)
        return (["experiment", "run", str(path), "--subject", "S01", *_simulated(tmp_path)],
                [str(path), "pitch_m: must lie in", "check its unit"])
    return case


def oversize_protocol(tmp_path, session):
    path = _protocol(tmp_path, "big", tail="# " + "x" * 1_100_000 + "\n")
    return (["experiment", "run", str(path), "--subject", "S01", *_simulated(tmp_path)],
            [str(path), "cap of a protocol file", "give grids as {start, stop, n} tables"])


def ten_billion_trials(tmp_path, session):
    path = _protocol(tmp_path, "p", blocks="10000000000")
    return (["experiment", "run", str(path), "--subject", "S01", *_simulated(tmp_path)],
            [str(path), "n_blocks", "less than or equal to 1000"])


def escape_sequences_in_prompt(tmp_path, session):
    path = _protocol(tmp_path, "p", prompt='prompt = "press \\u001b[2J\\u001b[31mY"')
    return (["experiment", "run", str(path), "--subject", "S01", *_simulated(tmp_path)],
            [str(path), "prompt: only printable characters", "remove control and escape characters"])


def a_name_and_birth_date_as_subject(tmp_path, session):
    return (["experiment", "run", str(_protocol(tmp_path, "p")), "--subject", "JaneDoe19850412",
             *_simulated(tmp_path)], ["--subject", "'JaneDoe19850412' looks like a name", "--subject-pattern"])


CASES = {
    "device absent": device_absent,
    "torn session file": torn_session,
    "foreign SQLite file": foreign_sqlite,
    "session missing a meta key (status)": missing_meta_status,
    "session missing a meta key (export)": missing_meta_export,
    "deeply nested TOML": deeply_nested_toml,
    "parameter = []": empty_parameter,
    "pitch 1e-300": _pitch("1e-300"),
    "pitch 1e300": _pitch("1e300"),
    "oversize protocol": oversize_protocol,
    "1e10 trials": ten_billion_trials,
    "prompt with terminal escape sequences": escape_sequences_in_prompt,
    "subject id JaneDoe19850412": a_name_and_birth_date_as_subject,
}


def _one_line_error(code, err, expected):
    lines = [line for line in err.splitlines() if line.strip()]
    assert code != 0, err
    assert "Traceback" not in err and len(lines) == 1, err
    for text in expected:
        assert text in lines[0], (text, lines[0])


@pytest.mark.parametrize("case", list(CASES))
def test_a_bad_input_gives_one_line_naming_the_file_or_option_and_the_fix(case, tmp_path, session, capsys):
    argv, expected = CASES[case](tmp_path, session)
    capsys.readouterr()
    code = cli_main(argv)
    _one_line_error(code, capsys.readouterr().err, expected)
    assert not list((tmp_path / "out").glob("*.sqlite")), "a refused run leaves no session file"


def test_a_device_lost_mid_session_gives_one_line_and_a_resumable_session(tmp_path, capsys):
    """The emulator goes away after a few frames of a several-trial session: one line, exit 3 (display
    fault), the trial in progress not scored, and the session resumable."""
    stop, logs, record = threading.Event(), [], tmp_path / "emu.jsonl"
    thread = threading.Thread(target=emulate, kwargs=dict(port=0, watchdog_s=1.0, record=record, max_seconds=60,
                                                          log=logs.append, stop=stop, handle_signals=False,
                                                          pairing_key=KEY),
                              daemon=True)
    thread.start()
    while not logs:
        stop.wait(0.005)
    port = int(logs[0].split(":")[2].split()[0])

    def pull_the_plug():
        while not stop.is_set():
            try:
                if read_record(record)["n_frames"] >= 40:
                    stop.set()
            except (OSError, ValueError, KeyError):
                pass
            stop.wait(0.005)

    watcher = threading.Thread(target=pull_the_plug, daemon=True)
    watcher.start()
    path = _protocol(tmp_path, "lost", repeats="20")
    capsys.readouterr()
    code = cli_main(["experiment", "run", str(path), "--subject", "S01", *_simulated(tmp_path),
                     "--display", f"udp://127.0.0.1:{port}", "--max-skipped", "1",
                     "--device", str(paired_description(tmp_path, DisplayDescription.braille_row()))])
    stop.set()
    thread.join(timeout=10)
    watcher.join(timeout=10)
    err = capsys.readouterr().err
    sessions = list((tmp_path / "out").glob("*.sqlite"))
    assert len(sessions) == 1
    _one_line_error(code, err, [f"udp://127.0.0.1:{port}", "was not scored", f"resume {sessions[0]}"])
    assert code == 3
    from tactilab.experiments import SessionLog, session_status

    assert session_status(sessions[0])["status"] == "failed"
    log = SessionLog(sessions[0])
    try:
        faults, trials = log.events("display_fault"), log.trials()
    finally:
        log.close()
    assert len(faults) == 1 and faults[0]["trial_index"] == len(trials)  # the lost trial is not among the scored


def test_a_type_error_deep_in_validation_is_still_one_line(tmp_path, capsys, monkeypatch):
    """The net under every validator: a value of a type no validator expected (``parameter = []``
    was one) is one line naming the file, never a traceback."""
    from tactilab.data_schemas.experiment import Protocol

    def unhashable(cls, data, context=None):
        raise TypeError("unhashable type: 'list'")

    monkeypatch.setattr(Protocol, "model_validate", classmethod(unhashable))
    path = _protocol(tmp_path, "p")
    with pytest.raises(ValueError, match=r"\(protocol\): a value has the wrong type \(unhashable type: 'list'\); "
                                         r"compare the file with docs/experiments.md"):
        Protocol.from_toml(path)
    code = cli_main(["experiment", "run", str(path), "--subject", "S01", *_simulated(tmp_path)])
    _one_line_error(code, capsys.readouterr().err, [str(path), "wrong type"])


@pytest.mark.parametrize("argv,message", [
    (["--watchdog", "0ms"], r"--watchdog: must be finite and > 0 s, got 0\.0; give a time with a unit, e\.g\. 50ms$"),
    (["--late-after=-1ms"], r"--late-after: must be finite and > 0 s, got -0\.001; give a time with a unit, e\.g\. 1ms$"),
    (["--max-seconds", "1e8s"], r"--max-seconds: must be at most 1e\+07 s \(about 4 months\), got '1e8s'; give e\.g\. 60s "),
    (["--watchdog", "5"], r"--watchdog: '5' has no unit, and a time needs one; write it with a unit, e\.g\. '5ms'"),
])
def test_time_option_hints_never_suggest_a_bare_number(argv, message, capsys):
    """A time option's fix is a time with a unit: a bare '0.05' (the library's seconds) would be refused."""
    assert cli_main(["device", "emulate", "--port", "0", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert re.search(message, err), err

"""Sizes and rules checked before any work (issue 26, item 5): the frame-rate cap and the memory
rule before rendering, subject patterns that cannot backtrack badly, --max-skipped a fraction."""

from __future__ import annotations

import pytest

from tactilab.cli.main import main as cli_main
from tactilab.core import rules
from tactilab.core.memory import MEMORY_LIMIT_BYTES, check_memory
from tactilab.core.patterns import MAX_REPEATS, safe_pattern
from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import MAX_FRAME_RATE_HZ, Protocol, Stimulus
from tactilab.experiments.devices import render_drive
from tactilab.experiments.devices.simulated_display import SimulatedDisplay
from tactilab.experiments.session import SimulatedObserver
from tactilab.experiments.session import runner as runner_module

STIMULUS = {"amplitude_m": "2um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s", "duration_s": "20ms",
            "ramp_s": "5ms"}


def test_frame_rate_is_capped_in_the_schema():
    assert Stimulus.model_validate({**STIMULUS, "frame_rate_hz": "100kHz"}).frame_rate_hz == MAX_FRAME_RATE_HZ
    with pytest.raises(ValueError, match=r"frame_rate_hz: must be <= 100000 Hz .*got 1000000000.0 Hz"):
        Stimulus.model_validate({**STIMULUS, "frame_rate_hz": "1e9Hz"})


def test_render_drive_applies_the_memory_rule_before_allocating():
    description = DisplayDescription.braille_row()
    with pytest.raises(ValueError, match=r"frame_rate_hz: the drive \(6000000 frames = 100000.0 Hz x 60.0 s, x 10 "
                                         r"tractors\) would need 1.79 GiB, more than the 1 GiB limit for one array; "
                                         r"give frame_rate_hz at most 55924.1 Hz at duration_s = 60.0 s"):
        render_drive(description, amplitude_m=1e-6, pitch_m=2e-3, speed_m_per_s=0.04, duration_s=60.0,
                     frame_rate_hz=1e5, ramp_s=0.0)
    frames = render_drive(description, amplitude_m=1e-6, pitch_m=2e-3, speed_m_per_s=0.04, duration_s=0.02,
                          frame_rate_hz=1e3, ramp_s=0.005)
    assert frames.shape == (20, 10)


def test_a_session_checks_the_frame_rate_before_rendering(tmp_path, monkeypatch):
    protocol = Protocol.model_validate({
        "name": "fast", "seed": 1, "task": {"kind": "2ifc"}, "stimulus": {**STIMULUS, "frame_rate_hz": "50kHz"},
        "procedure": {"method": "constant_stimuli", "parameter": "amplitude_m", "levels": ["1um"]}})
    rendered = []
    monkeypatch.setattr(runner_module, "render_drive", lambda *a, **k: rendered.append(k))
    display = SimulatedDisplay(DisplayDescription.braille_row(), realtime=False)
    with pytest.raises(ValueError, match=r"protocol: a planned stimulus's frame_rate_hz: 50000.0 Hz exceeds the "
                                         r"refresh rate"):
        runner_module.new_session(protocol, tmp_path / "s.sqlite", display, SimulatedObserver(protocol),
                                  subject="S01", realtime=False)
    assert rendered == [] and not (tmp_path / "s.sqlite").exists()


def test_check_memory_and_the_fraction_rule():
    assert check_memory(MEMORY_LIMIT_BYTES, "n", "x", "fix") == MEMORY_LIMIT_BYTES
    for bad in (MEMORY_LIMIT_BYTES + 1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="n: x would need .* GiB, more than the 1 GiB limit for one array; fix"):
            check_memory(bad, "n", "x", "fix")
    assert rules.fraction(0, "f") == 0.0 and rules.fraction(1, "f") == 1.0
    for bad in (2, -0.1, float("nan"), float("inf"), True, "x"):
        with pytest.raises(ValueError, match=r"f: must be a fraction in \[0, 1\], got "):
            rules.fraction(bad, "f")


@pytest.mark.parametrize("pattern", ["S[0-9]{3}", r"(MRI|EEG)_?\d{2,3}", r"[A-Z]{2}\d+", "P0*[1-9][0-9]?"])
def test_lab_subject_patterns_are_accepted(pattern):
    assert safe_pattern(pattern, "p").pattern == pattern


@pytest.mark.parametrize("pattern, message", [
    ("(a+)+$", "repeats a group, which can make matching take exponential time"),
    ("(a|a)*b", "repeats a group"),
    ("(?:ab)+", "repeats a group"),
    ("(?=S)S1", "uses assert"),
    (r"(a)\1", "uses groupref"),
    ("a*" * (MAX_REPEATS + 1), f"has {MAX_REPEATS + 1} repeats"),
    ("[", "is not a valid regular expression"),
    ("S" * 201, "must be a regular expression of 1-200 characters"),
])
def test_subject_patterns_that_could_backtrack_badly_are_refused(pattern, message):
    with pytest.raises(ValueError, match=f"p: .*{message}" if not message.startswith("must") else f"p: {message}"):
        safe_pattern(pattern, "p")


def test_the_command_line_refuses_a_slow_subject_pattern_and_a_bad_max_skipped(tmp_path, capsys):
    protocol = tmp_path / "p.toml"
    protocol.write_text('name = "x"\nseed = 1\n[task]\nkind = "2ifc"\n[stimulus]\namplitude_m = "2um"\n'
                        'pitch_m = "2mm"\nspeed_m_per_s = "40mm/s"\nduration_s = "20ms"\nramp_s = "5ms"\n'
                        '[procedure]\nmethod = "constant_stimuli"\nparameter = "amplitude_m"\nlevels = ["1um"]\n')
    base = ["experiment", "run", str(protocol), "--responses", "simulated", "--no-wait", "--quiet",
            "--out", str(tmp_path / "s")]
    assert cli_main([*base, "--subject", "a" * 31 + "b", "--subject-pattern", "(a+)+$"]) == 2
    assert "subject pattern: '(a+)+$' repeats a group" in capsys.readouterr().err
    for value in ("2", "nan"):
        assert cli_main([*base, "--subject", "S01", "--max-skipped", value]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "--max-skipped: must be a fraction in [0, 1]" in err, err
    assert not (tmp_path / "s").exists() or not any((tmp_path / "s").iterdir())

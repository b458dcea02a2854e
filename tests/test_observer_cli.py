"""The CLI's simulated observer reads any receptor hypothesis, and a resume rebuilds it.

Oracle: an observer reading xx@2mm (peak), run through ``tactilab experiment run`` on two
sessions of different pitch (2 and 8 mm: the depth's effect on the strain differs between
pitches), must be picked over zx@1mm by ``tactilab experiment compare``.
"""

from __future__ import annotations

import json

import pytest

from tactilab.cli.main import main
from tactilab.experiments.session import SessionLog


def _protocol(tmp_path, pitch_mm, levels_um, blocks=6):
    text = f"""
name = "p{pitch_mm}"
seed = {pitch_mm}
iti_s = 0
[task]
kind = "2ifc"
[stimulus]
amplitude_m = "1um"
pitch_m = "{pitch_mm}mm"
speed_m_per_s = "20mm/s"
duration_s = "50ms"
[procedure]
method = "constant_stimuli"
parameter = "amplitude_m"
levels = [{", ".join(f'"{a}um"' for a in levels_um)}]
repeats_per_block = 4
n_blocks = {blocks}
"""
    path = tmp_path / f"p{pitch_mm}.toml"
    path.write_text(text)
    return path


def _run(tmp_path, protocol, *extra):
    argv = ["experiment", "run", str(protocol), "--subject", "S01", "--responses", "simulated", "--no-wait",
            "--quiet", "--out", str(tmp_path / "sessions"), "--json", *extra]
    assert main(argv) == 0
    return sorted((tmp_path / "sessions").glob(f"*task-{protocol.stem}.sqlite"))[-1]


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_the_observer_reading_xx_at_2mm_is_picked_over_zx_at_1mm(tmp_path, capsys):
    observer = ["--observer", "xx@2mm", "--observer-threshold", "1e-4", "--observer-statistic", "peak",
                "--observer-strain", "surface"]
    paths = [_run(tmp_path, _protocol(tmp_path, 2, (0.5, 1, 2, 4, 8)), *observer),
             _run(tmp_path, _protocol(tmp_path, 8, (0.15, 0.3, 0.6, 1.2, 2.4)), *observer)]
    log = SessionLog(paths[0])
    try:
        config = log.meta()["responses_config"]
    finally:
        log.close()
    assert (config["hypothesis"], config["statistic"], config["strain"], config["threshold_strain"]) == \
        ("xx@2mm", "peak", "surface", 1e-4)
    capsys.readouterr()
    assert main(["experiment", "compare", *map(str, paths), "--model", "zx@1mm", "--model", "xx@2mm",
                 "--out", str(tmp_path), "--json"]) == 0
    rows = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["models"]
    assert rows["xx@2mm"]["verdict"] == "best" and rows["zx@1mm"]["verdict"] in ("worse", "weakly worse")


def test_resume_rebuilds_the_observer_and_the_options_are_checked(tmp_path, capsys):
    protocol = _protocol(tmp_path, 2, (0.5, 1, 2))
    path = _run(tmp_path, protocol, "--observer", "zx@2mm", "--observer-threshold", "1.4e-3")
    log = SessionLog(path)
    try:
        config = log.meta()["responses_config"]
    finally:
        log.close()
    assert config["strain"] == "display" and config["statistic"] == "peak"  # the default for a simulated display
    # resume's path: no observer option given, the recorded configuration rebuilds the same observer
    import argparse

    from tactilab.cli.experiment_observer import observer_responses
    from tactilab.data_schemas import DisplayDescription, Protocol
    from tactilab.experiments import SimulatedDisplay

    none = argparse.Namespace(observer=None, observer_statistic=None, observer_threshold=None, observer_strain=None)
    rebuilt = observer_responses("simulated", Protocol.from_toml(protocol),
                                 SimulatedDisplay(DisplayDescription.braille_row()), none, config)
    assert dict(rebuilt.config) == config and rebuilt.model.name == "zx@2mm/display"
    capsys.readouterr()
    cases = [(["--observer", "zx@2mm"], "--observer-threshold: give the readout of zx@2mm felt at d' = 1"),
             (["--observer-statistic", "rms"], "--observer-statistic: needs --observer"),
             (["--observer", "zx@2mm", "--observer-threshold", "-1"], "--observer-threshold: must be a strain > 0"),
             (["--observer", "qq@1mm", "--observer-threshold", "1e-3"], "--observer"),
             (["--observer", "zx@2mm", "--observer-threshold", "1e-3", "--observer-strain", "skin"],
              "--observer-strain: must be 'surface', 'display' or 'contact', got 'skin'")]
    for extra, match in cases:
        assert main(["experiment", "run", str(protocol), "--subject", "S02", "--responses", "simulated", "--no-wait",
                     "--quiet", "--out", str(tmp_path / "bad"), *extra]) == 2
        assert match in capsys.readouterr().err, extra
    assert main(["experiment", "run", str(protocol), "--subject", "S02", "--responses", "terminal", "--no-wait",
                 "--quiet", "--out", str(tmp_path / "bad"), "--observer", "zx@2mm"]) == 2
    assert "--observer: only with --responses simulated" in capsys.readouterr().err


@pytest.mark.parametrize("flag", ["--observer", "--observer-statistic", "--observer-threshold", "--observer-strain"])
def test_help_states_the_units(flag, capsys):
    with pytest.raises(SystemExit):
        main(["experiment", "run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert flag in text and "the unit of `power --threshold`" in text


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_an_observer_feeling_the_display_is_found_by_models_of_the_display(tmp_path, capsys):
    """The default for a simulated display: the observer feels what the display renders; compare
    --source display fits models of that same rendered strain (from the recorded description)."""
    observer = ["--observer", "xx@2mm", "--observer-threshold", "1e-4"]
    # the braille row renders 2 and 6 mm gratings with different xx-to-zx ratios (0.31 and 1.10 at these depths)
    paths = [_run(tmp_path, _protocol(tmp_path, 2, (0.15, 0.3, 0.6, 1.2, 2.4), blocks=12), *observer),
             _run(tmp_path, _protocol(tmp_path, 6, (0.04, 0.08, 0.16, 0.32, 0.64), blocks=12), *observer)]
    capsys.readouterr()
    argv = ["experiment", "compare", *map(str, paths), "--model", "zx@1mm", "--model", "xx@2mm", "--out",
            str(tmp_path), "--json"]
    assert main([*argv, "--source", "display"]) == 0
    rows = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["models"]
    assert rows["xx@2mm"]["verdict"] == "best" and rows["zx@1mm"]["verdict"] in ("worse", "weakly worse")
    assert main([*argv, "--source", "display", "--workers", "0"]) == 2
    assert "--source: 'display' is for a pooled comparison" in capsys.readouterr().err
    other = _run(tmp_path / "stress", _protocol(tmp_path, 2, (0.15, 0.3)), "--device", "stress2", *observer)
    capsys.readouterr()
    assert main([*argv[:2], str(paths[0]), str(other), *argv[4:], "--source", "display"]) == 2
    assert "--source: 'display' needs sessions recorded on one display" in capsys.readouterr().err

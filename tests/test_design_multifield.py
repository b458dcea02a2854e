"""Model discrimination over candidates that differ in several fields, from a protocol file:
``tactilab experiment run`` end to end, exact resume, and ``tactilab experiment compare``."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

from tactilab.cli.main import main
from tactilab.data_schemas.design_config import ModelDiscriminationConfig
from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments import SimulatedDisplay, new_session, resume_session, session_dataframe
from tactilab.experiments.modelling.design import ModelDiscrimination
from tactilab.experiments.modelling.models import TransductionModel
from tactilab.experiments.procedures.tasks import PlannedStimulus, plan_trial

from stop_after import StopAfter

PROTOCOL = """
name = "designmulti"
seed = 5
iti_s = 0

[task]
kind = "2ifc"

[stimulus]
amplitude_m = "10um"
pitch_m = "3mm"
speed_m_per_s = "20mm/s"
duration_s = "50ms"
ramp_s = "5ms"

[procedure]
method = "model_discrimination"
parameter = "pitch_m"
models = ["xx@1mm", "zx@1mm"]
max_trials = 16

[procedure.candidates]
pitch_m = ["2mm", "3mm", "5mm"]
amplitude_m = ["3um", "6um"]
surface = ["sinusoid", "square"]
speed_m_per_s = ["20mm/s"]
"""


def _interval(stimuli):
    """The shown (non-blank) interval of a 2IFC trial's recorded stimuli."""
    items = json.loads(stimuli) if isinstance(stimuli, str) else stimuli
    items = [s if isinstance(s, dict) else s.model_dump() for s in items]
    return next(s for s in items if s["amplitude_m"] > 0)


def test_planned_stimulus_fields_replace_the_protocol_stimulus():
    protocol = Protocol.model_validate(tomllib.loads(PROTOCOL))
    planned = PlannedStimulus(0.005, 3, 0, (("surface", "square"), ("amplitude_m", 5e-6)))
    plan = plan_trial(protocol, 0, planned, np.random.default_rng(0))
    shown = [s for s in plan.stimuli if s.amplitude_m > 0]
    blank = [s for s in plan.stimuli if s.amplitude_m == 0]
    assert len(shown) == len(blank) == 1
    assert (shown[0].surface, shown[0].amplitude_m, shown[0].pitch_m) == ("square", 5e-6, 0.005)
    assert shown[0].duration_s == protocol.stimulus.duration_s  # unlisted fields from [stimulus]
    assert blank[0].surface == "square" and blank[0].pitch_m == 0.005
    assert plan.level == 0.005 and plan.track == 3


def test_protocol_file_with_several_varied_fields_runs_through_the_cli(tmp_path, capsys):
    path = tmp_path / "design.toml"
    path.write_text(PROTOCOL)
    argv = ["experiment", "run", str(path), "--subject", "S01", "--responses", "simulated", "--no-wait", "--quiet",
            "--out", str(tmp_path / "out"), "--observer-threshold", "2e-4"]
    assert main(argv) == 0
    assert "P(xx@1mm)" in capsys.readouterr().out
    (session,) = (tmp_path / "out").glob("*.sqlite")
    frame = session_dataframe(session)
    protocol = Protocol.from_toml(path)
    design = ModelDiscrimination(protocol.procedure.models, protocol.procedure.stimuli())
    for stimuli, level, track in zip(frame["stimuli"], frame["level"], frame["track"]):
        shown, candidate = _interval(stimuli), design.candidates[track]
        # the commanded interval IS the candidate the design predicted (every listed field)
        assert (shown["surface"], shown["amplitude_m"], shown["pitch_m"]) == \
            (candidate.surface, candidate.amplitude_m, candidate.pitch_m)
        assert level == candidate.pitch_m
    shown = [_interval(s) for s in frame["stimuli"]]
    # the design predicts from what the braille row renders, where the pitch separates xx from zx (on the
    # ideal surface the waveform did): it shows several pitches
    assert len({s["pitch_m"] for s in shown}) >= 2

    # compare works on the design session as on any other; 16 trials all near ceiling cannot separate the
    # models, so the table says so instead of naming a best model
    assert main(["experiment", "compare", str(session), "--model", "xx@1mm", "--model", "zx@1mm",
                 "--out", str(tmp_path / "figs")]) == 0
    out = capsys.readouterr().out
    assert "xx@1mm" in out and "zx@1mm" in out
    assert "best" in out or "not identifiable on this design: " in out
    assert (tmp_path / "figs" / "compare.png").stat().st_size > 10_000




def _observer(protocol, stop_at=None):
    obs = StopAfter.from_model(protocol, TransductionModel("zx@1mm"), threshold_strain=2e-4, exponent=1.2,
                               lapse=0.02, seed=11)
    obs.stop_at = stop_at
    return obs


def test_multifield_session_resumes_equal_to_the_uninterrupted_one(tmp_path):
    protocol = Protocol.model_validate(tomllib.loads(PROTOCOL))
    frames, estimates = [], []
    for name, stop_at in (("whole", None), ("cut", 5)):
        path = tmp_path / f"{name}.sqlite"
        display = SimulatedDisplay(DisplayDescription.braille_row(), realtime=False)
        result = new_session(protocol, path, display, _observer(protocol, stop_at), subject="S01", realtime=False)
        if stop_at is not None:
            assert result.status == "interrupted" and result.n_completed == stop_at
            result = resume_session(path, SimulatedDisplay(DisplayDescription.braille_row(), realtime=False),
                                    _observer(protocol), realtime=False)
        assert result.status == "complete"
        frames.append(session_dataframe(path))
        estimates.append(result.estimate)
    assert estimates[0] == estimates[1]
    for col in ("level", "track", "correct", "response", "procedure_state", "stimuli"):
        assert frames[0][col].tolist() == frames[1][col].tolist(), col
    shown = {tuple(_interval(s)[k] for k in ("surface", "pitch_m", "amplitude_m")) for s in frames[0]["stimuli"]}
    assert len(shown) >= 2  # the resumed design went on choosing among multi-field candidates


@pytest.mark.parametrize("changes, match", [
    ({"pitch_m": {"start": "1mm", "stop": "8mm", "n": 40}, "amplitude_m": {"start": "1um", "stop": "9um", "n": 30}},
     "candidates: the lists give 2400 candidates"),
    ({"duration_s": ["0ms"]}, "candidates: .* is not a valid stimulus"),
])
def test_bad_multifield_candidates(changes, match):
    raw = tomllib.loads(PROTOCOL)["procedure"]
    raw["candidates"] = {**raw["candidates"], **changes}
    with pytest.raises(ValueError, match=match):
        ModelDiscriminationConfig.model_validate(raw)


def test_a_design_built_in_python_plans_every_field_its_candidates_vary():
    from tactilab.data_schemas.experiment import Stimulus

    cands = [Stimulus(surface=w, amplitude_m=a, pitch_m=p, speed_m_per_s=0.02, duration_s=d)
             for w in ("sinusoid", "square") for a in (5e-6, 1e-5) for p in (2e-3, 5e-3) for d in (0.05,)]
    design = ModelDiscrimination(["xx@1mm", "zx@1mm"], cands, rng=0, parameter="pitch_m")
    assert design.stimulus_fields == ("surface", "amplitude_m")  # duration_s is the same for all: not carried
    # from a protocol: the listed fields, and always those the statistic reads (here the waveform is
    # not listed, so the candidates are sinusoids, and that is what is shown, not [stimulus]'s square)
    raw = tomllib.loads(PROTOCOL)
    raw["stimulus"]["surface"] = "square"
    del raw["procedure"]["candidates"]["surface"]
    protocol = Protocol.model_validate(raw)
    from_file = ModelDiscrimination(protocol.procedure.models[:1] + ["zx@2mm"], protocol.procedure.stimuli(),
                                    config=protocol.procedure, parameter="pitch_m")
    assert from_file.stimulus_fields == ("surface", "amplitude_m", "speed_m_per_s")
    plan = plan_trial(protocol, 0, from_file.next_trial(0, np.random.default_rng(0)), np.random.default_rng(0))
    assert {s.surface for s in plan.stimuli} == {"sinusoid"}
    planned = design.next_trial(0, np.random.default_rng(0))
    chosen = design.candidates[planned.track]
    assert isinstance(planned, PlannedStimulus) and planned.level == chosen.pitch_m
    assert dict(planned.fields) == {"surface": chosen.surface, "amplitude_m": chosen.amplitude_m}


@pytest.mark.parametrize("candidates, stimulus, match", [
    # valid alone (the default duration is 0.5 s), invalid with [stimulus]'s 50 ms
    ({"ramp_s": ["5ms", "30ms"]}, {},
     r"procedure\.candidates\[1\] \(surface='sinusoid', amplitude_m=3e-06, pitch_m=0\.002, speed_m_per_s=0\.02, ramp_s=0\.03\) merged "
     r"with \[stimulus\] gives an invalid stimulus \(ramp_s: must lie in \[0, duration_s / 2\] = \[0, 0\.025\] s, "
     r"got 0\.03; .*\); 12 of 24 planned stimuli break the ramp_s rule; change the candidate lists or \[stimulus\]"),
    ({"frame_rate_hz": ["30Hz"]}, {},
     r"procedure\.candidates\[0\] .*frame_rate_hz=30\.0.* \(frame_rate_hz: 30\.0 Hz gives fewer than 2 frames in "
     r"0\.05 s; .*\); 12 of 12 planned stimuli break the frame_rate_hz rule"),
    # the [stimulus] side: a listed ramp that the protocol's own duration cannot hold
    ({"ramp_s": ["20ms"]}, {"duration_s": "30ms"}, r"procedure\.candidates\[0\] .*\(ramp_s: .*got 0\.02; .*\); "
     r"12 of 12 planned stimuli break the ramp_s rule"),
])
def test_candidates_are_validated_merged_with_the_protocol_stimulus(candidates, stimulus, match):
    raw = tomllib.loads(PROTOCOL)
    raw["procedure"]["candidates"] = {**raw["procedure"]["candidates"], **candidates}
    raw["stimulus"] = {**raw["stimulus"], **stimulus}
    ModelDiscriminationConfig.model_validate(raw["procedure"])  # each candidate is valid on its own
    with pytest.raises(ValueError, match=match):
        Protocol.model_validate(raw)


def test_a_protocol_whose_merged_candidate_is_invalid_fails_at_load_in_one_line(tmp_path, capsys):
    path = tmp_path / "design.toml"
    path.write_text(PROTOCOL.replace('speed_m_per_s = ["20mm/s"]', 'speed_m_per_s = ["20mm/s"]\nramp_s = ["30ms"]'))
    out = tmp_path / "out"
    argv = ["experiment", "run", str(path), "--subject", "S01", "--responses", "simulated", "--no-wait", "--quiet",
            "--out", str(out)]
    assert main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err + captured.out
    assert "procedure.candidates[0]" in lines[0] and "ramp_s: must lie in" in lines[0]
    assert not out.exists() or not list(out.glob("*.sqlite"))  # refused before any session file


def test_a_candidate_invalid_on_its_own_is_named_with_its_index():
    raw = tomllib.loads(PROTOCOL)["procedure"]
    raw["candidates"] = {**raw["candidates"], "duration_s": ["1s", "30ms"]}  # 30 ms < 2 x the default 20 ms ramp
    with pytest.raises(ValueError, match=r"candidates: candidate 1 \{.*'duration_s': 0\.03.*\} is not a valid "
                                         r"stimulus on its own \(.*ramp_s.*unlisted fields at their defaults: "
                                         r"duration_s 0\.5, ramp_s 0\.02, frame_rate_hz 1000\.0\)"):
        ModelDiscriminationConfig.model_validate(raw)


def test_a_candidate_frame_rate_the_display_cannot_play_is_refused_before_the_session(tmp_path, capsys):
    """The display is known when a session starts: every planned stimulus's frame rate is checked
    against its refresh rate (1 kHz for the Braille row) before a session file exists."""
    raw = tomllib.loads(PROTOCOL)
    raw["procedure"]["candidates"]["frame_rate_hz"] = ["500Hz", "5kHz"]
    protocol = Protocol.model_validate(raw)
    assert len(protocol.planned_stimuli()) == 24 and {s.frame_rate_hz for s in protocol.planned_stimuli()} == {500.0,
                                                                                                             5000.0}
    display = SimulatedDisplay(DisplayDescription.braille_row(), realtime=False)
    path = tmp_path / "s.sqlite"
    with pytest.raises(ValueError, match=r"protocol: a planned stimulus's frame_rate_hz: 5000.0 Hz exceeds the "
                                         r"refresh rate of display 'VirtualBrailleRow', 1000.0 Hz .*render the stimulus "
                                         r"at that rate or lower \(frame rates planned: \[500.0, 5000.0\] Hz\)"):
        new_session(protocol, path, display, _observer(protocol), subject="S01", realtime=False)
    assert not path.exists()
    toml = tmp_path / "design.toml"
    toml.write_text(PROTOCOL.replace('speed_m_per_s = ["20mm/s"]', 'speed_m_per_s = ["20mm/s"]\nframe_rate_hz = ["5kHz"]'))
    out = tmp_path / "out"
    assert main(["experiment", "run", str(toml), "--subject", "S01", "--responses", "simulated", "--no-wait",
                 "--quiet", "--out", str(out)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "exceeds the refresh rate" in err[0] and not list(out.glob("*.sqlite"))
    assert "session file:" not in captured.out  # no file, so no "session file: PATH" line either

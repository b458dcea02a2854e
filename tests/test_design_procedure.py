"""method = "model_discrimination" in a protocol: runner, interruption and exact resume."""

from __future__ import annotations

import json

import pytest

from tactilab.data_schemas.design_config import ModelDiscriminationConfig
from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments import SimulatedDisplay, make_procedure, new_session, resume_session
from tactilab.experiments import session_dataframe, session_status
from tactilab.experiments.modelling.design import ModelDiscrimination, from_config
from tactilab.experiments.modelling.models import TransductionModel

from stop_after import StopAfter

STIMULUS = {"amplitude_m": "5um", "pitch_m": "3mm", "speed_m_per_s": "20mm/s", "duration_s": "50ms",
            "ramp_s": "5ms"}
# the runner varies one field: the pitch (amplitude alone scales every hypothesis alike: metameric)
PROCEDURE = {"method": "model_discrimination", "parameter": "pitch_m", "models": ["zx@1mm", "zx@2mm"],
             "max_trials": 40, "stop_probability": 0.99,
             "candidates": {"pitch_m": {"start": "1mm", "stop": "8mm", "n": 8, "scale": "log"},
                            "amplitude_m": ["5um"], "speed_m_per_s": ["20mm/s"], "duration_s": ["50ms"],
                            "ramp_s": ["5ms"]}}


def _protocol(**changes):
    return Protocol.model_validate({"name": "design", "seed": 7, "iti_s": 0, "task": {"kind": "2ifc"},
                                    "stimulus": STIMULUS, "procedure": {**PROCEDURE, **changes}})




def _observer(protocol, stop_at=None):
    model = TransductionModel("zx@1mm")
    obs = StopAfter.from_model(protocol, model, threshold_strain=2e-4, exponent=1.2, lapse=0.02, seed=11)
    obs.stop_at = stop_at
    return obs


def _run(tmp_path, name, stop_at=None):
    protocol = _protocol()
    path = tmp_path / f"{name}.sqlite"
    display = SimulatedDisplay(DisplayDescription.braille_row(), realtime=False)
    first = new_session(protocol, path, display, _observer(protocol, stop_at), subject="S01", realtime=False)
    if stop_at is not None:
        assert first.status == "interrupted" and first.n_completed == stop_at
        first = resume_session(path, SimulatedDisplay(DisplayDescription.braille_row(), realtime=False),
                               _observer(protocol), realtime=False)
    return path, first


def test_interrupted_and_resumed_session_equals_the_uninterrupted_one(tmp_path):
    whole_path, whole = _run(tmp_path, "whole")
    cut_path, cut = _run(tmp_path, "cut", stop_at=6)
    assert whole.status == cut.status == "complete" and whole.n_completed == cut.n_completed
    assert whole.estimate == cut.estimate
    a, b = session_dataframe(whole_path), session_dataframe(cut_path)
    for col in ("level", "track", "correct", "response", "procedure_state"):
        assert a[col].tolist() == b[col].tolist(), col
    # posterior model probabilities after every trial, in the recorded state
    probs = [json.loads(s)["model_probabilities"] for s in a["procedure_state"]]
    assert len(probs) == whole.n_completed and all(abs(sum(p.values()) - 1) < 1e-9 for p in probs)
    assert session_status(cut_path)["estimate"] == whole.estimate


def test_make_procedure_builds_the_design_from_the_protocol():
    protocol = _protocol()
    proc = make_procedure(protocol.procedure, protocol.task.guess_rate)
    assert isinstance(proc, ModelDiscrimination) and proc.names == ["zx@1mm", "zx@2mm"]
    assert len(proc.candidates) == 8 and proc.n_planned == 40
    assert sorted(protocol.candidate_levels()) == sorted(c.pitch_m for c in proc.candidates)


def test_mixed_tasks_are_refused():
    protocol = _protocol()
    with pytest.raises(ValueError, match="task: mixed tasks: the design models 2ifc"):
        from_config(protocol.procedure, guess_rate=0.0)


@pytest.mark.parametrize("changes, match", [
    (dict(parameter="colour"), "parameter: must be one of"),
    (dict(candidates={}), "candidates: the candidate set is empty"),
    (dict(candidates={**PROCEDURE["candidates"], "size": ["1mm"]}), "candidates.size: unknown stimulus field"),
    (dict(candidates={**PROCEDURE["candidates"], "surface": ["triangle"]}), "candidates.surface: a list of"),
    (dict(models=["zx@1mm", "qq@2mm"]), r"models\[1\]: components: unknown component .qq."),
    (dict(candidates={"amplitude_m": ["5um"], "pitch_m": ["3mm"]}), r"candidates: need \['speed_m_per_s'\]"),
    (dict(parameter="duration_s", candidates={k: v for k, v in PROCEDURE["candidates"].items() if k != "duration_s"}),
     "candidates: must list the varied parameter 'duration_s'"),
])
def test_bad_configurations(changes, match):
    with pytest.raises(ValueError, match=match):
        ModelDiscriminationConfig.model_validate({**PROCEDURE, **changes})


def test_progress_line_shows_the_model_probabilities_and_the_verdict():
    from tactilab.experiments.session.runner import format_estimate

    line = format_estimate({"threshold": None, "p_zx@1mm": 0.934, "p_zx@2mm": 0.066, "verdict": "undecided"},
                           "pitch_m")
    assert line == "P(zx@1mm) 0.93, P(zx@2mm) 0.07; undecided"
    assert format_estimate({"threshold": 2.47e-6}, "amplitude_m") == "amplitude threshold 2.47 um"
    assert format_estimate({"threshold": None}, "amplitude_m") == "estimate: n/a"

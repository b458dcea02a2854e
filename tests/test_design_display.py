"""A model-discrimination design predicts from the stimulus the display renders (issue 24):
the session builds a model of its display (``design_display``), the design's hypotheses read the
rendered, limited strain (``TransductionModel(source="display")``), and a resume rebuilds it."""

from __future__ import annotations

import sqlite3

import numpy as np
import pytest

from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol, Stimulus
from tactilab.experiments import SimulatedDisplay, SimulatedObserver, make_procedure, new_session, resume_session
from tactilab.experiments import replay_session, session_dataframe
from tactilab.experiments.devices import limit_drive, render_drive
from tactilab.experiments.modelling.models import TransductionModel
from tactilab.experiments.session.display_check import design_display

from stop_after import StopAfter

STIMULUS = {"amplitude_m": "5um", "pitch_m": "3mm", "speed_m_per_s": "20mm/s", "duration_s": "50ms", "ramp_s": "5ms"}
# 20 um at 4 mm asks the braille row for about 104 kPa: its 50 kPa limit clips it (clipped = "allow")
PROCEDURE = {"method": "model_discrimination", "parameter": "pitch_m", "models": ["zx@1mm", "zx@2mm"],
             "max_trials": 12, "candidates": {"pitch_m": ["2mm", "4mm", "8mm"], "amplitude_m": ["5um", "20um"],
                            "speed_m_per_s": ["20mm/s"]}}


def _protocol():
    return Protocol.model_validate({"name": "designdisplay", "seed": 3, "iti_s": 0, "task": {"kind": "2ifc"},
                                    "stimulus": STIMULUS, "procedure": PROCEDURE, "clipped": "allow"})


def _played(protocol, candidate):
    """The interval a trial plays for a candidate: [stimulus] with the candidate's fields, built by hand."""
    return Stimulus.model_validate({**protocol.stimulus.model_dump(), "amplitude_m": candidate.amplitude_m,
                                    "pitch_m": candidate.pitch_m, "surface": candidate.surface,
                                    "speed_m_per_s": candidate.speed_m_per_s})


def test_design_on_a_clipping_display_predicts_from_the_clipped_stimulus():
    protocol, description = _protocol(), DisplayDescription.braille_row()
    design = make_procedure(protocol.procedure, 0.5, display=design_display(description, protocol))
    assert design.names == ["zx@1mm", "zx@2mm"] and all(m.source == "display" for m in design.models)
    bare = SimulatedDisplay(description, realtime=False)
    # the same display without limits: what it would render if nothing were clipped
    unlimited = SimulatedDisplay(description.model_copy(update={"max_traction_pa": 1e12}), realtime=False)
    ratios = []
    for c, candidate in enumerate(design.candidates):
        played = _played(protocol, candidate)
        frames = render_drive(description, **played.model_dump())
        _, interventions = limit_drive(frames, played.frame_rate_hz, description, "traction")
        for m, name in enumerate(design.names):
            rendered = TransductionModel(name, source="display", display=bare).statistic_of(played)
            assert design.stats[m, c, 0] == pytest.approx(rendered, rel=1e-12)
            wanted = TransductionModel(name, source="display", display=unlimited).statistic_of(played)
            if interventions:
                ratios.append(design.stats[m, c, 0] / wanted)
            else:
                assert design.stats[m, c, 0] == pytest.approx(wanted, rel=1e-12)
    # clipped candidates (20 um at 2, 4 and 8 mm) are predicted at the strain the limited drive gives
    assert len(ratios) == 6 and max(ratios) < 1 and min(ratios) < 0.75


def test_design_without_a_display_still_predicts_from_the_surface():
    protocol = _protocol()
    design = make_procedure(protocol.procedure, 0.5)
    assert all(m.source == "surface" for m in design.models)
    candidate = design.candidates[0]
    assert design.stats[0, 0, 0] == TransductionModel("zx@1mm").statistic_of(candidate)




def _run(tmp_path, name, stop_at=None):
    protocol = _protocol()
    observer = StopAfter.from_model(protocol, TransductionModel("zx@2mm"), threshold_strain=3e-4, exponent=1.2,
                                    lapse=0.02, seed=4)
    observer.stop_at = stop_at
    path = tmp_path / f"{name}.sqlite"
    result = new_session(protocol, path, SimulatedDisplay(DisplayDescription.braille_row(), realtime=False),
                         observer, subject="S01", realtime=False)
    if stop_at is not None:
        assert result.status == "interrupted" and result.n_completed == stop_at
        observer.stop_at = None
        result = resume_session(path, SimulatedDisplay(DisplayDescription.braille_row(), realtime=False),
                                observer, realtime=False)
    return path, result


def test_resume_rebuilds_the_display_design_and_makes_the_same_choices(tmp_path):
    whole_path, whole = _run(tmp_path, "whole")
    cut_path, cut = _run(tmp_path, "cut", stop_at=5)
    assert whole.status == cut.status == "complete" and whole.estimate == cut.estimate
    a, b = session_dataframe(whole_path), session_dataframe(cut_path)
    for col in ("level", "track", "procedure_state"):
        assert a[col].tolist() == b[col].tolist(), col
    replayed = replay_session(cut_path)
    assert replayed.meta["design_strain"] == "display"
    assert all(m.source == "display" for m in replayed.procedure.models)
    fresh = make_procedure(replayed.protocol.procedure, 0.5,
                           display=design_display(DisplayDescription.braille_row(), replayed.protocol))
    np.testing.assert_array_equal(replayed.procedure.stats, fresh.stats)


def test_an_edited_display_description_is_refused_at_replay(tmp_path):
    path, _ = _run(tmp_path, "edited")
    with sqlite3.connect(path) as db:
        db.execute("UPDATE meta SET value = ? WHERE key = 'display_description'", ('{"rows": -1}',))
    db.close()
    with pytest.raises(ValueError, match="recorded display description is invalid"):
        replay_session(path)


def test_a_deflection_display_leaves_the_design_on_the_surface_and_says_so(tmp_path):
    description = DisplayDescription.braille_row().model_copy(update={"max_traction_pa": None})
    protocol = _protocol()
    assert design_display(description, protocol) is None
    observer = SimulatedObserver.from_model(protocol, TransductionModel("zx@2mm"), threshold_strain=3e-4,
                                            exponent=1.2, lapse=0.02, seed=4)
    display = SimulatedDisplay(description, tractor_stiffness_pa_per_m=1e9, realtime=False)
    with pytest.warns(UserWarning, match="design predicts from the ideal surface"):
        new_session(protocol, tmp_path / "s.sqlite", display, observer, subject="S01", realtime=False)
    replayed = replay_session(tmp_path / "s.sqlite")
    assert replayed.meta["design_strain"] == "surface"
    assert all(m.source == "surface" for m in replayed.procedure.models)

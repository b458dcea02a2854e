"""A model-discrimination design predicts through the solved contact of the protocol's finger (issue 27):
a protocol with a ``[finger]`` table, on a display whose rendering cannot be modelled (commanded in
deflection), gives the design ``TransductionModel(source="contact")`` hypotheses; the session records
``design_strain = "contact"`` and a resume rebuilds the same design.

Oracle: the design's statistics equal those of ``TransductionModel(source="contact")`` built by hand
from ``FingerContact.from_config(protocol.finger)`` on every candidate (the same solves: equal to the bit)."""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments import SimulatedDisplay, make_procedure, new_session, resume_session
from tactilab.experiments import replay_session, session_dataframe
from tactilab.experiments.modelling import FingerContact
from tactilab.experiments.modelling.design import from_config
from tactilab.experiments.modelling.models import TransductionModel
from tactilab.experiments.session.design_source import design_source, recorded_design_source

from stop_after import StopAfter

STIMULUS = {"amplitude_m": "10um", "pitch_m": "3mm", "speed_m_per_s": "20mm/s", "duration_s": "50ms", "ramp_s": "5ms"}
PROCEDURE = {"method": "model_discrimination", "parameter": "pitch_m", "models": ["zx@1mm", "zz@2mm"],
             "max_trials": 10, "candidates": {"pitch_m": ["2mm", "4mm"], "amplitude_m": ["5um", "40um"],
                            "speed_m_per_s": ["20mm/s"]}}
FINGER = {"finger_radius_m": "10mm", "normal_force_n": "0.5N", "friction": 0.5, "young_modulus_pa": "1MPa"}
DEFLECTION = DisplayDescription.braille_row().model_copy(update={"max_traction_pa": None})


def _protocol(finger=True):
    return Protocol.model_validate({"name": "designcontact", "seed": 3, "iti_s": 0, "task": {"kind": "2ifc"},
                                    "stimulus": STIMULUS, "procedure": PROCEDURE, "clipped": "allow",
                                    **({"finger": FINGER} if finger else {})})


def test_the_design_predicts_through_the_fingers_solved_contact():
    protocol = _protocol()
    source = design_source(DEFLECTION, protocol)
    assert source.strain == "contact" and source.finger == protocol.finger and source.display is None
    design = make_procedure(protocol.procedure, 0.5, **source.keywords())
    assert design.names == ["zx@1mm", "zz@2mm"] and all(m.source == "contact" for m in design.models)
    finger = FingerContact.from_config(protocol.finger)
    for m, name in enumerate(design.names):
        by_hand = TransductionModel(name, source="contact", contact=finger)
        assert design.stats[m, :, 0].tolist() == [by_hand.statistic_of(c) for c in design.candidates]
    surface = make_procedure(protocol.procedure, 0.5)  # the ideal surface predicts otherwise: 40 um is far from it
    assert not np.allclose(surface.stats, design.stats, rtol=0.05)
    # a display that renders in traction is what the subject feels: it wins over the finger
    assert design_source(DisplayDescription.braille_row(), protocol).strain == "display"
    assert design_source(DEFLECTION, _protocol(finger=False)).strain == "surface"


def test_a_design_takes_one_strain_source():
    protocol = _protocol()
    rendered = design_source(DisplayDescription.braille_row(), protocol).display
    with pytest.raises(ValueError, match="display, finger: a design predicts from one strain source"):
        from_config(protocol.procedure, display=rendered, finger=protocol.finger)


def test_recorded_sources_that_the_session_lacks_are_refused():
    with pytest.raises(ValueError, match="session: design_strain 'ideal' is not one of"):
        recorded_design_source({"design_strain": "ideal"}, _protocol(), None)
    with pytest.raises(ValueError, match="design_strain 'contact' but the recorded protocol has no \\[finger\\]"):
        recorded_design_source({"design_strain": "contact"}, _protocol(finger=False), None)
    assert recorded_design_source({}, _protocol(), None).strain == "surface"  # recorded before design_strain




def _run(tmp_path, name, stop_at=None):
    protocol = _protocol()
    observer = StopAfter.from_model(protocol, TransductionModel("zz@2mm"), threshold_strain=3e-4, exponent=1.2,
                                    lapse=0.02, seed=4)
    observer.stop_at = stop_at
    path = tmp_path / f"{name}.sqlite"
    with pytest.warns(UserWarning, match=r"design predicts from the protocol's \[finger\] pressing the gratings"):
        result = new_session(protocol, path, SimulatedDisplay(DEFLECTION, tractor_stiffness_pa_per_m=1e9,
                                                              realtime=False), observer, subject="S01", realtime=False)
    if stop_at is not None:
        assert result.status == "interrupted" and result.n_completed == stop_at
        observer.stop_at = None
        result = resume_session(path, SimulatedDisplay(DEFLECTION, tractor_stiffness_pa_per_m=1e9, realtime=False),
                                observer, realtime=False)
    return path, result


def test_the_session_records_the_contact_design_and_resume_rebuilds_it(tmp_path):
    whole_path, whole = _run(tmp_path, "whole")
    cut_path, cut = _run(tmp_path, "cut", stop_at=4)
    assert whole.estimate == cut.estimate
    a, b = session_dataframe(whole_path), session_dataframe(cut_path)
    for col in ("level", "track", "procedure_state"):
        assert a[col].tolist() == b[col].tolist(), col
    replayed = replay_session(cut_path)
    assert replayed.meta["design_strain"] == "contact"
    assert all(m.source == "contact" for m in replayed.procedure.models)
    fresh = make_procedure(replayed.protocol.procedure, 0.5, finger=replayed.protocol.finger)
    np.testing.assert_array_equal(replayed.procedure.stats, fresh.stats)

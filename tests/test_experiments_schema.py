"""Protocol, trial-record and session schemas: units at the edge, validation, round trips."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import hypothesis.strategies as st
import pytest
from hypothesis import HealthCheck, given, settings

from tactilab.data_schemas.experiment import Protocol, Stimulus, Task, check_label
from tactilab.data_schemas.experiment_records import (
    Session, TrialRecord, trials_from_dataframe, trials_to_dataframe)

BASE = {
    "name": "det", "seed": 5, "task": {"kind": "2ifc"},
    "stimulus": {"amplitude_m": "20um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s", "duration_s": "300ms"},
    "procedure": {"method": "staircase", "parameter": "amplitude_m", "tracks": [
        {"start": "20um", "step_sizes": [0.2, 0.1], "min_level": "0.2um", "max_level": "100um"}]},
}


def with_(path: str, value):
    """BASE with one nested key replaced (``"a.b.0.c"``); value None deletes it."""
    import copy

    data = copy.deepcopy(BASE)
    keys = path.split(".")
    node = data
    for key in keys[:-1]:
        node = node[int(key)] if isinstance(node, list) else node[key]
    if value is None:
        del node[keys[-1]]
    else:
        node[keys[-1]] = value
    return data


def test_units_are_converted_to_si_once():
    protocol = Protocol.model_validate(BASE)
    assert protocol.stimulus.amplitude_m == pytest.approx(20e-6)
    assert protocol.stimulus.pitch_m == pytest.approx(2e-3)
    assert protocol.stimulus.speed_m_per_s == pytest.approx(0.04)
    assert protocol.stimulus.duration_s == pytest.approx(0.3)
    track = protocol.procedure.tracks[0]
    assert (track.start, track.min_level, track.max_level) == pytest.approx((20e-6, 0.2e-6, 100e-6))
    assert Protocol.model_validate_json(protocol.to_json()) == protocol  # SI floats pass unchanged


def test_example_protocol_files_load(tmp_path):
    from pathlib import Path

    examples = sorted((Path(__file__).resolve().parents[1] / "examples").glob("protocol_*.toml"))
    assert len(examples) >= 3
    for path in examples:
        protocol = Protocol.from_toml(path)
        assert Protocol.model_validate_json(protocol.to_json()) == protocol
    psi = Protocol.from_toml(examples[[p.name for p in examples].index("protocol_psi.toml")])
    assert psi.procedure.parameters["threshold"][0] == pytest.approx(0.5e-6)
    assert len(psi.procedure.levels) == 30


def test_staircase_track_built_directly_refuses_nan():
    from tactilab.data_schemas.experiment import StaircaseTrack

    with pytest.raises(ValueError, match="start: must be finite, got nan"):
        StaircaseTrack(start=math.nan, step_sizes=[0.1], min_level=1e-6, max_level=1e-5)


def test_linear_staircase_steps_take_units():
    data = with_("procedure.tracks.0.step_scale", "linear")
    data["procedure"]["tracks"][0]["step_sizes"] = ["2um", "1um"]
    assert Protocol.model_validate(data).procedure.tracks[0].step_sizes == pytest.approx([2e-6, 1e-6])


@pytest.mark.parametrize("path,value,match", [
    ("stimulus.pitch_m", "-2mm", "pitch_m: must be finite and > 0 m"),
    ("stimulus.pitch_m", "2kPa", "unit 'kPa' measures pressure, but a length is expected"),
    ("stimulus.pitch_m", "2 furlongs", "unknown unit 'furlongs'"),
    ("stimulus.amplitude_m", "-1um", "amplitude_m: must be >= 0 m"),
    ("stimulus.amplitude_m", "nan", "must be finite"),
    ("stimulus.speed_m_per_s", float("inf"), "must be finite"),
    ("stimulus.phase_rad", float("nan"), "phase_rad: must be finite"),
    ("stimulus.duration_s", "2min", "unknown unit 'min'"),
    ("stimulus.duration_s", "90s", "duration_s: must be <= 60 s"),
    ("stimulus.ramp_s", "200ms", "ramp_s: must lie in \\[0, duration_s / 2\\]"),
    ("stimulus.frame_rate_hz", "5Hz", "fewer than 2 frames"),
    ("stimulus.colour", "red", "Extra inputs are not permitted"),
    ("name", "my task", "must be 1-32 letters or digits"),
    ("seed", -1, "greater than or equal to 0"),
    ("iti_s", "2min", "unknown unit"),
    ("iti_s", "90s", "iti_s: must lie in \\[0, 60\\] s"),
    ("task.kind", "3afc", "Input should be"),
    ("task.interval_gap_s", "-1s", "interval_gap_s: must be >= 0 s"),
    ("task.catch_rate", 1.0, "catch_rate: must lie in \\[0, 1\\)"),
    ("task.same_rate", 0.0, "same_rate: must lie in \\(0, 1\\)"),
    ("task.magnitude_max", 12, "one digit key"),
    ("task.keys", {"1": "a"}, "keys: must map exactly the responses"),
    ("task.keys", {"1": "a", "2": "a"}, "keys: need distinct single printable keys"),
    ("task.keys", {"1": "q", "2": "w"}, "other than space and 'q'"),
    ("task.alternatives", {"l": {}, "r": {}}, "only a 2afc task takes alternatives"),
    ("procedure.method", "bisection", "method: must name a registered procedure"),
    ("procedure.parameter", "colour", "parameter: must be one of"),
    ("procedure.tracks", [], "at least 1 item"),
    ("procedure.tracks.0.step_sizes", [], "step_sizes: need at least one finite step > 0"),
    ("procedure.tracks.0.step_sizes", [0.1, -0.1], "step_sizes: need at least one finite step > 0"),
    ("procedure.tracks.0.start", "500um", "start: must lie in \\[min_level, max_level\\]"),
    ("procedure.tracks.0.min_level", "0um", "a log staircase needs min_level > 0"),
    ("procedure.tracks.0.start", "20mm/s", "measures speed, but a length is expected"),
    ("procedure.tracks.0.up", 0, "greater than or equal to 1"),
])
def test_invalid_protocols_are_rejected_with_field_rule_value_and_fix(path, value, match):
    with pytest.raises(ValueError, match=match):
        Protocol.model_validate(with_(path, value))


def test_every_level_a_procedure_can_choose_must_give_a_valid_stimulus():
    data = with_("procedure", {"method": "constant_stimuli", "parameter": "pitch_m", "levels": ["0mm", "2mm"]})
    with pytest.raises(ValueError, match="procedure: level 0.0 of pitch_m gives an invalid stimulus .*pitch_m: must be finite and > 0"):
        Protocol.model_validate(data)
    data = with_("procedure", {"method": "constant_stimuli", "parameter": "duration_s", "levels": ["1ms", "50ms"]})
    with pytest.raises(ValueError, match="level 0.001 of duration_s .*ramp_s: must lie in"):
        Protocol.model_validate(data)


def test_amplitude_ceiling_of_one_millimetre_is_not_a_schema_rule():
    """The schema accepts any non-negative amplitude; the display's safety layer limits the drive."""
    assert Protocol.model_validate(with_("stimulus.amplitude_m", "1mm")).stimulus.amplitude_m == 1e-3


@pytest.mark.parametrize("levels,match", [
    ([], "levels: needs at least one value"),
    ("5um", "expected a list of values or a \\{start, stop, n\\} table"),
    ({"start": "1um", "stop": "5um"}, "needs exactly start, stop, n"),
    ({"start": "1um", "stop": "5um", "n": 1}, "n: must be an integer in \\[2, 10000\\]"),
    ({"start": "1um", "stop": "5um", "n": 3, "scale": "cubic"}, "scale: must be 'linear' or 'log'"),
    ({"start": "0um", "stop": "5um", "n": 3, "scale": "log"}, "a log grid needs start and stop > 0"),
    ({"start": "5um", "stop": "1um", "n": 3}, "stop must exceed start"),
])
def test_level_grids_are_validated(levels, match):
    data = with_("procedure", {"method": "constant_stimuli", "parameter": "amplitude_m", "levels": levels})
    with pytest.raises(ValueError, match=match):
        Protocol.model_validate(data)


def _psi(**changes):
    proc = {"method": "psi", "parameter": "amplitude_m", "levels": ["1um", "2um", "4um"],
            "parameters": {"threshold": ["1um", "2um"], "slope": [2.0], "lapse": [0.0]}}
    proc.update(changes)
    return with_("procedure", proc)


@pytest.mark.parametrize("changes,match", [
    ({"likelihood": "mymod:f"}, "likelihood: must be the name of a registered likelihood"),
    ({"likelihood": "pickle:loads"}, "never holds an import path"),
    ({"likelihood": "../evil"}, "never holds an import path"),
    ({"parameters": {"threshold": ["1um"], "slope": [2.0]}}, "needs grids for exactly threshold, slope"),
    ({"parameters": {"threshold": ["1um"], "slope": [2.0], "lapse": [0.6]}}, "lapse: values must lie in"),
    ({"parameters": {"threshold": ["1um"], "slope": [-2.0], "lapse": [0.0]}}, "slope: values must be > 0"),
    ({"parameters": {"threshold": ["1um"], "slope": [2.0], "lapse": [0.0]}, "guess_rate": 1.0}, "guess_rate: must lie"),
    ({"likelihood": "mymodel", "parameters": {"a": [float("nan")]}}, "parameters.a\\[0\\]: must be finite"),
    ({"likelihood": "mymodel", "parameters": {"a": {"start": 0, "stop": 1, "n": 10000},
                                               "b": {"start": 0, "stop": 1, "n": 1000}}}, "above 5e6"),
])
def test_psi_configuration_is_validated(changes, match):
    with pytest.raises(ValueError, match=match):
        Protocol.model_validate(_psi(**changes))


def test_psi_custom_likelihood_grids_are_dimensionless_except_threshold():
    protocol = Protocol.model_validate(_psi(likelihood="strain_likelihood",
                                            parameters={"threshold": ["2um"], "gain": [1, 2]}))
    assert protocol.procedure.parameters == {"threshold": [2e-6], "gain": [1.0, 2.0]}


@pytest.mark.parametrize("task,extra,match", [
    ({"kind": "2afc"}, {}, "a 2afc task needs exactly two labelled alternatives"),
    ({"kind": "2afc", "alternatives": {"left": {"hue": 1}, "right": {}}}, {}, "unknown stimulus fields"),
    ({"kind": "2afc", "alternatives": {"le ft": {}, "right": {}}}, {}, "must be 1-32 letters or digits"),
    ({"kind": "2afc", "alternatives": {"left": {"amplitude_m": 1e-6}, "right": {}}}, {},
     "overrides amplitude_m, the parameter the procedure varies"),
    ({"kind": "2afc", "alternatives": {"left": {"pitch_m": -1.0}, "right": {}}}, {}, "task.alternatives.left: .*pitch_m"),
    ({"kind": "same_different"}, {}, "a same_different task needs a reference stimulus"),
    ({"kind": "magnitude_estimation"}, {}, "magnitude_estimation has no correct answer"),
])
def test_task_consistency_with_procedure_and_stimuli(task, extra, match):
    with pytest.raises(ValueError, match=match):
        Protocol.model_validate({**with_("task", task), **extra})


def test_task_labels_and_default_keys():
    assert Task(kind="2ifc").key_map == {"1": "1", "2": "2"}
    assert Task(kind="yes_no").key_map == {"y": "yes", "n": "no"}
    assert Task(kind="same_different").key_map == {"s": "same", "d": "different"}
    assert Task(kind="magnitude_estimation", magnitude_min=1, magnitude_max=3).key_map == {"1": "1", "2": "2", "3": "3"}
    two = Task(kind="2afc", alternatives={"left": {}, "right": {}}, keys={"left": "a", "right": "l"})
    assert two.key_map == {"a": "left", "l": "right"} and two.guess_rate == 0.5
    assert Task(kind="yes_no").guess_rate == 0.0


def test_invalid_toml_names_the_file(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("name = 'x\n")
    with pytest.raises(ValueError, match="bad.toml: not valid TOML"):
        Protocol.from_toml(path)
    with pytest.raises(FileNotFoundError, match="protocol file not found"):
        Protocol.from_toml(tmp_path / "missing.toml")
    load = tmp_path / "load.toml"  # a load file given as a protocol by mistake
    load.write_text("[grid]\nshape = [8, 8]\nspacing = '0.1mm'\n")
    with pytest.raises(ValueError, match=r"load.toml \(protocol\): name: missing; this key is required; .*"
                                         r"grid: unknown key"):
        Protocol.from_toml(load)


def test_check_label_refuses_names():
    assert check_label("S01", "subject") == "S01"
    with pytest.raises(ValueError, match="subject: must be 1-32 letters or digits.*never a name"):
        check_label("Jane Doe", "subject")


# ----- trial records ---------------------------------------------------------------------
def trial(index=0, **changes) -> TrialRecord:
    now = datetime(2026, 11, 22, 5, 0, tzinfo=UTC)
    data = dict(subject="S01", session="01", block=0, trial_index=index, attempt=0, repeated=False, track=0,
                parameter="amplitude_m", level=2e-6 * (index + 1),
                stimuli=[Stimulus(amplitude_m=0.0, pitch_m=2e-3, speed_m_per_s=0.04),
                         Stimulus(amplitude_m=2e-6, pitch_m=2e-3, speed_m_per_s=0.04)],
                target="2", procedure_state={"levels": [1e-6], "estimate": {"threshold": None}},
                response="2", correct=True, rt_s=0.41, utc_planned=now, utc_presented=now, utc_response=now,
                monotonic_onset_ns=10, monotonic_response_ns=410_000_010, seed=5, package_version="0.1.0",
                display_id="VirtualBrailleRow")
    data.update(changes)
    return TrialRecord(**data)


def test_trial_records_round_trip_through_json_and_dataframe():
    trials = [trial(0), trial(1, target=None, correct=None, response="1"), trial(2, attempt=1, repeated=True)]
    assert [TrialRecord.model_validate_json(t.model_dump_json()) for t in trials] == trials
    frame = trials_to_dataframe(trials)
    assert list(frame["interval2_amplitude_m"]) == [2e-6] * 3 and "amplitude_m" not in frame
    assert list(frame["interval1_surface"]) == ["sinusoid"] * 3 and frame["utc_presented"].dt.tz is not None
    assert trials_from_dataframe(frame) == trials


def test_session_round_trips_through_json():
    session = Session(session_id="abc", subject="S01", session="01", protocol=Protocol.model_validate(BASE), seed=5,
                      package_version="0.1.0", display_id="X", responses="simulated",
                      created_utc=datetime(2026, 11, 22, tzinfo=UTC), status="complete", trials=[trial(0), trial(1)])
    assert Session.model_validate_json(session.model_dump_json()) == session


@pytest.mark.parametrize("changes,match", [
    ({"level": math.nan}, "level: must be finite"),
    ({"rt_s": -0.1}, "rt_s: must be finite and >= 0 s"),
    ({"repeated": True}, "a repeated trial has attempt > 0"),
    ({"stimuli": []}, "stimuli: a trial commands at least one stimulus"),
    ({"subject": "Jane Doe"}, "subject: must be 1-32 letters or digits"),
])
def test_trial_record_validation(changes, match):
    with pytest.raises(ValueError, match=match):
        trial(0, **changes)


def test_session_trial_indices_unique_and_dataframe_columns_checked():
    with pytest.raises(ValueError, match="trial_index values must be unique"):
        Session(session_id="a", subject="S01", session="01", protocol=Protocol.model_validate(BASE), seed=5,
                package_version="0", display_id="X", responses="simulated", created_utc=datetime.now(UTC),
                status="running", trials=[trial(0), trial(0)])
    with pytest.raises(ValueError, match="frame: missing trial columns \\['subject'"):
        trials_from_dataframe(trials_to_dataframe([trial(0)]).drop(columns=["subject"]))


# ----- fuzzing: invalid protocol files are rejected with a clear error -----------------------
_BAD_VALUES = {
    "stimulus.pitch_m": st.sampled_from(["-1mm", "0mm", "nan", "inf", "2kPa", "x", "1 parsec", True]),
    "stimulus.amplitude_m": st.sampled_from(["-3um", "nan", "3ms", "um", None]),
    "stimulus.duration_s": st.one_of(st.floats(max_value=0.0), st.floats(min_value=60.001, allow_infinity=True)),
    "stimulus.speed_m_per_s": st.sampled_from(["fast", "1 m", "nan", "-inf"]),
    "task.kind": st.text(max_size=8).filter(lambda s: s not in ("2afc", "2ifc", "yes_no")),
    "task.catch_rate": st.one_of(st.floats(max_value=-1e-9), st.floats(min_value=1.0)),
    "procedure.tracks.0.start": st.sampled_from(["-1um", "1mm", "1kHz", "nan"]),
    "procedure.tracks.0.step_sizes": st.lists(st.floats(max_value=0.0), min_size=1, max_size=3),
    "procedure.parameter": st.text(max_size=12).filter(lambda s: s not in ("amplitude_m", "pitch_m")),
    "seed": st.one_of(st.integers(max_value=-1), st.just("seven"), st.integers(min_value=2**63)),
    "name": st.text(min_size=1, max_size=40).filter(lambda s: not s.isalnum() or not s.isascii() or len(s) > 32),
}


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_fuzzed_invalid_protocols_are_rejected_with_a_clear_error(data):
    """One corrupted field per draw: always a ValueError whose message names that field."""
    path = data.draw(st.sampled_from(sorted(_BAD_VALUES)))
    value = data.draw(_BAD_VALUES[path])
    with pytest.raises(ValueError) as info:
        Protocol.model_validate(with_(path, value))
    field = path.split(".")[-1] if not path.split(".")[-1].isdigit() else path.split(".")[-2]
    locations = [".".join(str(x) for x in e["loc"]) + " " + e["msg"] for e in info.value.errors()]
    assert any(field in text or "procedure" in text for text in locations), locations


# ----- bad inputs: caps, printable text, subject codes ------------------------------------------
def test_caps_on_planned_trials_text_and_file_size(tmp_path):
    from tactilab.data_schemas.experiment import MAX_PROTOCOL_BYTES

    huge = with_("procedure", {"method": "constant_stimuli", "parameter": "amplitude_m",
                               "levels": {"start": "1um", "stop": "9um", "n": 200},
                               "repeats_per_block": 1000, "n_blocks": 1000})
    with pytest.raises(ValueError, match="procedure: plans 200000000 trials, above the cap of 100000"):
        Protocol.model_validate(huge)
    with pytest.raises(ValueError, match="description: at most 2000 characters"):
        Protocol.model_validate(with_("description", "x" * 2001))
    with pytest.raises(ValueError, match="prompt: only printable characters .*'\\\\x1b'"):
        Protocol.model_validate(with_("task", {"kind": "2ifc", "prompt": "Which? \x1b[2J\x1b]0;owned\x07"}))
    big = tmp_path / "big.toml"
    big.write_text("# " + "x" * MAX_PROTOCOL_BYTES)
    with pytest.raises(ValueError, match="big.toml: 1000002 bytes, above the 1000000-byte cap"):
        Protocol.from_toml(big)
    deep = tmp_path / "deep.toml"
    deep.write_text("x = " + "[" * 5000 + "]" * 5000)
    with pytest.raises(ValueError, match="deep.toml: nested too deeply|deep.toml: not valid TOML"):
        Protocol.from_toml(deep)


@pytest.mark.parametrize("code,ok", [("S01", True), ("P0042", True), ("S19", True), ("A1B2C3", True),
                                     ("JaneDoe", False), ("JaneDoe19850412", False), ("S19850412", False),
                                     ("x120485", False), ("MaxMustermann", False)])
def test_subject_codes_that_look_like_names_or_dates_are_refused(code, ok):
    from tactilab.data_schemas.experiment import check_subject

    if ok:
        assert check_subject(code) == code
    else:
        with pytest.raises(ValueError, match="looks like a name or a date of birth"):
            check_subject(code)


def test_a_lab_pattern_replaces_the_heuristics():
    from tactilab.data_schemas.experiment import check_subject

    assert check_subject("KarlaX1", pattern="[A-Z][a-z]+X[0-9]") == "KarlaX1"
    with pytest.raises(ValueError, match="does not match the lab's subject pattern"):
        check_subject("S01", pattern="P[0-9]{4}")
    with pytest.raises(ValueError, match="is not a valid regular expression"):
        check_subject("S01", pattern="(")


def test_levels_are_validated_under_every_2afc_alternative_and_staircase_bound():
    # each alternative is valid with [stimulus] (300 ms) but not with the 100 ms level
    data = with_("procedure", {"method": "constant_stimuli", "parameter": "duration_s", "levels": ["100ms", "300ms"]})
    data["task"] = {"kind": "2afc", "alternatives": {"slow": {"ramp_s": "60ms"}, "fast": {}}}
    with pytest.raises(ValueError, match=r"procedure: level 0\.1 of duration_s under task\.alternatives\.slow gives "
                                         r"an invalid stimulus \(ramp_s: must lie in .*got 0\.06; .*\); 1 of 2 "
                                         r"planned stimuli break the ramp_s rule; narrow the levels"):
        Protocol.model_validate(data)
    # a staircase's bounds (every level between valid bounds is valid: each rule is an interval)
    track = {"start": "100ms", "step_sizes": [0.1], "min_level": "10ms", "max_level": "300ms"}
    data = with_("procedure", {"method": "staircase", "parameter": "duration_s", "tracks": [track]})
    with pytest.raises(ValueError, match=r"procedure: level 0\.01 of duration_s gives an invalid stimulus "
                                         r"\(ramp_s: .*got 0\.02; .*\); 1 of 2 planned stimuli"):
        Protocol.model_validate(data)
    track["min_level"] = "40ms"
    assert Protocol.model_validate(data).procedure.tracks[0].min_level == pytest.approx(0.04)


def _protocol_file(tmp_path, procedure: str):
    path = tmp_path / "protocol.toml"
    path.write_text(
        'name = "det"\nseed = 5\n[task]\nkind = "2ifc"\n[stimulus]\namplitude_m = "20um"\npitch_m = "2mm"\n'
        'speed_m_per_s = "40mm/s"\nduration_s = "300ms"\n[procedure]\n' + procedure, encoding="utf-8")
    return path


@pytest.mark.parametrize("procedure,message", [
    ('method = "constant_stimuli"\nparameter = "pitch_m"\nlevels = [0.8, 1.2]\n',
     r'levels = \[0\.8, 1\.2\] has no unit; in a protocol file every level of pitch_m \(a length\) is written with '
     r'its unit, e\.g\. levels = \["0\.8mm", "1\.2mm"\]; a bare number is not read as SI \(as m it would be '
     r'"800mm", "1200mm"\)'),
    ('method = "constant_stimuli"\nparameter = "pitch_m"\nlevels = {start = 0.8, stop = "3.2mm", n = 4}\n',
     r'levels\.start = 0\.8 has no unit;.* e\.g\. levels\.start = "0\.8mm"'),
    ('method = "staircase"\nparameter = "amplitude_m"\n[[procedure.tracks]]\nstart = 0.00002\n'
     'step_sizes = [0.2]\nmin_level = "0.2um"\nmax_level = "100um"\n',
     r'tracks\[0\]\.start = 2e-05 has no unit; .*amplitude_m \(a length\).* e\.g\. tracks\[0\]\.start = "2e-05um"; '
     r'a bare number is not read as SI \(as m it would be "20um"\)'),
    ('method = "staircase"\nparameter = "amplitude_m"\n[[procedure.tracks]]\nstart = "20um"\nstep_scale = "linear"\n'
     'step_sizes = [2e-6]\nmin_level = "0.2um"\nmax_level = 0.0001\n', r"tracks\[0\]\.max_level = 0\.0001 has no unit"),
    ('method = "staircase"\nparameter = "amplitude_m"\n[[procedure.tracks]]\nstart = "20um"\nstep_scale = "linear"\n'
     'step_sizes = [2e-6]\nmin_level = "0.2um"\nmax_level = "100um"\n', r"tracks\[0\]\.step_sizes = \[2e-06\] has no unit"),
    ('method = "psi"\nparameter = "amplitude_m"\nlevels = ["1um", "2um"]\n'
     'parameters = {threshold = [1e-6, 2e-6], slope = [2.0], lapse = [0.02]}\n',
     r"parameters\.threshold = \[1e-06, 2e-06\] has no unit"),
])
def test_bare_levels_in_a_protocol_file_are_refused_not_read_as_metres(tmp_path, procedure, message):
    """The file rule: a field without a unit in its name (levels, start, ...) needs its unit written."""
    with pytest.raises(ValueError, match=message):
        Protocol.from_toml(_protocol_file(tmp_path, procedure))


def test_levels_with_units_in_a_file_and_si_numbers_from_python_still_load(tmp_path):
    protocol = Protocol.from_toml(_protocol_file(
        tmp_path, 'method = "constant_stimuli"\nparameter = "pitch_m"\nlevels = ["0.8mm", "1.2mm"]\n'))
    assert protocol.procedure.levels == pytest.approx([0.8e-3, 1.2e-3])
    python = Protocol.model_validate(with_("procedure.tracks.0.start", 2e-5))  # Python numbers are SI
    assert python.procedure.tracks[0].start == 2e-5

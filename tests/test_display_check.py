"""Designs respect the display: a planned stimulus the display would limit is refused before a session.

Oracle: the safety layer itself (``limit_drive``): a stimulus is refused exactly when the
frames the runner would render for it are limited; the error names the stimulus and the limit.
Under ``clipped = "drop"`` exactly those stimuli are left out (the same oracle), counted and recorded.
"""

from __future__ import annotations

import json
import tomllib

import pytest

from tactilab.cli.main import main
from tactilab.data_schemas import DisplayDescription, Protocol
from tactilab.experiments import SimulatedDisplay, SimulatedObserver, new_session
from tactilab.experiments.session import check_display_limits, clipped_stimuli, drop_clipped
from tactilab.experiments.session.display_check import _limited
from tactilab.experiments.session.recording import SessionLog

from test_design_multifield import PROTOCOL

CONSTANT = """
name = "dropconst"
seed = 3
iti_s = 0
clipped = "drop"
[task]
kind = "2ifc"
[stimulus]
amplitude_m = "5um"
pitch_m = "2mm"
speed_m_per_s = "40mm/s"
duration_s = "50ms"
ramp_s = "5ms"
[procedure]
method = "constant_stimuli"
parameter = "amplitude_m"
levels = ["2um", "40um", "4um", "80um", "8um"]
repeats_per_block = 1
n_blocks = 1
"""

STAIRCASE = """
name = "dropstair"
seed = 3
iti_s = 0
[task]
kind = "2ifc"
[stimulus]
amplitude_m = "5um"
pitch_m = "2mm"
speed_m_per_s = "40mm/s"
duration_s = "50ms"
ramp_s = "5ms"
[procedure]
method = "staircase"
parameter = "amplitude_m"
[[procedure.tracks]]
start = "5um"
step_sizes = [0.1]
min_level = "1um"
max_level = "80um"
max_trials = 4
"""

LOUD = PROTOCOL.replace('amplitude_m = ["3um", "6um"]', 'amplitude_m = ["3um", "6um", "80um"]')


def test_a_design_candidate_above_the_amplitude_limit_is_refused_at_load(tmp_path, capsys):
    protocol = Protocol.model_validate(tomllib.loads(LOUD))
    braille = DisplayDescription.braille_row()
    bad = clipped_stimuli(protocol, braille)
    assert bad and all("amplitude 80 um" in where for where, _ in bad)  # only the loud candidates
    assert {hit["kind"] for _, hit in bad} == {"amplitude_clip"}
    assert clipped_stimuli(Protocol.model_validate(tomllib.loads(PROTOCOL)), braille) == []
    display = SimulatedDisplay(braille, realtime=False)
    with pytest.raises(ValueError, match=r"protocol: procedure.candidates\[[0-9]+\] .*amplitude 80 um.* exceeds "
                                         r"the display.s limits: amplitude_clip at [0-9.e+]+ Pa \(requested "
                                         r"[0-9.e+]+ Pa\)"):
        new_session(protocol, tmp_path / "s.sqlite", display, SimulatedObserver(protocol), subject="S01",
                    realtime=False)
    assert not (tmp_path / "s.sqlite").exists()  # refused before any file exists
    assert check_display_limits(protocol, braille, "allow") == len(bad)
    with pytest.raises(ValueError, match=r"clipped: must be one of \('refuse', 'drop', 'allow'\), got 'clip'"):
        check_display_limits(protocol, braille, "clip")
    (tmp_path / "loud.toml").write_text(LOUD)
    assert main(["experiment", "run", str(tmp_path / "loud.toml"), "--subject", "S01", "--responses", "simulated",
                 "--no-wait", "--quiet", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "amplitude 80 um" in err and "exceeds the display's limits: amplitude_clip at" in err
    assert not list((tmp_path / "out").glob("*.sqlite"))


def test_drop_removes_exactly_the_clipped_levels_counts_and_records_them(tmp_path):
    protocol = Protocol.model_validate(tomllib.loads(CONSTANT))
    braille = DisplayDescription.braille_row()
    limited = {i for i, _, _ in _limited(protocol, braille)}
    assert limited == {1, 3}  # 40 um and 80 um: what the safety layer would clip, nothing else
    kept, dropped = drop_clipped(protocol, braille)
    assert kept.procedure.levels == pytest.approx([2e-6, 4e-6, 8e-6])
    assert len(dropped) == 2 and "amplitude 40 um" in dropped[0] and "amplitude 80 um" in dropped[1]
    assert _limited(kept, braille) == []
    display = SimulatedDisplay(braille, realtime=False)
    with pytest.warns(UserWarning, match=r"clipped='drop': dropped 2 of 5 planned stimuli .* the other 3"):
        result = new_session(protocol, tmp_path / "s.sqlite", display, SimulatedObserver(protocol), subject="S01",
                             realtime=False)
    assert result.status == "complete" and result.n_completed == 3
    log = SessionLog(tmp_path / "s.sqlite")
    meta, events = log.meta(), log.events()
    assert meta["clipped"] == {"policy": "drop", "n_planned": 5, "dropped": dropped}
    assert meta["protocol"]["procedure"]["levels"] == pytest.approx([2e-6, 4e-6, 8e-6])  # the protocol run
    kinds = [e["kind"] for e in events]
    assert kinds[:2] == ["session_started", "planned_stimuli_dropped"]
    assert events[1]["payload"]["dropped"] == dropped
    # the argument overrides the protocol's field: refused under "refuse"
    with pytest.raises(ValueError, match=r"protocol: procedure: level 4e-05 of amplitude_m .* exceeds the display"):
        new_session(protocol, tmp_path / "r.sqlite", display, SimulatedObserver(protocol), subject="S01",
                    realtime=False, clipped="refuse")


def test_drop_removes_exactly_the_clipped_design_candidates():
    protocol = Protocol.model_validate(tomllib.loads(LOUD))
    braille = DisplayDescription.braille_row()
    before = protocol.procedure.planned_fields()
    limited = {i for i, _, _ in _limited(protocol, braille)}
    kept, dropped = drop_clipped(protocol, braille)
    assert len(dropped) == len(limited) > 0
    after = kept.procedure.planned_fields()
    assert [w for w, _ in after] == [w for i, (w, _) in enumerate(before) if i not in limited]  # original indices
    assert all(f["amplitude_m"] < 80e-6 for _, f in after)
    assert len(kept.procedure.stimuli()) == len(before) - len(limited)
    again = Protocol.model_validate(kept.model_dump(mode="json"))  # as a resumed session reads it back
    assert again.procedure.planned_fields() == after
    with pytest.raises(ValueError, match=r"dropped: must be distinct candidate indices in \[0, 18\) leaving at "
                                         r"least one candidate, got \[18\]"):
        Protocol.model_validate({**kept.model_dump(mode="json"),
                                 "procedure": {**kept.procedure.model_dump(mode="json"), "dropped": [18]}})


def test_a_staircase_bound_that_clips_is_refused_even_under_drop(tmp_path):
    protocol = Protocol.model_validate(tomllib.loads(STAIRCASE))
    braille = DisplayDescription.braille_row()
    with pytest.raises(ValueError, match=r"clipped: a staircase cannot drop its own range \(tracks\[0\].max_level = "
                                         r"8e-05 would be limited by the display, and a staircase may command "
                                         r"any level between its bounds\)"):
        drop_clipped(protocol, braille)
    display = SimulatedDisplay(braille, realtime=False)
    with pytest.raises(ValueError, match=r"clipped: a staircase cannot drop its own range"):
        new_session(protocol, tmp_path / "s.sqlite", display, SimulatedObserver(protocol), subject="S01",
                    realtime=False, clipped="drop")
    assert not (tmp_path / "s.sqlite").exists()


def test_drop_refuses_when_nothing_is_left_and_an_unknown_clipped_value():
    braille = DisplayDescription.braille_row()
    loud = CONSTANT.replace('["2um", "40um", "4um", "80um", "8um"]', '["40um", "80um"]')
    with pytest.raises(ValueError, match=r"clipped: the display would limit all 2 levels of amplitude_m; nothing is "
                                         r"left to run"):
        drop_clipped(Protocol.model_validate(tomllib.loads(loud)), braille)
    only = LOUD.replace('amplitude_m = ["3um", "6um", "80um"]', 'amplitude_m = ["80um"]')
    with pytest.raises(ValueError, match=r"clipped: the display would limit all 6 candidates; nothing is left"):
        drop_clipped(Protocol.model_validate(tomllib.loads(only)), braille)
    with pytest.raises(ValueError, match=r"clipped: must be one of \('refuse', 'drop', 'allow'\), got 'skip'; "
                                         r"'refuse' \(the default\)"):
        Protocol.model_validate(tomllib.loads(CONSTANT.replace('clipped = "drop"', 'clipped = "skip"')))


def test_cli_drop_prints_the_count_and_the_option_overrides_the_protocol(tmp_path, capsys):
    (tmp_path / "p.toml").write_text(CONSTANT)
    args = ["experiment", "run", str(tmp_path / "p.toml"), "--subject", "S01", "--responses", "simulated",
            "--no-wait", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert "dropped 2 of 5 planned stimuli the display would limit" in capsys.readouterr().err
    assert main([*args, "--out", str(tmp_path / "b"), "--clipped", "refuse"]) == 2
    assert "exceeds the display's limits" in capsys.readouterr().err
    assert not list((tmp_path / "b").glob("*.sqlite"))


class StopAt(SimulatedObserver):
    """The simulated observer, with Ctrl-C pressed at trial ``stop_at``."""

    stop_at = None

    def collect(self, plan):
        if plan.trial_index == self.stop_at:
            raise KeyboardInterrupt("test stop")
        return super().collect(plan)


def test_a_design_with_dropped_candidates_resumes_with_the_same_set(tmp_path):
    """The recorded protocol lists the dropped candidates: a resumed session runs the same design."""
    from tactilab.experiments.session import resume_session, session_dataframe

    protocol = Protocol.model_validate(tomllib.loads(LOUD))
    frames = []
    for name, stop in (("whole", None), ("cut", 4)):
        path = tmp_path / f"{name}.sqlite"
        observer = StopAt(protocol)
        observer.stop_at = stop
        with pytest.warns(UserWarning, match=r"clipped='drop': dropped 6 of 18 planned stimuli"):
            result = new_session(protocol, path, SimulatedDisplay(DisplayDescription.braille_row(), realtime=False),
                                 observer, subject="S01", realtime=False, clipped="drop")
        if stop is not None:
            assert result.status == "interrupted"
            result = resume_session(path, SimulatedDisplay(DisplayDescription.braille_row(), realtime=False),
                                    SimulatedObserver(protocol), realtime=False)
        assert result.status == "complete"
        log = SessionLog(path)
        assert len(log.meta()["protocol"]["procedure"]["dropped"]) == 6
        log.close()
        frames.append(session_dataframe(path))
    assert all(s[k]["amplitude_m"] < 80e-6 for s in frames[0]["stimuli"].map(json.loads) for k in range(len(s)))
    for col in ("level", "correct", "response", "procedure_state", "stimuli"):
        assert frames[0][col].tolist() == frames[1][col].tolist(), col

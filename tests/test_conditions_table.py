"""Constant stimuli over a conditions table (``conditions = "file.csv"``): a pitch x amplitude design.

Oracles: the CSV's values converted by hand (2 mm = 2e-3 m); the session's own trial records
(each trial shows its condition's fields, each condition ``repeats_per_block`` times per block);
the PsychoPy export's condition index against those records.
"""

from __future__ import annotations

import os
import tomllib

import pandas as pd
import pytest

from tactilab.cli.main import main
from tactilab.data_schemas import DisplayDescription, Protocol
from tactilab.data_schemas.conditions import read_conditions
from tactilab.experiments.session import drop_clipped, export_session
from tactilab.experiments.session.recording import SessionLog

PROTOCOL = """
name = "pitchamp"
seed = 6
iti_s = 0
[task]
kind = "2ifc"
[stimulus]
amplitude_m = "5um"
pitch_m = "3mm"
speed_m_per_s = "40mm/s"
duration_s = "20ms"
ramp_s = "5ms"
[procedure]
method = "constant_stimuli"
parameter = "amplitude_m"
conditions = "conditions.csv"
repeats_per_block = 2
n_blocks = 2
"""

TABLE = "pitch [mm],amplitude [um],surface\n2,3,sinusoid\n2,6,sinusoid\n4,3,square\n4,6,square\n"


def _write(folder, table: str = TABLE, protocol: str = PROTOCOL):
    (folder / "conditions.csv").write_text(table)
    (folder / "p.toml").write_text(protocol)
    return folder / "p.toml"


def test_a_conditions_table_gives_one_condition_per_row_in_si(tmp_path):
    protocol = Protocol.from_toml(_write(tmp_path))
    proc = protocol.procedure
    assert proc.conditions == [{"pitch_m": 2e-3, "amplitude_m": 3e-6, "surface": "sinusoid"},
                               {"pitch_m": 2e-3, "amplitude_m": 6e-6, "surface": "sinusoid"},
                               {"pitch_m": 4e-3, "amplitude_m": 3e-6, "surface": "square"},
                               {"pitch_m": 4e-3, "amplitude_m": 6e-6, "surface": "square"}]
    assert proc.levels == [3e-6, 6e-6, 3e-6, 6e-6] and proc.n_planned() == 16
    assert [f for _, f in proc.planned_fields()] == proc.conditions
    again = Protocol.model_validate(protocol.model_dump(mode="json"))  # as a session records and resumes it
    assert again == protocol


def test_a_session_shows_each_condition_and_exports_it_for_psychopy(tmp_path, capsys):
    path = _write(tmp_path)
    assert main(["experiment", "run", str(path), "--subject", "S01", "--responses", "simulated", "--no-wait",
                 "--quiet", "--out", str(tmp_path / "s")]) == 0
    capsys.readouterr()
    (session,) = (tmp_path / "s").glob("*.sqlite")
    log = SessionLog(session)
    trials = log.trials()
    log.close()
    assert len(trials) == 16
    shown = [next(s for s in t.stimuli if s.amplitude_m > 0) for t in trials]  # the 2IFC blank is amplitude 0
    rows = {(2e-3, 3e-6, "sinusoid"), (2e-3, 6e-6, "sinusoid"), (4e-3, 3e-6, "square"), (4e-3, 6e-6, "square")}
    for block in (0, 1):
        got = [(s.pitch_m, s.amplitude_m, s.surface) for s, t in zip(shown, trials) if t.block == block]
        assert sorted(got) == sorted(list(rows) * 2)  # every condition twice per block
    assert all(t.level == s.amplitude_m for s, t in zip(shown, trials))
    (csv,) = export_session(session, tmp_path / "x", "psychopy")
    frame = pd.read_csv(csv)
    assert list(frame.columns[4:7]) == ["amplitude_m", "pitch_m", "surface"]
    table = Protocol.from_toml(path).procedure.conditions
    for i, s, (_, r) in zip(frame["trials.thisIndex"], shown, frame.iterrows()):
        assert table[i] == {"pitch_m": s.pitch_m, "amplitude_m": s.amplitude_m, "surface": s.surface}
        assert (r["pitch_m"], r["amplitude_m"], r["surface"]) == (s.pitch_m, s.amplitude_m, s.surface)


@pytest.mark.parametrize("table, match", [
    ("pitch,amplitude [um]\n2,3\n", r"column 'pitch' has no unit; write it in brackets, e\.g\. 'pitch \[mm\]'"),
    ("pitch [mm],amplitude [um]\n2,3\n2,3\n", r"conditions 0 and 1 are the same .*; list each condition once"),
    ("pitch [mm],amplitude [um],colour\n2,3,red\n", r"unknown column 'colour'; use \['amplitude', 'duration', "),
    ("pitch [mm],pitch [um],amplitude [um]\n2,3,4\n", r"column 'pitch' appears twice; keep one"),
    ("pitch [mm],amplitude [um],surface [mm]\n2,3,square\n", r"surface takes no unit"),
    ("pitch [mm],amplitude [um]\n2,\n", r"line 2: empty cell in column amplitude_m; fill it in"),
    ("pitch [mm],amplitude [um]\n2\n", r"line 2: 1 cells for 2 columns"),
    ("pitch [mm],amplitude [um]\n", r"has a header but no conditions"),
    ("", r"is empty; give a header row"),
    ("pitch [mm],amplitude [furlong]\n2,3\n", r"amplitude_m"),
    ("pitch [mm],surface\n2,square\n", r"conditions: no column for the varied parameter 'amplitude_m'"),
    ("pitch [mm],amplitude [um],surface\n2,3,wavy\n", r"condition 0 surface must be 'sinusoid' or 'square', got 'wavy'"),
])
def test_a_bad_conditions_table_is_refused_with_a_clear_error(tmp_path, table, match):
    with pytest.raises(ValueError, match=r"p\.toml \(protocol\): .*" + match):
        Protocol.from_toml(_write(tmp_path, table))


def test_the_table_must_be_a_regular_file_inside_the_protocols_folder(tmp_path):
    inner = tmp_path / "lab"
    inner.mkdir()
    (tmp_path / "outside.csv").write_text(TABLE)
    for name, match in [("../outside.csv", r"must lie inside the protocol's folder with no '\.\.' or symlink"),
                        (str(tmp_path / "outside.csv"), r"must be a file name relative to the protocol's folder"),
                        ("missing.csv", r"is not a regular file \(missing, or a folder or device\)"),
                        ("sub", r"is not a regular file")]:
        (inner / "sub").mkdir(exist_ok=True)
        (inner / "p.toml").write_text(PROTOCOL.replace('"conditions.csv"', f'"{name}"'))
        with pytest.raises(ValueError, match=r"procedure\.conditions: .*" + match):
            Protocol.from_toml(inner / "p.toml")
    os.symlink(tmp_path / "outside.csv", inner / "link.csv")
    with pytest.raises(ValueError, match=r"'link\.csv' must lie inside the protocol's folder with no '\.\.' or symlink"):
        read_conditions(inner, "link.csv")


def test_rows_from_python_and_the_fields_that_cannot_go_together(tmp_path):
    data = tomllib.loads(PROTOCOL)
    with pytest.raises(ValueError, match=r"conditions: the file 'conditions\.csv' is read when the protocol is loaded "
                                         r"from its file"):
        Protocol.model_validate(data)
    data["procedure"]["conditions"] = [{"pitch_m": "2mm", "amplitude_m": "3um"}, {"pitch_m": "4mm", "amplitude_m": 3e-6}]
    protocol = Protocol.model_validate(data)
    assert protocol.procedure.conditions[1] == {"pitch_m": 4e-3, "amplitude_m": 3e-6}
    data["procedure"]["levels"] = ["3um", "5um"]
    with pytest.raises(ValueError, match=r"levels: give levels or a conditions table, not both"):
        Protocol.model_validate(data)
    del data["procedure"]["levels"]
    data["procedure"]["conditions"] = [{"pitch_m": "2mm", "amplitude_m": "3um"}, {"amplitude_m": "3um"}]
    with pytest.raises(ValueError, match=r"condition 1 sets \['amplitude_m'\], condition 0 sets .*every condition "
                                         r"sets the same fields"):
        Protocol.model_validate(data)
    data["procedure"]["conditions"] = []
    with pytest.raises(ValueError, match=r"conditions: must be a non-empty list of conditions"):
        Protocol.model_validate(data)
    data["procedure"]["conditions"] = [{"pitch_m": "2mm", "amplitude_m": "3um", "colour": "red"}]
    with pytest.raises(ValueError, match=r"conditions: condition 0 has unknown fields \['colour'\]"):
        Protocol.model_validate(data)


def test_clipped_drop_removes_exactly_the_rows_the_display_would_clip(tmp_path):
    loud = TABLE + "4,80,square\n"
    protocol = Protocol.from_toml(_write(tmp_path, loud))
    kept, dropped = drop_clipped(protocol, DisplayDescription.braille_row())
    assert len(dropped) == 1 and dropped[0].startswith("procedure: condition 4 ")
    assert kept.procedure.conditions == protocol.procedure.conditions[:4] and kept.procedure.levels == [3e-6, 6e-6] * 2
    only = "pitch [mm],amplitude [um]\n4,80\n2,90\n"
    with pytest.raises(ValueError, match=r"clipped: the display would limit all 2 conditions; nothing is left to run"):
        drop_clipped(Protocol.from_toml(_write(tmp_path, only)), DisplayDescription.braille_row())


def test_a_conditions_session_resumes_equal_to_the_uninterrupted_one(tmp_path):
    """Its rows live in the recorded protocol: resume rebuilds the same trial order without the file."""
    from tactilab.experiments import SimulatedDisplay, SimulatedObserver
    from tactilab.experiments.session import new_session, resume_session, session_dataframe

    class StopAt(SimulatedObserver):
        stop_at = None

        def collect(self, plan):
            if plan.trial_index == self.stop_at:
                raise KeyboardInterrupt("test stop")
            return super().collect(plan)

    protocol = Protocol.from_toml(_write(tmp_path))
    frames = []
    for name, stop_at in (("whole", None), ("cut", 6)):
        path = tmp_path / f"{name}.sqlite"
        observer = StopAt(protocol)
        observer.stop_at = stop_at
        result = new_session(protocol, path, SimulatedDisplay(DisplayDescription.braille_row(), realtime=False),
                             observer, subject="S01", realtime=False)
        if stop_at is not None:
            assert result.status == "interrupted" and result.n_completed == 6
            (tmp_path / "conditions.csv").unlink()  # the session does not need the file again
            result = resume_session(path, SimulatedDisplay(DisplayDescription.braille_row(), realtime=False),
                                    SimulatedObserver(protocol), realtime=False)
        assert result.status == "complete" and result.n_completed == 16
        frames.append(session_dataframe(path))
    for col in ("level", "block", "correct", "response", "procedure_state", "stimuli"):
        assert frames[0][col].tolist() == frames[1][col].tolist(), col

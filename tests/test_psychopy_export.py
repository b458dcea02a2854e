"""``experiment export --format psychopy``: the session's trials in PsychoPy's trial-per-row CSV.

Oracle: the session's own SQLite trial records (``SessionLog.trials``), read independently of
the export; the CSV is read back with pandas as a PsychoPy analysis script reads it.
"""

from __future__ import annotations

import json

import pandas as pd
import pytest

from tactilab.cli.main import main
from tactilab.data_schemas import Protocol
from tactilab.experiments.session import export_session
from tactilab.experiments.session.recording import SessionLog

CONSTANT = """
name = "ppconst"
seed = 4
iti_s = 0
[task]
kind = "2ifc"
[stimulus]
amplitude_m = "5um"
pitch_m = "2mm"
speed_m_per_s = "40mm/s"
duration_s = "20ms"
ramp_s = "5ms"
[procedure]
method = "constant_stimuli"
parameter = "amplitude_m"
levels = ["1um", "2um", "4um", "8um"]
repeats_per_block = 2
n_blocks = 3
"""

STAIRCASE = CONSTANT.replace('''method = "constant_stimuli"
parameter = "amplitude_m"
levels = ["1um", "2um", "4um", "8um"]
repeats_per_block = 2
n_blocks = 3''', '''method = "staircase"
parameter = "amplitude_m"
[[procedure.tracks]]
start = "6um"
step_sizes = [0.1]
min_level = "1um"
max_level = "10um"
max_trials = 6''')


def _session(tmp_path, text: str):
    (tmp_path / "p.toml").write_text(text)
    assert main(["experiment", "run", str(tmp_path / "p.toml"), "--subject", "S01", "--responses", "simulated",
                 "--no-wait", "--quiet", "--out", str(tmp_path / "s")]) == 0
    (path,) = (tmp_path / "s").glob("*.sqlite")
    return path


def test_psychopy_export_is_one_row_per_trial_with_the_loop_counters(tmp_path, capsys):
    session = _session(tmp_path, CONSTANT)
    capsys.readouterr()
    assert main(["experiment", "export", str(session), "--format", "psychopy", "--out", str(tmp_path / "x"),
                 "--json"]) == 0
    (path,) = json.loads(capsys.readouterr().out)["files"]
    assert path.endswith("sub-S01_ses-01_task-ppconst_psychopy.csv")
    frame = pd.read_csv(path)
    log = SessionLog(session)
    trials, meta = log.trials(), log.meta()
    log.close()
    levels = Protocol.model_validate(meta["protocol"]).procedure.levels
    assert len(frame) == len(trials) == 24
    assert list(frame.columns[:5]) == ["trials.thisRepN", "trials.thisTrialN", "trials.thisN", "trials.thisIndex",
                                       "amplitude_m"]
    assert frame["trials.thisN"].tolist() == [t.trial_index for t in trials] == list(range(24))
    assert frame["trials.thisRepN"].tolist() == [t.block for t in trials] == [b for b in range(3) for _ in range(8)]
    assert frame["trials.thisTrialN"].tolist() == list(range(8)) * 3
    assert [levels[i] for i in frame["trials.thisIndex"]] == pytest.approx([t.level for t in trials])
    assert frame["amplitude_m"].tolist() == pytest.approx([t.level for t in trials])
    # in each block every condition appears repeats_per_block times: PsychoPy's loop, shuffled per repetition
    assert all(sorted(g) == [0, 0, 1, 1, 2, 2, 3, 3] for _, g in frame.groupby("trials.thisRepN")["trials.thisIndex"])
    assert frame["key_resp.keys"].astype(str).tolist() == [t.response for t in trials]  # 2ifc keys 1, 2 = labels
    assert frame["corrAns"].astype(str).tolist() == [t.target for t in trials]
    assert frame["key_resp.corr"].tolist() == [int(t.correct) for t in trials]
    assert frame["key_resp.rt"].tolist() == pytest.approx([t.rt_s for t in trials])
    assert frame["interval1_amplitude_m"].tolist() == pytest.approx([t.stimuli[0].amplitude_m for t in trials])
    assert set(frame["participant"]) == {"S01"} and set(frame["expName"]) == {"ppconst"}
    assert frame["session"].tolist() == [1] * 24  # "01", as pandas reads a number
    assert frame["date"].str.fullmatch(r"\d{4}-\d\d-\d\d_\d\dh\d\d\.\d\d\.\d{3}").all()


def test_psychopy_export_of_a_staircase_leaves_the_condition_index_empty(tmp_path):
    session = _session(tmp_path, STAIRCASE)
    (path,) = export_session(session, tmp_path / "x", "psychopy")
    frame = pd.read_csv(path)
    assert len(frame) == 6 and frame["trials.thisIndex"].isna().all()  # a staircase has no condition list
    assert frame["trials.thisRepN"].tolist() == [0] * 6 and frame["trials.thisTrialN"].tolist() == list(range(6))
    with pytest.raises(ValueError, match=r"out: .*_psychopy.csv already exists; export to another folder, or add "
                                         r"--force"):
        export_session(session, tmp_path / "x", "psychopy", overwrite=False)
    with pytest.raises(ValueError, match=r"format: must be one of \('bids', 'csv', 'parquet', 'json', 'psychopy'\), "
                                         r"got 'psychopy2'"):
        export_session(session, tmp_path / "x", "psychopy2")

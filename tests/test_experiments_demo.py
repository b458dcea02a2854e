"""The experiment demo section writes its session, BIDS files and plot, and reports its error; its
``experiment/`` folder passes the real BIDS validator."""

from __future__ import annotations

import json
import re

import pytest

from test_bids_export import validate

from tactilab.demo.experiments import run_demo
from tactilab.experiments.session.recording import SessionLog


@pytest.mark.slow
def test_demo_runs_a_recorded_exported_and_plotted_session(tmp_path):
    lines = list(run_demo(tmp_path, progress=False))
    out = tmp_path / "experiment"
    session = out / "sourcedata" / "sub-DEMO_ses-01_task-gratingdetection.sqlite"
    trials = SessionLog(session).trials()
    assert len(trials) == 40 and {t.track for t in trials} == {0, 1}
    assert (out / "derivatives" / "tactilab" / "staircase_track.png").stat().st_size > 10_000
    assert (out / "sub-DEMO" / "ses-01" / "beh" / "sub-DEMO_ses-01_task-gratingdetection_beh.json").is_file()
    text = "\n".join(lines)
    error = float(re.search(r"error ([+-]\d+) %", text).group(1))
    assert abs(error) < 100  # 40 trials: the estimate is the right order of magnitude
    assert str(session) in text and "staircase_track.png" in text
    assert list(run_demo(tmp_path, progress=False))[2] == lines[2]  # reruns afresh, same seed, same result
    # the dataset root holds only BIDS files (the log in sourcedata/, the plot in derivatives/), with Authors
    report = validate(out)
    assert report["issues"]["errors"] == [], [e["key"] for e in report["issues"]["errors"]]
    assert not [w for w in report["issues"]["warnings"] if w["key"] == "NO_AUTHORS"]
    assert json.loads((out / "dataset_description.json").read_text())["Authors"]

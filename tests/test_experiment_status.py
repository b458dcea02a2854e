"""`experiment status` as a table and as JSON; run/resume summaries: interventions by kind, frame rates,
repeated trials and why, the status in words, the fitted threshold with its interval."""

from __future__ import annotations

import contextlib
import json
import re
import shutil
import sqlite3

import pytest

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.modelling.analysis import fit_conditions
from tactilab.experiments.session.recording import SessionLog
from tactilab.experiments.modelling.session_report import session_summary, summary_lines

PROTOCOL = """
name = "status"
seed = 8
iti_s = 0
[task]
kind = "2ifc"
[stimulus]
amplitude_m = "2um"
pitch_m = "2mm"
speed_m_per_s = "40mm/s"
duration_s = "20ms"
ramp_s = "5ms"
[procedure]
method = "staircase"
parameter = "amplitude_m"
[[procedure.tracks]]
start = "3um"
step_sizes = [0.2]
min_level = "0.3um"
max_level = "6um"
max_trials = 8
"""


@pytest.fixture(scope="module")
def weak_run(tmp_path_factory):
    """A session on a display whose traction limit clips every stimulus: interventions to report."""
    folder = tmp_path_factory.mktemp("status")
    (folder / "p.toml").write_text(PROTOCOL)
    weak = DisplayDescription.braille_row().model_copy(update={"max_traction_pa": 500.0, "display_id": "Weak"})
    (folder / "weak.json").write_text(weak.model_dump_json())
    return folder


def test_run_json_is_one_object_with_interventions_by_kind_and_the_files(weak_run, capsys):
    argv = ["experiment", "run", str(weak_run / "p.toml"), "--subject", "S01", "--responses", "simulated",
            "--no-wait", "--quiet", "--out", str(weak_run / "s"), "--device", str(weak_run / "weak.json"),
            "--export", "bids", "--json", "--clipped", "allow"]  # the weak display clips: what this test reports
    assert cli_main(argv) == 0
    out = capsys.readouterr().out
    assert len(out.strip().splitlines()) == 1  # --json: nothing else on stdout
    s = json.loads(out)
    path = weak_run / "s" / "sub-S01_ses-01_task-status.sqlite"
    events = SessionLog(path).events("safety_intervention")
    assert s["command"] == "experiment run" and s["status"] == "complete" and s["trials_completed"] == 8
    assert s["safety_interventions"] == len(events) > 0
    kinds = {}
    for e in events:
        kinds[e["payload"]["kind"]] = kinds.get(e["payload"]["kind"], 0) + 1
    assert s["safety_interventions_by_kind"] == kinds
    assert any(f"{len(events)} safety interventions" in w for w in s["warnings"])
    assert s["files"][0] == str(path) and any(f.endswith("_beh.tsv") for f in s["files"])
    assert (weak_run / "s" / "bids" / "dataset_description.json").is_file()
    # the same session's status: a table for people, and the same numbers as JSON
    assert cli_main(["experiment", "status", str(path)]) == 0
    table = capsys.readouterr().out
    assert re.search(rf"^safety interventions +{len(events)}: amplitude_clip {len(events)} \(\d+ frames\)$", table,
                     re.M), table
    assert re.search(r"^warnings +1$", table, re.M) and "Weak, description SHA-256" in table
    assert cli_main(["experiment", "status", str(path), "--json"]) == 0
    status = json.loads(capsys.readouterr().out)
    assert {k: status[k] for k in ("trials_completed", "safety_interventions_by_kind", "frames_sent")} == \
        {k: s[k] for k in ("trials_completed", "safety_interventions_by_kind", "frames_sent")}


def test_status_json_is_si_with_units_in_keys_and_matches_the_fit(weak_run, capsys):
    path = weak_run / "s" / "sub-S01_ses-01_task-status.sqlite"
    if not path.exists():  # run alone: make the session
        test_run_json_is_one_object_with_interventions_by_kind_and_the_files(weak_run, capsys)
    s = session_summary(path)
    (condition,) = s["conditions"]
    fit = fit_conditions([path], rng=0)[0]
    threshold = fit.fit.params["threshold"]
    assert condition["threshold_m"] == pytest.approx(threshold.map * 1e-6)  # the fit is in um
    lo, hi = condition["threshold_ci95_m"]
    assert lo < condition["threshold_m"] < hi and 1e-7 < condition["threshold_m"] < 1e-5
    assert condition["levels_m"] == sorted(set(condition["levels_m"])) and all(v < 1e-5 for v in condition["levels_m"])
    trials = SessionLog(path).trials()
    assert s["frames_sent"] == sum(t.frames_sent for t in trials) and s["frames_late_fraction"] == 0.0
    assert s["rt_min_s"] <= s["rt_median_s"] <= s["rt_max_s"] < 5
    lines = "\n".join(summary_lines(s))
    assert f"{threshold.map:.3g} µm (95 % interval" in lines
    assert re.search(r"^response time +median \d+ ms \(range \d+ to \d+ ms\)$", lines, re.M)


def _edit(path, sql: list[tuple[str, tuple]]) -> None:
    with contextlib.closing(sqlite3.connect(path)) as db, db:
        for statement, params in sql:
            db.execute(statement, params)


def test_late_frames_a_clean_stop_and_a_repeated_trial_are_reported(weak_run, tmp_path, capsys):
    source = weak_run / "s" / "sub-S01_ses-01_task-status.sqlite"
    if not source.exists():
        test_run_json_is_one_object_with_interventions_by_kind_and_the_files(weak_run, capsys)
    path = tmp_path / "sub-S01_ses-01_task-status.sqlite"
    shutil.copy(source, path)
    sent = sum(t.frames_sent for t in SessionLog(path).trials()[:6])
    # trials 0-5 stay, with 10 late frames each; trial 2 needed a second attempt after a display fault;
    # trial 6 was planned when the subject pressed q (a clean stop)
    _edit(path, [
        ("UPDATE trials SET record = json_set(record, '$.frames_late', 10)", ()),
        ("UPDATE trials SET record = json_set(record, '$.attempt', 1) WHERE trial_index = 2", ()),
        ("INSERT INTO events (kind, trial_index, attempt, utc, monotonic_ns, payload) VALUES "
         "('display_fault', 2, 0, '2026-01-01T00:00:00+00:00', 0, ?)", (json.dumps({"reason": "ALARM: test"}),)),
        ("DELETE FROM trials WHERE trial_index >= 6", ()),
        ("DELETE FROM events WHERE kind = 'session_complete' OR trial_index >= 7 OR "
         "(trial_index = 6 AND kind NOT IN ('trial_planned', 'stimulus_presented'))", ()),
        ("INSERT INTO events (kind, trial_index, attempt, utc, monotonic_ns, payload) VALUES "
         "('session_stopped', NULL, NULL, '2026-01-01T00:00:01+00:00', 0, ?)",
         (json.dumps({"reason": "interrupted (q)"}),)),
    ])
    s = session_summary(path)
    assert s["status"] == "interrupted" and s["trials_completed"] == 6
    assert s["status_text"] == "interrupted: stopped cleanly (interrupted (q)); resume to go on"
    assert s["frames_late"] == 60 and s["frames_late_fraction"] == pytest.approx(60 / sent)
    assert any(re.fullmatch(rf"60 of {sent} frames late \([0-9.]+ %, above 1 %\)", w) for w in s["warnings"])
    assert s["repeated_trials"] == [{"trial_index": 2, "attempts": 2, "felt_before": False,
                                     "why": "display fault: ALARM: test"}]
    assert s["display_faults"] == [{"trial_index": 2, "attempt": 0, "reason": "ALARM: test"}]
    assert cli_main(["experiment", "status", str(path)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^repeated trials +trial 2 x2 \(display fault: ALARM: test\)$", out, re.M), out
    assert re.search(rf"^frames +{sent} sent; 60 late \([0-9.]+ %\), 0 skipped \(0 %\), 0 missing \(0 %\)$", out, re.M)
    assert f"resume with: tactilab experiment resume {path}" in out and "False" not in out


def test_status_of_a_session_without_a_fit_says_why(tmp_path, capsys):
    (tmp_path / "p.toml").write_text(PROTOCOL.replace("max_trials = 8", "max_trials = 1"))
    assert cli_main(["experiment", "run", str(tmp_path / "p.toml"), "--subject", "S02", "--responses", "simulated",
                     "--no-wait", "--quiet", "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    assert cli_main(["experiment", "status", str(tmp_path / "sub-S02_ses-01_task-status.sqlite")]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^fitted threshold +none yet \(session: condition .* has trials at one amplitude only", out,
                     re.M), out


def test_export_json_lists_the_files(weak_run, tmp_path, capsys):
    source = weak_run / "s" / "sub-S01_ses-01_task-status.sqlite"
    if not source.exists():
        test_run_json_is_one_object_with_interventions_by_kind_and_the_files(weak_run, capsys)
    assert cli_main(["experiment", "export", str(source), "--format", "csv", "--out", str(tmp_path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out == {"command": "experiment export", "format": "csv", "out": str(tmp_path),
                   "files": [str(tmp_path / "sub-S01_ses-01_task-status_trials.csv")]}


def test_a_run_that_ends_in_a_display_fault_still_prints_its_summary(tmp_path, monkeypatch, capsys):
    """Late frames on every stimulus, then a stale acknowledgement (a display fault) in trial 3:
    the summary block reports both on stdout, the error stays one line on stderr, exit 3."""
    import dataclasses

    from tactilab.experiments.devices import SimulatedDisplay, registry

    class LateThenStale(SimulatedDisplay):
        plays = 0

        def _play(self, frames, frame_rate_hz):
            report = super()._play(frames, frame_rate_hz)
            LateThenStale.plays += 1
            LateThenStale.frames_per_play = report.frames_sent
            late = dataclasses.replace(report, late=report.frames_sent // 4)
            return dataclasses.replace(late, stale=3) if LateThenStale.plays == 7 else late

    # a device kind registered for this test only: the CLI opens it by name (--display late_then_stale)
    monkeypatch.setitem(registry._DEVICES, "late_then_stale",
                        lambda spec, description, **kw: LateThenStale(description, realtime=False))
    (tmp_path / "p.toml").write_text(PROTOCOL)
    code = cli_main(["experiment", "run", str(tmp_path / "p.toml"), "--subject", "S03", "--responses", "simulated",
                     "--display", "late_then_stale", "--no-wait", "--quiet", "--out", str(tmp_path)])
    captured = capsys.readouterr()
    assert code == 3 and captured.err.count("\n") == 1 and "ALARM" in captured.err
    out = captured.out
    assert "--- tactilab experiment run: summary ---" in out
    assert re.search(r"^status +failed: a display fault in trial 3 \(ALARM: 3 of \d+ frames .*\); resume repeats the trial$", out, re.M), out
    assert re.search(r"^progress +3 of 8 planned trials \(38 %\)$", out, re.M), out
    # 3 scored trials (6 plays) and the aborted trial's first interval (the 7th play) reached the display
    per_play = LateThenStale.frames_per_play
    assert re.search(rf"^frames +{7 * per_play} sent \({per_play} in trials a display fault aborted\); "
                     r"\d+ late \(2[45] %\)", out, re.M), out
    assert re.search(r"^display faults +1$", out, re.M) and re.search(r"^  - \d+ of \d+ frames late \(2[45]\.\d %", out, re.M)
    assert re.search(r"^  - display fault in trial 3: ALARM", out, re.M)


def test_a_running_session_says_who_runs_it(weak_run, tmp_path, capsys):
    from tactilab.experiments.session.recording import Recorder

    source = weak_run / "s" / "sub-S01_ses-01_task-status.sqlite"
    if not source.exists():
        test_run_json_is_one_object_with_interventions_by_kind_and_the_files(weak_run, capsys)
    path = tmp_path / source.name
    shutil.copy(source, path)
    _edit(path, [("DELETE FROM events WHERE kind = 'session_complete'", ())])
    recorder = Recorder.open(path)  # holds the lock and records itself as the owner, like a runner
    try:
        s = session_summary(path)
    finally:
        recorder.close()
    assert s["status"] == "running" and re.fullmatch(r"running: pid \d+ on .+, last heartbeat \S+", s["status_text"])
    assert 1e-7 < s["procedure_estimate_si"]["threshold"] < 1e-5  # SI: an amplitude threshold in m, not um


def test_an_interrupted_run_reports_the_stop_and_exports_nothing(tmp_path, monkeypatch, capsys):
    """q pressed in trial 2: exit 130, the summary says it stopped cleanly, --export says why it did not run."""
    from tactilab.experiments import session

    real = session.make_responses

    class QuitsInTrial2:
        def __init__(self, inner):
            self.inner, self.n = inner, 0

        def arm(self, plan, onset_ns):
            self.inner.arm(plan, onset_ns)

        def collect(self, plan):
            self.n += 1
            if self.n == 3:
                raise KeyboardInterrupt("q")
            return self.inner.collect(plan)

        def close(self):
            self.inner.close()

        def __getattr__(self, name):  # name, config, ...: the real source's
            return getattr(self.inner, name)

    monkeypatch.setattr(session, "make_responses", lambda *a, **kw: QuitsInTrial2(real(*a, **kw)))
    (tmp_path / "p.toml").write_text(PROTOCOL)
    code = cli_main(["experiment", "run", str(tmp_path / "p.toml"), "--subject", "S04", "--responses", "simulated",
                     "--no-wait", "--quiet", "--out", str(tmp_path), "--export", "bids", "--json"])
    captured = capsys.readouterr()
    assert code == 130
    s = json.loads(captured.out)
    assert s["status"] == "interrupted" and s["trials_completed"] == 2 and s["interrupted_trial"] == 2
    assert s["status_text"] == "interrupted: stopped cleanly (interrupted (q)); resume to go on"
    assert s["files"] == [str(tmp_path / "sub-S04_ses-01_task-status.sqlite")] and not (tmp_path / "bids").exists()
    assert "--export: not exported, the session is interrupted" in captured.err
    assert "resume with: tactilab experiment resume" in captured.err


def test_frames_a_display_fault_aborted_are_counted_as_sent(tmp_path, monkeypatch, capsys):
    """A fault in the first trial's second interval: the display played both intervals' frames, and the
    status says so (it said 'frames 0 sent': only scored trials were counted)."""
    import dataclasses

    from tactilab.experiments.devices import SimulatedDisplay, registry

    class StaleSecondPlay(SimulatedDisplay):
        plays, sent = 0, 0

        def _play(self, frames, frame_rate_hz):
            report = super()._play(frames, frame_rate_hz)
            StaleSecondPlay.plays += 1
            StaleSecondPlay.sent += report.frames_sent
            return dataclasses.replace(report, stale=2) if StaleSecondPlay.plays == 2 else report

    monkeypatch.setitem(registry._DEVICES, "stale_second_play",
                        lambda spec, description, **kw: StaleSecondPlay(description, realtime=False))
    (tmp_path / "p.toml").write_text(PROTOCOL)
    code = cli_main(["experiment", "run", str(tmp_path / "p.toml"), "--subject", "S04", "--responses", "simulated",
                     "--display", "stale_second_play", "--no-wait", "--quiet", "--out", str(tmp_path), "--json"])
    assert code == 3
    summary = json.loads(capsys.readouterr().out)
    assert summary["trials_completed"] == 0 and StaleSecondPlay.sent > 0
    assert summary["frames_sent"] == summary["frames_sent_aborted"] == StaleSecondPlay.sent
    (path,) = tmp_path.glob("sub-S04_*.sqlite")
    lines = summary_lines(session_summary(path))
    assert any(re.fullmatch(rf"frames +{StaleSecondPlay.sent} sent \({StaleSecondPlay.sent} in trials a display "
                            r"fault aborted\); 0 late \(0 %\), 0 skipped \(0 %\), 0 missing \(0 %\)", line)
               for line in lines), lines

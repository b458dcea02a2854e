"""Run reports: summary block, --json (one JSON object, nothing else on stdout), output folders that never
overwrite without --force, warnings collected, the sensors invert leaves out, the emcee bar reaching 100 %."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from tactilab.cli.common import RunReport, choose_out
from tactilab.cli.main import main


@pytest.fixture
def load(tmp_path):
    path = tmp_path / "load.npz"
    x = (np.arange(16) - 8) * 1e-4
    np.savez(path, p=np.exp(-(x[None, :] ** 2 + x[:, None] ** 2) / 1e-7) * 1e4, spacing=1e-4)
    return path


def test_choose_out_default_never_overwrites(tmp_path):
    base = tmp_path / "rec-inversion"
    assert choose_out(None, base) == base and base.is_dir()
    assert choose_out(None, base) == base  # still empty: reused
    (base / "a.txt").write_text("x")
    second = choose_out(None, base)
    assert second == tmp_path / "rec-inversion-2"
    (second / "b.txt").write_text("x")
    assert choose_out(None, base) == tmp_path / "rec-inversion-3"


def test_choose_out_refuses_a_non_empty_folder_without_force(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "field.nc").write_text("old")
    with pytest.raises(ValueError, match=r"--out: the folder .* exists and is not empty; .* --force"):
        choose_out(out, tmp_path / "unused")
    assert choose_out(out, tmp_path / "unused", force=True) == out


def test_stress_summary_block_and_refusal(load, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["stress", str(load), "--depth", "1mm", "--method", "dcfft", "--components", "zz"]) == 0
    text = capsys.readouterr().out
    for key in ("--- tactilab stress: summary ---", "computed: strain (dimensionless, tensor shear), components zz", "method: ",
                "error estimate: estimated relative error", "dropped: nothing", "warnings: 0",
                "files: load-stress/ (field.nc, field.png)"):
        assert key in text
    assert main(["stress", str(load), "--depth", "1mm", "--method", "dcfft", "--components", "zz"]) == 0  # default folder taken: a new one
    assert "files: load-stress-2/" in capsys.readouterr().out
    assert main(["stress", str(load), "--depth", "1mm", "--method", "dcfft", "--components", "zz", "--out", "load-stress"]) == 2
    assert "exists and is not empty" in capsys.readouterr().err
    assert main(["stress", str(load), "--depth", "1mm", "--method", "dcfft", "--components", "zz", "--out", "load-stress", "--force"]) == 0


def test_stress_json_is_the_only_stdout_and_collects_warnings(load, tmp_path, capsys):
    assert main(["stress", str(load), "--depth", "1um", "--out", str(tmp_path / "o"), "--json"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)  # one JSON object, nothing else
    assert summary["command"] == "stress" and summary["depths_mm"] == [pytest.approx(1e-3)]
    assert len(summary["warnings"]) == 1 and "no method meets tol" in summary["warnings"][0]
    assert sorted(p.rsplit("/", 1)[1] for p in summary["files"]) == ["field.nc", "field.png"]
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tactilab stress: warning: no method meets tol")


def test_strict_still_turns_plausibility_warnings_into_errors(tmp_path):
    from tactilab.data_schemas.plausibility import PlausibilityWarning

    report = RunReport("x")
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        with pytest.raises(PlausibilityWarning, match="far"):
            with report.collecting_warnings():
                warnings.warn("far outside", PlausibilityWarning)
    before = report.warnings  # outside main() the count runs on from earlier calls in this process
    with report.collecting_warnings():
        warnings.warn("far outside", PlausibilityWarning)
        warnings.warn("far outside", PlausibilityWarning)  # repeated warnings are each reported
    assert report.warnings == before + ["far outside", "far outside"]


def test_stress_help_says_strain_by_default(capsys):
    with pytest.raises(SystemExit):
        main(["stress", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "strain by default" in text and "--json" in text and "--force" in text


def test_synthesis_json(capsys):
    assert main(["synthesis", "--depth", "1mm", "--no-sensitivity", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["command"] == "synthesis" and summary["out"] is None
    (row,) = summary["designs"]
    assert row["depth_mm"] == pytest.approx(1.0) and 0.2 <= row["d_mm"] <= 5.0
    assert "relative residual" in summary["error_estimate"]


def test_synthesis_summary_block(capsys):
    assert main(["synthesis", "--depth", "1mm,2mm", "--no-sensitivity"]) == 0
    text = capsys.readouterr().out
    assert "--- tactilab synthesis: summary ---" in text and "files: none (printed only)" in text


def test_invert_names_the_sensors_it_leaves_out():
    from types import SimpleNamespace

    from tactilab.cli.cmd_invert import _report_selection

    rec = SimpleNamespace(sensor_ids=tuple(f"s{i}" for i in range(100)))
    report = RunReport("invert")
    _report_selection(report, rec, {"sensor_ids": ["s3", "s4", "s5", "s40", "s41", "s42"], "time_stride": 4}, 1500)
    assert report.dropped[0].startswith("sensors: uses 6 of 100 (s3, s4, s5, s40, s41, s42): the defect inversion "
                                        "keeps the sensors with the largest RMS signal")
    assert "every 4th time sample" in report.dropped[1] and "--max-data 1500" in report.dropped[1]
    assert report.data["sensors_used"] == ["s3", "s4", "s5", "s40", "s41", "s42"]


def test_invert_table_in_mm():
    import pandas as pd

    from tactilab.cli.cmd_invert import _table_in_display_units

    table = pd.DataFrame({"mean": [1e-3, 2e-4, 5e-8], "sd": [1e-5, 1e-5, 1e-9], "r_hat": [1.0, 1.0, 1.0]},
                         index=["x0", "y0", "amplitude"])
    shown = _table_in_display_units(table)
    assert list(shown.index) == ["x0 [mm]", "y0 [mm]", "amplitude [mm^2]"]
    np.testing.assert_allclose(shown["mean"], [1.0, 0.2, 0.05])
    np.testing.assert_allclose(shown["r_hat"], 1.0)


def test_emcee_bar_reaches_100_percent_when_it_converges_early(rng, capsys):
    from tactilab.inversion import sample_posterior
    from test_inversion_sampler import FAST, toy

    tree = sample_posterior(toy(rng), rng, progress=True, **FAST)
    assert tree.attrs["converged"] == 1
    steps = int(tree.attrs["n_steps"]) if "n_steps" in tree.attrs else None
    err = capsys.readouterr().err
    last = err.replace("\r", "\n").strip().splitlines()[-1]
    assert "emcee converged at step" in last and "100%" in last
    if steps is not None:
        assert f"at step {steps} of at most 3000" in last


def test_invert_profile_json_in_mm(rng, tmp_path, capsys):
    from test_inversion_scene import small_scene, synthetic_recording

    scene = small_scene()
    rec, _ = synthetic_recording(scene, rng)
    rec_path, scene_path = rec.save(tmp_path / "rec.json"), scene.save(tmp_path / "scene.json")
    argv = ["invert", str(rec_path), "--scene", str(scene_path), "--method", "profile", "--json",
            "--out", str(tmp_path / "inv")]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["sensors_used"] == list(rec.sensor_ids) and summary["dropped"] == []
    assert abs(summary["profile_peak_x_mm"]) < 0.5  # the defect sits at x = 0, reported in mm
    assert "lam by evidence" in summary["method"] and "mm^2/mm" in summary["error_estimate"]
    assert main(argv) == 2 and "--force" in capsys.readouterr().err


def test_invert_json_with_batch_is_refused(tmp_path, capsys):
    scene = tmp_path / "scene.json"
    assert main(["invert", "--scene", str(scene), "--batch", str(tmp_path), "--json"]) == 2
    assert "--json: not available with --batch" in capsys.readouterr().err

"""`tactilab demo`: a new report folder per run, --force, and --json (one object on stdout).

The real sections take minutes; a one-section stand-in exercises the command's own wiring.
"""

from __future__ import annotations

import json
import types

import pytest

import tactilab.demo
from tactilab.cli.main import main


def _fake_section(out, progress=True):
    (out / "figure.png").write_bytes(b"png")
    yield "fake: wrote figure.png"


@pytest.fixture
def one_section(monkeypatch):
    section = types.SimpleNamespace(__name__="tactilab.demo.fake", __doc__="Demo section: a stand-in.",
                                    run_demo=_fake_section)
    monkeypatch.setattr(tactilab.demo, "SECTIONS", (section,))


def test_each_run_gets_a_new_folder(one_section, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["demo", "--quiet"]) == 0
    assert main(["demo", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert (tmp_path / "tactilab-report" / "figure.png").exists()
    assert (tmp_path / "tactilab-report-2" / "figure.png").exists()
    assert "report written to" in out and "--- tactilab demo: summary ---" in out
    assert "section fake: a stand-in." in out


def test_an_existing_out_needs_force(one_section, tmp_path, capsys):
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / "old.txt").write_text("keep")
    assert main(["demo", "--out", str(tmp_path / "r")]) == 2
    assert "--out: the folder" in capsys.readouterr().err
    assert main(["demo", "--out", str(tmp_path / "r"), "--force", "--quiet"]) == 0
    assert (tmp_path / "r" / "old.txt").read_text() == "keep"


def test_json_prints_one_object(one_section, tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path / "r"), "--json"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert summary["command"] == "demo"
    assert summary["files"] == [str(tmp_path / "r" / "figure.png")]
    assert "fake: wrote figure.png" in captured.err

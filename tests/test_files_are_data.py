"""Files are data: nothing in a folder of protocols or sessions becomes code, a path outside
``--out``, a trigger, a raw terminal escape (issue 26, item 4). One test per route."""

from __future__ import annotations

import contextlib
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from tactilab.cli.main import main as cli_main

PROTOCOL = """
name = "plugin"
seed = 4
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
max_trials = 3
"""

EVIL = '''
import pathlib
pathlib.Path(__file__).with_name("RAN").write_text("plug-in code ran")


def open_rig(spec, description, *, realtime, max_skipped_fraction):
    raise SystemExit("plug-in code ran")
'''


def _plant_dist_info(folder: Path, group: str, name: str) -> None:
    """A *.dist-info that declares ``name`` in ``group``, pointing at a module that leaves a mark."""
    info = folder / "tl_evil-1.0.dist-info"
    info.mkdir(parents=True)
    (folder / "tl_evil.py").write_text(EVIL)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: tl-evil\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(f"[{group}]\n{name} = tl_evil:open_rig\n")


def _cli(args: list[str], cwd: Path, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tactilab.cli", *args], cwd=cwd, capture_output=True, text=True,
                          env={**os.environ, **(env or {})}, timeout=120)


def test_a_dist_info_beside_the_protocol_is_never_loaded_under_python_m(tmp_path):
    """``python -m`` puts the current folder on sys.path; a *.dist-info there declares nothing."""
    _plant_dist_info(tmp_path, "tactilab.devices", "tl_evil")
    (tmp_path / "p.toml").write_text(PROTOCOL)
    done = _cli(["experiment", "run", "p.toml", "--subject", "S01", "--responses", "simulated", "--display",
                 "tl_evil://x", "--no-wait", "--quiet", "--out", "s"], cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert "device 'tl_evil' is not registered" in done.stderr and len(done.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "RAN").exists()


def test_installed_entry_point_skips_the_current_folder_but_not_an_installed_one(tmp_path, monkeypatch):
    from tactilab.core.plugins import installed_entry_point

    here, site = tmp_path / "here", tmp_path / "site"
    _plant_dist_info(here, "tactilab.likelihoods", "tl_evil")
    _plant_dist_info(site, "tactilab.likelihoods", "tl_fine")
    monkeypatch.chdir(here)
    monkeypatch.syspath_prepend("")
    monkeypatch.syspath_prepend(str(site))
    assert installed_entry_point("tactilab.likelihoods", "tl_evil") is None
    assert installed_entry_point("tactilab.likelihoods", "tl_fine").value == "tl_evil:open_rig"
    assert not (here / "RAN").exists() and not (site / "RAN").exists()  # found, never imported here


@pytest.fixture
def session(tmp_path, capsys) -> Path:
    """A complete 3-trial session recorded on the simulated display."""
    (tmp_path / "p.toml").write_text(PROTOCOL)
    code = cli_main(["experiment", "run", str(tmp_path / "p.toml"), "--subject", "S01", "--responses", "simulated",
                     "--no-wait", "--quiet", "--out", str(tmp_path / "sessions")])
    assert code == 0, capsys.readouterr().err
    capsys.readouterr()
    return next((tmp_path / "sessions").glob("*.sqlite"))


def _edit(path: Path, *statements: tuple[str, tuple]) -> None:
    with contextlib.closing(sqlite3.connect(path)) as db, db:
        for sql, params in statements:
            db.execute(sql, params)
        db.execute("PRAGMA journal_mode=DELETE")


def _one_error(capsys) -> str:
    captured = capsys.readouterr()
    assert len(captured.err.strip().splitlines()) == 1, captured.err
    return captured.err


@pytest.mark.parametrize("key, value", [("subject", "../../escaped"), ("subject", "S01\n"), ("session", "/tmp/x"),
                                        ("session", 7)])
def test_subject_and_session_are_revalidated_on_every_read(session, tmp_path, capsys, key, value):
    """An edited label never becomes a path: status, export and resume refuse it in one line."""
    import json

    _edit(session, ("UPDATE meta SET value = ? WHERE key = ?", (json.dumps(value), key)))
    for command in (["status"], ["export", "--out", str(tmp_path / "out")], ["resume"]):
        assert cli_main(["experiment", *command[:1], str(session), *command[1:]]) == 2
        err = _one_error(capsys)
        assert f"holds an invalid {key}: must be 1-32 letters or digits" in err, err
    assert not (tmp_path / "escaped").exists() and not any(tmp_path.glob("**/escaped*"))
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").rglob("*.tsv"))


def test_an_export_never_leaves_out_through_a_symlinked_folder(session, tmp_path, capsys):
    outside, out = tmp_path / "outside", tmp_path / "out"
    outside.mkdir()
    out.mkdir()
    (out / "sub-S01").symlink_to(outside, target_is_directory=True)
    assert cli_main(["experiment", "export", str(session), "--out", str(out), "--force"]) == 2
    assert "resolves outside" in _one_error(capsys)
    assert not any(outside.iterdir())


@pytest.mark.parametrize("dangling", [True, False])
@pytest.mark.parametrize("fmt", ["csv", "json", "bids"])
def test_export_refuses_a_symlink_at_a_target_even_with_force(session, tmp_path, capsys, fmt, dangling):
    """--force replaces a file, never the file a link points to; a dangling link is refused too."""
    out, victim = tmp_path / "out", tmp_path / "victim.txt"
    assert cli_main(["experiment", "export", str(session), "--out", str(out), "--format", fmt]) == 0
    written = [Path(line.removeprefix("wrote ")) for line in capsys.readouterr().out.splitlines()]
    for target in written:
        if not dangling:
            victim.write_text("keep me")
        target.unlink()
        target.symlink_to(victim)
        assert cli_main(["experiment", "export", str(session), "--out", str(out), "--format", fmt, "--force"]) == 2
        assert "is a symlink; tactilab never writes through a link" in _one_error(capsys)
        assert (victim.read_text() == "keep me") if not dangling else not victim.exists()
        target.unlink()
        victim.unlink(missing_ok=True)
    assert cli_main(["experiment", "export", str(session), "--out", str(out), "--format", fmt, "--force"]) == 0
    assert not list(out.rglob("*.tmp"))  # the temporary files were renamed into place


def test_written_exports_are_whole_files_with_the_usual_mode(session, tmp_path, capsys):
    out = tmp_path / "out"
    old = os.umask(0o022)
    try:
        assert cli_main(["experiment", "export", str(session), "--out", str(out), "--format", "csv"]) == 0
    finally:
        os.umask(old)
    (target,) = out.glob("*.csv")
    assert target.stat().st_mode & 0o777 == 0o644 and "trial_index" in target.read_text().splitlines()[0].split(",")


@pytest.mark.parametrize("sql", [
    "CREATE TRIGGER rewrite AFTER INSERT ON events BEGIN UPDATE trials SET record = 'x'; END",
    "CREATE VIEW v AS SELECT * FROM trials",
    "CREATE TABLE extra (x)",
    "CREATE INDEX by_kind ON events(kind)",
])
def test_a_session_whose_schema_holds_anything_else_is_refused(session, capsys, sql):
    """A trigger would rewrite a scored trial when resume writes: the file is refused first."""
    _edit(session, ("UPDATE events SET kind = 'session_stopped' WHERE kind = 'session_complete'", ()), (sql, ()))
    with contextlib.closing(sqlite3.connect(session)) as db:
        before = db.execute("SELECT record FROM trials").fetchall()
    for command in ("status", "export", "resume"):
        assert cli_main(["experiment", command, str(session)]) == 2
        err = _one_error(capsys)
        assert "which no tactilab session has" in err and "restore it from a copy" in err, err
    with contextlib.closing(sqlite3.connect(session)) as db:
        assert db.execute("SELECT record FROM trials").fetchall() == before


def test_control_characters_in_printed_fields_are_escaped(session, capsys):
    import json

    _edit(session, ("UPDATE meta SET value = ? WHERE key = 'display_id'", (json.dumps("\x1b[2J\x1b]0;owned\x07"),)))
    assert cli_main(["experiment", "status", str(session)]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out and "\\x1b[2J" in out


def test_printable_escapes_every_control_character():
    from tactilab.core.outputs import printable

    assert printable("S01 ok é") == "S01 ok é"
    assert printable("a\x1b[31m\tb\nc\x7f\x9b\u202e") == "a\\x1b[31m\\tb\\nc\\x7f\\x9b\\u202e"


def test_output_path_refuses_names_that_are_not_plain(tmp_path):
    from tactilab.core.outputs import output_path

    assert output_path(tmp_path, "sub-S01", "a.tsv") == tmp_path / "sub-S01" / "a.tsv"
    for bad in ("..", "a/b", "", ".", "a\x00b"):
        with pytest.raises(ValueError, match="is not one plain file name"):
            output_path(tmp_path, bad)


def test_a_netcdf_recording_with_external_storage_is_refused(tmp_path):
    """HDF5 external storage would read another local file as the recording's values."""
    import h5py
    import numpy as np

    from tactilab.data_schemas import Recording
    from tactilab.data_schemas.recording_io import read_recording, write_recording

    recording = Recording(values=np.ones((4, 1, 1)), sampling_rate_hz=1000.0, sensor_ids=("s0",),
                          components=("zz",))
    path = write_recording(recording, tmp_path)
    assert read_recording(path).values.shape == (4, 1, 1)
    secret = tmp_path / "secret.bin"
    secret.write_bytes(np.arange(4.0).tobytes())
    for how in ("external", "link", "virtual"):
        evil = tmp_path / f"{how}.nc"
        evil.write_bytes(path.read_bytes())
        with h5py.File(evil, "a") as f:
            del f["values"]
            if how == "external":
                f.create_dataset("values", shape=(4, 1, 1), dtype="<f8", external=[(str(secret), 0, 32)])
            elif how == "link":
                f["values"] = h5py.ExternalLink(str(path), "/values")
            else:
                layout = h5py.VirtualLayout(shape=(4, 1, 1), dtype="<f8")
                layout[:] = h5py.VirtualSource(str(path), "values", shape=(4, 1, 1))
                f.create_virtual_dataset("values", layout)
        with pytest.raises(ValueError, match="a recording must hold all of its own data"):
            read_recording(evil)

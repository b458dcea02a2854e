"""Protocols and sessions are data, never code: every route a file could take to run code is
refused, and a canary module proves that nothing was imported (issue: a protocol file ran code)."""

from __future__ import annotations

import contextlib
import json
import pickle
import sqlite3
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from tactilab.cli.main import main as cli_main
from tactilab.experiments import (
    SimulatedDisplay, SimulatedObserver, UnregisteredError, export_session, new_session, register_likelihood,
    replay_session, resume_session, session_status)
from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments.procedures import registry

CANARY = "tactilab_canary_mod"
CANARY_CODE = """
import pathlib
pathlib.Path(__file__).with_name("CANARY_RAN").write_text("imported")
def f(level, **params):
    pathlib.Path(__file__).with_name("CANARY_RAN").write_text("called")
    return 0.5 + 0 * level
"""

PSI = """
name = "nocode"
seed = 5
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
method = "psi"
parameter = "amplitude_m"
levels = LEVELS
likelihood = "LIKELIHOOD"
n_trials = 4
[procedure.parameters]
threshold = ["1um", "2um", "4um"]
slope = [2.0]
lapse = [0.0]
"""


@pytest.fixture
def canary(tmp_path, monkeypatch):
    """A module beside the protocol (and on sys.path) that leaves a file when imported or called."""
    (tmp_path / f"{CANARY}.py").write_text(CANARY_CODE)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    yield tmp_path / "CANARY_RAN"
    sys.modules.pop(CANARY, None)


def _protocol(tmp_path, likelihood="weibull", levels='["1um", "2um", "4um"]') -> Path:
    path = tmp_path / "p.toml"
    path.write_text(PSI.replace("LIKELIHOOD", likelihood).replace("LEVELS", levels))
    return path


def _run(tmp_path, protocol: Path) -> int:
    return cli_main(["experiment", "run", str(protocol), "--subject", "S01", "--responses", "simulated",
                     "--no-wait", "--quiet", "--out", str(tmp_path / "sessions")])


@pytest.mark.parametrize("likelihood", [f"{CANARY}:f", "pickle:loads", "os:system", f"{CANARY}.f"])
def test_an_import_path_in_a_protocol_is_refused_and_nothing_runs(tmp_path, canary, capsys, likelihood):
    protocol = _protocol(tmp_path, likelihood)
    assert _run(tmp_path, protocol) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and str(protocol) in err and "never holds an import path" in err
    assert not canary.exists() and CANARY not in sys.modules
    assert not (tmp_path / "sessions").exists() or not any((tmp_path / "sessions").iterdir())


def test_a_module_beside_the_protocol_named_by_its_name_is_not_imported(tmp_path, canary, capsys):
    """A valid-looking name that no one registered: refused, with how to register it."""
    assert _run(tmp_path, _protocol(tmp_path, CANARY)) == 2
    err = capsys.readouterr().err
    assert f"{CANARY!r} is not registered" in err and "register_likelihood" in err
    assert "tactilab.likelihoods" in err
    assert not canary.exists() and CANARY not in sys.modules
    assert not list((tmp_path / "sessions").glob("*.sqlite")), "no session file is created"


def test_pickle_bytes_hidden_in_the_levels_are_never_unpickled(tmp_path, canary, capsys):
    """The levels are floats and stay floats; the route that would unpickle them is refused."""
    payload = pickle.dumps(("os", "system"))
    payload += b"\0" * (-len(payload) % 8)
    floats = [struct.unpack("<d", payload[i:i + 8])[0] for i in range(0, len(payload), 8)]
    levels = "[" + ", ".join(f'"{abs(v) if v == v and abs(v) < 1e300 else 1e-6!r}m"' for v in floats) + "]"
    assert _run(tmp_path, _protocol(tmp_path, "pickle:loads", levels)) == 2
    assert "never holds an import path" in capsys.readouterr().err
    as_text = _protocol(tmp_path, "weibull", json.dumps([payload.decode("latin-1")]))
    assert _run(tmp_path, as_text) == 2
    assert not canary.exists()


def _session(tmp_path, likelihood="weibull") -> Path:
    protocol = Protocol.from_toml(_protocol(tmp_path, likelihood))
    display = SimulatedDisplay(DisplayDescription.braille_row(), realtime=False)
    path = tmp_path / "s.sqlite"
    result = new_session(protocol, path, display, SimulatedObserver(protocol), subject="S01", realtime=False)
    assert result.status == "complete"
    return path


def _edit_meta(path: Path, key: str, value) -> None:
    with contextlib.closing(sqlite3.connect(path)) as db, db:
        db.execute("UPDATE meta SET value = ? WHERE key = ?", (json.dumps(value), key))


def _every_reader(path: Path, tmp_path: Path) -> list[Exception]:
    errors = []
    display = SimulatedDisplay(DisplayDescription.braille_row(), realtime=False)
    for action in (lambda: replay_session(path), lambda: session_status(path),
                   lambda: export_session(path, tmp_path / "out", "json"),
                   lambda: resume_session(path, display, SimulatedObserver(replay_protocol(path)), realtime=False)):
        with pytest.raises(ValueError) as info:
            action()
        errors.append(info.value)
    return errors


def replay_protocol(path: Path) -> Protocol:
    with contextlib.closing(sqlite3.connect(path)) as db, db:
        meta = json.loads(db.execute("SELECT value FROM meta WHERE key = 'protocol'").fetchone()[0])
    meta["procedure"]["likelihood"] = "weibull"
    return Protocol.model_validate(meta)


def test_an_edited_session_meta_never_imports(tmp_path, canary):
    path = _session(tmp_path)
    assert session_status(path)["status"] == "complete"
    _edit_meta(path, "likelihood", f"{CANARY}:f")  # the recorded likelihood
    for err in _every_reader(path, tmp_path):
        assert "the metadata was edited" in str(err)
    with contextlib.closing(sqlite3.connect(path)) as db, db:  # the protocol itself
        protocol = json.loads(db.execute("SELECT value FROM meta WHERE key = 'protocol'").fetchone()[0])
    protocol["procedure"]["likelihood"] = f"{CANARY}:f"
    _edit_meta(path, "protocol", protocol)
    for err in _every_reader(path, tmp_path):
        assert "holds an invalid protocol" in str(err) and "never holds an import path" in str(err)
    assert not canary.exists() and CANARY not in sys.modules


def strain_likelihood(level, threshold, slope, lapse):
    return 0.5 + 0.5 * (1 - lapse) * (1 - 2.0 ** (-(level / threshold) ** slope))


def test_a_registered_likelihood_is_recorded_by_name_and_replay_needs_it_registered(tmp_path):
    register_likelihood("test_custom_psy", strain_likelihood, replace=True)
    path = _session(tmp_path, "test_custom_psy")
    with contextlib.closing(sqlite3.connect(path)) as db, db:
        assert json.loads(db.execute("SELECT value FROM meta WHERE key = 'likelihood'").fetchone()[0]) \
            == "test_custom_psy"
    assert replay_session(path).procedure.n_done == 4
    registry._LIKELIHOODS.pop("test_custom_psy")
    with pytest.raises(UnregisteredError, match="register_likelihood\\('test_custom_psy', f\\)"):
        session_status(path)
    register_likelihood("test_custom_psy", strain_likelihood)
    assert session_status(path)["completed"] == 4


def test_status_of_an_unregistered_likelihood_from_the_cli_is_one_line(tmp_path):
    register_likelihood("test_custom_cli", strain_likelihood, replace=True)
    path = _session(tmp_path, "test_custom_cli")
    proc = subprocess.run([sys.executable, "-m", "tactilab.cli.main", "experiment", "status", str(path)],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "'test_custom_cli' is not registered" in proc.stderr


PLUGIN = '''
def psy(level, threshold, slope, lapse):
    return 0.5 + 0.5 * (1 - lapse) * (1 - 2.0 ** (-(level / threshold) ** slope))
'''


def test_a_likelihood_installed_as_a_plugin_is_found_through_the_entry_point_group(tmp_path, monkeypatch, capsys):
    """An installed distribution (a *.dist-info with entry_points.txt, on sys.path) that declares a
    likelihood in the group: a protocol naming it runs, in this process and in a fresh one, with no
    register_likelihood call; a name no plug-in declares is refused with the registration hint."""
    from importlib import metadata

    site = tmp_path / "site"
    (site / "tl_plugin_psy-1.0.dist-info").mkdir(parents=True)
    (site / "tl_plugin_psy.py").write_text(PLUGIN)
    (site / "tl_plugin_psy-1.0.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: tl-plugin-psy\nVersion: 1.0\n")
    (site / "tl_plugin_psy-1.0.dist-info" / "entry_points.txt").write_text(
        f"[{registry.ENTRY_POINT_GROUP}]\nplugin_psy = tl_plugin_psy:psy\n")
    monkeypatch.syspath_prepend(str(site))
    try:
        assert registry.ENTRY_POINT_GROUP == "tactilab.likelihoods"
        declared = {e.name: e.value for e in metadata.entry_points(group=registry.ENTRY_POINT_GROUP)}
        assert declared.get("plugin_psy") == "tl_plugin_psy:psy"
        assert "plugin_psy" not in registry.registered_likelihoods()  # nobody registered it from Python
        assert _run(tmp_path, _protocol(tmp_path, "plugin_psy")) == 0
        assert "plugin_psy" in registry.registered_likelihoods()  # loaded from the entry point on first use
        path = next((tmp_path / "sessions").glob("*.sqlite"))
        with contextlib.closing(sqlite3.connect(path)) as db, db:
            assert json.loads(db.execute("SELECT value FROM meta WHERE key = 'likelihood'").fetchone()[0]) \
                == "plugin_psy"  # the name, never a path
        fresh = subprocess.run([sys.executable, "-m", "tactilab.cli.main", "experiment", "status", str(path)],
                               capture_output=True, text=True, env={**__import__("os").environ, "PYTHONPATH": str(site)})
        assert fresh.returncode == 0 and "all 4 planned trials done" in fresh.stdout, fresh.stderr
        capsys.readouterr()
        assert _run(tmp_path, _protocol(tmp_path, "plugin_absent")) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "'plugin_absent' is not registered" in err
        assert "register_likelihood('plugin_absent', f)" in err and "'tactilab.likelihoods' entry-point group" in err
    finally:
        registry._LIKELIHOODS.pop("plugin_psy", None)
        sys.modules.pop("tl_plugin_psy", None)

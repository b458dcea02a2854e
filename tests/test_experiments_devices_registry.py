"""The device registry: display specs name a registered kind, plug-ins come only through entry points."""

from __future__ import annotations

import sys
from importlib import metadata

import pytest

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments import SimulatedDisplay, register_device
from tactilab.experiments.devices import Display, open_display, registered_devices, registry


@pytest.fixture
def description():
    return DisplayDescription.braille_row()


def test_the_built_in_kinds_are_registered_by_name(description):
    assert {"simulated", "udp"} <= set(registered_devices())
    display = open_display("simulated", description, realtime=False)
    try:
        assert type(display) is SimulatedDisplay and display.realtime is False
    finally:
        display.close()
    # the udp opener parses its own target: a bad URL is refused by UdpDisplay.from_url, before any socket
    with pytest.raises(ValueError, match="url: expected udp://HOST:PORT"):
        open_display("udp://no-port", description)


def test_unknown_and_malformed_specs_are_refused(description):
    with pytest.raises(ValueError, match=r"spec: device 'tcp' is not registered \(known: \[.*'simulated', 'udp'.*\]\); "
                                         r"register it with tactilab.experiments.devices.register_device\('tcp', opener\), "
                                         r"or install a plug-in that declares 'tcp' in the 'tactilab.devices' entry-point group"):
        open_display("tcp://host:1", description)
    with pytest.raises(ValueError, match="spec: must be the name of a registered device"):
        open_display("my_pkg.devices:Open", description)  # an import path is never imported
    with pytest.raises(ValueError, match="spec: must be a display spec such as 'simulated'"):
        open_display(None, description)
    with pytest.raises(ValueError, match="spec: the simulated display takes no target, got 'simulated://x'"):
        open_display("simulated://x", description)


def test_register_device_checks_its_arguments(description, monkeypatch):
    monkeypatch.setattr(registry, "_DEVICES", dict(registry._DEVICES))  # undone after the test

    def opener(spec, description, *, realtime, max_skipped_fraction):
        return SimulatedDisplay(description, realtime=False)

    register_device("bench_rig", opener)
    register_device("bench_rig", opener)  # the same opener again is no change
    display = open_display("bench_rig://anything", description)
    display.close()
    assert isinstance(display, Display) and "bench_rig" in registered_devices()
    with pytest.raises(ValueError, match="name: device 'bench_rig' is already registered; pass replace=True"):
        register_device("bench_rig", lambda *a, **k: None)
    register_device("bench_rig", lambda *a, **k: object(), replace=True)
    with pytest.raises(TypeError, match="opener: the opener registered for 'bench_rig' returned object, not a "
                                        "tactilab.experiments.devices.Display"):
        open_display("bench_rig", description)
    with pytest.raises(ValueError, match="opener: must be callable"):
        register_device("other_rig", "tl_plugin:open")
    with pytest.raises(ValueError, match="name: must be the name of a registered device"):
        register_device("Bad-Name", opener)


PLUGIN = '''
from tactilab.experiments.devices import SimulatedDisplay

OPENED = []


def open_rig(spec, description, *, realtime, max_skipped_fraction):
    OPENED.append((spec, realtime, max_skipped_fraction))
    return SimulatedDisplay(description, realtime=False)
'''

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


def test_a_device_installed_as_a_plugin_is_found_through_the_entry_point_group(tmp_path, monkeypatch, capsys):
    """An installed distribution (a *.dist-info with entry_points.txt on sys.path) declares a device
    kind: ``--display tl_rig://bench-1`` opens it with no register_device call; only that entry
    point is loaded, and a kind no plug-in declares is refused with the registration hint."""
    site = tmp_path / "site"
    info = site / "tl_plugin_rig-1.0.dist-info"
    info.mkdir(parents=True)
    (site / "tl_plugin_rig.py").write_text(PLUGIN)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: tl-plugin-rig\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(f"[{registry.ENTRY_POINT_GROUP}]\ntl_rig = tl_plugin_rig:open_rig\n")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setattr(registry, "_DEVICES", dict(registry._DEVICES))
    try:
        assert registry.ENTRY_POINT_GROUP == "tactilab.devices"
        declared = {e.name: e.value for e in metadata.entry_points(group=registry.ENTRY_POINT_GROUP)}
        assert declared.get("tl_rig") == "tl_plugin_rig:open_rig"
        assert "tl_rig" not in registered_devices() and "tl_plugin_rig" not in sys.modules
        with pytest.raises(ValueError, match="spec: device 'tl_absent' is not registered"):
            open_display("tl_absent", DisplayDescription.braille_row())
        assert "tl_plugin_rig" not in sys.modules  # another name's plug-in is not loaded
        (tmp_path / "p.toml").write_text(PROTOCOL)
        code = cli_main(["experiment", "run", str(tmp_path / "p.toml"), "--subject", "S01", "--responses", "simulated",
                         "--display", "tl_rig://bench-1", "--no-wait", "--quiet", "--out", str(tmp_path / "s")])
        assert code == 0, capsys.readouterr().err
        assert "tl_rig" in registered_devices()  # loaded from the entry point on first use
        assert sys.modules["tl_plugin_rig"].OPENED == [("tl_rig://bench-1", False, 0.01)]
    finally:
        sys.modules.pop("tl_plugin_rig", None)

"""The rooms of tactilab.experiments: one door each, imports one way, a staircase without the models.

Rooms: ``devices``, ``procedures``, ``session``, ``modelling`` (subpackages of ``experiments/``).
Door rule: library code outside a room imports it only through its ``__init__``. Direction:
``devices`` and ``procedures`` import no other room, ``session`` imports those two, ``modelling``
imports ``procedures`` and ``session`` but not ``devices`` (a model asks the display object it is
given for its strain); no room imports the part's face (``tactilab.experiments``), which sits on top.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PARTS = ("core", "data_schemas", "forward", "inversion", "experiments", "demo", "cli")
FACE = "tactilab.experiments"
#: room -> the rooms it may import (through their doors)
MAY_IMPORT = {"devices": set(), "procedures": set(), "session": {"devices", "procedures"},
              "modelling": {"procedures", "session"}}
ROOM_MODULES = {room: {p.stem for p in (ROOT / "experiments" / room).glob("*.py") if p.stem != "__init__"}
                for room in MAY_IMPORT}


def module_name(path: Path) -> str:
    """``experiments/devices/udp.py`` -> ``tactilab.experiments.devices.udp``."""
    return ".".join(("tactilab",) + path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")


def imported_modules(source: str, module: str, is_package: bool) -> list[str]:
    """Absolute names of what ``source`` imports, with ``from X import name`` as ``X.name``
    when ``name`` is a module of a room (so that ``from ..devices import udp`` counts as the module)."""
    package = module if is_package else module.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module != "__future__":
            if node.level:
                bits = package.split(".")
                base = ".".join(bits[: len(bits) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            room = base.split(".")[2] if base.startswith(FACE + ".") else None
            inner = [a.name for a in node.names if room in ROOM_MODULES and a.name in ROOM_MODULES[room]]
            out += [f"{base}.{name}" for name in inner] or [base]
    return out


def room_of(name: str) -> str | None:
    bits = name.split(".")
    return bits[2] if len(bits) > 2 and bits[:2] == ["tactilab", "experiments"] and bits[2] in MAY_IMPORT else None


def breaches(source: str, module: str, is_package: bool = False) -> set[str]:
    """Imports of ``module`` that break the door rule, the direction or the face rule (one line each)."""
    here = room_of(module)
    found = set()
    for target in imported_modules(source, module, is_package):
        there = room_of(target)
        if here is not None and target == FACE:
            found.add(f"{target} (a room imports other rooms' doors, never the part's face)")
        if there is None or there == here:
            continue
        if target != f"{FACE}.{there}":
            found.add(f"{target} (import {FACE}.{there}, the room's door)")
        if here is not None and there not in MAY_IMPORT[here]:
            found.add(f"{target} ({here} may import only {sorted(MAY_IMPORT[here]) or 'no other room'})")
    return found


def _library_modules():
    for part in PARTS:
        for path in sorted((ROOT / part).rglob("*.py")) if (ROOT / part).is_dir() else ():
            yield path


@pytest.mark.parametrize("path", list(_library_modules()), ids=lambda p: str(p.relative_to(ROOT)))
def test_rooms_are_entered_through_their_doors_and_import_one_way(path):
    found = breaches(path.read_text(), module_name(path), path.name == "__init__.py")
    assert not found, f"{path.relative_to(ROOT)}: {sorted(found)}"


def test_every_experiments_module_lives_in_a_room():
    loose = [p.name for p in (ROOT / "experiments").glob("*.py") if p.name != "__init__.py"]
    assert not loose, f"experiments/ holds only the face and the rooms; move {loose} into a room"
    assert {p.parent.name for p in (ROOT / "experiments").glob("*/__init__.py")} == set(MAY_IMPORT)


def test_the_checker_catches_each_kind_of_breach():
    cli, runner, udp = "tactilab.cli.cmd_experiment", "tactilab.experiments.session.runner", \
        "tactilab.experiments.devices.udp"
    assert breaches("from tactilab.experiments.session import new_session", cli) == set()
    assert breaches("from tactilab.experiments.session.runner import new_session", cli) == {
        "tactilab.experiments.session.runner (import tactilab.experiments.session, the room's door)"}
    assert breaches("import tactilab.experiments.devices.udp", cli) != set()
    assert breaches("from ..devices import SafeDisplay\nfrom .recording import Recorder", runner) == set()
    assert breaches("from ..devices import safety", runner) == {
        "tactilab.experiments.devices.safety (import tactilab.experiments.devices, the room's door)"}
    assert breaches("from ..modelling import fit_psychometric", runner) == {
        "tactilab.experiments.modelling (session may import only ['devices', 'procedures'])"}
    assert breaches("def f():\n    from ..procedures import Staircase\n", udp) == {
        "tactilab.experiments.procedures (devices may import only no other room)"}
    assert breaches("from .. import Staircase", runner) == {
        "tactilab.experiments (a room imports other rooms' doors, never the part's face)"}


STAIRCASE_SESSION = """
import pathlib, sys, tempfile
from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments import SimulatedDisplay, SimulatedObserver, new_session

folder = pathlib.Path(tempfile.mkdtemp())
(folder / "p.toml").write_text(sys.argv[1])
protocol = Protocol.from_toml(folder / "p.toml")
display = SimulatedDisplay(DisplayDescription.braille_row(), realtime=False)
result = new_session(protocol, folder / "s.sqlite", display, SimulatedObserver(protocol, seed=1), subject="S01",
                     realtime=False)
assert result.n_completed == 6, result
print("\\n".join(sorted(m for m in sys.modules if m.startswith("tactilab.experiments."))))
"""
PROTOCOL = """
name = "light"
seed = 3
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
max_trials = 6
"""


def test_a_plain_staircase_session_loads_nothing_from_modelling():
    """A simulated 2IFC staircase session, run start to end in a fresh interpreter, imports no
    module of the modelling room (nor psi, whose module loads only when a protocol names it)."""
    proc = subprocess.run([sys.executable, "-P", "-c", STAIRCASE_SESSION, PROTOCOL], capture_output=True, text=True,
                          cwd=ROOT.parent, timeout=120)
    assert proc.returncode == 0, proc.stderr
    loaded = proc.stdout.split()
    assert "tactilab.experiments.session.runner" in loaded and "tactilab.experiments.procedures.staircase" in loaded
    assert not [m for m in loaded if m.startswith("tactilab.experiments.modelling")], loaded
    assert "tactilab.experiments.procedures.psi" not in loaded


BUILD_EACH = """
import sys
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments.procedures import make_procedure, registered_procedures

def loaded():
    return {m.rsplit(".", 1)[1] for m in sys.modules if m.startswith("tactilab.experiments.")
            and m.count(".") == 3}

print(sorted(registered_procedures()))
for procedure in PROCEDURES:
    protocol = Protocol.model_validate({"name": "each", "seed": 1, "iti_s": 0, "task": {"kind": "2ifc"},
                                        "stimulus": STIMULUS, "procedure": procedure})
    built = make_procedure(protocol.procedure, guess_rate=0.5)
    print(procedure["method"], type(built).__name__, sorted(loaded() & {"staircase", "psi", "design"}))
"""
STIMULUS = {"amplitude_m": "5um", "pitch_m": "3mm", "speed_m_per_s": "20mm/s", "duration_s": "50ms", "ramp_s": "5ms"}
PROCEDURES = [
    {"method": "staircase", "parameter": "amplitude_m",
     "tracks": [{"start": "3um", "step_sizes": [0.2], "min_level": "0.3um", "max_level": "6um", "max_trials": 4}]},
    {"method": "psi", "parameter": "amplitude_m", "levels": ["1um", "3um", "9um"], "n_trials": 4,
     "parameters": {"threshold": ["2um", "4um"], "slope": [2.0], "lapse": [0.0]}},
    {"method": "model_discrimination", "parameter": "pitch_m", "models": ["zx@1mm", "zx@2mm"], "max_trials": 4,
     "candidates": {"pitch_m": ["1mm", "4mm"], "amplitude_m": ["5um"], "speed_m_per_s": ["20mm/s"],
                    "duration_s": ["50ms"], "ramp_s": ["5ms"]}},
]


def test_each_built_in_procedure_loads_its_module_when_a_protocol_first_names_it():
    """In a fresh interpreter the registry lists every built-in before any is loaded, and building
    each one imports its module then: staircase alone, then psi, then the modelling room's design."""
    script = f"STIMULUS = {STIMULUS!r}\nPROCEDURES = {PROCEDURES!r}\n" + BUILD_EACH
    proc = subprocess.run([sys.executable, "-P", "-c", script], capture_output=True, text=True, cwd=ROOT.parent,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [
        "['constant_stimuli', 'model_discrimination', 'psi', 'staircase']",
        "staircase Staircase ['staircase']",
        "psi Psi ['psi', 'staircase']",
        "model_discrimination ModelDiscrimination ['design', 'psi', 'staircase']",
    ]


def test_every_built_in_procedure_is_named_by_a_door_and_registers_its_method():
    import importlib

    from tactilab.data_schemas.experiment import StaircaseConfig
    from tactilab.experiments.procedures import registry

    for method, (door, cls) in registry.BUILTIN_PROCEDURES.items():
        assert door in {f"{FACE}.{room}" for room in MAY_IMPORT}, (method, door)
        assert cls in importlib.import_module(door).__all__
        registry._load_builtin(method)
        assert method in registry._PROCEDURES
    # a built-in's name is taken even before a protocol names it: registering it needs replace=True
    with pytest.raises(ValueError, match="name: procedure 'staircase' is already registered; pass replace=True"):
        registry.register_procedure("staircase", StaircaseConfig, lambda config, *, guess_rate=0.0: None)

"""The memory rule at every size a user gives: estimated before allocation, refused above the limit in
one line naming the largest size that fits (``tactilab metamer --receptors 100000000`` grew to 24 GB and
was killed after 100 s with no message)."""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.cli.main import main
from tactilab.core.memory import MEMORY_LIMIT_BYTES, check_count
from tactilab.data_schemas.display import DisplayDescription
from tactilab.inversion import SinusoidFamily, TractorFamily, check_max_steps, check_receptor_memory, metamer_pair

DESIGN = '[[trials]]\namplitude_m = "0.3um"\npitch_m = "2mm"\nspeed_m_per_s = "20mm/s"\nn = 50\n'


def test_check_count_names_the_largest_count_that_fits():
    most = MEMORY_LIMIT_BYTES // 24
    assert check_count(most, 24, "n", "things") == most
    with pytest.raises(ValueError, match=rf"^n: {most + 1} things would need 1 GiB, more than the 1 GiB limit for "
                                         rf"one array; give n at most {most}; or fewer$"):
        check_count(most + 1, 24, "n", "things", "or fewer")


def test_receptor_memory_boundary():
    per = 144 * 2 * 10 + 8
    most = MEMORY_LIMIT_BYTES // per
    assert check_receptor_memory(most, 10, 2) == most
    with pytest.raises(ValueError, match=rf"receptors: {most + 1} receptors \(readouts of 2 depth\(s\) x 10 "
                                         rf"parameter\(s\), {per} bytes per receptor\).*give receptors at most {most}"):
        check_receptor_memory(most + 1, 10, 2)


@pytest.mark.parametrize("argv, message", [
    (["metamer", "--target", "sinusoid:A=0.5mm,p=4mm", "--receptors", "100000000"],
     r"--receptors: 100000000 receptors .* would need 135 GiB, .*; give --receptors at most 741534"),
    (["metamer", "--target", "sinusoid:A=0.5mm,p=4mm", "--receptors", "100000000", "--scan-pitch", "2mm"],
     r"--receptors: 100000000 receptors .*; give --receptors at most 741534"),
    (["metamer", "--target", "sinusoid:A=0.5mm,p=4mm", "--scan", "1000000000"],
     r"--scan: 1000000000 frames .* would need 14.9 GiB, .*; give --scan at most 67108864"),
    (["synthesis", "--depth", "1mm", "--pairs", "100000000"],
     r"--pairs: 100000000 tractor pairs .* would need 7.45 GiB, .*; give --pairs at most 13421772"),
    (["synthesis", "--depth", "1mm", "--sensitivity-pairs", "3,100000000"],
     r"--sensitivity-pairs: 100000000 tractor pairs .*; give --sensitivity-pairs at most 13421772"),
    (["invert", "missing.nc", "--scene", "missing.toml", "--max-steps", "1000000000"],
     r"--max-steps: 1000000000 steps \(4 ensembles x 16 walkers x 2 parameters, 4096 bytes per step\) .*; give "
     r"--max-steps at most 262144"),
    (["device", "emulate", "--port", "0", "--tractors", "10000000000"],
     r"--tractors: a FRAME carries at most 16000 values .* got 10000000000; give at most 16000"),
])
def test_cli_sizes_are_refused_before_allocation(tmp_path, capsys, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    key = None
    if argv[:2] == ["device", "emulate"]:  # the emulator needs its pairing key (frame format 3) before any size
        from tactilab.experiments.devices import create_pairing_key

        key = create_pairing_key(tmp_path.parent / f"{tmp_path.name}.key")
        argv = [*argv, "--pairing-key", str(key)]
    try:
        assert main(argv) == 2
    finally:
        if key is not None:
            key.unlink()
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    import re

    assert re.search(message, err), err
    assert not any(tmp_path.iterdir())  # refused before any output folder or file


@pytest.mark.parametrize("option, message", [
    (["--seeds", "1000000000"], r"--seeds: 1000000000 seeds .*; give --seeds at most 349525"),
    (["--seeds", "2", "--repeats", "100000000000"], r"--repeats: 100000000000 simulated experiments .*; give "
                                                    r"--repeats at most 16777216"),
])
def test_experiment_power_sweep_sizes_are_refused_before_anything_is_written(tmp_path, capsys, option, message):
    (tmp_path / "d.toml").write_text(DESIGN)
    out = tmp_path / "out"
    argv = ["experiment", "power", "--true", "zx@1mm", "--rival", "zx@3mm", "--design", str(tmp_path / "d.toml"),
            "--out", str(out), *option]
    assert main(argv) == 2
    import re

    assert re.search(message, capsys.readouterr().err)
    assert not out.exists()


def test_python_entry_points_apply_the_same_rule(tmp_path):
    from tactilab.experiments.modelling import TransductionModel, power_analysis, power_sweep, read_design
    from tactilab.forward import optimal_half_spacing
    from tactilab.inversion import metamer_scan

    family = TractorFamily.from_display(DisplayDescription.wh2008(), 1.54e6)
    receptors = np.broadcast_to(0.0, (10**7,))  # a view: the test allocates no receptor array
    with pytest.raises(ValueError, match=r"^receptors: 10000000 receptors .*; give receptors at most 371794"):
        metamer_pair(SinusoidFamily(4e-3).stimulus([1e-4]), family, "xx,zx@1mm,2mm;noise=1e-3", receptors)
    with pytest.raises(ValueError, match=r"^receptors: 10000000 receptors .*; give receptors at most 741534"):
        family.matrix("xx@1mm", receptors)
    with pytest.raises(ValueError, match=r"^scan_frames: 1000000000 frames .*; give scan_frames at most 67108864"):
        metamer_scan([4e-3], [0.0], [DisplayDescription.wh2008()], "xx@1mm;noise=1e-3", amplitude=1e-4,
                     young_modulus=1.5e6, receptors=np.linspace(-5e-3, 5e-3, 21), out_dir=tmp_path / "scan",
                     scan_frames=10**9, progress=False, workers=0)
    assert not (tmp_path / "scan").exists()
    with pytest.raises(ValueError, match=r"^pairs: 1000000000 tractor pairs .*; give pairs at most 13421772"):
        optimal_half_spacing(1e-3, 10e-3, 10**9)
    assert check_max_steps(262144, 2) == 262144
    with pytest.raises(ValueError, match=r"^max_steps: 262145 steps .*; give max_steps at most 262144"):
        check_max_steps(262145, 2)
    (tmp_path / "d.toml").write_text(DESIGN)
    design = read_design(tmp_path / "d.toml")
    args = (TransductionModel("zx@1mm"), dict(threshold_strain=1e-4, exponent=1.0, lapse=0.02),
            TransductionModel("zx@3mm"), design)
    with pytest.raises(ValueError, match=r"^n_repeats: 100000000000 simulated experiments .*at most 16777216"):
        power_analysis(*args, method="simulate", n_repeats=10**11)
    with pytest.raises(ValueError, match=r"^n_seeds: 1000000000 seeds .*; give n_seeds at most 1048576"):
        power_sweep(*args, [50], n_seeds=10**9, seed=0, out_dir=tmp_path / "p", workers=0, progress=False)
    assert not (tmp_path / "p").exists()

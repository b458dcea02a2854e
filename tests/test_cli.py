"""The CLI: --help everywhere, --version, one-line user errors, and the stress command."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from tactilab.cli.main import _command_modules, build_parser, main, one_line


def _subcommand_paths():
    parser = build_parser()
    paths = []

    def walk(p, prefix):
        for action in p._actions:
            if action.__class__.__name__ == "_SubParsersAction":
                for name, sub in action.choices.items():
                    paths.append(prefix + [name])
                    walk(sub, prefix + [name])

    walk(parser, [])
    return paths


def test_top_level_help_lists_every_command(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    for module in _command_modules():
        assert module.NAME in text
        assert module.HELP.split()[0] in text


@pytest.mark.parametrize("path", _subcommand_paths(), ids=" ".join)
def test_every_subcommand_has_help(path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([*path, "--help"])
    assert exit_info.value.code == 0
    assert "usage: tactilab" in capsys.readouterr().out


def test_version(capsys):
    with pytest.raises(SystemExit):
        main(["--version"])
    assert capsys.readouterr().out.startswith("tactilab ")


def test_no_command_prints_help_and_fails(capsys):
    assert main([]) == 2
    assert "usage" in capsys.readouterr().out


@pytest.mark.slow
def test_user_mistakes_are_one_line_without_traceback(tmp_path):
    cmd = [sys.executable, "-m", "tactilab.cli", "stress", str(tmp_path / "missing.toml"), "--depth", "1mm"]
    out = subprocess.run(cmd, capture_output=True, text=True)
    assert out.returncode == 2
    assert "Traceback" not in out.stderr
    assert out.stderr.strip().count("\n") == 0
    assert "load file not found" in out.stderr


def test_one_line_flattens_pydantic_errors():
    from pydantic import BaseModel, field_validator

    class M(BaseModel):
        depth_m: float

        @field_validator("depth_m")
        @classmethod
        def positive(cls, v):
            if v <= 0:
                raise ValueError("must be > 0")
            return v

    with pytest.raises(ValueError) as info:
        M(depth_m=-1)
    assert one_line(info.value) == "depth_m: must be > 0"


def test_stress_command_writes_field_and_map(tmp_path, capsys):
    load = tmp_path / "load.npz"
    x = (np.arange(32) - 16) * 1e-4
    np.savez(load, p=np.exp(-(x[None, :] ** 2 + x[:, None] ** 2) / 1e-7) * 1e4, spacing=1e-4)
    assert main(["stress", str(load), "--depth", "0.5mm", "--depth", "1mm", "--quantity", "stress",
                 "--components", "zz,zx", "--out", str(tmp_path / "out")]) == 0
    text = capsys.readouterr().out
    assert "method: " in text and "estimated relative error" in text
    assert (tmp_path / "out" / "field.nc").exists() and (tmp_path / "out" / "field.png").exists()
    import xarray as xr

    ds = xr.open_dataset(tmp_path / "out" / "field.nc", engine="h5netcdf")
    assert ds["stress"].shape == (2, 2, 32, 32) and float(ds["stress"].sel(component="zz").min()) < 0
    ds.close()


def test_stress_command_reports_accuracy_warning_in_one_line(tmp_path, capsys):
    """A depth far below the grid spacing cannot meet tol: one 'warning:' line, no source line."""
    load = tmp_path / "load.npz"
    np.savez(load, p=np.ones((8, 8)), spacing=1e-4)
    assert main(["stress", str(load), "--depth", "1um", "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tactilab stress: warning: no method meets tol=1e-06")


@pytest.mark.parametrize("argv,message", [
    (["--depth=-1mm"], "depth: every depth must be finite and > 0"),
    (["--depth", "1furlong"], "unknown unit 'furlong'"),
    (["--depth", "1mm", "--young-modulus", "5mm"], "measures length, but a pressure is expected"),
    (["--depth", "1mm", "--components", "zz,qq"], "unknown component"),
])
def test_stress_command_bad_options(tmp_path, capsys, argv, message):
    load = tmp_path / "load.npz"
    np.savez(load, p=np.ones((8, 8)), spacing=1e-4)
    assert main(["stress", str(load), *argv, "--out", str(tmp_path / "o")]) == 2
    assert message in capsys.readouterr().err


GRID = '[grid]\nshape = [16]\nspacing = "0.1mm"\n'


@pytest.mark.parametrize("text,message", [
    (GRID + '[[patch]]\nshape = "cone"\nradius = "1mm"\npressure = "1kPa"\n', r"patch\[0\].shape: unknown patch shape"),
    (GRID + '[[patch]]\nradius = "1mm"\npressure = "1kPa"\ncolour = 1\n', "unknown key"),
    (GRID, r"no \[\[patch\]\]"),
    ('title = "x"\n', r"missing \[grid\]"),
    ('[grid]\nshape = [0]\nspacing = "0.1mm"\n', "grid.shape must be"),
    ('[grid]\nshape = [16]\nspacing = "-0.1mm"\n', "grid.spacing: must be > 0"),
    (GRID + '[[patch]]\ncentre = ["0mm", "1mm"]\nradius = "1mm"\n', "centre: needs 1 coordinate"),
    (GRID + '[[patch]]\nradius = "0mm"\n', "radius: must be > 0"),
])
def test_toml_load_files_validate(tmp_path, text, message):
    from tactilab.forward.load_files import read_load

    path = tmp_path / "l.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_load(path)


def test_npz_and_unknown_load_files_validate(tmp_path):
    from tactilab.forward.load_files import read_load

    bad = tmp_path / "x.csv"
    bad.write_text("1,2")
    with pytest.raises(ValueError, match="load file: unknown type"):
        read_load(bad)
    npz = tmp_path / "a.npz"
    np.savez(npz, spacing=1e-4)
    with pytest.raises(ValueError, match="holds none of the arrays p, qx, qy"):
        read_load(npz)
    np.savez(npz, p=np.ones(4))
    with pytest.raises(ValueError, match="missing 'spacing'"):
        read_load(npz)


def test_toml_gaussian_patch_values(tmp_path):
    from tactilab.forward.load_files import read_load

    path = tmp_path / "l.toml"
    path.write_text(GRID + '[[patch]]\nshape = "gaussian"\nradius = "0.3mm"\npressure = "2kPa"\ntraction_x = "1kPa"\n')
    load = read_load(path)
    assert load.ndim == 1 and np.isclose(load.p.max(), 2e3) and np.isclose(load.qx.max(), 1e3)


def test_example_load_file_reads():
    from pathlib import Path

    from tactilab.forward.load_files import read_load

    load = read_load(Path(__file__).resolve().parents[1] / "examples" / "fingertip_load.toml")
    assert load.shape == (128, 128) and np.isclose(load.p.max(), 42e3, rtol=1e-3)


def test_stress_command_unwritable_out_names_the_option(tmp_path, capsys):
    load = tmp_path / "load.npz"
    np.savez(load, p=np.ones((8, 8)), spacing=1e-4)
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert main(["stress", str(load), "--depth", "1mm", "--out", str(blocker / "sub")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out: cannot create the output folder" in err


@pytest.mark.parametrize("argv,message", [
    (["stress", "x.toml", "--depth", "-1mm"], "needs '=', e.g. --depth=-1mm"),
    (["nosuch"], "invalid choice: 'nosuch'"),
    (["stress"], "the following arguments are required"),
])
def test_argparse_mistakes_are_one_line(argv, message, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert message in err and err.strip().count("\n") == 0 and "usage:" not in err


def test_synthesis_rejects_a_non_positive_amplitude(capsys):
    assert main(["synthesis", "--depth", "1mm", "--amplitude=-5um", "--young-modulus", "1MPa"]) == 2
    assert "--amplitude: the sinusoid amplitude must be > 0" in capsys.readouterr().err

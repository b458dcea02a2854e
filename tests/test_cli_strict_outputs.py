"""A command that fails part-way, on a warning that ``--strict`` makes an error, leaves no output behind."""

import numpy as np
import pytest

from tactilab.cli.main import main

#: a fingertip on 1 kPa skin: 27 % strain at 1 mm, above the small-strain limit (a warning; --strict: an error)
SOFT = ["sphere:R=10mm", "--normal-force", "0.8N", "--young-modulus", "1kPa", "--grid", "32", "--depth", "1mm"]


def test_contact_strict_failure_writes_nothing(tmp_path, capsys):
    out = tmp_path / "c"
    assert main(["--strict", "contact", *SOFT, "--out", str(out)]) == 2
    assert "small-strain limit" in capsys.readouterr().err
    assert not out.exists()  # contact.nc and pressure.png were written before the strain map warned


def test_contact_strict_failure_keeps_an_existing_folder_as_it_was(tmp_path, capsys):
    out = tmp_path / "c"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert main(["--strict", "contact", *SOFT, "--out", str(out), "--force"]) == 2
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_stress_strict_failure_writes_nothing(tmp_path, capsys):
    load = tmp_path / "load.npz"
    np.savez(load, p=np.full((16, 16), 5e4), spacing=1e-4)  # 50 kPa on 1 kPa skin: far above small strain
    out = tmp_path / "s"
    code = main(["--strict", "stress", str(load), "--depth", "0.5mm", "--young-modulus", "1kPa", "--out", str(out)])
    assert code == 2 and "small-strain limit" in capsys.readouterr().err
    assert not out.exists()  # not even the empty folder the run created

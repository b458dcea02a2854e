"""A bad receptor hypothesis on the command line names the option that carried it."""

from __future__ import annotations

import pytest

from tactilab.cli.main import main


@pytest.mark.parametrize("argv, option", [
    (["metamer", "--target", "sinusoid:A=0.5mm,p=4mm", "--hypothesis", "zx@1.25"], "--hypothesis 'zx@1.25'"),
    (["experiment", "compare", "s.sqlite", "--model", "zx@1", "--model", "xx@1mm"], "--model 'zx@1'"),
    (["experiment", "power", "--true", "zx@1mm", "--rival", "yy@2", "--design", "d.toml"], "--rival 'yy@2'"),
    (["experiment", "power", "--true", "qq@1mm", "--rival", "xx@1mm", "--design", "d.toml"], "--true 'qq@1mm'"),
])
def test_the_error_names_the_option(argv, option, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and option in err

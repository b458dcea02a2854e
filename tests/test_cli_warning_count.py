"""Every warning a command prints is in its run summary's count (text and ``--json``), wherever it
was raised: while reading the options (before the summary exists), inside the computation, or in
a command with no collecting block at all."""

import json
import pathlib

import numpy as np
import pytest

from tactilab.cli.main import main

EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples"


def _printed(err: str) -> list[str]:
    return [line.split(": warning: ", 1)[1] for line in err.splitlines() if ": warning: " in line]


def _stress_load(tmp_path):
    load = tmp_path / "load.npz"
    np.savez(load, p=np.ones((8, 8)), spacing=1e-4)
    return load


@pytest.mark.parametrize("argv, as_json", [
    # an option's plausibility warning, printed before the summary exists (was "warnings: 0")
    (lambda tmp: ["simulate", str(EXAMPLES / "fingerprint_texture.toml"), "--grid-spacing", "50m", "--no-plots",
                  "--quiet", "--out", str(tmp / "sim")], False),
    (lambda tmp: ["simulate", str(EXAMPLES / "fingerprint_texture.toml"), "--grid-spacing", "50m", "--no-plots",
                  "--quiet", "--out", str(tmp / "sim")], True),
    # a command whose computation has no collecting block (was "warnings: 0")
    (lambda tmp: ["synthesis", "--depth", "125mm", "--width", "1m", "--no-sensitivity"], False),
    (lambda tmp: ["synthesis", "--depth", "125mm", "--width", "1m", "--no-sensitivity"], True),
    # a warning inside the computation's collecting block
    (lambda tmp: ["stress", str(_stress_load(tmp)), "--depth", "1um", "--out", str(tmp / "o")], False),
], ids=["simulate-text", "simulate-json", "synthesis-text", "synthesis-json", "stress-text"])
def test_summary_counts_every_printed_warning(tmp_path, capsys, argv, as_json):
    assert main(argv(tmp_path) + (["--json"] if as_json else [])) == 0
    out, err = capsys.readouterr()
    printed = _printed(err)
    assert printed  # each of these runs prints a warning
    if as_json:
        assert json.loads(out)["warnings"] == printed
    else:
        assert f"warnings: {len(printed)}\n" in out
        for text in printed:
            assert f"  - {text}" in out


def test_a_second_command_counts_only_its_own_warnings(tmp_path, capsys):
    argv = ["synthesis", "--depth", "125mm", "--width", "1m", "--no-sensitivity", "--json"]
    assert main(argv) == 0
    capsys.readouterr()
    assert main(["synthesis", "--depth", "1.25mm", "--no-sensitivity", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["warnings"] == []


def test_demo_profile_section_warns_instead_of_printing_a_line(tmp_path):
    """The demo's criteria disagreement is a warning (counted by ``tactilab demo``'s summary), not a text line."""
    from tactilab.demo.inversion import _profile_section

    with pytest.warns(UserWarning, match=r"\[inversion\] profile: regularisation criteria disagree"):
        lines = list(_profile_section(tmp_path, np.random.default_rng([20261122, 1])))
    assert not any("warning" in line for line in lines)

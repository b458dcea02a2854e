"""The inversion demo runs, writes its files and reports its diagnostics."""

from __future__ import annotations

import pathlib

import pytest


@pytest.mark.slow
def test_run_demo(tmp_path: pathlib.Path):
    from tactilab.demo.inversion import run_demo

    lines = list(run_demo(tmp_path, progress=False))
    text = "\n".join(lines)
    out = tmp_path / "inversion"
    for name in ("profile.png", "profile_criteria.png", "defect_corner.png", "defect_posterior.nc"):
        assert (out / name).stat().st_size > 1000
    assert "lam chosen by: gcv" in text and "evidence" in text
    assert "truth inside the 95% band" in text
    assert "R-hat" in text and "ESS" in text and "converged" in text

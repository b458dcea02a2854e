"""The metameres demo runs, writes its figures and reports the paper's case and the mechanics."""

from __future__ import annotations

import pathlib
import re

from tactilab.demo import SECTIONS, inversion, metameres


def test_run_demo(tmp_path: pathlib.Path):
    assert SECTIONS.index(metameres) == SECTIONS.index(inversion) + 1
    text = "\n".join(metameres.run_demo(tmp_path, progress=False))
    out = tmp_path / "metameres"
    for name in ("paper_pair.png", "spectrum_one_depth.png", "spectrum_two_depths.png"):
        assert (out / name).stat().st_size > 1000
    fav = float(re.search(r"favourable phase .*?relative residual ([0-9.]+)", text).group(1))
    unfav = float(re.search(r"unfavourable phase .*?relative residual ([0-9.]+)", text).group(1))
    assert fav < 0.15 < 0.8 < unfav
    assert "volumetric@1.25mm,2.5mm  resolved    0 of" in text
    breaks = re.findall(r"residual ([0-9.]+) \(closed form \|Z2 - Z\| / \(Z2 \|1 - kZ\|\) = ([0-9.]+)\)", text)
    assert len(breaks) == 2 and all(got == closed for got, closed in breaks)
    assert "paper's Q" in text

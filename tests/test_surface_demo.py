"""The surface-inversion demo section (demo/surface.py): a simulated scan of a known random profile, inverted."""

from __future__ import annotations

import re

import numpy as np
import pytest

from tactilab.demo import SECTIONS, metameres, surface


def test_the_section_follows_the_metameres():
    assert SECTIONS.index(surface) == SECTIONS.index(metameres) + 1


def test_the_truth_is_the_profile_the_scene_engine_scanned(rng):
    """The truth on the profile grid is the scene's own surface at those nodes (what the error is measured against)."""
    scene, recording, x, truth = surface.simulate(rng)
    assert np.abs(scene.surface.height_at(x, np.zeros_like(x)) - truth).max() < 1e-15
    assert recording.n_times == scene.scan.n_samples and 0.5e-6 < np.std(truth) < 2e-6


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_the_section_recovers_the_relief_and_the_force(tmp_path):
    """The relief error stays within three posterior relief sd (the section's seed), the finger touched
    part of the strip (its ends only bound the surface), and the force's 90 % interval holds the truth."""
    text = "\n".join(surface.run_demo(tmp_path, progress=False))
    touched = float(re.search(r"touched fraction ([\d.]+)", text)[1])
    error, relief, sd = (float(v) for v in re.search(
        r"relief error \(rms over touched nodes\) ([\d.]+) um against a relief of ([\d.]+) um rms \(posterior "
        r"relief sd, median ([\d.]+) um\)", text).groups())
    low, high = (float(v) for v in re.search(r"90 % \[([\d.]+), ([\d.]+)\]", text).groups())
    assert 0.3 < touched < 1.0
    assert error < 3 * sd and error < 0.2 * relief
    assert low <= surface.FORCE <= high
    assert (tmp_path / "surface" / "surface.png").stat().st_size > 20_000

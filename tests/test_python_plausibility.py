"""The Python entry points give the plausibility warning the options and the files give
(one rule: tactilab.data_schemas.plausibility.check_plausible)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tactilab.data_schemas.plausibility import PlausibilityWarning
from tactilab.data_schemas.units import to_si
from tactilab.forward import HalfSpace
from tactilab.forward.contact.hertz import HertzContact
from tactilab.forward.halfspace.loads import SurfaceLoad

DEPTH = r"depth = 1\.25 m is outside the usual range \(receptor and sensor depths are 1 um to 20 mm\); check its unit"
RADIUS = r"finger_radius = 10 m is outside the usual range \(finger and indenter radii are 0\.1 mm to 1 m\); check its unit"


def _small_load() -> SurfaceLoad:
    x = (np.arange(16) - 8) * 0.25e-3
    return SurfaceLoad(p=1e3 * np.exp(-(x[None, :] ** 2 + x[:, None] ** 2) / 1e-6), spacing=0.25e-3)


def test_a_depth_meant_in_mm_warns_in_python_as_at_the_edges():
    with pytest.warns(PlausibilityWarning, match=DEPTH) as record:
        HalfSpace(E=1e6).strain(_small_load(), depth=1.25, components=("zz",))
    assert record[0].filename == __file__  # points at the user's line, not the solver's
    with pytest.warns(PlausibilityWarning, match=r"^--depth = 1\.25 m is outside the usual range \(receptor"):
        to_si("1.25m", "length", name="--depth")  # the same rule at the option edge
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        HalfSpace(E=1e6).strain(_small_load(), depth=1.25e-3, components=("zz",))


def test_a_finger_radius_meant_in_mm_warns_in_python_as_at_the_edges():
    with pytest.warns(PlausibilityWarning, match=RADIUS) as record:
        HertzContact(normal_force=0.8, finger_radius=10, young_modulus=1e6)
    assert record[0].filename == __file__
    with pytest.warns(PlausibilityWarning, match=r"^--finger-radius = 10 m is outside the usual range \(finger"):
        to_si("10m", "length", name="--finger-radius")
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        HertzContact(normal_force=0.8, finger_radius=10e-3, young_modulus=1e6)
        HertzContact(normal_force=0.8, young_modulus=1e6)  # the default radius (0.1 m) is plausible

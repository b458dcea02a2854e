"""The ground floor (tactilab.core): its face, the finite rule, the plain unit parser, the version."""

from __future__ import annotations

import warnings
from importlib import metadata

import numpy as np
import pytest

import tactilab.core as core
from tactilab.core import rules


def test_the_face_lists_its_names_and_loads_them_on_use():
    assert {"COMPONENTS", "COMPONENT_ALIASES", "to_si", "run_batch", "attach", "package_version"} <= set(core.__all__)
    assert core.COMPONENTS == ("xx", "yy", "zz", "yz", "zx", "xy")
    assert set(core.COMPONENT_ALIASES.values()) <= set(core.COMPONENTS)
    from tactilab.core import rules as by_name

    assert by_name is rules
    with pytest.raises(AttributeError, match="module 'tactilab.core' has no attribute 'skin'"):
        core.skin  # noqa: B018


def test_finite_rule():
    assert rules.finite(np.float64(-2.5), "x_start", "m") == -2.5
    with pytest.raises(ValueError, match=r"x_start: must be finite, got nan; give a finite number in m, e.g. 1.25e-3$"):
        rules.finite(np.nan, "x_start", "m")
    with pytest.raises(ValueError, match=r"gain: must be finite, got inf; give a finite number$"):
        rules.finite(np.inf, "gain")
    with pytest.raises(ValueError, match=r"gain: must be finite, got 'big'; give a finite number$"):
        rules.finite("big", "gain")
    with pytest.raises(ValueError, match=r"gain: must be finite, got True"):
        rules.finite(True, "gain")


def test_poisson_ratio_bounds_are_the_rule():
    low, high = rules.POISSON_RATIO_BOUNDS
    assert rules.poisson_ratio(high) == high
    assert rules.poisson_ratio(np.nextafter(low, 0.0)) > low
    with pytest.raises(ValueError, match=r"nu: Poisson's ratio must lie in \(-1, 0.5\]"):
        rules.poisson_ratio(low)


def test_the_ground_floor_unit_parser_knows_units_not_skin():
    """core.units converts; the records' to_si adds the plausibility of skin quantities on top."""
    from tactilab.core.units import to_si as plain
    from tactilab.data_schemas import to_si as with_skin
    from tactilab.data_schemas.plausibility import PlausibilityWarning

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert plain("5m", "length", name="depth") == 5.0  # 5 m deep in the skin: valid, not plausible
    with pytest.warns(PlausibilityWarning):
        assert with_skin("5m", "length", name="depth") == 5.0


def test_package_version_is_defined_once_with_a_pep440_fallback(monkeypatch):
    import tactilab
    from tactilab.core import version

    assert tactilab.__version__ == core.package_version() == metadata.version("tactilab")

    def not_installed(name):
        raise metadata.PackageNotFoundError(name)

    version.package_version.cache_clear()
    monkeypatch.setattr(version.metadata, "version", not_installed)
    try:
        assert version.package_version() == "0+unknown"
    finally:
        monkeypatch.undo()
        version.package_version.cache_clear()
    assert version.package_version() == metadata.version("tactilab")

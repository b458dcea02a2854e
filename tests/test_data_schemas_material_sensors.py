"""SkinMaterial and SensorArray: derived values, component conventions and every validation rule."""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.core import rules
from tactilab.data_schemas.base import unit_of
from tactilab.data_schemas.material import SkinMaterial
from tactilab.data_schemas.sensors import (
    COMPONENTS,
    SensorArray,
    SensorGrid,
    check_components,
    engineering_factors,
    voigt_indices,
)


# ----- material -----------------------------------------------------------------------------
def test_material_moduli_follow_isotropic_elasticity():
    m = SkinMaterial(young_modulus_pa=1.2e6, poisson_ratio=0.2)
    assert m.shear_modulus_pa == pytest.approx(1.2e6 / 2.4)
    assert m.plane_strain_modulus_pa == pytest.approx(1.2e6 / 0.96)
    assert not m.is_incompressible


def test_material_incompressible_limit_is_allowed_exactly_and_default():
    m = SkinMaterial(young_modulus_pa=1e6)
    assert m.poisson_ratio == 0.5 and m.is_incompressible
    # G = E / 3 at nu = 1/2
    assert m.shear_modulus_pa == pytest.approx(1e6 / 3)


@pytest.mark.parametrize(
    ("fields", "pattern"),
    [
        (dict(young_modulus_pa=0.0), r"young_modulus_pa must be > 0 \(a stiffness\), got 0.0; give Young's modulus"),
        (dict(young_modulus_pa=-1e6), r"young_modulus_pa must be > 0 .*got -1000000.0"),
        (dict(young_modulus_pa=float("nan")), r"young_modulus_pa must be finite, got nan"),
        (dict(young_modulus_pa=float("inf")), r"young_modulus_pa must be finite, got inf"),
        (dict(young_modulus_pa=1e6, poisson_ratio=0.5000001), r"poisson_ratio: Poisson's ratio must lie in \(-1, 0.5\] .*got 0.5000001; skin is close to 0.5"),
        (dict(young_modulus_pa=1e6, poisson_ratio=-1.0), r"poisson_ratio: Poisson's ratio must lie in \(-1, 0.5\] .*got -1.0"),
        (dict(young_modulus_pa=1e6, poisson_ratio=float("nan")), r"poisson_ratio: Poisson's ratio must lie in \(-1, 0.5\] .*got nan"),
        (dict(young_modulus_pa=1e6, shear=3), r"shear"),
    ],
)
def test_material_rules(fields, pattern):
    with pytest.raises(ValueError, match=pattern):
        SkinMaterial(**fields)


# ----- components ---------------------------------------------------------------------------
def test_voigt_order_indices_and_engineering_factors():
    assert COMPONENTS is rules.COMPONENTS  # the one order (tests/test_core.py pins it)
    np.testing.assert_array_equal(voigt_indices(["zx", "xx"]), [4, 0])
    np.testing.assert_array_equal(engineering_factors(["xx", "zx", "zz", "xy", "yz", "yy"]),
                                  [1, 2, 1, 2, 2, 1])


@pytest.mark.parametrize(
    ("components", "pattern"),
    [
        ("zz", r"components must be a list of component names, got the string 'zz'; write e.g. \['zz'\]"),
        ([], r"components: empty selection; pick names from \('xx', 'yy'"),
        (["zz", "pressure"], r"components: unknown component 'pressure'; valid names are \('xx', 'yy', 'zz'"),
        (["zz", "zx", "zz"], r"components: names repeat in \('zz', 'zx', 'zz'\)"),
        (["zx", "xz"], r"components: names repeat .*aliases count as their Voigt name"),
    ],
)
def test_component_rules(components, pattern):
    with pytest.raises(ValueError, match=pattern):
        check_components(components)
    with pytest.raises(ValueError, match=pattern):
        SensorArray(positions_m=[[0, 0]], depth_m=1e-3, components=components)


@pytest.mark.parametrize(("alias", "name"), [("xz", "zx"), ("zy", "yz"), ("yx", "xy")])
def test_sensor_records_accept_the_shear_aliases_like_the_solver(alias, name):
    """Relaxation of issue 22: sensor records used to refuse 'xz'; the solver and the hypothesis
    grammar accepted it. One rule now (tactilab.core.rules.components): the alias names the same
    tensor entry and comes back as its Voigt name."""
    from tactilab.forward.halfspace import validation

    assert check_components(["zz", alias]) == ("zz", name) == validation.components(["zz", alias])
    sensors = SensorArray(positions_m=[[0, 0]], depth_m=1e-3, components=["zz", alias])
    assert sensors.components == ("zz", name)
    np.testing.assert_array_equal(sensors.voigt_indices, [2, COMPONENTS.index(name)])


# ----- sensor arrays ------------------------------------------------------------------------
def test_sensor_grid_is_centred_row_major():
    s = SensorArray.grid(3, 2, 1e-3, 2e-3, spacing_y_m=0.5e-3, center_m=(1e-3, 0.0),
                         components=["zz"])
    expected = [[0, -0.25e-3], [1e-3, -0.25e-3], [2e-3, -0.25e-3],
                [0, 0.25e-3], [1e-3, 0.25e-3], [2e-3, 0.25e-3]]
    np.testing.assert_allclose(s.positions_m, expected, atol=1e-18)
    assert s.n_sensors == 6 and s.n_components == 1 and s.unit == "Pa"
    assert s.ids == ("s0", "s1", "s2", "s3", "s4", "s5")
    # square grid by default
    np.testing.assert_allclose(SensorGrid(nx=2, ny=2, spacing_x_m=1.0).positions_m()[:, 1], [-0.5, -0.5, 0.5, 0.5])


def test_sensor_array_stores_read_only_float_arrays_and_strain_unit():
    s = SensorArray(positions_m=[[0, 0], [1, 2]], depth_m=1e-3, quantity="strain",
                    components=("xx", "zx"), sensor_ids=("a", "b"), noise_std=1e-5)
    assert s.positions_m.dtype == np.float64 and not s.positions_m.flags.writeable
    assert s.unit == "strain" and s.ids == ("a", "b")
    np.testing.assert_array_equal(s.voigt_indices, [0, 4])
    with pytest.raises(ValueError, match="read-only"):
        s.positions_m[0, 0] = 5.0


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        (dict(depth_m=-0.001), r"depth_m must be > 0 \(sensors sit inside the skin\), got -0.001; "
                               r"give the depth below the surface as a positive number in m"),
        (dict(depth_m=0.0), r"depth_m must be > 0 .*got 0.0"),
        (dict(depth_m=float("nan")), r"depth_m must be finite, got nan"),
        (dict(noise_std=-1.0), r"noise_std must be >= 0 \(a standard deviation\), got -1.0; give the noise level"),
        (dict(noise_std=float("inf")), r"noise_std must be finite, got inf"),
        (dict(positions_m=[[0.0, np.nan]]), r"positions_m must be finite everywhere, got nan at index \(0, 1\)"),
        (dict(positions_m=[0.0, 1.0]), r"positions_m must have 2 dimension\(s\), shape \(n, 2\).*got shape \(2,\)"),
        (dict(positions_m=[[0.0, 1.0, 2.0]]), r"positions_m must have 2 columns .*got shape \(1, 3\)"),
        (dict(positions_m=np.zeros((0, 2))), r"positions_m must not be empty, got shape \(0, 2\)"),
        (dict(positions_m=[[0.0, 1.0], [2.0]]), r"positions_m must be an array of numbers"),
        (dict(positions_m=[["a", "b"]]), r"positions_m must be an array of numbers"),
        (dict(sensor_ids=("a",)), r"sensor_ids has 1 entries but positions_m has shape \(2, 2\); give one id per sensor"),
        (dict(sensor_ids=("a", "a")), r"sensor_ids must be unique, got \['a'\] more than once"),
        (dict(quantity="pressure"), r"quantity"),
    ],
)
def test_sensor_array_rules(change, pattern):
    fields = dict(positions_m=[[0, 0], [1e-3, 0]], depth_m=3e-3, components=["zz"])
    fields.update(change)
    with pytest.raises(ValueError, match=pattern):
        SensorArray(**fields)


@pytest.mark.parametrize(
    ("fields", "pattern"),
    [
        (dict(nx=0, spacing_x_m=1e-3), r"nx must be >= 1 \(sensors along x\), got 0"),
        (dict(nx=2, ny=0, spacing_x_m=1e-3), r"ny must be >= 1"),
        (dict(nx=2, spacing_x_m=-1e-3), r"spacing_x_m must be > 0"),
        (dict(nx=2, spacing_x_m=1e-3, spacing_y_m=0.0), r"spacing_y_m must be > 0"),
        (dict(nx=2, spacing_x_m=1e-3, center_m=(np.inf, 0.0)), r"center_m.*must be finite, got inf"),
    ],
)
def test_sensor_grid_rules(fields, pattern):
    with pytest.raises(ValueError, match=pattern):
        SensorGrid(**fields)


def test_field_units_come_from_name_suffixes():
    assert [unit_of(n) for n in ("depth_m", "speed_m_per_s", "young_modulus_pa", "normal_force_n",
                                 "duration_s", "frame_rate_hz", "max_slew_rate_per_s", "phase_rad",
                                 "poisson_ratio")] == ["m", "m/s", "Pa", "N", "s", "Hz", "1/s", "rad", ""]


def test_sensor_array_copies_the_callers_array():
    positions = np.array([[0.0, 0.0], [1e-3, 0.0]])
    s = SensorArray(positions_m=positions, depth_m=1e-3, components=["zz"])
    positions[0, 0] = 5.0  # the caller keeps a writable array; the record does not see the change
    assert s.positions_m[0, 0] == 0.0
    assert s == SensorArray(positions_m=[[0, 0], [1e-3, 0]], depth_m=1e-3, components=["zz"])
    assert s != s.replace(depth_m=2e-3) and hash(s) == hash(s.replace())

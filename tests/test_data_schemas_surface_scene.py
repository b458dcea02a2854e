"""Surfaces (height profiles and rules), Contact, Scan and Scene records."""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.material import SkinMaterial
from tactilab.data_schemas.scene import Contact, Scan, Scene
from tactilab.data_schemas.sensors import SensorArray
from tactilab.data_schemas.surface import (
    SURFACE_KINDS,
    FlatSurface,
    HeightMap,
    IsolatedDefect,
    SinusoidalGrating,
    SquareWaveGrating,
)


# ----- height profiles ----------------------------------------------------------------------
def test_sinusoid_matches_its_formula():
    g = SinusoidalGrating(period_m=2e-3, amplitude_m=20e-6, phase_rad=0.3)
    x = np.linspace(-5e-3, 5e-3, 101)
    np.testing.assert_allclose(g.height_at(x), 20e-6 * np.sin(2 * np.pi * x / 2e-3 + 0.3),
                               rtol=1e-12, atol=1e-18)
    assert g.wavenumber_per_m == pytest.approx(np.pi / 1e-3)
    # ridges run along y: height does not depend on y
    np.testing.assert_array_equal(g.height_at(x, 7e-3 * np.ones_like(x)), g.height_at(x))


def test_flat_surface_is_zero_everywhere():
    assert not FlatSurface().height_at(np.linspace(-1, 1, 5), np.ones(5)).any()


def test_regular_square_wave_alternates_with_period_two_elements():
    g = SquareWaveGrating(element_width_m=0.25e-3, amplitude_m=1e-5, start_m=0.0)
    assert g.period_m == pytest.approx(0.5e-3) and g.n_elements is None
    centres = (np.arange(-4, 8) + 0.5) * 0.25e-3
    np.testing.assert_array_equal(g.height_at(centres), 1e-5 * np.array([1, -1] * 6))
    finite = g.replace(length_m=1e-3)
    np.testing.assert_array_equal(finite.signs(), [1, -1, 1, -1])
    np.testing.assert_array_equal(finite.height_at([-1e-4, 1.1e-3]), [0.0, 0.0])


def test_random_square_wave_is_fixed_by_its_seed(seed):
    g = SquareWaveGrating(pattern="random", element_width_m=1e-4, amplitude_m=1e-5, length_m=0.2,
                          seed=seed, start_m=-0.1)
    assert g.n_elements == 2000
    signs = g.signs()
    np.testing.assert_array_equal(signs, g.replace().signs())
    assert set(np.unique(signs)) == {-1.0, 1.0}
    # a fair coin: the mean of 2000 signs is within 4 standard errors of 0
    assert abs(signs.mean()) < 4 / np.sqrt(2000)
    centres = -0.1 + (np.arange(2000) + 0.5) * 1e-4
    np.testing.assert_array_equal(g.height_at(centres), 1e-5 * signs)
    assert not np.array_equal(signs, g.replace(seed=seed + 1).signs())


def test_defect_shapes():
    bump = IsolatedDefect(shape="bump", size_m=1e-3, height_m=50e-6, position_m=(1e-3, -1e-3))
    x0, y0 = bump.position_m
    assert bump.height_at(x0, y0) == pytest.approx(50e-6)
    # raised cosine: half height at half the radius, zero at and beyond the rim
    assert bump.height_at(x0 + 0.25e-3, y0) == pytest.approx(25e-6)
    np.testing.assert_array_equal(bump.height_at([x0 + 0.5e-3, x0], [y0, y0 + 0.6e-3]), [0.0, 0.0])
    dot = bump.replace(shape="dot", height_m=-10e-6)
    np.testing.assert_array_equal(dot.height_at([x0 + 0.49e-3, x0 + 0.51e-3], y0), [-10e-6, 0.0])
    step = bump.replace(shape="edge_step")
    np.testing.assert_allclose(step.height_at([x0 - 1e-3, x0, x0 + 1e-3]), [0.0, 25e-6, 50e-6], rtol=1e-12)


def test_height_map_reproduces_a_plane_exactly():
    """Linear interpolation is exact for a plane: an independent check of the grid placement."""
    x = 1e-3 + np.arange(6) * 0.5e-3
    y = -2e-3 + np.arange(4) * 0.25e-3
    plane = lambda x, y: 3.0 * x - 2.0 * y + 1e-4  # noqa: E731
    h = HeightMap(heights_m=plane(*np.meshgrid(x, y)), spacing_x_m=0.5e-3, spacing_y_m=0.25e-3,
                  origin_m=(1e-3, -2e-3))
    np.testing.assert_allclose(h.x_m, x) and np.testing.assert_allclose(h.y_m, y)
    px = np.array([1.1e-3, 2.3e-3, 3.4e-3])
    py = np.array([-1.9e-3, -1.5e-3, -1.3e-3])
    np.testing.assert_allclose(h.height_at(px, py), plane(px, py), rtol=1e-12)
    assert h.height_at(0.0, 0.0) == 0.0  # outside the grid
    profile = HeightMap(heights_m=[0.0, 1e-5, 0.0], spacing_x_m=1e-3)
    np.testing.assert_allclose(profile.height_at([0.5e-3, 1e-3, 5e-3], [9.0, 0.0, 0.0]), [5e-6, 1e-5, 0.0])
    np.testing.assert_array_equal(profile.y_m, [0.0])


def test_surface_kinds_registry():
    assert set(SURFACE_KINDS) == {"flat", "sinusoidal_grating", "square_wave_grating", "defect", "height_map",
                                 "random_rough", "measured"}
    for kind, model in SURFACE_KINDS.items():
        assert model.model_fields["kind"].default == kind


@pytest.mark.parametrize(
    ("make", "pattern"),
    [
        (lambda: SinusoidalGrating(period_m=0.0, amplitude_m=1e-5), r"period_m must be > 0 \(the grating spacing\), got 0.0"),
        (lambda: SinusoidalGrating(period_m=1e-3, amplitude_m=-1e-5), r"amplitude_m must be > 0"),
        (lambda: SinusoidalGrating(period_m=1e-3, amplitude_m=1e-5, phase_rad=np.nan), r"phase_rad must be finite"),
        (lambda: SquareWaveGrating(element_width_m=-1e-3, amplitude_m=1e-5), r"element_width_m must be > 0"),
        (lambda: SquareWaveGrating(pattern="random", element_width_m=1e-3, amplitude_m=1e-5, length_m=1e-2),
         r"seed is missing for pattern = 'random'"),
        (lambda: SquareWaveGrating(pattern="random", element_width_m=1e-3, amplitude_m=1e-5, seed=1),
         r"length_m is missing for pattern = 'random'"),
        (lambda: SquareWaveGrating(element_width_m=1e-3, amplitude_m=1e-5, seed=1),
         r"seed = 1 is given but pattern = 'regular' has no randomness"),
        (lambda: SquareWaveGrating(pattern="random", element_width_m=1e-3, amplitude_m=1e-5, length_m=1e-2, seed=-3),
         r"seed must be >= 0 \(a numpy seed\), got -3"),
        (lambda: SquareWaveGrating(element_width_m=1e-3, amplitude_m=1e-5).signs(),
         r"signs\(\) needs a finite length_m"),
        (lambda: SquareWaveGrating(pattern="zigzag", element_width_m=1e-3, amplitude_m=1e-5), r"pattern"),
        (lambda: IsolatedDefect(size_m=0.0, height_m=1e-5), r"size_m must be > 0"),
        (lambda: IsolatedDefect(size_m=1e-3, height_m=0.0), r"height_m must not be 0 \(a defect has relief\)"),
        (lambda: IsolatedDefect(size_m=1e-3, height_m=np.inf), r"height_m must be finite"),
        (lambda: IsolatedDefect(size_m=1e-3, height_m=1e-5, position_m=(0.0, np.nan)), r"position_m.*must be finite"),
        (lambda: IsolatedDefect(shape="crater", size_m=1e-3, height_m=1e-5), r"shape"),
        (lambda: HeightMap(heights_m=np.zeros((2, 2, 2)), spacing_x_m=1e-3, spacing_y_m=1e-3),
         r"heights_m must have shape \(nx,\) or \(ny, nx\), got \(2, 2, 2\)"),
        (lambda: HeightMap(heights_m=[1e-5], spacing_x_m=1e-3),
         r"heights_m needs at least 2 samples along each axis to interpolate, got shape \(1,\)"),
        (lambda: HeightMap(heights_m=np.zeros((3, 3)), spacing_x_m=1e-3),
         r"spacing_y_m is missing but heights_m is a 2-D map of shape \(3, 3\)"),
        (lambda: HeightMap(heights_m=[0.0, np.nan], spacing_x_m=1e-3), r"heights_m must be finite everywhere"),
        (lambda: HeightMap(heights_m=[0.0, 1.0], spacing_x_m=0.0), r"spacing_x_m must be > 0"),
        (lambda: FlatSurface().height_at(np.zeros(3), np.zeros(4)),
         r"x and y must broadcast together, got shapes \(3,\) and \(4,\)"),
    ],
)
def test_surface_rules(make, pattern):
    with pytest.raises(ValueError, match=pattern):
        make()


# ----- contact, scan, scene -----------------------------------------------------------------
def _scene(**changes):
    fields = dict(
        material=SkinMaterial(young_modulus_pa=1e6),
        surface=SinusoidalGrating(period_m=2e-3, amplitude_m=2e-5),
        contact=Contact(normal_force_n=0.5, finger_radius_m=8e-3),
        sensors=SensorArray.grid(5, 1, 1e-3, 1e-3, components=["xx"], quantity="strain"),
        scan=Scan(speed_m_per_s=0.02, duration_s=0.1, sampling_rate_hz=1000.0, start_position_m=-1e-3),
    )
    fields.update(changes)
    return Scene(**fields)


def test_scan_times_and_positions():
    scan = Scan(speed_m_per_s=0.02, duration_s=0.1, sampling_rate_hz=1000.0, start_position_m=-1e-3)
    assert scan.n_samples == 100 and scan.distance_m == pytest.approx(2e-3)
    np.testing.assert_allclose(scan.times_s[:3], [0.0, 1e-3, 2e-3])
    np.testing.assert_allclose(scan.positions_m[[0, -1]], [-1e-3, -1e-3 + 0.02 * 0.099])
    # 0.3 s at 10 Hz is 3 samples although 0.3 * 10 = 2.9999999999999996 in floating point
    assert Scan(speed_m_per_s=0.0, duration_s=0.3, sampling_rate_hz=10.0).n_samples == 3


def test_scene_accepts_a_display_without_contact():
    s = _scene(contact=None, display=DisplayDescription.stress2())
    assert s.contact is None and s.display.n_tractors == 60
    # surface given as a dict picks its model by kind
    s2 = _scene(surface={"kind": "defect", "size_m": 1e-3, "height_m": 5e-5})
    assert isinstance(s2.surface, IsolatedDefect)


@pytest.mark.parametrize(
    ("make", "pattern"),
    [
        (lambda: Contact(normal_force_n=0.0, finger_radius_m=1e-2),
         r"normal_force_n must be > 0 \(the finger presses on the surface\), got 0.0; give the normal force in N"),
        (lambda: Contact(normal_force_n=-0.5, finger_radius_m=1e-2), r"normal_force_n must be > 0 .*got -0.5"),
        (lambda: Contact(normal_force_n=np.nan, finger_radius_m=1e-2), r"normal_force_n must be finite, got nan"),
        (lambda: Contact(normal_force_n=0.5, finger_radius_m=-1e-2), r"finger_radius_m must be > 0"),
        (lambda: Contact(normal_force_n=0.5, finger_radius_m=1e-2, friction_coefficient=-0.1),
         r"friction_coefficient must be >= 0 \(a friction coefficient\), got -0.1"),
        (lambda: Contact(normal_force_n=0.5, finger_radius_m=1e-2, adhesion=1.5),
         r"adhesion must lie in \[0, 1\] \(0 frictionless, 1 fully adhesive\), got 1.5"),
        (lambda: Contact(normal_force_n=0.5, finger_radius_m=1e-2, fingerprint_period_m=0.0),
         r"fingerprint_period_m must be > 0"),
        (lambda: Scan(speed_m_per_s=-0.01, duration_s=1.0, sampling_rate_hz=1e3),
         r"speed_m_per_s must be >= 0 \(the finger moves along \+x\), got -0.01"),
        (lambda: Scan(speed_m_per_s=0.01, duration_s=0.0, sampling_rate_hz=1e3), r"duration_s must be > 0"),
        (lambda: Scan(speed_m_per_s=0.01, duration_s=1.0, sampling_rate_hz=-1e3), r"sampling_rate_hz must be > 0"),
        (lambda: Scan(speed_m_per_s=0.01, duration_s=1e-4, sampling_rate_hz=1e3),
         r"duration_s \* sampling_rate_hz must give at least 1 sample, got 0.0001 s x 1000.0 Hz"),
        (lambda: Scan(speed_m_per_s=0.01, duration_s=1.0, sampling_rate_hz=1e3, start_position_m=np.inf),
         r"start_position_m must be finite"),
        (lambda: _scene(contact=None), r"contact and display are both missing \(nothing touches the skin\)"),
        (lambda: _scene(surface={"kind": "spiral"}), r"surface\n.*'spiral'"),
        (lambda: _scene(surface=None), r"surface"),
    ],
)
def test_contact_scan_scene_rules(make, pattern):
    with pytest.raises(ValueError, match=pattern):
        make()


def test_scene_json_round_trip_is_exact(tmp_path):
    s = _scene(display=DisplayDescription.braille_row(),
               surface=HeightMap(heights_m=np.linspace(0, 1e-5, 7), spacing_x_m=1e-4))
    assert Scene.from_json(s.to_json()) == s
    assert Scene.load(s.save(tmp_path / "scene.json")) == s
    assert s != _scene()

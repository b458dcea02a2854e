"""Surfaces on the scan strip: data_schemas surface records as features, random square waves,
the finite Surface, and the rigid sliding-surface pressure."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactilab.data_schemas import (FlatSurface, HeightMap, IsolatedDefect, SinusoidalGrating,
                                   SquareWaveGrating)
from tactilab.forward.surfaces import (RandomSquareWaveGrating, RecordFeature, Surface, as_feature,
                                       rigid_surface_pressure)


@pytest.mark.parametrize("nu", [0.5, 0.3, 0.0, -0.4])
def test_rigid_surface_pressure_sinusoid(nu):
    """P~ = E rho H~ / (2 (1 - nu^2)) on an exactly periodic sinusoid, 1-D and 2-D; nu in (-1, 0.5]
    (an auxetic nu < 0 used to be refused here while the solver accepted it)."""
    p, A, E, n = 2e-3, 20e-6, 1.5e6, 64
    dx = p / 16
    x = np.arange(n) * dx
    load = rigid_surface_pressure(SinusoidalGrating(period_m=p, amplitude_m=A).height_at(x), dx, E, nu)
    assert load.periodic and load.spacing == (dx,)  # one period of the grating, not an isolated load
    pres = load.p
    k = 2 * math.pi / p
    np.testing.assert_allclose(pres, E * k * A / (2 * (1 - nu ** 2)) * np.sin(k * x), atol=1e-9 * E * k * A)
    X, Y = np.meshgrid(x, x)
    oblique = A * np.sin(math.pi * (X + Y) / p)  # period p sqrt(2) along the diagonal: rho = k / sqrt(2)
    pres2 = rigid_surface_pressure(oblique, (dx, dx), E, nu).p
    np.testing.assert_allclose(pres2, E * k / math.sqrt(2) / (2 * (1 - nu ** 2)) * oblique,
                               atol=1e-9 * E * k * A)


def test_rigid_surface_pressure_anisotropic_spacing():
    """A grating along y on a grid with dx != dy: the pressure uses the y wavenumber."""
    p, A, E = 2e-3, 5e-6, 1e6
    dx, dy = p / 10, p / 16
    y = np.arange(32) * dy
    H = np.broadcast_to((A * np.sin(2 * math.pi * y / p))[:, None], (32, 20))
    pres = rigid_surface_pressure(H, (dx, dy), E, 0.5).p
    k = 2 * math.pi / p
    np.testing.assert_allclose(pres, E * k / 1.5 * H, atol=1e-9 * E * k * A)


def test_sliding_sinusoid_strain_matches_physics_4a():
    """The pressure of a sliding sinusoid, fed to the sinusoidal-load closed forms (docs/theory.md 3)
    and Hooke's law (nu = 1/2, plane strain), gives the 4a strain, independent of E."""
    p, A, Z, n = 2e-3, 10e-6, 1e-3, 128
    dx = p / 32
    x = np.arange(n) * dx
    k = 2 * math.pi / p
    for E in (0.5e6, 3e6):
        P = rigid_surface_pressure(A * np.sin(k * x), dx, E, 0.5).p
        amp = P.max()  # p(x) = amp sin kx; phase-shifted cos closed forms
        e = math.exp(-k * Z)
        sxx = -amp * (1 - k * Z) * e * np.sin(k * x)
        szz = -amp * (1 + k * Z) * e * np.sin(k * x)
        sxz = amp * k * Z * e * np.cos(k * x)
        nu = 0.5
        syy = nu * (sxx + szz)
        tr = sxx + syy + szz
        exx = ((1 + nu) * sxx - nu * tr) / E
        gzx = 2 * (1 + nu) * sxz / E
        c = 4 * math.pi ** 2 * A * Z / p ** 2 * math.exp(-2 * math.pi * Z / p)
        np.testing.assert_allclose(exx, c * np.sin(k * x), atol=1e-9 * c)
        np.testing.assert_allclose(gzx, 2 * c * np.cos(k * x), atol=1e-9 * c)


def test_gratings_and_random_square_wave(rng):
    sq = RecordFeature(SquareWaveGrating(element_width_m=0.5e-3, amplitude_m=5e-6))
    x = np.linspace(0, 10e-3, 10001)[:-1]
    h = sq.height(x)
    assert set(np.unique(h)) == {-5e-6, 5e-6}
    assert np.mean(h > 0) == pytest.approx(0.5, abs=1e-3)
    assert sq.peak() == 5e-6 and sq.bounds() is None and sq.integral() == 0.0
    seed = int(rng.integers(1 << 30))
    g1 = RandomSquareWaveGrating.from_rng(np.random.default_rng(seed), 1000, 0.1e-3, 2e-6)
    g2 = RandomSquareWaveGrating.from_rng(np.random.default_rng(seed), 1000, 0.1e-3, 2e-6)
    np.testing.assert_array_equal(g1.bits, g2.bits)
    assert abs(g1.bits.mean()) < 0.15
    xb = (np.arange(1000) + 0.5) * 0.1e-3
    np.testing.assert_array_equal(g1.height(xb), 2e-6 * g1.bits)
    np.testing.assert_array_equal(g1.height(xb + 1000 * 0.1e-3), g1.height(xb))  # periodic


def test_defects_and_height_map():
    bump = IsolatedDefect(shape="bump", size_m=0.4e-3, height_m=30e-6, position_m=(5e-3, 1e-3))
    b = as_feature(bump)
    h = 1e-6
    xs = np.arange(4.7e-3, 5.3e-3, h)
    ys = np.arange(0.7e-3, 1.3e-3, h)
    X, Y = np.meshgrid(xs, ys)
    assert b.height(X, Y).sum() * h * h == pytest.approx(b.integral(), rel=1e-3)
    assert b.height(5e-3, 1e-3) == pytest.approx(30e-6)
    assert b.bounds() == pytest.approx((4.8e-3, 5.2e-3, 0.8e-3, 1.2e-3)) and b.label == "defect bump"
    dot = as_feature(IsolatedDefect(shape="dot", size_m=0.4e-3, height_m=30e-6, position_m=(5e-3, 1e-3)))
    assert dot.height(X, Y).sum() * h * h == pytest.approx(dot.integral(), rel=1e-2)
    s = RecordFeature(IsolatedDefect(shape="edge_step", size_m=1e-4, height_m=1e-5, position_m=(2e-3, 0.0)))
    assert s.height(1.9e-3) == 0 and s.height(2.1e-3) == 1e-5
    assert s.height(2e-3) == pytest.approx(0.5e-5) and s.bounds()[2:] == (-math.inf, math.inf)
    heights = np.add.outer(np.arange(5) * 2.0, np.arange(7) * 3.0) * 1e-6  # 3 x + 2 y (in cells)
    hm = RecordFeature(HeightMap(heights_m=heights, spacing_x_m=1e-4, spacing_y_m=1e-4, origin_m=(1e-3, 0.0)))
    px, py = 1e-3 + 2.3e-4, 1.7e-4
    assert hm.height(px, py) == pytest.approx((3 * 2.3 + 2 * 1.7) * 1e-6)
    assert hm.height(0.0, 0.0) == 0.0 and hm.peak() == pytest.approx(heights.max())
    prof = RecordFeature(HeightMap(heights_m=[0.0, 1e-6, 0.0], spacing_x_m=1e-4))
    assert prof.height(0.5e-4, 7.0) == pytest.approx(0.5e-6)
    # records go on a Surface as they are (wrapped in RecordFeature)
    surf = Surface(length=10e-3, width=4e-3, features=(bump, s.record, hm.record))
    assert all(isinstance(f, RecordFeature) for f in surf.features)
    assert surf.height(5e-3, 1e-3) == pytest.approx(30e-6 + 1e-5)
    assert surf.height(-1e-3, 0.0) == 0.0
    mod = surf.modulation(np.array([5e-3, 1e-3]), np.array([1e-3, 0.0]), reference_height=1e-5)
    np.testing.assert_allclose(mod, [1 + 4.0, 1.0])
    neg = Surface(length=1e-2, features=(bump.replace(height_m=-3e-5, position_m=(5e-3, 0.0)),))
    assert neg.modulation(5e-3, 0.0, reference_height=1e-5) == 0.0


def test_bad_input_raises():
    def bump(x, y):
        return IsolatedDefect(shape="bump", size_m=1e-3, height_m=1e-5, position_m=(x, y))

    with pytest.raises(ValueError, match="features\\[0\\]: defect bump spans .* outside the surface"):
        Surface(length=10e-3, features=(bump(12e-3, 0.0),))
    with pytest.raises(ValueError, match="outside the surface"):
        Surface(length=10e-3, width=2e-3, features=(bump(5e-3, 1.5e-3),))
    with pytest.raises(ValueError, match="features\\[0\\]: expected a data_schemas surface record or a surface Feature"):
        Surface(length=1e-2, features=("bump",))
    with pytest.raises(ValueError, match="surface: expected a data_schemas surface record"):
        RecordFeature(object())
    with pytest.raises(ValueError, match="amplitude: must be finite"):
        RandomSquareWaveGrating(bit_length=1e-4, amplitude=math.nan, bits=np.array([1.0, -1.0]))
    with pytest.raises(ValueError, match="bit_length: must be finite and > 0"):
        RandomSquareWaveGrating(bit_length=0.0, amplitude=1e-6, bits=np.array([1.0, -1.0]))
    with pytest.raises(ValueError, match="bits: need a 1-D array"):
        RandomSquareWaveGrating(bit_length=1e-4, amplitude=1e-6, bits=np.array([1.0, 0.5]))
    with pytest.raises(ValueError, match="rng: expected a numpy.random.Generator"):
        RandomSquareWaveGrating.from_rng(42, 10, 1e-4, 1e-6)
    with pytest.raises(ValueError, match="n_bits: must be an integer >= 2"):
        RandomSquareWaveGrating.from_rng(np.random.default_rng(0), 1, 1e-4, 1e-6)
    with pytest.raises(ValueError, match="reference_height: must be finite and > 0"):
        Surface(length=1e-2).modulation(0.0, reference_height=0.0)
    with pytest.raises(ValueError, match="x, y: surface points must be finite"):
        Surface(length=1e-2).height(np.array([np.nan]))
    with pytest.raises(ValueError, match="length: must be finite"):
        Surface(length=-1.0)
    with pytest.raises(ValueError, match="heights: need a finite array"):
        rigid_surface_pressure(np.array([np.nan, 0.0]), 1e-4, 1e6)
    with pytest.raises(ValueError, match="spacing: expected one value or 2 values"):
        rigid_surface_pressure(np.zeros((4, 4)), (1e-4, 1e-4, 1e-4), 1e6)
    with pytest.raises(ValueError, match="spacing: grid spacing must be finite and > 0 m"):
        rigid_surface_pressure(np.zeros(4), -1e-4, 1e6)
    with pytest.raises(ValueError, match="young_modulus: Young's modulus must be finite and > 0 Pa"):
        rigid_surface_pressure(np.zeros(4), 1e-4, 0.0)
    with pytest.raises(ValueError, match=r"poisson_ratio: Poisson's ratio must lie in \(-1, 0.5\]"):
        rigid_surface_pressure(np.zeros(4), 1e-4, 1e6, poisson_ratio=0.6)


@pytest.mark.parametrize("feature", [
    SinusoidalGrating(period_m=1e-3, amplitude_m=1e-6),
    SquareWaveGrating(element_width_m=0.5e-3, amplitude_m=1e-6),
    SquareWaveGrating(pattern="random", element_width_m=1e-4, amplitude_m=1e-6, length_m=1e-3, seed=3),
    RandomSquareWaveGrating(bit_length=1e-4, amplitude=1e-6, bits=np.array([1.0, -1.0, 1.0])),
    IsolatedDefect(shape="bump", size_m=1e-3, height_m=1e-5),
    IsolatedDefect(shape="edge_step", size_m=1e-4, height_m=1e-5),
    HeightMap(heights_m=np.zeros((3, 3)), spacing_x_m=1e-4, spacing_y_m=1e-4),
    FlatSurface(),
], ids=lambda f: getattr(f, "kind", type(f).__name__))
def test_every_feature_rejects_non_finite_points(feature):
    """NaN positions used to come back as NaN heights from the features (only Surface checked);
    the records' own ``height_at`` checks them too."""
    if not isinstance(feature, RandomSquareWaveGrating):
        with pytest.raises(ValueError, match="x, y: surface points must be finite"):
            feature.height_at(np.array([0.0, np.nan]), np.array([0.0, 0.0]))
        feature = as_feature(feature)
    assert np.all(np.isfinite(feature.height(np.array([0.0, 1e-4]), np.array([0.0, 0.0]))))
    with pytest.raises(ValueError, match="x, y: surface points must be finite"):
        feature.height(np.array([0.0, np.nan]), np.array([0.0, 0.0]))
    with pytest.raises(ValueError, match="x, y: surface points must be finite"):
        feature.height(np.array([0.0, 1e-4]), np.array([np.inf, 0.0]))

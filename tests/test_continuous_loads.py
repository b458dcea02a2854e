"""Continuous loads (ContinuousLoad protocol) through HalfSpace.stress/strain: grids, refinement,
warnings and bad input. The accuracy of the estimates is the catalogue's job
(tests/test_error_estimates.py)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tactilab.forward import (AccuracyWarning, DeflectionLoad, HalfSpace, HertzContact, SurfaceLoad,
                              TractionField)
from tactilab.forward.halfspace.continuous import (coarse_grid, refined_grid, sampling_error, shared_nodes,
                                                  spectral_sampling_error)
from tactilab.forward.halfspace.fields import output_weights

CONTACT = HertzContact(0.5, finger_radius=0.01, young_modulus=1e6, poisson_ratio=0.5)
A = CONTACT.contact_radius


@pytest.mark.parametrize("n", [5, 8, 9, 17, 64, 65])
def test_shared_nodes_sit_at_the_same_positions(n):
    for periodic in (False, True):
        if periodic and n % 2:
            assert coarse_grid((n,), (1.0,), True) is None
            continue
        (m,), _ = coarse_grid((n,), (1.0,), periodic)
        (f,), (c,) = shared_nodes((n,), (m,))
        xf = (np.arange(n) - n // 2)[f]
        xc = 2 * (np.arange(m) - m // 2)[c]
        assert len(xf) >= (m - 1) and np.array_equal(xf, xc)
        (nn,), _ = refined_grid((m,), (2.0,), periodic)
        assert nn >= n - 1


def test_sampling_error_recovers_a_known_order():
    """Outputs F_h = 1 + C h^2 on nested grids: the bound is 2x the true error d1/3."""
    levels = [np.array([1 + 0.01 * h**2]) for h in (1, 2, 4)]
    est, order = sampling_error([v[None, None] for v in levels], None)
    assert order == pytest.approx(2.0)
    assert est == pytest.approx(2 * 0.01 / levels[0][0], rel=1e-9)


@pytest.mark.parametrize("shape", [(32,), (8, 32)])
def test_spectral_sampling_estimate_sees_only_what_the_grid_misses(shape):
    """A cosine of 3 periods is represented exactly by the trigonometric interpolant of its
    samples (estimate at rounding level) but not by nodal forces, whose spectrum repeats beyond
    the Nyquist wavenumber (images at k +- 2 pi / h, attenuated by the depth: the estimate falls
    like (1 + k z) exp(-k z) with k = 2 pi / h - k0)."""
    n, h = shape[-1], 1e-4
    k0 = 2 * np.pi * 3 / (n * h)
    f = (lambda x: 1e3 * np.cos(k0 * x)) if len(shape) == 1 else (lambda x, y: 1e3 * np.cos(k0 * x) + 0 * y)
    load = TractionField(p=f, shape=shape, spacing=h, periodic=True)
    coarse = load.nodal()
    weights = output_weights("stress", ("zz",), 1e6, 0.3)
    for depth in (0.5 * h, 2 * h):
        depths = np.array([depth])
        peak = 1e3 * (1 + k0 * depth) * np.exp(-k0 * depth)
        exact = spectral_sampling_error(load, coarse, depths, 0.3, weights, band_limited=True, peak=peak)
        assert exact < 1e-13
        nodal = spectral_sampling_error(load, coarse, depths, 0.3, weights, band_limited=False, peak=peak)
        k1 = 2 * np.pi / h - k0  # the nearest image; the estimate carries the safety factor 2 (1-D) or 3 (2-D)
        image = (1 + k1 * depth) * np.exp(-k1 * depth) * 1e3 / peak
        assert image < nodal < (4 if len(shape) == 1 else 8) * image  # 2-D: images at 2 pi / h along y too


def test_the_spectral_bound_is_reported_for_content_beyond_the_nyquist_wavenumber():
    """A Hertz contact's edge puts content beyond the grid's Nyquist wavenumber, which aliases alike
    on the 2h and 4h grids: the Richardson bound is not trusted there, the spectral one is reported."""
    load = CONTACT.load(friction=0.3, spacing=A / 8)
    attrs = HalfSpace(1e6).stress(load, A / 2, method="dcfft", tol=1.0).data.attrs
    assert attrs["sampling_error_estimate"] == attrs["sampling_spectral"] > attrs["sampling_richardson"]
    # a sinusoidal deflection: the Richardson bound is below the method's rounding estimate, the
    # spectral bound is not computed (it could lower the total by less than 2x)
    n, pitch = 64, 2e-3
    sine = DeflectionLoad(lambda x: 2e-5 * np.sin(2 * np.pi * x / pitch), 2e5, 0.3, shape=n, spacing=pitch / n)
    attrs = HalfSpace(2e5, 0.3).strain(sine, 0.5e-3).data.attrs
    assert np.isnan(attrs["sampling_spectral"])
    assert attrs["sampling_error_estimate"] == attrs["sampling_richardson"] <= attrs["method_error_estimate"]


def test_auto_refines_the_grid_until_tol_is_met():
    load = CONTACT.load(friction=0.3, spacing=A / 8)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        result = HalfSpace(1e6).stress(load, A / 2, tol=1e-2)
    assert result.error_estimate <= 1e-2
    assert result.data.attrs["grid_refinements"] >= 1
    assert result.data.attrs["sampled_spacing_m"][0] < A / 8
    assert result.data.attrs["error_covers"] == "method+sampling"


def test_a_tol_out_of_reach_warns_and_names_the_spacing():
    load = CONTACT.load(friction=0.3, spacing=A / 8)
    with pytest.warns(AccuracyWarning, match=r"sampling the load at spacing .* m \(shape"):
        result = HalfSpace(1e6).stress(load, A / 2, tol=1e-8)
    assert result.error_estimate > 1e-8
    assert result.data.attrs["grid_refinements"] == 0  # the grid it would need is beyond MAX_NODES


def test_forced_method_does_not_refine_but_warns():
    load = CONTACT.load(friction=0.3, spacing=A / 8)
    with pytest.warns(AccuracyWarning, match="continuous load: error estimate"):
        result = HalfSpace(1e6).stress(load, A / 2, method="dcfft", tol=1e-3)
    assert result.data.attrs["grid_refinements"] == 0 and result.data.sizes["x"] == load.shape[-1]


def test_line_contact_and_sensor_points():
    line = HertzContact(200.0, finger_radius=0.01, young_modulus=1e6, line=True)
    a = line.contact_radius
    load = line.load(friction=0.2, spacing=a / 16)
    result = HalfSpace(1e6).strain(load, a, tol=1.0)
    assert result.data["strain"].dims == ("depth", "component", "x")
    pts = np.array([[0.1 * A, 0.0], [0.37 * A, 0.21 * A]])
    on_points = HalfSpace(1e6).stress(CONTACT.load(friction=0.3), A / 2, points=pts, tol=1.0)
    assert on_points.data["stress"].shape == (1, 6, 2)
    assert on_points.data.attrs["sampling_error_estimate"] > 0


def test_deflection_load_matches_pressure_from_deflection():
    n, h = 32, 1e-4
    load = DeflectionLoad(lambda x, y: 1e-5 * np.cos(2 * np.pi * x / (n * h)), 1e6, 0.5, shape=(8, n), spacing=h)
    sampled = load.nodal()
    assert sampled.periodic and sampled.shape == (8, n)
    assert np.isclose(np.abs(sampled.p).max(), 1e6 * 2 * np.pi / (n * h) * 1e-5 / (2 * 0.75))


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: TractionField(shape=9, spacing=1e-4), "give at least one of p, qx, qy"),
        (lambda: TractionField(p=3.0, shape=9, spacing=1e-4), "p: expected a function of position"),
        (lambda: TractionField(p=np.cos, shape=(0, 4), spacing=1e-4), r"shape: expected \(nx,\) or \(ny, nx\)"),
        (lambda: TractionField(p=np.cos, shape=10, spacing=1e-4, periodic=True), "divisible by 4"),
        (lambda: DeflectionLoad(1e-5, 1e6, 0.5, shape=8, spacing=1e-4), "height: expected a function"),
        (lambda: CONTACT.load(spacing=-1.0), "spacing"),
        (lambda: CONTACT.load(half_width=0.0), "half_width"),
        (lambda: CONTACT.load(condition="partial"), "tangential_force"),
        (lambda: CONTACT.load().sample((9,), (1e-4,)), "shape: this contact needs a 2-D grid"),
    ],
)
def test_bad_continuous_loads_are_refused(build, match):
    with pytest.raises(ValueError, match=match):
        build()


def test_the_facade_names_the_load_types_it_accepts():
    with pytest.raises(ValueError, match="expected a SurfaceLoad or a ContinuousLoad"):
        HalfSpace(1e6).stress(np.zeros((4, 4)), 1e-3)
    assert isinstance(CONTACT.load().nodal(), SurfaceLoad)

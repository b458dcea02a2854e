"""The HalfSpace facade: method choice, agreement between methods, the operator, bad input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tactilab.forward.halfspace.facade import AccuracyWarning, HalfSpace
from tactilab.forward.halfspace.kernels import point_load_stress
from tactilab.forward.halfspace.loads import SurfaceLoad
from tactilab.forward.halfspace.methods import Spectral, image_error

HS = HalfSpace(E=1e6, nu=0.5)


def gaussian(n, h, width, ndim=2, centre=(0.0, 0.0)):
    x = (np.arange(n) - n // 2) * h
    if ndim == 1:
        return np.exp(-((x - centre[0]) ** 2) / (2 * width**2))
    xx, yy = np.meshgrid(x, x)
    return np.exp(-((xx - centre[0]) ** 2 + (yy - centre[1]) ** 2) / (2 * width**2))


def test_auto_choice_is_reported_and_meets_tol():
    periodic = SurfaceLoad(p=gaussian(64, 1e-4, 5e-4), spacing=1e-4, periodic=True)
    r = HS.stress(periodic, 1e-3)
    assert r.method == "spectral" and r.error_estimate < 1e-6 and r.data.attrs["method"] == "spectral"
    isolated = SurfaceLoad(p=gaussian(64, 1e-4, 3e-4), spacing=1e-4)
    r = HS.stress(isolated, 1e-3)
    assert r.method == "dcfft" and r.error_estimate <= 1e-6
    assert set(r.candidates) == {"closed_form", "spectral", "dcfft"}
    # few loaded nodes, few sensors: the direct closed-form sum is cheapest
    few = np.zeros((64, 64))
    few[32, 32] = few[30, 35] = 1e5
    r = HS.stress(SurfaceLoad(p=few, spacing=1e-4), 1e-3, points=[[0.0, 0.0], [1e-4, 3e-4]])
    assert r.method == "closed_form"
    # a loose tolerance lets the cheaper (image-affected) spectral method in, in float32
    wide = SurfaceLoad(p=gaussian(256, 1e-4, 2e-4), spacing=1e-4)
    r = HS.stress(wide, 5e-4, tol=5e-2)
    assert r.method == "spectral" and r.data["stress"].dtype == np.float32 and r.error_estimate <= 5e-2


def test_methods_agree_on_an_isolated_load(rng):
    p = rng.uniform(0, 1e4, size=(12, 14)) * (rng.uniform(size=(12, 14)) < 0.3)
    load = SurfaceLoad(p=p, qx=0.3 * p, qy=rng.normal(size=p.shape) * 100, spacing=(1e-4, 1.2e-4))
    a = HS.stress(load, [3e-4, 8e-4], method="dcfft").data["stress"].values
    b = HS.stress(load, [3e-4, 8e-4], method="closed_form").data["stress"].values
    assert np.abs(a - b).max() < 1e-11 * np.abs(b).max()


def test_closed_form_matches_boussinesq_for_a_single_node():
    p = np.zeros((9, 9))
    p[4, 4] = 1e6
    load = SurfaceLoad(p=p, spacing=1e-4)
    pts = np.array([[2e-4, -1e-4], [0.0, 0.0], [3e-4, 3e-4]])
    r = HS.stress(load, 7e-4, points=pts, method="closed_form").data["stress"].values[0]
    force = 1e6 * 1e-8
    want = point_load_stress(pts[:, 0], pts[:, 1], 7e-4, fz=force, nu=0.5)
    np.testing.assert_allclose(r.T, want, rtol=1e-12)


@pytest.mark.parametrize("ndim,rate", [(2, 2.0), (1, 1.0)])
def test_periodic_images_vanish_at_the_stated_rate(ndim, rate):
    """Periodic (spectral) vs isolated (DC-FFT) on the same isolated load as the period L
    grows: the worst component (in-plane stress of a tangential load) differs by ~ (Z/L)^2
    in 2-D and ~ Z/L in 1-D (docs/theory.md s5); the image-error estimate bounds it within 20x.
    Normal loads converge faster and stay below the estimate."""
    h, z = 1e-4, 5e-4
    sizes = [32, 64, 128]
    errors = {"qx": [], "p": []}
    estimates = []
    for n in sizes:
        g = gaussian(n, h, 2e-4, ndim)
        for name in errors:
            iso = SurfaceLoad(**{name: g}, spacing=h)
            per = SurfaceLoad(**{name: g}, spacing=h, periodic=True)
            a = HS.stress(iso, z, method="dcfft").data["stress"].values
            b = HS.stress(per, z, method="spectral").data["stress"].values
            errors[name].append(np.abs(a - b).max() / np.abs(a).max())
        estimates.append(image_error(iso, np.array([z])))
    slope = -np.polyfit(np.log(sizes), np.log(errors["qx"]), 1)[0]
    assert abs(slope - rate) < 0.25
    for err, est in zip(errors["qx"], estimates):
        assert err <= est <= 20 * err
    assert all(e <= est for e, est in zip(errors["p"], estimates))


def test_shallow_depth_is_reported_not_silent():
    load = SurfaceLoad(p=gaussian(32, 1e-4, 3e-4), spacing=1e-4)
    with pytest.warns(AccuracyWarning, match="no method meets tol"):
        r = HS.stress(load, 2e-5, method="auto", tol=1e-6)
    assert r.error_estimate > 1e-6
    forced = HS.stress(load, 2e-5, method="dcfft")
    assert forced.error_estimate > 0.1  # depth < h: the estimate says the result is unresolved


def test_plane_strain_reduction_and_points():
    x = (np.arange(32) - 16) * 1e-4
    row = np.cos(2 * np.pi * x / 3.2e-3)
    load2 = SurfaceLoad(p=np.tile(row, (8, 1)), spacing=1e-4, periodic=True)
    r2 = HS.strain(load2, 1e-3)
    assert r2.data.attrs["reduced_to_1d"] == 1
    r1 = HS.strain(SurfaceLoad(p=row, spacing=1e-4, periodic=True), 1e-3)
    np.testing.assert_allclose(r2.data["strain"].values[0, :, 3], r1.data["strain"].values[0], atol=1e-20)
    # on-grid and off-grid points agree with the grid values / the exact interpolant
    pts = np.array([[x[5], 0.0], [x[9] + 0.37e-4, 2e-4]])
    rp = HS.strain(load2, 1e-3, points=pts, components=("zz",)).data["strain"].values[0, 0]
    k = 2 * np.pi / 3.2e-3
    exact_sigma = lambda xx: -(1 + k * 1e-3) * np.exp(-k * 1e-3) * np.cos(k * xx)  # noqa: E731
    want = (exact_sigma(pts[:, 0]) - 0.5 * (-(1 - k * 1e-3) * np.exp(-k * 1e-3) * np.cos(k * pts[:, 0])
                                            + 0.5 * (exact_sigma(pts[:, 0]) - (1 - k * 1e-3) * np.exp(-k * 1e-3)
                                                     * np.cos(k * pts[:, 0]))) ) / 1e6
    # sigma_yy = nu (sigma_xx + sigma_zz) in plane strain: eps_zz = (szz - nu (sxx + syy)) / E
    assert np.allclose(rp, want, rtol=1e-10)


def test_invariants_against_a_hand_computed_tensor(rng):
    load = SurfaceLoad(p=rng.normal(size=(8, 8)), qx=rng.normal(size=(8, 8)), spacing=1e-4, periodic=True)
    hs = HalfSpace(2e5, 0.3)
    ds = hs.strain(load, [4e-4], invariants=True).data
    e = ds["strain"].values[0, :, 2, 5]
    s = ds["stress"].values[0, :, 2, 5]
    T = np.array([[e[0], e[5], e[4]], [e[5], e[1], e[3]], [e[4], e[3], e[2]]])
    S = np.array([[s[0], s[5], s[4]], [s[5], s[1], s[3]], [s[4], s[3], s[2]]])
    dev = T - np.trace(T) / 3 * np.eye(3)
    assert np.isclose(ds["volumetric"].values[0, 2, 5], np.trace(T))
    assert np.isclose(ds["von_mises"].values[0, 2, 5], np.sqrt(2 / 3 * np.sum(dev * dev)))
    assert np.isclose(ds["energy_density"].values[0, 2, 5], 0.5 * np.sum(S * T))
    lam = np.sort(np.linalg.eigvalsh(T))[::-1]
    np.testing.assert_allclose(ds["principal"].values[0, 2, 5], lam)
    assert np.isclose(ds["max_shear"].values[0, 2, 5], (lam[0] - lam[2]) / 2)
    # Hooke consistency of the strain with the stress
    nu, E = 0.3, 2e5
    assert np.isclose(e[0], (s[0] - nu * (s[1] + s[2])) / E) and np.isclose(e[4], (1 + nu) * s[4] / E)


@pytest.mark.parametrize("periodic", [True, False])
@pytest.mark.parametrize("sensors", ["all", "grid", "off"])
@pytest.mark.parametrize("ndim", [1, 2])
def test_operator_dot_test_and_agreement(rng, periodic, sensors, ndim):
    shape = (20,) if ndim == 1 else (10, 12)
    spacing = 1e-4 if ndim == 1 else (1e-4, 1.3e-4)
    template = SurfaceLoad(p=np.zeros(shape), spacing=spacing)
    if sensors == "all":
        pts = None
    elif sensors == "grid":
        pts = template.x[::3] if ndim == 1 else np.column_stack([template.x[::3], template.y[: len(template.x[::3])]])
    else:
        pts = rng.uniform(-4e-4, 4e-4, size=(6, ndim))
    loads = ("p", "qx") if ndim == 1 else ("p", "qx", "qy")
    op = HS.operator(shape, spacing, sensors=pts, depth=3e-4, components=("zz", "zx", "xx"), loads=loads,
                     quantity="strain", periodic=periodic)
    x = rng.normal(size=(op.shape[1], 3))
    y = rng.normal(size=(op.shape[0], 3))
    lhs, rhs = np.sum(y * (op @ x)), np.sum((op.H @ y) * x)
    assert abs(lhs - rhs) <= 1e-12 * max(abs(lhs), 1e-300) * 10
    batch = op @ x
    np.testing.assert_allclose(batch[:, 1], op @ x[:, 1], rtol=1e-12, atol=1e-30)
    load = SurfaceLoad(**dict(zip(loads, x[:, 0].reshape(op.model_shape))), spacing=spacing, periodic=periodic)
    ref = HS.strain(load, 3e-4, points=pts, components=("zz", "zx", "xx"),
                    method="spectral" if periodic else "closed_form").data["strain"].values[0]
    got = (op @ x[:, 0]).reshape(op.dimsd)
    np.testing.assert_allclose(got, ref.reshape(got.shape), atol=1e-10 * np.abs(ref).max())


def test_bad_input_names_the_argument():
    load = SurfaceLoad(p=np.ones((4, 4)), spacing=1e-4)
    with pytest.raises(ValueError, match="E: Young's modulus"):
        HalfSpace(E=-1.0)
    with pytest.raises(ValueError, match="nu: Poisson's ratio"):
        HalfSpace(E=1e6, nu=0.6)
    with pytest.raises(ValueError, match="depth: every depth must be finite and > 0"):
        HS.stress(load, -1e-3)
    with pytest.raises(ValueError, match="depth: expected one depth or a non-empty 1-D"):
        HS.stress(load, [])
    with pytest.raises(ValueError, match="components: unknown component"):
        HS.stress(load, 1e-3, components=("zz", "qq"))
    with pytest.raises(ValueError, match="components: names repeat"):
        HS.stress(load, 1e-3, components=("zz", "zz"))
    with pytest.raises(ValueError, match="tol: must be a finite"):
        HS.stress(load, 1e-3, tol=0)
    with pytest.raises(ValueError, match="method: unknown method"):
        HS.stress(load, 1e-3, method="magic")
    with pytest.raises(ValueError, match="method: expected 'auto'"):
        HS.stress(load, 1e-3, method=3)
    with pytest.raises(ValueError, match="cannot run here"):
        HS.stress(SurfaceLoad(p=np.ones(4), spacing=1e-4, periodic=True), 1e-3, method="dcfft")
    with pytest.raises(ValueError, match="points: a 2-D load needs"):
        HS.stress(load, 1e-3, points=[1e-4, 2e-4])
    with pytest.raises(ValueError, match="points: coordinates must be finite"):
        HS.stress(load, 1e-3, points=[[np.nan, 0.0]])
    with pytest.raises(ValueError, match="points: expected shape"):
        HS.stress(load, 1e-3, points=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="load: expected a SurfaceLoad"):
        HS.stress(np.ones(4), 1e-3)
    with pytest.raises(ValueError, match="invariants: need all six"):
        HS.strain(load, 1e-3, components=("zz",), invariants=True)
    with pytest.raises(ValueError, match="quantity: must be"):
        HS.operator((4, 4), 1e-4, quantity="displacement")
    with pytest.raises(ValueError, match="loads: give distinct names"):
        HS.operator((4, 4), 1e-4, loads=("p", "r"))
    with pytest.raises(ValueError, match="sensors: expected finite positions"):
        HS.operator((4, 4), 1e-4, sensors=np.zeros((3, 1)))
    with pytest.raises(ValueError, match="shape: expected"):
        HS.operator((0, 4), 1e-4)
    with pytest.raises(ValueError, match="depth: every depth must be finite and > 0 m"):
        HS.operator((4, 4), 1e-4, depth=0.0)
    with pytest.raises(ValueError, match="method: 'dcfft' cannot run here: sensors lie off the grid nodes"):
        from tactilab.forward.halfspace.methods import DCFFT, Problem
        DCFFT().compute(Problem(load, np.array([1e-3]), 0.5, np.eye(6), np.array([[0.5e-4, 0.0]]), np.dtype(float)))


def test_surface_load_validation():
    with pytest.raises(ValueError, match="p: traction must be finite"):
        SurfaceLoad(p=np.array([0.0, np.inf]), spacing=1e-4)
    with pytest.raises(ValueError, match="share one shape"):
        SurfaceLoad(p=np.zeros(4), qx=np.zeros(5), spacing=1e-4)
    with pytest.raises(ValueError, match="give at least one of p, qx, qy"):
        SurfaceLoad(spacing=1e-4)
    with pytest.raises(ValueError, match="spacing: grid spacing must be finite and > 0"):
        SurfaceLoad(p=np.zeros(4), spacing=0.0)
    with pytest.raises(ValueError, match="spacing: expected one value or 2 values"):
        SurfaceLoad(p=np.zeros((2, 2)), spacing=(1e-4, 1e-4, 1e-4))
    with pytest.raises(ValueError, match="expected shape"):
        SurfaceLoad(p=np.zeros((2, 2, 2)), spacing=1e-4)
    with pytest.raises(ValueError, match="real array"):
        SurfaceLoad(p=np.array(["a"]), spacing=1e-4)
    with pytest.raises(ValueError, match="grid is empty"):
        SurfaceLoad(p=np.zeros(0), spacing=1e-4)
    with pytest.raises(ValueError, match="periodic: must be True or False"):
        SurfaceLoad(p=np.zeros(3), spacing=1e-4, periodic="yes")
    with pytest.raises(ValueError, match="varies in y"):
        SurfaceLoad(p=np.eye(3), spacing=1e-4).row()


def test_zero_load_and_extreme_amplitudes(rng):
    zero = SurfaceLoad(p=np.zeros((16, 16)), spacing=1e-4)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = HS.stress(zero, 1e-3)
    assert not r.data["stress"].values.any()
    p = rng.uniform(size=(16, 16))
    base = HS.stress(SurfaceLoad(p=p, spacing=1e-4), 1e-3, method="dcfft").data["stress"].values
    for amp in (1e-9, 1e9):
        got = HS.stress(SurfaceLoad(p=amp * p, spacing=1e-4), 1e-3, method="dcfft").data["stress"].values
        assert np.abs(got / amp - base).max() <= 1e-12 * np.abs(base).max()


def test_spectral_error_estimate_for_periodic_is_rounding():
    load = SurfaceLoad(p=np.ones((4, 4)), spacing=1e-4, periodic=True)
    assert Spectral().error_estimate(
        __import__("tactilab.forward.halfspace.methods", fromlist=["Problem"]).Problem(
            load, np.array([1e-3]), 0.5, np.eye(6), None, np.dtype(float))) < 1e-13


@pytest.mark.parametrize("depth_over_h", [0.5, 0.7, 1.0, 1.5, 2.0])
def test_reported_estimate_bounds_the_error_relative_to_the_field(depth_over_h):
    """DC-FFT's reported estimate (rescaled to the field's peak) bounds the error against a
    3x refined grid of the same smooth load, measured relative to the field's peak."""
    h, width = 1e-4, 2e-4
    z = depth_over_h * h

    def field(spacing, n):
        x = (np.arange(n) - n // 2) * spacing
        xx, yy = np.meshgrid(x, x)
        g = 1e4 * np.exp(-(xx**2 + yy**2) / (2 * width**2))
        r = HS.stress(SurfaceLoad(p=g, qx=0.5 * g, spacing=spacing), z, method="dcfft")
        return r, r.data["stress"].values[0]

    coarse, a = field(h, 33)
    _, fine = field(h / 3, 97)  # node 3k of the fine grid sits on node k of the coarse one
    err = np.abs(a - fine[:, ::3, ::3]).max() / np.abs(fine).max()
    assert err <= coarse.error_estimate


def test_dense_operator_built_in_sensor_chunks_matches_closed_form(rng):
    """More sensor-node pairs than one chunk (2^20): chunk edges must not shift rows."""
    pts = rng.uniform(-1.5e-3, 1.5e-3, size=(1100, 2))
    op = HS.operator((32, 32), 1e-4, sensors=pts, depth=5e-4, components=("zz",), loads=("p",))
    assert op.path == "dense"
    p = rng.uniform(size=(32, 32))
    ref = HS.stress(SurfaceLoad(p=p, spacing=1e-4), 5e-4, points=pts, components=("zz",),
                    method="closed_form").data["stress"].values[0, 0]
    np.testing.assert_allclose(op @ p.ravel(), ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())

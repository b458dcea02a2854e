"""Oracles for the closed-form point and line load kernels (method 1, tactilab.forward.halfspace.kernels).

Independent references: the polar Boussinesq and Flamant forms of docs/theory.md section 3, a
brute-force quadrature of the spectral solution of docs/theory.md section 2 (written here, not
shared with the library), equilibrium by finite differences, traction-free surface and total
force balance by quadrature.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.forward.halfspace.kernels import (
    COMPONENTS,
    direct_stress,
    direct_stress_from_forces,
    line_green,
    line_load_stress,
    point_green,
    point_load_stress,
)
from tactilab.forward.halfspace.loads import SurfaceLoad

XX, YY, ZZ, YZ, ZX, XY = range(6)


# ----------------------------------------------------------------------------- helpers
def _spectral_point(x, y, z, f, nu, n_rho=240, n_phi=256, umax=60.0):
    """Stress of a point force by quadrature of docs/theory.md section 2 in polar frequency coordinates.

    sigma(x) = (2 pi)^-2 int rho d rho d phi sigma~(rho, phi) exp(i rho (x cos phi + y sin phi)),
    Gauss-Legendre in u = rho z on [0, umax], trapezoid (spectral) in phi.
    """
    fx, fy, fz = f
    u, wu = np.polynomial.legendre.leggauss(n_rho)
    u, wu = 0.5 * umax * (u + 1), 0.5 * umax * wu
    rho = (u / z)[:, None]
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    c, s = np.cos(phi), np.sin(phi)
    weight = (wu / z)[:, None] * rho * (2 * np.pi / n_phi)
    sz = rho * z
    e = np.exp(-sz)
    qpar, qperp = c * fx + s * fy, -s * fx + c * fy
    szz = -fz * (1 + sz) * e + 1j * qpar * sz * e
    s11 = -fz * (1 - sz) * e + 1j * qpar * (2 - sz) * e
    s13 = 1j * fz * sz * e - qpar * (1 - sz) * e
    s22 = nu * (s11 + szz)
    s23 = -qperp * e
    s12 = 1j * qperp * e
    tensor = (
        c * c * s11 + s * s * s22 - 2 * c * s * s12,
        s * s * s11 + c * c * s22 + 2 * c * s * s12,
        szz,
        s * s13 + c * s23,
        c * s13 - s * s23,
        c * s * (s11 - s22) + (c * c - s * s) * s12,
    )
    phase = np.exp(1j * rho * (c * x + s * y))
    return np.array([np.sum(weight * t * phase).real for t in tensor]) / (2 * np.pi) ** 2


def _spectral_line(x, z, f, nu, n=400, umax=70.0):
    """Plane-strain stress of a line force: 1-D quadrature of docs/theory.md section 2 (i -> i sign xi)."""
    fx, fy, fz = f
    u, wu = np.polynomial.legendre.leggauss(n)
    u, wu = 0.5 * umax * (u + 1), 0.5 * umax * wu
    xi = u / z
    e = np.exp(-u)
    szz = -fz * (1 + u) * e + 1j * fx * u * e
    sxx = -fz * (1 - u) * e + 1j * fx * (2 - u) * e
    szx = 1j * fz * u * e - fx * (1 - u) * e
    tensor = (sxx, nu * (sxx + szz), szz, -fy * e, szx, 1j * fy * e)
    # sigma(x) = (1/pi) Re int_0^inf sigma~(xi) exp(i xi x) d xi (Hermitian symmetry)
    return np.array([np.sum(wu / z * t * np.exp(1j * xi * x)).real for t in tensor]) / np.pi


def _divergence(fun, p, h):
    """div sigma at p by 4th-order central differences; fun(x, y, z) -> (6,)."""
    grads = np.zeros((3, 6))
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        grads[k] = (8 * (fun(*(p + step)) - fun(*(p - step))) - (fun(*(p + 2 * step)) - fun(*(p - 2 * step)))) / (12 * h)
    # rows: d/dx, d/dy, d/dz; div_i = sum_j d_j sigma_ij
    return np.array([
        grads[0, XX] + grads[1, XY] + grads[2, ZX],
        grads[0, XY] + grads[1, YY] + grads[2, YZ],
        grads[0, ZX] + grads[1, YZ] + grads[2, ZZ],
    ])


# ----------------------------------------------------------------------------- Boussinesq
def test_boussinesq_matches_polar_forms(rng):
    """All six components vs sigma_r, sigma_theta, sigma_zz, sigma_rz of docs/theory.md section 3."""
    n = 200
    x, y = rng.uniform(-3e-3, 3e-3, (2, n))
    z = rng.uniform(1e-4, 3e-3, n)
    nu = rng.uniform(-0.9, 0.5)
    force = 2.5
    r, big_r = np.hypot(x, y), np.sqrt(x * x + y * y + z * z)
    c, s = x / r, y / r
    sig_r = force / (2 * np.pi) * ((1 - 2 * nu) / r**2 * (1 - z / big_r) - 3 * z * r**2 / big_r**5)
    sig_t = -force * (1 - 2 * nu) / (2 * np.pi) * ((1 - z / big_r) / r**2 - z / big_r**3)
    sig_rz = -3 * force * r * z**2 / (2 * np.pi * big_r**5)
    expected = np.stack([
        sig_r * c * c + sig_t * s * s,
        sig_r * s * s + sig_t * c * c,
        -3 * force * z**3 / (2 * np.pi * big_r**5),
        sig_rz * s,
        sig_rz * c,
        (sig_r - sig_t) * c * s,
    ], axis=-1)
    got = point_load_stress(x, y, z, fz=force, nu=nu)
    scale = force / big_r**2
    np.testing.assert_allclose(got / scale[:, None], expected / scale[:, None], rtol=0, atol=1e-10)


@pytest.mark.parametrize("nu", [0.5, 0.3, -0.5])
def test_boussinesq_axis_limit(nu):
    """r -> 0: sigma_r = sigma_theta = P (1 - 2 nu)/(4 pi z^2), shears vanish; continuous in r."""
    z, force = 2e-3, 1.3
    on_axis = point_load_stress(0.0, 0.0, z, fz=force, nu=nu)
    expected = np.array([1 - 2 * nu, 1 - 2 * nu, -6.0, 0, 0, 0]) * force / (4 * np.pi * z * z)
    np.testing.assert_allclose(on_axis, expected, rtol=1e-14, atol=1e-14 * force / z**2)
    near = point_load_stress(1e-7 * z, -2e-7 * z, z, fz=force, nu=nu)
    # shears grow linearly in r/z = 2e-7 off the axis; normal stresses quadratically
    np.testing.assert_allclose(near, on_axis, atol=1e-6 * force / z**2)


# ----------------------------------------------------------------------------- Cerruti
def test_cerruti_z_components_match_brief(rng):
    x, y = rng.uniform(-3e-3, 3e-3, (2, 100))
    z = rng.uniform(1e-4, 3e-3, 100)
    q = -0.7
    big_r5 = (x * x + y * y + z * z) ** 2.5
    got = point_load_stress(x, y, z, fx=q, nu=0.45)
    np.testing.assert_allclose(got[:, ZZ], -3 * q * x * z * z / (2 * np.pi * big_r5), rtol=1e-12)
    np.testing.assert_allclose(got[:, ZX], -3 * q * x * x * z / (2 * np.pi * big_r5), rtol=1e-12)
    np.testing.assert_allclose(got[:, YZ], -3 * q * x * y * z / (2 * np.pi * big_r5), rtol=1e-12)
    # A force along +y is the +x solution rotated by 90 degrees: (x, y) -> (y, -x).
    rot = point_load_stress(-y, x, z, fy=q, nu=0.45)
    np.testing.assert_allclose(rot[:, ZZ], got[:, ZZ], rtol=1e-12)
    np.testing.assert_allclose(rot[:, YZ], got[:, ZX], rtol=1e-12)
    np.testing.assert_allclose(rot[:, XX], got[:, YY], rtol=1e-12)


@pytest.mark.parametrize("direction", [0, 1, 2])
@pytest.mark.parametrize("nu", [0.5, 0.2, -0.6])
def test_point_kernels_match_spectral_quadrature(rng, direction, nu):
    """Full tensors of Boussinesq and Cerruti vs a brute-force quadrature of docs/theory.md section 2."""
    f = np.zeros(3)
    f[direction] = 1.0
    for _ in range(3):
        z = rng.uniform(0.5e-3, 2e-3)
        x, y = rng.uniform(-1.0, 1.0, 2) * z
        expected = _spectral_point(x, y, z, f, nu)
        got = point_load_stress(x, y, z, *f, nu=nu)
        scale = 1.0 / (x * x + y * y + z * z)
        np.testing.assert_allclose(got / scale, expected / scale, rtol=0, atol=1e-10)


def test_point_equilibrium_by_finite_differences(rng):
    for _ in range(6):
        f = rng.normal(size=3)
        nu = rng.uniform(-0.9, 0.5)
        p = np.array([*rng.uniform(-2e-3, 2e-3, 2), rng.uniform(0.3e-3, 2e-3)])
        big_r = np.linalg.norm(p)
        div = _divergence(lambda *q: point_load_stress(*q, *f, nu=nu), p, 1e-3 * big_r)
        scale = np.linalg.norm(f) / big_r**3  # |sigma| / R
        assert np.max(np.abs(div)) < 1e-8 * scale


def test_point_surface_is_traction_free_away_from_the_force(rng):
    x, y = rng.uniform(-3e-3, 3e-3, (2, 50))
    f = rng.normal(size=3)
    exact = point_load_stress(x, y, 0.0, *f, nu=0.3)
    assert np.all(exact[:, [ZZ, YZ, ZX]] == 0)
    r = np.hypot(x, y)
    near = point_load_stress(x, y, 1e-9 * r, *f, nu=0.3)
    scale = np.linalg.norm(f) / r**2
    assert np.max(np.abs(near[:, [ZZ, YZ, ZX]]) / scale[:, None]) < 1e-8
    # the in-plane surface stresses are finite and continuous in z
    np.testing.assert_allclose(near[:, [XX, YY, XY]] / scale[:, None], exact[:, [XX, YY, XY]] / scale[:, None],
                               atol=1e-8)


def test_point_total_force_balance(rng):
    """int sigma_zj dA over a plane at depth z equals -f_j (equilibrium of the slab above)."""
    z = 1.7e-3
    f = rng.normal(size=3)
    t, wt = np.polynomial.legendre.leggauss(200)
    t, wt = 0.25 * np.pi * (t + 1), 0.25 * np.pi * wt  # r = z tan t, t in [0, pi/2)
    n_phi = 64
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    r = z * np.tan(t)[:, None]
    w = (wt * z / np.cos(t) ** 2)[:, None] * r * (2 * np.pi / n_phi)
    sigma = point_load_stress(r * np.cos(phi), r * np.sin(phi), z, *f, nu=0.37)
    totals = [np.sum(w * sigma[..., k]) for k in (ZX, YZ, ZZ)]
    np.testing.assert_allclose(totals, -f, rtol=0, atol=1e-10 * np.linalg.norm(f))


# ----------------------------------------------------------------------------- line loads
def test_flamant_matches_brief(rng):
    x = rng.uniform(-3e-3, 3e-3, 100)
    z = rng.uniform(1e-4, 3e-3, 100)
    normal, tangential, nu = 40.0, -15.0, 0.42
    r4 = (x * x + z * z) ** 2
    got = line_load_stress(x, z, fx=tangential, fz=normal, nu=nu)
    sxx = -2 * normal * x * x * z / (np.pi * r4) - 2 * tangential * x**3 / (np.pi * r4)
    szz = -2 * normal * z**3 / (np.pi * r4) - 2 * tangential * x * z * z / (np.pi * r4)
    szx = -2 * normal * x * z * z / (np.pi * r4) - 2 * tangential * x * x * z / (np.pi * r4)
    np.testing.assert_allclose(got[:, XX], sxx, rtol=1e-12)
    np.testing.assert_allclose(got[:, ZZ], szz, rtol=1e-12)
    np.testing.assert_allclose(got[:, ZX], szx, rtol=1e-12)
    np.testing.assert_allclose(got[:, YY], nu * (sxx + szz), rtol=1e-12)
    assert np.all(got[:, [YZ, XY]] == 0)


@pytest.mark.parametrize("direction", [0, 1, 2])
def test_line_kernels_match_spectral_quadrature(rng, direction):
    """Including the antiplane line force fy, which docs/theory.md section 3 does not list."""
    f = np.zeros(3)
    f[direction] = 1.0
    for _ in range(4):
        z = rng.uniform(0.5e-3, 2e-3)
        x = rng.uniform(-1.5, 1.5) * z
        expected = _spectral_line(x, z, f, 0.33)
        got = line_load_stress(x, z, *f, nu=0.33)
        scale = 1.0 / np.hypot(x, z)
        np.testing.assert_allclose(got / scale, expected / scale, rtol=0, atol=1e-11)


def test_line_equilibrium_and_force_balance(rng):
    f, nu = rng.normal(size=3), 0.25
    for _ in range(5):
        p = np.array([rng.uniform(-2e-3, 2e-3), 0.0, rng.uniform(0.3e-3, 2e-3)])
        div = _divergence(lambda x, y, z: line_load_stress(x, z, *f, nu=nu), p, 1e-3 * np.hypot(p[0], p[2]))
        assert np.max(np.abs(div)) < 1e-8 * np.linalg.norm(f) / (p[0] ** 2 + p[2] ** 2)
    z = 0.9e-3
    t, wt = np.polynomial.legendre.leggauss(300)
    t, wt = 0.5 * np.pi * t, 0.5 * np.pi * wt  # x = z tan t, t in (-pi/2, pi/2)
    sigma = line_load_stress(z * np.tan(t), z, *f, nu=nu)
    w = wt * z / np.cos(t) ** 2
    totals = [np.sum(w * sigma[:, k]) for k in (ZX, YZ, ZZ)]
    np.testing.assert_allclose(totals, -f, atol=1e-10 * np.linalg.norm(f))


# ----------------------------------------------------------------------------- extremes
def test_incompressible_limit_is_continuous(rng):
    x, y = rng.uniform(-2e-3, 2e-3, (2, 50))
    z = rng.uniform(1e-4, 2e-3, 50)
    f = rng.normal(size=3)
    a = point_load_stress(x, y, z, *f, nu=0.5)
    b = point_load_stress(x, y, z, *f, nu=0.4999999)
    scale = np.linalg.norm(f) / (x * x + y * y + z * z)
    assert np.max(np.abs(a - b) / scale[:, None]) < 1e-6
    a1 = line_load_stress(x, z, *f, nu=0.5)
    b1 = line_load_stress(x, z, *f, nu=0.4999999)
    assert np.max(np.abs(a1 - b1) * np.hypot(x, z)[:, None]) < 1e-6 * np.linalg.norm(f)


def test_far_field_and_tiny_depth_stay_finite():
    f = (0.3, -0.2, 1.0)
    z = 1e-3
    far = point_load_stress(1e6 * z, 0.5e6 * z, z, *f)
    assert np.all(np.isfinite(far)) and np.any(far != 0)
    tiny = point_load_stress(1e-3, 2e-3, 1e-300, *f)
    assert np.all(np.isfinite(tiny))
    huge = point_load_stress(1e200, 1e200, 1e199, *f)
    assert np.all(np.isfinite(huge))
    line = line_load_stress(np.array([1e6 * z, 1e200, 1e-3]), np.array([z, 1e199, 1e-300]), *f)
    assert np.all(np.isfinite(line))
    # 1/R^2 decay far away: doubling the distance divides the stress by 4
    np.testing.assert_allclose(point_load_stress(2e3, 1e3, 2e-3, *f), far / 4, rtol=1e-12)


def test_green_functions_match_full_tensors(rng):
    x, y = rng.uniform(-1e-3, 1e-3, (2, 20))
    z = rng.uniform(1e-4, 1e-3, 20)
    for d, direction in enumerate("xyz"):
        f = np.eye(3)[d]
        full = point_load_stress(x, y, z, *f, nu=0.4)
        line = line_load_stress(x, z, *f, nu=0.4)
        for k, comp in enumerate(COMPONENTS):
            np.testing.assert_array_equal(point_green(comp, direction, x, y, z, nu=0.4), full[:, k])
            np.testing.assert_array_equal(line_green(comp, direction, x, z, nu=0.4), line[:, k])


# ----------------------------------------------------------------------------- method 1
def test_direct_stress_2d_is_the_node_sum(rng, monkeypatch):
    import tactilab.forward.halfspace.kernels as kernels

    monkeypatch.setattr(kernels, "_PAIR_BUDGET", 7)  # force several blocks
    p, qx, qy = rng.normal(size=(3, 4, 5)) * 1e3
    p[1, 2] = qx[1, 2] = qy[1, 2] = 0.0
    load = SurfaceLoad(p=p, qx=qx, qy=qy, spacing=(2e-4, 3e-4))
    points = np.column_stack([rng.uniform(-1e-3, 1e-3, (9, 2)), rng.uniform(1e-4, 1e-3, 9)])
    got = direct_stress(load, points, nu=0.35, components=("zx", "xx", "xy"))
    area = 2e-4 * 3e-4
    expected = np.zeros((9, 6))
    for j, y0 in enumerate(load.y):
        for i, x0 in enumerate(load.x):
            expected += point_load_stress(points[:, 0] - x0, points[:, 1] - y0, points[:, 2],
                                          qx[j, i] * area, qy[j, i] * area, p[j, i] * area, nu=0.35)
    np.testing.assert_allclose(got, expected[:, [ZX, XX, XY]], rtol=1e-12, atol=1e-12 * np.abs(expected).max())


def test_direct_stress_1d_is_the_node_sum(rng):
    p, qx, qy = rng.normal(size=(3, 7)) * 1e3
    load = SurfaceLoad(p=p, qx=qx, qy=qy, spacing=1e-4)
    points = np.column_stack([rng.uniform(-1e-3, 1e-3, 5), rng.uniform(1e-4, 1e-3, 5)])
    got = direct_stress(load, points, nu=0.5)
    expected = sum(line_load_stress(points[:, 0] - x0, points[:, 1], qx[i] * 1e-4, qy[i] * 1e-4, p[i] * 1e-4)
                   for i, x0 in enumerate(load.x))
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


def test_direct_stress_from_forces_and_zero_load(rng):
    forces = rng.normal(size=(3, 3))
    positions = rng.uniform(-1e-3, 1e-3, (3, 2))
    points = np.column_stack([rng.uniform(-1e-3, 1e-3, (4, 2)), rng.uniform(1e-4, 1e-3, 4)])
    got = direct_stress_from_forces(forces, positions, points, nu=0.45)
    expected = sum(point_load_stress(points[:, 0] - px, points[:, 1] - py, points[:, 2], *f, nu=0.45)
                   for f, (px, py) in zip(forces, positions))
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    zero = direct_stress(SurfaceLoad(p=np.zeros((3, 3)), spacing=1e-4), points)
    assert zero.shape == (4, 6) and np.all(zero == 0)
    line = direct_stress_from_forces(forces, positions[:, 0], points[:, [0, 2]], components=["yz"])
    assert line.shape == (4, 1)


# ----------------------------------------------------------------------------- bad input
def test_bad_input_raises():
    ok = np.array([[0.0, 0.0, 1e-3]])
    with pytest.raises(ValueError, match="nu: Poisson's ratio must lie"):
        point_load_stress(1e-3, 0, 1e-3, fz=1, nu=0.7)
    with pytest.raises(ValueError, match="nu: Poisson's ratio must lie"):
        point_load_stress(1e-3, 0, 1e-3, fz=1, nu=np.nan)
    with pytest.raises(ValueError, match="nu: Poisson's ratio must lie in .*got 'soft'"):
        line_load_stress(1e-3, 1e-3, fz=1, nu="soft")
    with pytest.raises(ValueError, match="x: coordinates must be finite"):
        point_load_stress(np.array([0.0, np.nan]), 0, 1e-3, fz=1)
    with pytest.raises(ValueError, match="z: depth must be >= 0"):
        point_load_stress(1e-3, 0, -1e-3, fz=1)
    with pytest.raises(ValueError, match="z: depth must be >= 0"):
        line_load_stress(1e-3, -1e-3, fz=1)
    with pytest.raises(ValueError, match="coincides with the point force"):
        point_load_stress(0.0, 0.0, 0.0, fz=1)
    with pytest.raises(ValueError, match="coincides with the line force"):
        line_load_stress(0.0, 0.0, fz=1)
    with pytest.raises(ValueError, match="fz: force must be finite"):
        point_load_stress(1e-3, 0, 1e-3, fz=np.inf)
    with pytest.raises(ValueError, match="component: unknown component 'xq'"):
        point_green("xq", "z", 1e-3, 0, 1e-3)
    assert point_green("xz", "x", 1e-3, 2e-4, 1e-3) == point_green("zx", "x", 1e-3, 2e-4, 1e-3)  # an alias
    with pytest.raises(ValueError, match="components: empty selection"):
        direct_stress_from_forces([[0, 0, 1]], [[0, 0]], ok, components=())
    with pytest.raises(ValueError, match="components: names repeat"):
        direct_stress_from_forces([[0, 0, 1]], [[0, 0]], ok, components=("zz", "zz"))
    with pytest.raises(ValueError, match="components: expected a sequence"):
        direct_stress_from_forces([[0, 0, 1]], [[0, 0]], ok, components=3)
    with pytest.raises(ValueError, match="direction: force direction"):
        point_green("zz", "w", 1e-3, 0, 1e-3)
    with pytest.raises(ValueError, match="direction: force direction"):
        line_green("zz", "w", 1e-3, 1e-3)
    with pytest.raises(ValueError, match=r"positions: expected shape \(m, 2\)"):
        direct_stress_from_forces([[0, 0, 1]], [[0, 0, 0]], ok)
    with pytest.raises(ValueError, match=r"forces: expected shape \(1, 3\)"):
        direct_stress_from_forces([[0, 1]], [[0, 0]], ok)
    with pytest.raises(ValueError, match="forces: force must be finite"):
        direct_stress_from_forces([[0, np.nan, 1]], [[0, 0]], ok)
    with pytest.raises(ValueError, match=r"points: expected shape \(n, 3\)"):
        direct_stress_from_forces([[0, 0, 1]], [[0, 0]], ok[:, :2])
    with pytest.raises(ValueError, match=r"points: expected shape \(n, 2\) of \(x, z\)"):
        direct_stress(SurfaceLoad(p=np.ones(3), spacing=1e-4), ok)
    with pytest.raises(ValueError, match="points: coordinates must be finite"):
        direct_stress(SurfaceLoad(p=np.ones((3, 3)), spacing=1e-4), np.array([[0, np.nan, 1e-3]]))
    with pytest.raises(ValueError, match="points: depth z must be > 0"):
        direct_stress(SurfaceLoad(p=np.ones((3, 3)), spacing=1e-4), np.array([[0, 0, 0.0]]))
    with pytest.raises(ValueError, match="load: expected a SurfaceLoad"):
        direct_stress(np.ones((3, 3)), ok)

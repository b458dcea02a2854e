"""benchmarks/hamilton_reference.py against two references written apart from it.

1. Frictionless (mu = 0) on the z axis: Huber's closed form for Hertz contact
   (sigma_zz = -p0 a^2/(a^2 + z^2), sigma_xx = sigma_yy = -p0 [(1 + nu)(1 - (z/a) atan(a/z))
   - a^2/(2 (a^2 + z^2))]), on the axis itself and just off it (both code branches).
2. Off the axis, with sliding friction: direct 2-D quadrature (scipy.integrate.fixed_quad,
   Gauss-Legendre in both directions) of the Boussinesq and Cerruti point-force solutions over the
   contact disc, weighted by the Hertz pressure and by mu times it. The point-force solutions are
   written here in Cartesian form from the polar forms of docs/theory.md section 3.
Agreement is required to 1e-6 of p0.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import fixed_quad

REF = Path(__file__).resolve().parents[1] / "benchmarks" / "hamilton_reference.py"


@pytest.fixture(scope="module")
def ham():
    spec = importlib.util.spec_from_file_location("hamilton_reference", REF)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def boussinesq(x, y, z, nu):
    """Stress (per N) of a unit normal force pushing into the half-space at the origin."""
    r2 = x * x + y * y
    rho = np.sqrt(r2 + z * z)
    c = 1 - 2 * nu
    sxx = c / r2 * ((1 - z / rho) * (x * x - y * y) / r2 + z * y * y / rho**3) - 3 * z * x * x / rho**5
    syy = c / r2 * ((1 - z / rho) * (y * y - x * x) / r2 + z * x * x / rho**3) - 3 * z * y * y / rho**5
    sxy = c / r2 * (2 * (1 - z / rho) * x * y / r2 - x * y * z / rho**3) - 3 * x * y * z / rho**5
    szz = -3 * z**3 / rho**5
    syz = -3 * y * z * z / rho**5
    szx = -3 * x * z * z / rho**5
    return np.stack([sxx, syy, szz, syz, szx, sxy]) / (2 * np.pi)


def cerruti(x, y, z, nu):
    """Stress (per N) of a unit tangential force along +x at the origin."""
    rho = np.sqrt(x * x + y * y + z * z)
    c = 1 - 2 * nu
    rz = rho + z
    sxx = x / rho**3 * (-3 * x * x / rho**2 + c / rz**2 * (rho**2 - y * y - 2 * rho * y * y / rz))
    syy = x / rho**3 * (-3 * y * y / rho**2 + c / rz**2 * (3 * rho**2 - x * x - 2 * rho * x * x / rz))
    sxy = y / rho**3 * (-3 * x * x / rho**2 + c / rz**2 * (-(rho**2) + x * x + 2 * rho * x * x / rz))
    szz = -3 * x * z * z / rho**5
    syz = -3 * x * y * z / rho**5
    szx = -3 * x * x * z / rho**5
    return np.stack([sxx, syy, szz, syz, szx, sxy]) / (2 * np.pi)


def quadrature(x, y, z, *, a, p0, mu, nu, n):
    """Superpose point forces over the disc: r' = a sin(u) makes p dA = p0 a^2 sin u cos^2 u du dt."""

    def over_angle(u):  # u: (nu_,) nodes -> (6, nu_)
        def integrand(t):  # t: (nt,) -> (6, nu_, nt)
            xs = a * np.sin(u)[:, None] * np.cos(t)[None, :]
            ys = a * np.sin(u)[:, None] * np.sin(t)[None, :]
            kern = boussinesq(x - xs, y - ys, z, nu) + mu * cerruti(x - xs, y - ys, z, nu)
            return kern

        inner, _ = fixed_quad(integrand, 0.0, 2 * np.pi, n=2 * n)
        return inner * (p0 * a * a * np.sin(u) * np.cos(u) ** 2)

    value, _ = fixed_quad(over_angle, 0.0, np.pi / 2, n=n)
    return value


def huber_axis(z, *, a, p0, nu):
    zeta = z / a
    szz = -p0 / (1 + zeta**2)
    srr = -p0 * ((1 + nu) * (1 - zeta * np.arctan(1 / zeta)) - 1 / (2 * (1 + zeta**2)))
    return srr, szz


@pytest.mark.parametrize("nu", [0.0, 0.3, 0.49, 0.4999, 0.5])
def test_frictionless_axis_matches_huber(ham, nu):
    a, p0 = 1.2e-3, 3.0e4
    z = a * np.array([0.01, 0.2, 0.5, 0.78, 1.0, 3.0, 20.0])
    srr, szz = huber_axis(z, a=a, p0=p0, nu=nu)
    # on the axis itself, just off it (first-order expansion branch) and further off (formulas);
    # the normal stresses are even in r: off the axis they differ from Huber's by O(r^2)
    for r in (0.0, 3e-4 * a, 1.5e-3 * a):
        s = ham.hamilton_stress(r / np.sqrt(2), -r / np.sqrt(2), z, a=a, p0=p0, mu=0.0, nu=nu)
        assert s.shape == (6, z.size)
        tol = 1e-6 * p0 + 2 * p0 * (r / a) ** 2
        np.testing.assert_allclose(s[0], srr, rtol=0, atol=tol)
        np.testing.assert_allclose(s[1], srr, rtol=0, atol=tol)
        np.testing.assert_allclose(s[2], szz, rtol=0, atol=tol)
        # shears vanish on the axis and grow like r off it: bounded by 2 p0 r/a here
        np.testing.assert_allclose(s[3:], 0.0, rtol=0, atol=1e-12 * p0 + 2 * p0 * r / a)


POINTS = [  # (x/a, y/a, z/a): inside, outside and on the edge of the contact, shallow and deep
    (0.3, 0.2, 0.5), (1.2, -0.4, 0.25), (-0.7, 0.9, 1.0), (0.0, 0.0, 0.5),
    (0.0, 0.6, 0.3), (-0.5, 0.0, 0.3), (2.5, 1.0, 0.7), (1.0, 0.0, 0.5), (0.02, -0.01, 2.0),
    (3e-4, 2e-4, 0.6),
]


@pytest.mark.parametrize("nu", [0.0, 0.3, 0.49, 0.4999, 0.5])
def test_sliding_contact_matches_point_force_quadrature(ham, nu):
    a, p0, mu = 0.8e-3, 2.0e4, 0.45
    pts = np.array(POINTS) * a
    got = ham.hamilton_stress(pts[:, 0], pts[:, 1], pts[:, 2], a=a, p0=p0, mu=mu, nu=nu)
    for k, (x, y, z) in enumerate(pts):
        ref = quadrature(x, y, z, a=a, p0=p0, mu=mu, nu=nu, n=160)
        np.testing.assert_allclose(got[:, k], ref, rtol=0, atol=1e-6 * p0, err_msg=f"point {k}")


def test_quadrature_is_converged(ham):
    """The oracle itself: doubling the nodes changes it by far less than the 1e-6 p0 tolerance."""
    a, p0 = 1.0, 1.0
    for x, y, z in POINTS[:3]:
        lo = quadrature(x, y, z, a=a, p0=p0, mu=0.45, nu=0.3, n=160)
        hi = quadrature(x, y, z, a=a, p0=p0, mu=0.45, nu=0.3, n=320)
        assert np.abs(lo - hi).max() < 1e-9


def test_surface_tractions_are_the_hertz_load(ham):
    """At z = 0 inside the contact: sigma_zz = -p, sigma_zx = -mu p, sigma_yz = 0 (docs/theory.md 1)."""
    a, p0, mu = 1e-3, 1e4, 0.3
    x = a * np.array([0.0, 0.3, -0.6, 0.1, 0.95])
    y = a * np.array([0.0, 0.2, 0.1, -0.7, 0.0])
    s = ham.hamilton_stress(x, y, 0.0, a=a, p0=p0, mu=mu, nu=0.4)
    p = p0 * np.sqrt(1 - (x * x + y * y) / a**2)
    np.testing.assert_allclose(s[2], -p, rtol=0, atol=1e-9 * p0)
    np.testing.assert_allclose(s[4], -mu * p, rtol=0, atol=1e-9 * p0)
    np.testing.assert_allclose(s[3], 0.0, rtol=0, atol=1e-9 * p0)
    edge = ham.hamilton_stress(a, 0.0, 0.0, a=a, p0=p0, mu=mu, nu=0.4)  # 0/0 in the formulas
    assert np.all(np.isfinite(edge))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"a": 0.0}, "a must be a positive"),
        ({"nu": 0.6}, r"nu must lie in \[0, 0.5\]"),
        ({"z": -1e-3}, "z must be >= 0"),
        ({"x": np.array([0.0, np.nan])}, r"x must be finite; first bad index \[1\]"),
    ],
)
def test_bad_input_is_refused(ham, kwargs, match):
    args = {"x": 0.0, "y": 0.0, "z": 1e-3, "a": 1e-3, "p0": 1.0, "mu": 0.2, "nu": 0.3}
    args.update(kwargs)
    x, y, z = args.pop("x"), args.pop("y"), args.pop("z")
    with pytest.raises(ValueError, match=match):
        ham.hamilton_stress(x, y, z, **args)

"""Fingertip contact: Hertz force balance and approach, friction law, partial slip, stuck limit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from tactilab.forward.contact import HertzContact, interfacial_traction, stick_radius


def _grid(a, n=161, span=1.2):
    h = 2 * span * a / (n - 1)
    x = (np.arange(n) - n // 2) * h
    X, Y = np.meshgrid(x, x)
    return X, Y, h


def test_hertz_force_balance_3d_and_line():
    """iint p dA = F (quadrature) and int p dx = F' for the line contact."""
    c = HertzContact(normal_force=0.8, finger_radius=0.1, young_modulus=2e6, poisson_ratio=0.5)
    X, Y, h = _grid(c.contact_radius, n=301)
    assert c.pressure(X, Y).sum() * h * h == pytest.approx(0.8, rel=2e-3)
    total, _ = integrate.quad(lambda r: c.pressure(r, 0.0) * 2 * math.pi * r, 0, c.contact_radius)
    assert total == pytest.approx(0.8, rel=1e-9)
    line = HertzContact(normal_force=200.0, finger_radius=0.01, young_modulus=1e6, line=True)
    total, _ = integrate.quad(lambda x: line.pressure(x), -line.contact_radius, line.contact_radius)
    assert total == pytest.approx(200.0, rel=1e-9)


def test_hertz_contact_radius_matches_rigid_body_approach():
    """Independent oracle: the surface deflection under p at r = 0, u_z = (2/E*) int_0^a p dr,
    equals the Hertz approach a^2 / R; and p vanishes exactly at r = a."""
    for F, R, E, nu in [(0.5, 0.1, 1e6, 0.5), (1.0, 0.01, 4e6, 0.3)]:
        c = HertzContact(F, R, E, nu)
        a = c.contact_radius
        assert a == pytest.approx((3 * F * R / (4 * E / (1 - nu ** 2))) ** (1 / 3))
        uz0 = 2 / c.effective_modulus * integrate.quad(lambda r: c.pressure(r, 0.0), 0, a)[0]
        assert uz0 == pytest.approx(a * a / R, rel=1e-8)
        assert c.pressure(a * (1 + 1e-9), 0.0) == 0.0 and c.pressure(a * (1 - 1e-3), 0.0) > 0


def test_typical_biomimetic_values():
    """Defaults (R = 0.1 m, E = 2 MPa, nu = 0.5) give a 4.8-6.1 mm contact at 0.5-1 N."""
    assert 2e3 * HertzContact(0.5).contact_radius == pytest.approx(4.83, abs=0.01)
    assert 2e3 * HertzContact(1.0).contact_radius == pytest.approx(6.08, abs=0.01)


def test_sliding_friction_law():
    c = HertzContact(1.0)
    X, Y, h = _grid(c.contact_radius, n=201)
    p, q = interfacial_traction(c, X, Y, friction=0.7, condition="sliding")
    np.testing.assert_array_equal(q, 0.7 * p)
    p, q = interfacial_traction(c, X, Y, condition="frictionless")
    assert not q.any()


@pytest.mark.parametrize("line", [False, True])
def test_partial_slip_continuum(line):
    """Cattaneo--Mindlin: total traction = Q, stick radius formula, Q -> mu F is sliding,
    mu -> infinity approaches the stuck (Mindlin) traction."""
    F = 150.0 if line else 1.0
    c = HertzContact(F, line=line)
    a = c.contact_radius
    n = 4001 if line else 301
    h = 2.4 * a / (n - 1)
    x = (np.arange(n) - n // 2) * h
    pts = (x,) if line else np.meshgrid(x, x)
    area = h if line else h * h
    for ratio in (0.0, 0.3, 0.9):
        _, q = interfacial_traction(c, *pts, friction=0.5, condition="partial", tangential_force=ratio * 0.5 * F)
        assert q.sum() * area == pytest.approx(ratio * 0.5 * F, rel=2e-3, abs=1e-6 * F)
    power = 0.5 if line else 1 / 3
    assert stick_radius(c, 0.5, 0.3 * 0.5 * F) == pytest.approx(a * 0.7 ** power)
    _, q_full = interfacial_traction(c, *pts, friction=0.5, condition="partial", tangential_force=0.5 * F)
    _, q_slide = interfacial_traction(c, *pts, friction=0.5, condition="sliding")
    np.testing.assert_allclose(q_full, q_slide, atol=1e-12 * q_slide.max())
    Q = 0.2 * F
    _, q_hi = interfacial_traction(c, *pts, friction=1e4, condition="partial", tangential_force=Q)
    _, q_stuck = interfacial_traction(c, *pts, condition="stuck", tangential_force=Q)
    rho = np.abs(pts[0]) if line else np.hypot(*pts)
    centre = rho < 0.8 * a
    np.testing.assert_allclose(q_hi[centre], q_stuck[centre], rtol=2e-3)


@pytest.mark.parametrize("line", [False, True])
def test_stuck_cell_average_carries_Q(line):
    c = HertzContact(120.0 if line else 0.6, line=line)
    a = c.contact_radius
    n = 101
    h = 2.5 * a / (n - 1)
    x = (np.arange(n) - n // 2) * h
    pts = (x,) if line else np.meshgrid(x, x)
    cell = (h,) if line else (h, h)
    _, q = interfacial_traction(c, *pts, condition="stuck", tangential_force=0.25, cell=cell)
    assert q.sum() * (h if line else h * h) == pytest.approx(0.25, rel=1e-9)
    assert np.all(np.isfinite(q))


def test_stick_radius_subnormal_friction():
    """Regression (hypothesis, mu = 5e-324): mu F underflowed to 0 and stick_radius divided by zero."""
    c = HertzContact(0.5, 0.25, 1e5, 0.0)
    assert stick_radius(c, 5e-324, 0.0) == c.contact_radius
    with pytest.raises(ValueError, match="exceeds the friction limit"):
        stick_radius(c, 5e-324, 1e-300)


def test_bad_input_raises():
    with pytest.raises(ValueError, match="normal_force: must be finite and > 0"):
        HertzContact(-0.5)
    with pytest.raises(ValueError, match="finger_radius"):
        HertzContact(1.0, finger_radius=0.0)
    with pytest.raises(ValueError, match="young_modulus"):
        HertzContact(1.0, young_modulus=float("nan"))
    with pytest.raises(ValueError, match=r"poisson_ratio: Poisson's ratio must lie in \(-1, 0.5\]"):
        HertzContact(1.0, poisson_ratio=0.6)
    c = HertzContact(1.0)
    with pytest.raises(ValueError, match="friction: the friction coefficient must be >= 0"):
        interfacial_traction(c, 0.0, 0.0, friction=-0.1)
    with pytest.raises(ValueError, match="condition: must be one of"):
        interfacial_traction(c, 0.0, 0.0, condition="sticky")
    with pytest.raises(ValueError, match="tangential_force: condition='partial' needs"):
        interfacial_traction(c, 0.0, 0.0, friction=0.5, condition="partial")
    with pytest.raises(ValueError, match="tangential_force: must be finite"):
        interfacial_traction(c, 0.0, 0.0, friction=0.5, condition="partial", tangential_force=math.inf)
    with pytest.raises(ValueError, match="exceeds the friction limit"):
        interfacial_traction(c, 0.0, 0.0, friction=0.5, condition="partial", tangential_force=0.6)
    with pytest.raises(ValueError, match="exceeds the friction limit"):
        stick_radius(c, 0.0, 0.1)
    assert stick_radius(c, 0.0, 0.0) == 0.0 and stick_radius(c, math.inf, 0.3) == c.contact_radius
    with pytest.raises(ValueError, match="sliding contact needs a finite friction"):
        interfacial_traction(c, 0.0, 0.0, friction=math.inf)
    with pytest.raises(ValueError, match="condition='partial' needs a finite friction"):
        interfacial_traction(c, 0.0, 0.0, friction=math.inf, condition="partial", tangential_force=0.1)
    with pytest.raises(ValueError, match="x, y: contact points must be finite"):
        c.pressure(np.nan, 0.0)
    with pytest.raises(ValueError, match="x, y: contact points must be finite"):
        interfacial_traction(c, 0.0, np.inf, friction=0.5)
    with pytest.raises(ValueError, match="y: a 3-D contact needs both"):
        c.pressure(0.0)
    with pytest.raises(ValueError, match="y: a line contact"):
        HertzContact(100.0, line=True).pressure(0.0, 0.0)
    with pytest.raises(ValueError, match="cell: the grid"):
        interfacial_traction(c, np.array([1.0]), np.array([1.0]), condition="stuck", tangential_force=0.1,
                             cell=(1e-4, 1e-4))


from hypothesis import example, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")  # the asserts check the sums
@settings(max_examples=30, deadline=None)
@given(force=st.floats(0.05, 5.0), radius=st.floats(0.005, 0.3), modulus=st.floats(1e5, 5e6),
       nu=st.floats(0.0, 0.5), mu=st.floats(0.0, 2.0), ratio=st.floats(0.0, 1.0))
@example(force=1.0, radius=0.25, modulus=1e5, nu=0.0, mu=1.0, ratio=1.192092896e-07)  # stick radius 4e-8 a short of a
@example(force=0.5, radius=0.25, modulus=1e5, nu=0.0, mu=5e-324, ratio=0.0)  # mu F underflows to 0
@example(force=1.0, radius=0.25, modulus=1e5, nu=0.0, mu=1.0, ratio=1e-06)
@example(force=0.75, radius=0.25, modulus=1e5, nu=0.0, mu=5e-324, ratio=1.0)  # Q = mu F, both subnormal
@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_force_balance_property(force, radius, modulus, nu, mu, ratio):
    """For any contact: the Hertz pressure integrates to F (polar quadrature) and the
    Cattaneo--Mindlin traction to Q = ratio mu F (with the analytic stick-zone integral)."""
    c = HertzContact(force, radius, modulus, nu)
    a = c.contact_radius
    total, _ = integrate.quad(lambda r: c.pressure(r, 0.0) * 2 * math.pi * r, 0, a)
    assert total == pytest.approx(force, rel=1e-8)
    Q = ratio * mu * force
    stick = stick_radius(c, mu, Q)

    def ring(r):
        return interfacial_traction(c, r, 0.0, friction=mu, condition="partial", tangential_force=Q)[1] * 2 * math.pi * r

    # r = c sin(t) on the stick zone and r = a sin(t) on the slip annulus remove the square-root
    # edges at r = c and r = a; plain quad on r lost ~1e-9 mu F there, which is all of Q when
    # Q << mu F (hypothesis found ratio = 1.2e-7 and 1e-6).
    q_stick, _ = integrate.quad(lambda t: ring(stick * math.sin(t)) * stick * math.cos(t), 0.0, math.pi / 2,
                                epsabs=0.0, epsrel=1e-10, limit=200)
    q_slip, _ = integrate.quad(lambda t: ring(a * math.sin(t)) * a * math.cos(t), math.asin(min(stick / a, 1.0)),
                               math.pi / 2, epsabs=0.0, epsrel=1e-10, limit=200)
    assert q_stick + q_slip == pytest.approx(Q, rel=1e-6, abs=1e-12 * force)

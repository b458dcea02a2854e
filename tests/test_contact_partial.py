"""Partial slip and stuck contact through solve_contact (the tangential solver is tested on its own in
tests/test_contact_friction.py).

Oracles: Cattaneo-Mindlin (Johnson, Contact Mechanics, 7.2): stick radius c/a = (1 - Q/(mu P))^(1/3)
for a sphere, (1 - Q/(mu P))^(1/2) for a cylinder, exact at nu = 1/2; Ciavarella (Int. J. Solids
Struct. 35, 1998) and Jaeger: in plane strain at nu = 1/2, q = mu [p(P) - p(P - Q/mu)] for any profile.
"""

import math
import warnings

import numpy as np
import pytest

from contact_oracles import check_complementarity, ellipse, grid, hertz_cylinder, hertz_sphere
from tactilab.forward import AccuracyWarning, HalfSpace, solve_contact
from tactilab.forward.contact import ContactCompliance

E, R = 1.0e6, 0.01
TOL = 1e-8


def test_cattaneo_mindlin_sphere():
    Es = E / 0.75
    a, p0 = hertz_sphere(0.5, R, Es)
    n = 64
    h = 2.5 * a / n
    x = grid(n, h)
    X, Y = np.meshgrid(x, x)
    g0 = (X**2 + Y**2) / (2 * R)
    sol = solve_contact(HalfSpace(E, 0.5), g0, h, normal_force=0.5, friction=0.5, condition="partial",
                        tangential_force=(0.125, 0.0), tol=1e-7)
    check_complementarity(sol, g0, 1e-7)
    c = math.sqrt(sol.stick.sum() * h * h / math.pi)
    assert abs(c - a * 0.5 ** (1 / 3)) <= h
    assert sol.qx.sum() * h * h == pytest.approx(0.125, rel=1e-9)
    q = np.hypot(sol.qx, sol.qy)
    assert (q <= 0.5 * sol.pressure * (1 + 1e-9)).all()
    assert np.array_equal(sol.stick | sol.slip, sol.contact)
    # no slip in the stick zone: the skin's tangential displacement there is one rigid shift
    ux, uy = ContactCompliance(HalfSpace(E, 0.5), g0.shape, h, periodic=False).tangential(sol.qx, sol.qy)
    assert np.ptp(ux[sol.stick]) <= 1e-5 * np.abs(ux).max() and np.ptp(uy[sol.stick]) <= 1e-5 * np.abs(ux).max()
    r, c_exact = np.hypot(X, Y), a * 0.5 ** (1 / 3)
    q_exact = 0.5 * (ellipse(r, a, p0) - ellipse(r, c_exact, p0 * c_exact / a))  # Johnson 7.34
    true = max(float(np.abs(sol.qx - q_exact).max()), float(np.abs(sol.pressure - ellipse(r, a, p0)).max())) / p0
    assert sol.error_estimate >= true


def test_cattaneo_mindlin_cylinder_and_ciavarella_jaeger():
    Es = E / 0.75
    P, mu, Q = 100.0, 0.4, 20.0
    a, _ = hertz_cylinder(P, R, Es)
    n = 256
    h = 3 * a / n
    x = grid(n, h)
    rough = x**2 / (2 * R) + 0.3e-6 * np.cos(2 * np.pi * x / (a / 3))  # a rough profile for Ciavarella-Jaeger
    for g0, hertz in ((x**2 / (2 * R), True), (rough - rough.min(), False)):
        sol = solve_contact(HalfSpace(E, 0.5), g0, h, normal_force=P, friction=mu, condition="partial",
                            tangential_force=Q)
        lighter = solve_contact(HalfSpace(E, 0.5), g0, h, normal_force=P - Q / mu)
        expected = mu * (sol.pressure - lighter.pressure)
        assert np.abs(sol.qx - expected).max() <= 0.02 * mu * sol.pressure.max()
        if hertz:
            c = sol.stick.sum() * h / 2
            assert abs(c - a * math.sqrt(1 - Q / (mu * P))) <= h


def test_stuck_plane_strain_has_no_slip():
    Es = E / 0.75
    P = 100.0
    a, _ = hertz_cylinder(P, R, Es)
    n = 128
    h = 3 * a / n
    x = grid(n, h)
    sol = solve_contact(HalfSpace(E, 0.5), x**2 / (2 * R), h, normal_force=P, friction=math.inf,
                        condition="stuck", tangential_force=10.0)
    assert not sol.slip.any() and np.array_equal(sol.stick, sol.contact)
    assert sol.qx.sum() * h == pytest.approx(10.0, rel=1e-9)


def test_partial_slip_below_half_reports_the_coupling():
    """At nu = 0.3 the stick zone departs from Cattaneo-Mindlin; the coupling is reported (not 0)."""
    nu = 0.3
    Es = E / (1 - nu**2)
    a, _ = hertz_sphere(0.5, R, Es)
    n = 48
    h = 2.5 * a / n
    x = grid(n, h)
    X, Y = np.meshgrid(x, x)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        sol = solve_contact(HalfSpace(E, nu), (X**2 + Y**2) / (2 * R), h, normal_force=0.5, friction=0.5,
                            condition="partial", tangential_force=(0.125, 0.0), tol=1e-6)
    assert sol.coupling["area"] != 0.0 and sol.coupling["force"] == pytest.approx(0.0, abs=1e-12)
    assert sol.qx.sum() * h * h == pytest.approx(0.125, rel=1e-6)

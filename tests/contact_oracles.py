"""Closed-form contact solutions used as oracles by the contact tests (Johnson, Contact Mechanics)."""

import math

import numpy as np


def grid(n, h, offset=0.0):
    """Node positions as SurfaceLoad puts them, shifted by ``offset`` nodes (m)."""
    return (np.arange(n) - n // 2 + offset) * h


def hertz_sphere(F, R, Es):
    """Contact radius a (m) and peak pressure p0 (Pa) of a sphere, Johnson 4.22-4.23."""
    a = (3 * F * R / (4 * Es)) ** (1 / 3)
    return a, 3 * F / (2 * math.pi * a * a)


def hertz_cylinder(P, R, Es):
    """Half-width a (m) and peak pressure p0 (Pa) of a cylinder under P (N/m), Johnson 4.43-4.44."""
    a = math.sqrt(4 * P * R / (math.pi * Es))
    return a, 2 * P / (math.pi * a)


def ellipse(r, a, p0):
    """p0 sqrt(1 - r^2/a^2) inside a, 0 outside."""
    return p0 * np.sqrt(np.clip(1 - (r / a) ** 2, 0, None))


def westergaard(x, L, pm, p_star):
    """Pressure (Pa) under a rigid sinusoid h = D cos(2 pi x/L) at mean pressure pm (Johnson 13.3)."""
    if pm >= p_star:
        return pm + p_star * np.cos(2 * np.pi * x / L)
    s2 = pm / p_star  # sin^2(pi a / L)
    inside = np.sin(np.pi * x / L) ** 2 < s2
    root = np.sqrt(np.clip(s2 - np.sin(np.pi * x / L) ** 2, 0, None))
    return np.where(inside & (np.cos(np.pi * x / L) > 0), 2 * pm / s2 * np.cos(np.pi * x / L) * root, 0.0)


def periodic_punch(x, L, b, pm):
    """Pressure (Pa) under a periodic row of rigid flat punches of half-width b, period L, mean pressure pm."""
    s = np.sin(np.pi * x / L) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(np.abs(x) < b, pm * np.cos(np.pi * x / L) / np.sqrt(np.sin(np.pi * b / L) ** 2 - s), 0.0)


def check_complementarity(sol, g0, tol):
    """p >= 0, g >= 0 and max(p g) <= tol max p max g0 (relative, as the solver promises)."""
    p, g = sol.pressure, sol.gap
    assert (p >= 0).all() and (g >= 0).all()
    assert float((p * g).max()) <= tol * float(p.max()) * float(np.ptp(g0))
    assert np.array_equal(sol.contact, p > 0)

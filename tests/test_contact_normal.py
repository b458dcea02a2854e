"""Frictionless normal contact (forward/contact/solve.py) against closed forms.

Oracles (Johnson, Contact Mechanics, 1985): Hertz sphere (eqs. 4.22-4.23) and cylinder
(4.43-4.44); Westergaard's sinusoid (section 13.3); Johnson, Greenwood and Higginson's
bi-sinusoid (Int. J. Mech. Sci. 27, 1985): full contact at sqrt(2) pi E* D / L and a Hertz
contact of radius of curvature L^2 / (4 pi^2 D) at each peak under a light load; the periodic
flat punch (its inverse-square-root edge). Every solution is also checked for complementarity.
"""

import dataclasses
import math

import numpy as np
import pytest

from contact_oracles import (check_complementarity, ellipse, grid, hertz_cylinder, hertz_sphere, periodic_punch,
                             westergaard)
from tactilab.forward import AccuracyWarning, HalfSpace, solve_contact

E, NU = 1.0e6, 0.5
ES = E / (1 - NU**2)
R = 0.01
SKIN = HalfSpace(E, NU)
TOL = 1e-8


def sphere(n, F=0.5, cover=3.0, offset=0.0):
    a, p0 = hertz_sphere(F, R, ES)
    h = cover * a / n
    x = grid(n, h, offset)
    X, Y = np.meshgrid(x, x)
    r = np.hypot(X, Y)
    return r**2 / (2 * R), h, r, a, p0


@pytest.mark.parametrize("n", [32, 64])
def test_hertz_sphere(n):
    g0, h, r, a, p0 = sphere(n, offset=0.3)
    sol = solve_contact(SKIN, g0, h, normal_force=0.5)
    check_complementarity(sol, g0, TOL)
    assert sol.converged and sol.normal_force == pytest.approx(0.5, rel=1e-12)
    assert abs(math.sqrt(sol.area / math.pi) - a) <= h
    true = float(np.abs(sol.pressure - ellipse(r, a, p0)).max()) / p0
    assert sol.error_estimate >= true
    assert sol.pressure.max() == pytest.approx(p0, rel=0.03)
    assert sol.approach == pytest.approx(a * a / R, rel=0.02)  # Johnson 4.23: delta = a^2 / R


def test_hertz_sphere_converges_with_the_grid():
    errors = []
    for n in (24, 48, 96):
        g0, h, r, a, p0 = sphere(n)
        sol = solve_contact(SKIN, g0, h, normal_force=0.5)
        errors.append(float(np.sqrt(np.mean((sol.pressure - ellipse(r, a, p0)) ** 2))) / p0)
    assert errors[2] < errors[1] < errors[0]


def test_hertz_sphere_under_approach_control():
    g0, h, r, a, p0 = sphere(48)
    sol = solve_contact(SKIN, g0, h, approach=a * a / R)
    check_complementarity(sol, g0, TOL)
    assert sol.normal_force == pytest.approx(0.5, rel=0.03)


@pytest.mark.parametrize("n,offset", [(128, 0.0), (200, 0.37)])
def test_hertz_cylinder(n, offset):
    P = 100.0
    a, p0 = hertz_cylinder(P, R, ES)
    h = 3 * a / n
    x = grid(n, h, offset)
    sol = solve_contact(SKIN, x**2 / (2 * R), h, normal_force=P)
    check_complementarity(sol, x**2 / (2 * R), TOL)
    assert sol.qy is None and sol.normal_force == pytest.approx(P, rel=1e-12)
    assert abs(sol.area / 2 - a) <= h
    true = float(np.abs(sol.pressure - ellipse(x, a, p0)).max()) / p0
    assert sol.error_estimate >= true
    rms = [float(np.sqrt(np.mean((s.pressure - ellipse(xx, a, p0)) ** 2))) / p0 for s, xx in
           [(solve_contact(SKIN, xx**2 / (2 * R), 3 * a / m, normal_force=P), xx)
            for m, xx in ((m, grid(m, 3 * a / m, offset)) for m in (n // 2, n))]]
    assert rms[1] < rms[0]


L, D = 1e-3, 2e-6
P_STAR = math.pi * ES * D / L


@pytest.mark.parametrize("ratio", [0.01, 0.1, 0.5, 0.9])
def test_westergaard(ratio):
    errs, fracs = [], []
    for n in (64, 256):
        x = grid(n, L / n)
        g0 = D * (1 - np.cos(2 * np.pi * x / L))
        a = L / math.pi * math.asin(math.sqrt(ratio))
        if 2 * a / L * n < 8:  # fewer than 8 nodes across: the solver says so
            with pytest.warns(AccuracyWarning, match="spacing: the largest contact patch spans only"):
                sol = solve_contact(SKIN, g0, L / n, mean_pressure=ratio * P_STAR, periodic=True)
        else:
            sol = solve_contact(SKIN, g0, L / n, mean_pressure=ratio * P_STAR, periodic=True)
        check_complementarity(sol, g0, TOL)
        exact = westergaard(x, L, ratio * P_STAR, P_STAR)
        true = float(np.abs(sol.pressure - exact).max()) / exact.max()
        assert sol.error_estimate >= true
        assert abs(sol.contact_fraction - 2 * a / L) <= 1.0 / n + 1e-12  # the edge within half a node each side
        # the first harmonics of p against those of the exact pressure (sampled finely)
        xf = grid(8192, L / 8192)
        ref = np.fft.rfft(westergaard(xf, L, ratio * P_STAR, P_STAR))[:6] / 8192
        got = np.fft.rfft(sol.pressure)[:6] / n
        errs.append(float(np.abs(np.abs(got) - np.abs(ref)).max()) / (ratio * P_STAR))
        fracs.append(abs(sol.contact_fraction - 2 * a / L))
    assert errs[1] < errs[0] or errs[1] < 1e-3


@pytest.mark.parametrize("ratio", [1.0, 1.5])
def test_westergaard_full_contact_at_and_above_p_star(ratio):
    n = 64
    x = grid(n, L / n)
    g0 = D * (1 - np.cos(2 * np.pi * x / L))
    sol = solve_contact(SKIN, g0, L / n, mean_pressure=ratio * P_STAR * (1 + 1e-9), periodic=True)
    assert (sol.gap <= TOL * 2 * D).all()  # touching everywhere (at p* the trough carries ~0 pressure)
    assert sol.contact.all() or ratio == 1.0
    exact = westergaard(x, L, ratio * P_STAR * (1 + 1e-9), P_STAR)
    true = float(np.abs(sol.pressure - exact).max())
    assert true <= 1e-5 * P_STAR and true <= sol.error_estimate * sol.pressure.max()


def bisinusoid(n):
    x = grid(n, L / n)
    X, Y = np.meshgrid(x, x)
    return D - D * np.cos(2 * np.pi * X / L) * np.cos(2 * np.pi * Y / L)


def test_jgh_full_contact_pressure():
    n, p_full = 32, math.sqrt(2) * math.pi * ES * D / L
    g0 = bisinusoid(n)
    above = solve_contact(SKIN, g0, L / n, mean_pressure=1.001 * p_full, periodic=True)
    assert above.contact.all()
    x = grid(n, L / n)
    X, Y = np.meshgrid(x, x)
    exact = p_full * (1.001 + np.cos(2 * np.pi * X / L) * np.cos(2 * np.pi * Y / L))  # pressed flat
    true = float(np.abs(above.pressure - exact).max()) / float(exact.max())
    assert true <= 1e-6 and true <= above.error_estimate
    below = solve_contact(SKIN, g0, L / n, mean_pressure=0.97 * p_full, periodic=True)
    assert not below.contact.all()
    check_complementarity(below, g0, TOL)


def test_jgh_light_load_is_hertz_at_each_peak():
    n, p_full = 128, math.sqrt(2) * math.pi * ES * D / L
    pm = 0.003 * p_full
    g0 = bisinusoid(n)
    sol = solve_contact(SKIN, g0, L / n, mean_pressure=pm, periodic=True)
    check_complementarity(sol, g0, TOL)
    a, p0 = hertz_sphere(pm * L * L / 2, L * L / (4 * math.pi**2 * D), ES)  # two peaks per cell
    h = L / n
    assert abs(math.sqrt(sol.area / 2 / math.pi) - a) <= h
    assert sol.pressure.max() == pytest.approx(p0, rel=0.05)


def test_deep_grating_is_a_periodic_flat_punch():
    n, period, b = 512, 1e-3, 0.25e-3
    h = period / n
    x = grid(n, h)
    g0 = np.where(np.abs(x) < b - h / 2, 0.0, 50e-6)  # plateaus of half-width b, grooves never touched
    pm = 1e3
    sol = solve_contact(SKIN, g0, h, mean_pressure=pm, periodic=True)
    check_complementarity(sol, g0, TOL)
    assert sol.normal_force == pytest.approx(pm * period, rel=1e-12)
    assert sol.gap[np.abs(x) > b].min() > 0  # the grooves stay open
    b_eff = b - h / 2  # the plateau's nodes cover |x| < b - h/2 with their cells
    inner = np.abs(x) < b_eff - 2.5 * h  # more than 2 nodes from the edges
    exact = periodic_punch(x, period, b_eff, pm)
    assert np.allclose(sol.pressure[inner], exact[inner], rtol=0.1)
    assert np.allclose(sol.pressure[np.abs(x) < b / 2], exact[np.abs(x) < b / 2], rtol=0.01)
    inner_error = float(np.abs(sol.pressure - exact)[inner].max()) / float(exact[inner].max())
    assert sol.error_estimate >= inner_error
    edge = np.flatnonzero(sol.contact)[-1]  # last node in contact on the right
    dist = b_eff - x[edge - 10: edge - 2]
    slope = np.polyfit(np.log(dist), np.log(sol.pressure[edge - 10: edge - 2]), 1)[0]
    assert slope == pytest.approx(-0.5, abs=0.1)


def test_periodic_translation_invariance(rng):
    n = 64
    g0 = bisinusoid(n) + 0.2 * D * rng.random((n, n))
    sol = solve_contact(SKIN, g0, L / n, mean_pressure=0.2 * P_STAR, periodic=True)
    moved = solve_contact(SKIN, np.roll(g0, (5, -7), axis=(0, 1)), L / n, mean_pressure=0.2 * P_STAR, periodic=True)
    assert np.allclose(np.roll(sol.pressure, (5, -7), axis=(0, 1)), moved.pressure, atol=1e-5 * sol.pressure.max())


def test_warm_start_gives_the_cold_answer():
    g0, h, r, a, p0 = sphere(48)
    cold = solve_contact(SKIN, g0, h, normal_force=0.5)
    warm = solve_contact(SKIN, g0, h, normal_force=0.5, initial=cold)
    assert warm.iterations <= 2
    assert np.allclose(warm.pressure, cold.pressure, atol=1e-6 * p0)
    bare = solve_contact(SKIN, g0, h, normal_force=0.5, initial=dataclasses.replace(cold, _coarse_pressure=None))
    assert np.allclose(bare.pressure, cold.pressure, atol=1e-6 * p0)  # no check solution carried: a cascade
    assert bare.error_parts["discretisation"] == pytest.approx(cold.error_parts["discretisation"], rel=1e-4)
    other = solve_contact(SKIN, np.roll(g0, 2, axis=1), h, normal_force=0.5, initial=cold)
    ref = solve_contact(SKIN, np.roll(g0, 2, axis=1), h, normal_force=0.5)
    assert np.allclose(other.pressure, ref.pressure, atol=1e-5 * p0)


def test_a_pressure_start_without_the_check_solve_gives_the_cold_answer():
    """estimate_error=False from a pressure array: no check solve, the same pressure to the solver's
    tolerance, the estimate reported as not made (NaN); without a start the check solve still runs."""
    g0, h, r, a, p0 = sphere(48)
    cold = solve_contact(SKIN, g0, h, normal_force=0.5, tol=1e-10)
    near = solve_contact(SKIN, g0 + 1e-8 * np.cos(r / a), h, normal_force=0.45, tol=1e-10)
    fast = solve_contact(SKIN, g0, h, normal_force=0.5, tol=1e-10, initial=np.array(near.pressure),
                         estimate_error=False)
    bound = (fast.error_parts["solver"] + cold.error_parts["solver"]) * cold.pressure.max()
    assert np.abs(fast.pressure - cold.pressure).max() <= max(bound, 1e-8 * p0)
    assert np.isnan(fast.error_estimate) and np.isnan(fast.error_parts["discretisation"])
    assert fast._coarse_pressure is None and np.isfinite(fast.error_parts["solver"])
    alone = solve_contact(SKIN, g0, h, normal_force=0.5, tol=1e-10, estimate_error=False)
    assert alone.error_estimate == pytest.approx(cold.error_estimate, rel=1e-3)
    with pytest.raises(ValueError, match="initial: a pressure start must be finite, >= 0"):
        solve_contact(SKIN, g0, h, normal_force=0.5, initial=-np.ones_like(g0))


def test_warm_started_sliding_sequence_equals_cold_solves_frame_by_frame():
    """A fingertip sliding one node per frame over a rough plate, each frame started from the previous
    one shifted with the plate: the fine and the check solve both start warm, and every frame gives the
    cold answer (to the solver's own error bound) with the same discretisation estimate."""
    from tactilab.data_schemas import random_rough_surface

    n, frames, h = 48, 4, 100e-6
    plate = random_rough_surface((n, n + frames), h, rms_height=2e-6, hurst=0.8, rng=np.random.default_rng(3))
    X, Y = np.meshgrid(grid(n, h), grid(n, h))
    kw = dict(normal_force=0.5, friction=0.5, condition="sliding")
    previous = None
    for k in range(frames):
        g0 = (X**2 + Y**2) / (2 * R) - plate[:, k:k + n]
        cold = solve_contact(SKIN, g0, h, **kw)
        if previous is not None:
            start = dataclasses.replace(previous, pressure=np.roll(previous.pressure, -1, axis=-1))
            warm = solve_contact(SKIN, g0, h, initial=start, **kw)
            bound = (warm.error_parts["solver"] + cold.error_parts["solver"]) * cold.pressure.max()
            assert np.abs(warm.pressure - cold.pressure).max() <= bound
            assert np.allclose(warm.qx, 0.5 * warm.pressure)
            assert warm.error_parts["discretisation"] == pytest.approx(cold.error_parts["discretisation"], rel=1e-3)
            assert warm._coarse_pressure is not None and warm._coarse_pressure.shape == (n // 2, n // 2)
            check_complementarity(warm, g0, TOL)
            previous = warm
        else:
            previous = cold


@pytest.mark.filterwarnings("ignore:spacing. the largest contact patch")  # small rough patches, on purpose
@pytest.mark.filterwarnings("ignore:gap. the isolated contact reaches")  # a grid-filling patch: two methods compared
@pytest.mark.parametrize("periodic", [True, False])
def test_both_methods_give_one_answer(periodic, rng):
    n = 64
    g0 = bisinusoid(n) + 0.3 * D * rng.random((n, n))
    kw = dict(mean_pressure=0.1 * P_STAR, periodic=True) if periodic else dict(normal_force=0.1 * P_STAR * L * L)
    fast = solve_contact(SKIN, g0, L / n, **kw)
    pk = solve_contact(SKIN, g0, L / n, method="polonsky_keer", **kw)
    from tactilab.forward.contact import METHODS

    as_callable = solve_contact(SKIN, g0, L / n, method=METHODS["polonsky_keer"], **kw)
    assert np.array_equal(as_callable.pressure, pk.pressure) and as_callable.method == "polonsky_keer"
    assert fast.method == "preconditioned_cg" and pk.method == "polonsky_keer"
    assert fast.iterations < pk.iterations
    force = 0.1 * P_STAR * L * L
    assert fast.normal_force == pytest.approx(force, rel=1e-12) and pk.normal_force == pytest.approx(force, rel=1e-12)
    assert np.allclose(fast.pressure, pk.pressure, atol=1e-6 * fast.pressure.max())
    check_complementarity(fast, g0, TOL)
    check_complementarity(pk, g0, TOL)


@pytest.mark.parametrize("n", [15, 16, 17, 18])
@pytest.mark.parametrize("periodic", [True, False])
def test_coarse_grid_is_centred_and_interpolates_linear_fields(n, periodic):
    """The check solve uses every other node with the origin kept (SurfaceLoad's centring), and its
    solution returns by linear interpolation: exact for a linear field between coarse nodes."""
    from tactilab.forward.contact.starts import coarse_index, prolong

    x = grid(n, 1.0)
    sub = coarse_index((n,))
    xc = x[sub]
    assert 0.0 in xc and np.allclose(xc, grid(len(xc), 2.0))
    fine = prolong(3.0 * xc + 1.0, (n,), periodic)
    inside = (x >= xc[0]) & (x <= xc[-1])
    assert np.allclose(fine[inside], 3.0 * x[inside] + 1.0)
    field = np.add.outer(xc, 2 * xc)
    assert np.allclose(prolong(field, (n, n), periodic)[np.ix_(inside, inside)],
                       np.add.outer(x, 2 * x)[np.ix_(inside, inside)])


@pytest.mark.filterwarnings("ignore:gap. the isolated contact reaches")  # the uniform gap fills the grid on purpose
def test_flat_circular_punch_under_approach_control():
    """A rigid flat circular punch pressed by delta: F = 2 a E* delta (Johnson, Contact Mechanics, 3.39)."""
    n, h, delta = 64, 5e-5, 1e-6
    x = grid(n, h)
    X, Y = np.meshgrid(x, x)
    g0 = np.where(np.hypot(X, Y) < 20 * h, 0.0, 1e-3)  # the punch's face; the rest never touches
    sol = solve_contact(SKIN, g0, h, approach=delta)
    assert sol.converged and sol.contact.sum() == (g0 == 0).sum()
    a = math.sqrt(sol.area / math.pi)
    assert sol.normal_force == pytest.approx(2 * a * ES * delta, rel=0.03)
    uniform = solve_contact(SKIN, np.zeros((n, n)), h, approach=delta)  # a uniform gap moves too
    assert uniform.contact.all() and uniform.converged


"""Partial slip and stuck contact (forward/contact/tangential.py) against closed forms.

Oracles: Cattaneo (1938) and Mindlin (1949), as in Johnson, Contact Mechanics (1985), 7.2 (sphere)
and 7.1 (cylinder): under a Hertz pressure of peak p0 and radius a, a tangential force Q < mu P
leaves a central stick zone of radius c, c/a = (1 - Q/(mu P))^(1/3) (sphere) or ^(1/2) (cylinder),
and the traction q = mu p0 [sqrt(1 - r^2/a^2) - (c/a) sqrt(1 - r^2/c^2)]; Mindlin's no-slip traction
Q / (2 pi a sqrt(a^2 - r^2)) (sphere) and Q / (pi sqrt(a^2 - x^2)) (cylinder); Ciavarella (1998) and
Jaeger (1998): in plane strain at nu = 1/2, q = mu [p(P) - p(P - Q/mu)] for any profile.
The pressure is the sampled Hertz closed form (not a normal solve), so the tangential solver is
tested alone.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactilab.forward import HalfSpace
from tactilab.forward.contact import ContactCompliance, solve_tangential

E, A, P0, MU = 1e6, 1e-3, 1e4, 0.5  # Pa, m (contact radius), Pa (peak pressure), friction


def _hertz(n: int, nu: float = 0.5, line: bool = False, periodic: bool = False):
    """Grid of n nodes per axis over 4 a, the sampled Hertz pressure, and its compliance."""
    h = 4 * A / n
    x = (np.arange(n) - n // 2) * h
    if line:
        r = np.abs(x)
    else:
        X, Y = np.meshgrid(x, x)
        r = np.hypot(X, Y)
    p = P0 * np.sqrt(np.clip(1 - r * r / A ** 2, 0, None))
    C = ContactCompliance(HalfSpace(E, nu), p.shape, h, periodic)
    return C, p, r, h


def _total(p, h, line):
    return p.sum() * (h if line else h * h)


def _mindlin(r, c):
    """Cattaneo-Mindlin traction over mu p0 (sphere and cylinder alike)."""
    return np.sqrt(np.clip(1 - r * r / A ** 2, 0, None)) - (c / A) * np.sqrt(np.clip(1 - r * r / c ** 2, 0, None))


@pytest.mark.parametrize("ratio", [0.3, 0.5, 0.8])
def test_cattaneo_mindlin_sphere(ratio):
    """3-D, nu = 1/2: stick radius within one grid spacing (the stick zone's equivalent radius) and
    the traction profile. Mindlin's solution assumes q parallel to Q; the exact 3-D solution has a
    small transverse part (measured max |qy| = 0.060 mu p0 at 64^2), so qx is compared to 0.1 mu p0
    at the stick edge and 0.02 mu p0 (measured 0.010) more than 2 nodes from both edges."""
    C, p, r, h = _hertz(64)
    Q = ratio * MU * _total(p, h, False)
    sol = solve_tangential(C, p, p > 0, MU, (Q, 0.0))
    assert sol.converged and sol.qy is not None
    c = A * (1 - ratio) ** (1 / 3)
    assert abs(math.sqrt(sol.stick.sum() * h * h / math.pi) - c) <= h
    err = np.abs(sol.qx / (MU * P0) - _mindlin(r, c))
    away = (np.abs(r - c) > 2 * h) & (r < A - 2 * h)
    assert err.max() < 0.1 and err[away].max() < 0.02
    assert np.abs(sol.qy).max() < 0.08 * MU * P0


@pytest.mark.parametrize("ratio", [0.3, 0.5, 0.8])
def test_cattaneo_mindlin_cylinder(ratio):
    """Plane strain, nu = 1/2 (exact): c/a = (1 - Q/(mu P))^(1/2) within one spacing, the traction to
    0.03 mu p0 everywhere and 0.005 mu p0 more than 2 nodes from the edges."""
    C, p, r, h = _hertz(256, line=True)
    Q = ratio * MU * _total(p, h, True)
    sol = solve_tangential(C, p, p > 0, MU, Q)
    assert sol.converged and sol.qy is None
    c = A * (1 - ratio) ** 0.5
    assert abs(sol.stick.sum() * h / 2 - c) <= h
    err = np.abs(sol.qx / (MU * P0) - _mindlin(r, c))
    away = (np.abs(r - c) > 2 * h) & (r < A - 2 * h)
    assert err.max() < 0.03 and err[away].max() < 0.005


def test_mindlin_exact_at_nu_zero():
    """At nu = 0 the tangential compliance is isotropic, the slip stays along x and Cattaneo-Mindlin
    is exact for the tangential problem: qy = 0 and the stick radius within a spacing. At nu = 1/2
    the transverse traction is what makes Mindlin approximate (test above)."""
    C, p, r, h = _hertz(64, nu=0.0)
    sol = solve_tangential(C, p, p > 0, MU, (0.5 * MU * _total(p, h, False), 0.0))
    assert np.abs(sol.qy).max() < 1e-9 * MU * P0
    c = A * 0.5 ** (1 / 3)
    assert abs(math.sqrt(sol.stick.sum() * h * h / math.pi) - c) <= h


def _check_coulomb(sol, p, force, area, mu=MU):
    """Complementarity: |q| <= mu p, no slip in the stick zone, q against the slip, force exact."""
    q = np.stack([sol.qx] + ([sol.qy] if sol.qy is not None else []))
    mag = np.sqrt((q * q).sum(axis=0))
    assert np.all(mag <= mu * p * (1 + 1e-12))
    assert not q[:, p <= 0].any()
    np.testing.assert_allclose(q.reshape(len(q), -1).sum(axis=1) * area, force, rtol=1e-10,
                               atol=1e-12 * mu * p.sum() * area)
    slip = sol.displacement - sol.shift.reshape((-1,) + (1,) * p.ndim)  # skin relative to the surface
    size = np.sqrt((slip * slip).sum(axis=0))
    scale = np.abs(sol.displacement).max()
    assert size[sol.stick].max(initial=0.0) <= 1e-6 * scale
    moving = sol.slip & (size > 1e-3 * size.max()) & (p > 0)
    cosine = -(q * slip).sum(axis=0)[moving] / (mag[moving] * size[moving])
    assert np.all(cosine > 1 - 1e-6)
    assert np.all((q * slip).sum(axis=0)[sol.slip] <= 1e-9 * scale * mu * p.max())


@pytest.mark.parametrize("line", [False, True])
@pytest.mark.parametrize("periodic", [False, True])
def test_complementarity(line, periodic):
    C, p, r, h = _hertz(128 if line else 48, line=line, periodic=periodic)
    area = h if line else h * h
    force = 0.6 * MU * _total(p, h, line) * (np.array([1.0]) if line else np.array([0.6, -0.8]))
    sol = solve_tangential(C, p, p > 0, MU, force[0] if line else force)
    assert sol.converged and sol.stick.any() and sol.slip.any()
    _check_coulomb(sol, p, force, area)



@pytest.mark.parametrize("line", [False, True])
@pytest.mark.parametrize("ratio", [1e-9, 1e-3, 0.999999])
def test_complementarity_at_extreme_forces(line, ratio):
    """A force a billionth of mu P is solved as accurately as a large one (the residual is relative
    to the traction, not to mu p), and one a millionth below mu P leaves (almost) no stick zone; the
    contact mask may hold nodes of zero pressure (they carry no traction)."""
    C, p, r, h = _hertz(32 if not line else 64, line=line)
    area = h if line else h * h
    force = ratio * MU * _total(p, h, line) * (np.array([1.0]) if line else np.array([0.3, 0.9539392014169456]))
    sol = solve_tangential(C, p, p >= 0, MU, force[0] if line else force)
    assert sol.converged and not sol.stick[p == 0].any()
    _check_coulomb(sol, p, force, area)
    assert sol.stick[p > 0].all() if ratio < 1e-2 else sol.stick.sum() <= 1



@pytest.mark.parametrize("periodic", [True, False])
def test_rough_contact_complementarity(periodic, rng):
    """A random rough surface (3-D, many contact patches; the normal solution from solve_contact):
    every Coulomb condition at three force levels, and a stuck contact without slip."""
    from tactilab.forward import solve_contact

    n, h = 64, 20e-6
    k2 = np.fft.fftfreq(n)[:, None] ** 2 + np.fft.fftfreq(n)[None, :] ** 2
    spectrum = np.where((k2 > 0) & (k2 < 0.1), (k2 + 1e-4) ** -0.9, 0.0)
    surface = np.real(np.fft.ifft2(spectrum * np.exp(2j * np.pi * rng.random((n, n)))))
    surface *= 5e-6 / surface.std()
    x = (np.arange(n) - n // 2) * h
    X, Y = np.meshgrid(x, x)
    gap = (0.0 if periodic else (X * X + Y * Y) / 0.02) - surface
    skin = HalfSpace(E, 0.5)
    load = dict(mean_pressure=1e4) if periodic else dict(normal_force=2e-3)
    normal = solve_contact(skin, gap - gap.min(), h, periodic=periodic, tol=1e-10, **load)
    p = normal.pressure
    assert np.sum(np.diff(normal.contact.astype(int), axis=1) == 1) >= 10  # many patches
    C = ContactCompliance(skin, (n, n), h, periodic)
    for ratio in (0.2, 0.5, 0.9):
        force = ratio * MU * _total(p, h, False) * np.array([0.8, 0.6])
        sol = solve_tangential(C, p, normal.contact, MU, force)
        assert sol.converged and sol.stick.any() and sol.slip.any()
        _check_coulomb(sol, p, force, h * h)
    stuck = solve_tangential(C, p, normal.contact, math.inf, 0.3 * _total(p, h, False) * np.array([0.8, 0.6]),
                             stuck=True)
    slip = stuck.displacement - stuck.shift[:, None, None]
    assert stuck.converged and np.abs(slip[:, normal.contact]).max() <= 1e-6 * np.abs(stuck.displacement).max()


@pytest.mark.parametrize("line", [False, True])
def test_no_force_no_traction_and_full_sliding(line):
    """Q = 0 gives q = 0 (all stuck); Q = mu P gives the sliding traction q = mu p (all slipping)."""
    C, p, r, h = _hertz(32 if not line else 64, line=line)
    zero = 0.0 if line else (0.0, 0.0)
    sol = solve_tangential(C, p, p > 0, MU, zero)
    assert not sol.qx.any() and (sol.qy is None or not sol.qy.any())
    assert np.array_equal(sol.stick, p > 0) and not sol.slip.any()
    full = MU * _total(p, h, line)
    sol = solve_tangential(C, p, p > 0, MU, full if line else (0.0, -full))
    along = sol.qx if line else -sol.qy
    np.testing.assert_allclose(along, MU * p, rtol=1e-12)
    assert np.array_equal(sol.slip, p > 0) and not sol.stick.any()



@pytest.mark.parametrize("line, sizes", [(False, (32, 64)), (True, (256, 512))])
def test_mindlin_no_slip(line, sizes):
    """Stuck (mu = inf): Mindlin's traction Q / (2 pi a sqrt(a^2 - r^2)) (sphere) or
    Q / (pi sqrt(a^2 - x^2)) (cylinder), parallel to Q, within r <= 0.8 a; the error converges at
    first order (the edge is resolved to a spacing: measured 7.9 % at 64^2, 1.5 % at 512 nodes);
    no slip anywhere in the contact and the force exact."""
    errors = []
    for n in sizes:
        C, p, r, h = _hertz(n, line=line)
        Q = 0.3 * _total(p, h, line)
        force = np.array([Q]) if line else np.array([0.6 * Q, -0.8 * Q])
        sol = solve_tangential(C, p, p > 0, math.inf, force[0] if line else force, stuck=True)
        assert sol.converged and np.array_equal(sol.stick, p > 0) and not sol.slip.any()
        inside = r <= 0.8 * A
        root = np.sqrt(np.clip(A * A - r * r, A * A * 1e-12, None))
        shape = 1 / (math.pi * root) if line else 1 / (2 * math.pi * A * root)
        q = np.stack([sol.qx] + ([] if line else [sol.qy]))
        errors.append(max(np.abs(q[j][inside] / (force[j] * shape[inside]) - 1).max() for j in range(len(force))))
        area = h if line else h * h
        np.testing.assert_allclose(q.reshape(len(q), -1).sum(axis=1) * area, force, rtol=1e-10)
        slip = sol.displacement - sol.shift.reshape((-1,) + (1,) * p.ndim)
        assert np.abs(slip[:, p > 0]).max() <= 1e-6 * np.abs(sol.displacement).max()
        assert not q[:, p <= 0].any()
    assert errors[1] < 0.09 and errors[1] < 0.6 * errors[0]



def test_ciavarella_jaeger_rough_plane_strain(rng):
    """Plane strain, nu = 1/2, a cylinder carrying seven random harmonics (several contact patches):
    q = mu [p(P) - p(P - Q/mu)], the pressures from the normal solver on the same gap, and the stick
    zone is the lighter load's contact. The identity holds for the discrete problem too (the
    tangential and normal compliances are equal there), so only the solvers' tolerances remain
    (measured 2e-8 of mu max p)."""
    from tactilab.forward import solve_contact

    radius, P, mu, Q = 0.01, 100.0, 0.4, 20.0  # m, N/m, 1, N/m
    a = math.sqrt(4 * P * radius / (math.pi * E / 0.75))
    n = 256
    h = 3 * a / n
    x = (np.arange(n) - n // 2) * h
    gap = x * x / (2 * radius)
    for k in range(1, 8):
        gap += 3e-6 / k * np.cos(2 * np.pi * k * x / (a / 2) + rng.uniform(0, 2 * np.pi))
    gap -= gap.min()
    skin = HalfSpace(E, 0.5)
    full = solve_contact(skin, gap, h, normal_force=P, tol=1e-10)
    light = solve_contact(skin, gap, h, normal_force=P - Q / mu, tol=1e-10)
    assert np.sum(np.diff(light.contact.astype(int)) == 1) >= 3  # several stick patches
    C = ContactCompliance(skin, (n,), h, False)
    sol = solve_tangential(C, full.pressure, full.contact, mu, Q, tol=1e-10)
    assert np.abs(sol.qx - mu * (full.pressure - light.pressure)).max() <= 1e-6 * mu * full.pressure.max()
    assert np.array_equal(sol.stick, light.contact)
    _check_coulomb(sol, full.pressure, [Q], h, mu)


@pytest.mark.parametrize("stuck", [False, True])
def test_warm_start_gives_the_cold_answer(stuck):
    """A converged traction as ``initial`` is a fixed point (a few products), a perturbed one
    converges to the cold answer."""
    C, p, r, h = _hertz(48)
    force = (0.5 * MU * _total(p, h, False), 0.0)
    mu = math.inf if stuck else MU
    cold = solve_tangential(C, p, p > 0, mu, force, stuck=stuck, tol=1e-10)
    q = np.stack([cold.qx, cold.qy])
    warm = solve_tangential(C, p, p > 0, mu, force, stuck=stuck, tol=1e-10, initial=q)
    assert warm.iterations <= 0.2 * cold.iterations
    bumped = solve_tangential(C, p, p > 0, mu, force, stuck=stuck, tol=1e-10, initial=1.3 * q[::-1])
    for sol in (warm, bumped):
        assert sol.converged and np.array_equal(sol.stick, cold.stick)
        assert np.abs(sol.qx - cold.qx).max() <= 1e-6 * np.abs(cold.qx).max()



@pytest.mark.parametrize("nu", [0.5, 0.3])
def test_coupling_below_half_after_frictionless_loading(nu):
    """nu < 1/2, the normal load applied first without friction, then Q with the normal-tangential
    coupling (the tangential step's offset is the pressure change's tangential displacement),
    alternated with the normal solve. The stick radius stays within a spacing of Cattaneo-Mindlin
    (measured at 64^2: +0.12 h at nu = 0.45, +0.19 h at 0.3, +0.30 h at 0; +0.12 h at 1/2), and the
    pressure shifts against Q: q along +x pushes the surface ahead of it into a compressible skin,
    opening the gap there (measured centroid -0.029 a at nu = 0.3, 64^2; exactly 0 at nu = 1/2)."""
    from tactilab.forward.contact.normal import polonsky_keer

    radius, P, n = 0.01, 0.5, 48
    a = (3 * P * radius / (4 * E / (1 - nu * nu))) ** (1 / 3)
    h = 2.5 * a / n
    x = (np.arange(n) - n // 2) * h
    X, Y = np.meshgrid(x, x)
    gap = (X * X + Y * Y) / (2 * radius)
    C = ContactCompliance(HalfSpace(E, nu), (n, n), h, False)

    def normal(start, extra=None):
        return polonsky_keer(C, gap, total=P / (h * h), approach=None, tol=1e-10, max_iter=1000, p0=start,
                             extra_gap=extra).pressure

    hertz = normal(np.ones((n, n)))
    p, sol = hertz, None
    for outer in range(40):
        offset = np.stack(C.tangential_from_normal(p - hertz))
        start = None if sol is None else np.stack([sol.qx, sol.qy])
        sol = solve_tangential(C, p, p > 0, MU, (0.5 * MU * P, 0.0), pressure_displacement=offset, initial=start,
                               tol=1e-10)
        new = normal(p, sol.normal_displacement)
        change, p = np.abs(new - p).max() / p.max(), new
        if change < 1e-8:
            break
    assert change < 1e-8 and outer < 20
    c = math.sqrt(sol.stick.sum() * h * h / math.pi)
    assert abs(c - a * 0.5 ** (1 / 3)) <= h
    centroid = (p * X).sum() / p.sum() / a
    if nu == 0.5:
        assert outer == 0 and not sol.normal_displacement.any() and abs(centroid) < 1e-8
    else:
        assert -0.05 < centroid < -0.015



@pytest.mark.parametrize("d", [1, 2])
def test_projection_is_the_euclidean_projection(d, rng):
    """friction_qp.project: the result is admissible (discs, force) and satisfies the variational
    inequality that characterises the Euclidean projection onto a convex set, (z - q).(y - q) <= 0
    for every admissible y (random admissible points: convex combinations of scaled extremes)."""
    from tactilab.forward.contact.friction_qp import project

    n, area = 200, 0.3
    bound = rng.uniform(0.0, 2.0, n)
    Q = 0.4 * area * bound.sum() * (np.array([1.0]) if d == 1 else np.array([0.6, 0.8]))
    z = rng.normal(0.0, 2.0, (n, d))
    q, _ = project(z, bound, area, Q, np.zeros(d))
    assert np.all(np.sqrt((q * q).sum(axis=1)) <= bound * (1 + 1e-12))
    np.testing.assert_allclose(q.sum(axis=0) * area, Q, rtol=1e-10)
    for _ in range(50):
        angle = rng.uniform(0, 2 * np.pi, n)
        if d == 2:
            direction = np.stack([np.cos(angle), np.sin(angle)], axis=1)
        else:
            direction = np.sign(rng.normal(size=(n, 1)))
        y = bound[:, None] * direction * rng.uniform(0, 1, (n, 1))
        y, _ = project(y, bound, area, Q, np.zeros(d))  # an admissible point
        assert np.sum((z - q) * (y - q)) <= 1e-9 * np.sum(z * z)


def test_newton_phase_agrees_with_the_gradient_method():
    """Two methods, one answer: the accelerated projected gradient alone (thousands of products)
    and the solver's gradient-then-Newton phases reach the same traction on a 3-D Hertz frame."""
    from tactilab.forward.contact import friction_qp as qp

    C, p, r, h = _hertz(40)
    sol = solve_tangential(C, p, p > 0, MU, (0.4 * MU * _total(p, h, False), 0.1 * MU * _total(p, h, False)),
                           tol=1e-11)
    nodes = np.nonzero(p > 0)
    bound = MU * p[nodes]

    def apply(q):
        grids = [np.zeros(p.shape), np.zeros(p.shape)]
        for j in range(2):
            grids[j][nodes] = q[:, j]
        return np.stack([u[nodes] for u in C.tangential(*grids)], axis=1)

    force = np.array([sol.qx.sum(), sol.qy.sum()]) * h * h
    L, _ = qp.largest_eigenvalue(apply, np.repeat(bound[:, None], 2, axis=1))
    q0, _ = qp.project(np.zeros((len(bound), 2)), bound, h * h, force, np.zeros(2))
    q, u, used = qp._fista(apply, bound, h * h, force, np.zeros_like(q0), q0, apply(q0), L, 1e-12, 20000)
    assert used < 20000
    scale = MU * P0
    assert np.abs(q[:, 0] - sol.qx[nodes]).max() < 1e-8 * scale
    assert np.abs(q[:, 1] - sol.qy[nodes]).max() < 1e-8 * scale



@pytest.mark.parametrize("line", [False, True])
def test_isolated_answer_does_not_depend_on_the_empty_grid_around_it(line):
    """An isolated contact embedded in a grid twice as wide (solved on its cropped bounding box)
    has the traction of the tight grid (solved uncropped), and the same slip s - u_t (plane strain
    displacements differ by a constant, the rigid shift with them)."""
    n = 32 if not line else 64
    C, p, r, h = _hertz(n, line=line)
    p = np.where(r < A, p, 0.0)
    wide = np.pad(p, n // 2)
    Cw = ContactCompliance(C.skin, wide.shape, h, False)
    force = 0.5 * MU * _total(p, h, line)
    F = force if line else (force, 0.0)
    tight = solve_tangential(C, p, p > 0, MU, F, tol=1e-11)
    embedded = solve_tangential(Cw, wide, wide > 0, MU, F, tol=1e-11)
    inner = (slice(n // 2, n // 2 + n),) * p.ndim
    scale = MU * P0
    assert np.abs(embedded.qx[inner] - tight.qx).max() < 1e-8 * scale
    assert np.array_equal(embedded.stick[inner], tight.stick)
    s_tight = tight.displacement - tight.shift.reshape((-1,) + (1,) * p.ndim)
    s_wide = (embedded.displacement - embedded.shift.reshape((-1,) + (1,) * p.ndim))[(slice(None),) + inner]
    assert np.abs((s_wide - s_tight)[:, p > 0]).max() < 1e-7 * np.abs(tight.displacement).max()



def test_unloading_mindlin_deresiewicz_cylinder():
    """A loading history through pressure_displacement: load to Q* = 0.8 mu P, then unload to
    Q = 0.2 mu P, the second step passing -C q* (nu = 1/2, plane strain). Mindlin and Deresiewicz
    (Johnson, Contact Mechanics, 7.2): the traction is q* minus the partial-slip traction of friction
    2 mu at force Q* - Q, mu p0 [-sqrt(1 - x^2/a^2) + 2 (b/a) sqrt(1 - x^2/b^2) - (c/a) sqrt(1 - x^2/c^2)]
    with c/a = (1 - Q*/(mu P))^(1/2) and b/a = (1 - (Q* - Q)/(2 mu P))^(1/2); reverse slip q = -mu p
    beyond b, and the stick zone |x| < b."""
    C, p, r, h = _hertz(256, line=True)
    P = _total(p, h, True)
    loaded = solve_tangential(C, p, p > 0, MU, 0.8 * MU * P, tol=1e-10)
    history = -C.tangential(loaded.qx)[0][None]
    sol = solve_tangential(C, p, p > 0, MU, 0.2 * MU * P, pressure_displacement=history,
                           initial=loaded.qx[None], tol=1e-10)
    c, b = A * math.sqrt(0.2), A * math.sqrt(0.7)
    root = lambda w: np.sqrt(np.clip(1 - r * r / w ** 2, 0, None))  # noqa: E731
    expected = MU * P0 * (-root(A) + 2 * (b / A) * root(b) - (c / A) * root(c))
    away = (np.abs(r - c) > 2 * h) & (np.abs(r - b) > 2 * h) & (r < A - 2 * h)
    err = np.abs(sol.qx - expected) / (MU * P0)
    assert sol.converged and err[away].max() < 0.008 and err.max() < 0.05  # measured 0.0036, 0.029
    assert abs(sol.stick.sum() * h / 2 - b) <= h  # measured -0.05 h
    np.testing.assert_allclose(sol.qx[sol.slip & (p > 0)], -MU * p[sol.slip & (p > 0)], rtol=1e-9)



def test_a_force_along_y_gives_the_transposed_traction():
    """Rotating the load by 90 degrees on a square grid rotates the answer: Q along y gives the
    transpose of the traction and stick zone of Q along x (a check of the operator's x-y coupling)."""
    C, p, r, h = _hertz(48)
    Q = 0.5 * MU * _total(p, h, False)
    along_x = solve_tangential(C, p, p > 0, MU, (Q, 0.0), tol=1e-10)
    along_y = solve_tangential(C, p, p > 0, MU, (0.0, Q), tol=1e-10)
    scale = MU * P0
    assert np.abs(along_y.qy - along_x.qx.T).max() < 1e-7 * scale
    assert np.abs(along_y.qx - along_x.qy.T).max() < 1e-7 * scale
    assert np.array_equal(along_y.stick, along_x.stick.T)


def test_bad_input():
    C, p, r, h = _hertz(16)
    ok = dict(compliance=C, pressure=p, contact=p > 0, friction=MU, tangential_force=(1e-3, 0.0))

    def call(**change):
        return solve_tangential(**{**ok, **change})

    with pytest.raises(ValueError, match="friction: the friction coefficient must be >= 0"):
        call(friction=-0.1)
    with pytest.raises(ValueError, match="friction: the friction coefficient must be >= 0"):
        call(friction=float("nan"))
    with pytest.raises(ValueError, match="friction: partial slip needs a finite friction"):
        call(friction=math.inf)
    limit = MU * _total(p, h, False)
    with pytest.raises(ValueError, match=r"tangential_force: \|Q\| = .* exceeds the friction limit mu P"):
        call(tangential_force=(0.8 * limit, 0.8 * limit))
    with pytest.raises(ValueError, match="tangential_force: expected a pair"):
        call(tangential_force=(float("nan"), 0.0))
    with pytest.raises(ValueError, match="tangential_force: expected a pair"):
        call(tangential_force=1e-3)
    bad = p.copy()
    bad[3, 4] = np.nan
    with pytest.raises(ValueError, match=r"pressure: must be finite \(no NaN or inf\) in Pa, got nan at index"):
        call(pressure=bad)
    with pytest.raises(ValueError, match="pressure: must be >= 0 Pa"):
        call(pressure=-p)
    with pytest.raises(ValueError, match=r"pressure: expected shape \(16, 16\)"):
        call(pressure=p[:8])
    with pytest.raises(ValueError, match="contact: expected a bool mask"):
        call(contact=(p > 0).astype(int))
    with pytest.raises(ValueError, match="tol: must be finite and > 0, got 0.0"):
        call(tol=0.0)
    with pytest.raises(ValueError, match="max_iter: must be >= 1"):
        call(max_iter=0)
    with pytest.raises(ValueError, match=r"initial: expected shape \(2, 16, 16\)"):
        call(initial=np.zeros((16, 16)))
    with pytest.raises(ValueError, match=r"pressure_displacement: expected shape \(2, 16, 16\)"):
        call(pressure_displacement=np.zeros((1, 16, 16)))
    with pytest.raises(ValueError, match="contact: a stuck contact with a tangential force needs"):
        call(contact=np.zeros_like(p, dtype=bool), stuck=True, friction=math.inf)

"""The linearised contact and the scan Jacobian: dot tests and finite differences of the full solve.

Oracles: the non-linear solve itself (``solve_contact`` at perturbed heights, force or modulus,
with the contact set unchanged: the pressure is then affine in the heights), and the adjoint
identity <J x, y> = <x, J^T y>.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.forward import AccuracyWarning, ContactCompliance, ContactLinearisation, HalfSpace, dottest, solve_contact
from tactilab.inversion.surface_jacobian import ScanJacobian
from tactilab.inversion.surface_scan import ContactScan, ProfileGrid

E, R = 1e6, 10e-3


def _sphere(n, dx, rng, rough=0.2e-6):
    x = (np.arange(n) - n // 2) * dx
    xx, yy = np.meshgrid(x, x)
    return (xx**2 + yy**2) / (2 * R) - rough * rng.standard_normal((n, n))


def test_linearisation_matches_finite_differences_of_the_solve(rng):
    n, dx, force = 48, 40e-6, 0.03
    skin = HalfSpace(E=E, nu=0.5)
    gap = _sphere(n, dx, rng)
    sol = solve_contact(skin, gap, dx, normal_force=force, tol=1e-13)
    lin = ContactLinearisation(ContactCompliance(skin, (n, n), (dx, dx), False), sol.contact, force_control=True)
    dh = 1e-10 * rng.standard_normal((n, n))
    moved = solve_contact(skin, gap - dh, dx, normal_force=force, tol=1e-14, initial=sol)
    assert np.array_equal(moved.contact, sol.contact)
    dp = lin.solve(dh)
    assert np.abs(moved.pressure - sol.pressure - dp).max() < 1e-6 * np.abs(dp).max()
    assert np.all(dp[~sol.contact] == 0) and abs(dp.sum()) < 1e-9 * np.abs(dp).sum()
    # the force response: sum 1, and the pressure change of a (slightly) larger force
    f = lin.force_response()
    assert f.sum() == pytest.approx(1.0, rel=1e-10)
    step = 1e-6 * force
    up = solve_contact(skin, gap, dx, normal_force=force + step, tol=1e-14, initial=sol)
    down = solve_contact(skin, gap, dx, normal_force=force - step, tol=1e-14, initial=sol)
    fd = (up.pressure - down.pressure) / (2 * step / dx**2)
    assert np.abs(fd - f).max() < 1e-5 * np.abs(f).max()


def test_linearisation_is_symmetric_and_batched(rng):
    n, dx = 32, 40e-6
    skin = HalfSpace(E=E, nu=0.5)
    comp = ContactCompliance(skin, (n, n), (dx, dx), False)
    sols = [solve_contact(skin, _sphere(n, dx, rng), dx, normal_force=0.01, tol=1e-12) for _ in range(3)]
    lin = ContactLinearisation(comp, np.stack([s.contact for s in sols]), force_control=True)
    a, b = rng.standard_normal((2, 3, n, n))
    sa, sb = lin.solve(a), lin.solve(b)
    assert np.sum(sa * b) == pytest.approx(np.sum(a * sb), rel=1e-9)
    one = ContactLinearisation(comp, sols[1].contact, force_control=True).solve(a[1])
    assert np.allclose(sa[1], one, rtol=0, atol=1e-9 * np.abs(one).max())
    assert np.allclose(lin.solve(a[1:2], frames=[1])[0], one, rtol=0, atol=1e-9 * np.abs(one).max())


def test_linearisation_refuses_bad_input():
    skin = HalfSpace(E=E, nu=0.5)
    comp = ContactCompliance(skin, (8, 8), (1e-4, 1e-4), False)
    mask = np.zeros((8, 8), dtype=bool)
    mask[3:5, 3:5] = True
    with pytest.raises(ValueError, match="compliance: expected a ContactCompliance"):
        ContactLinearisation(skin, mask, force_control=True)
    with pytest.raises(ValueError, match="contact: expected a boolean mask of shape"):
        ContactLinearisation(comp, mask.astype(float), force_control=True)
    with pytest.raises(ValueError, match="contact: a set is empty"):
        ContactLinearisation(comp, np.zeros((8, 8), dtype=bool), force_control=True)
    lin = ContactLinearisation(comp, mask, force_control=False)
    with pytest.raises(ValueError, match="rhs: expected finite values of shape"):
        lin.solve(np.full((8, 8), np.nan))
    with pytest.raises(ValueError, match="frames: need 1 indices"):
        lin.solve(np.ones((8, 8)), frames=[3])
    with pytest.raises(ValueError, match="force_control: the force response needs"):
        lin.force_response()
    stacked = ContactLinearisation(comp, np.stack([mask, mask]), force_control=True)
    with pytest.raises(ValueError, match="rhs: 3 right-hand sides for 2 contact sets"):
        stacked.solve(np.ones((3, 8, 8)))


def _scan(rng, quantity="stress", geometry="line", n=24, dx=40e-6, frames=4):
    x = (np.arange(n) - n // 2) * dx
    xx, yy = np.meshgrid(x, x)
    pos = np.arange(frames) * 2 * dx
    px = np.arange(x[0] + pos[0] - dx, x[-1] + pos[-1] + 2 * dx, dx)
    profile = ProfileGrid(x=px, y=None if geometry == "line" else x.copy())
    w_p, w_q = rng.standard_normal((2, n * n, 3))
    scan = ContactScan(young_modulus=E, poisson_ratio=0.5, grid_shape=(n, n), spacing=dx,
                       shape_gap=(xx**2 + yy**2) / (2 * R), positions=pos, weights_p=w_p, weights_q=w_q,
                       profile=profile, normal_force=0.008, friction=0.4, tol=1e-13, quantity=quantity)
    heights = 0.3e-6 * rng.standard_normal(profile.shape)
    return scan, heights, scan.solve(heights)


@pytest.mark.parametrize("quantity", ["stress", "strain"])
@pytest.mark.parametrize("geometry", ["line", "patch"])
def test_scan_jacobian_dot_test_and_explicit_matrix(rng, quantity, geometry):
    scan, _, state = _scan(rng, quantity, geometry)
    # solves to 1e-12 (the default 1e-8 is an accuracy choice): the dot test checks the adjoint's formula
    jac = ScanJacobian(scan, state, free=("normal_force", "friction", "young_modulus"), tol=1e-12)
    assert dottest(jac, rng, rtol=1e-8) < 1e-8
    v = rng.standard_normal(jac.shape[1])
    dense = jac.matrix()
    # two threads, each a contiguous run of the frames' sets with its own solver: the same matrix
    two = ScanJacobian(scan, state, free=("normal_force", "friction", "young_modulus"), tol=1e-12, workers=2)
    two.lin.chunk = scan.n_out  # one set per chunk: 4 chunks, 2 runs
    assert two._distinct()[0].size == scan.n_frames == 4
    assert np.abs(two.matrix() - dense).max() < 1e-9 * np.abs(dense).max()
    assert np.abs(dense @ v - jac.matvec(v)).max() < 1e-9 * np.abs(dense @ v).max()
    # a fresh operator's adjoint reads the force and modulus columns without the force responses
    # (<f, g> = <f0, g> - <A f0, S g>): the same as the matrix built from them
    y = rng.standard_normal(jac.shape[0])
    fresh = ScanJacobian(scan, state, free=("normal_force", "friction", "young_modulus"), tol=1e-12)
    got = fresh.rmatvec(y)
    want = dense.T @ y
    assert fresh._force is None and np.abs(got - want).max() < 1e-9 * np.abs(want).max()
    assert np.allclose(got[-3:], want[-3:], rtol=1e-8, atol=0)


def test_an_adjoint_started_from_an_earlier_one_gives_the_same_gradient(rng):
    """ScanJacobian.adjoint(y, initial=...): started from another iterate's solves (other heights,
    other residuals) it returns rmatvec's gradient to the solves' tolerance, and its solves."""
    scan, heights, state = _scan(rng)
    free = ("normal_force", "friction")
    y = rng.standard_normal(scan.n_frames * scan.n_out)
    want = ScanJacobian(scan, state, free=free, tol=1e-12).rmatvec(y)
    other = scan.solve(heights + 0.05e-6 * rng.standard_normal(heights.shape))
    _, start = ScanJacobian(scan, other, free=free, tol=1e-12).adjoint(y + 0.1 * rng.standard_normal(y.shape))
    got, solves = ScanJacobian(scan, state, free=free, tol=1e-12).adjoint(y, initial=start)
    assert np.abs(got - want).max() < 1e-9 * np.abs(want).max()
    assert solves.shape == (scan.n_frames, *scan.grid_shape) and not solves[~state.contact].any()


@pytest.mark.parametrize("quantity", ["stress", "strain"])
def test_scan_jacobian_matches_finite_differences(rng, quantity):
    scan, heights, state = _scan(rng, quantity)
    free = ("normal_force", "friction", "young_modulus")
    jac = ScanJacobian(scan, state, free=free)
    dh = 1e-10 * rng.standard_normal(heights.shape)
    moved = scan.solve(heights + dh)
    assert np.array_equal(moved.contact, state.contact)
    lin = jac.matvec(np.concatenate([dh.ravel(), np.zeros(3)]))
    assert np.abs((moved.outputs - state.outputs).ravel() - lin).max() < 1e-6 * np.abs(lin).max()
    for k, name in enumerate(free):
        step = 1e-6 * max(state.context[name], 1.0 if name == "friction" else 0.0)
        up, down = (scan.solve(heights, {name: state.context[name] + s}) for s in (step, -step))
        fd = (up.outputs - down.outputs).ravel() / (2 * step)
        col = jac.matvec(np.eye(jac.shape[1])[scan.profile.size + k])
        assert np.abs(fd - col).max() < 1e-5 * np.abs(col).max(), name


def test_scan_refuses_bad_input(rng):
    scan, heights, state = _scan(rng)
    with pytest.raises(ValueError, match="heights: expected finite values of shape"):
        scan.solve(heights[:-1])
    with pytest.raises(ValueError, match="context: unknown parameter 'depth'"):
        scan.solve(heights, {"depth": 1e-3})
    with pytest.raises(ValueError, match="profile: the frames read the surface at x in"):
        ContactScan(young_modulus=E, poisson_ratio=0.5, grid_shape=scan.grid_shape, spacing=scan.spacing,
                    shape_gap=scan.shape_gap, positions=scan.positions + 1e-3, weights_p=scan.weights_p,
                    weights_q=scan.weights_q, profile=scan.profile, normal_force=0.008)
    kwargs = dict(young_modulus=E, grid_shape=scan.grid_shape, spacing=scan.spacing, shape_gap=scan.shape_gap,
                  positions=scan.positions, weights_p=scan.weights_p, weights_q=scan.weights_q, profile=scan.profile)
    with pytest.raises(ValueError, match="poisson_ratio: the surface inversion solves frictionless frames"):
        ContactScan(poisson_ratio=0.3, normal_force=0.008, friction=0.5, **kwargs)
    with pytest.raises(ValueError, match="normal_force, mean_pressure: give exactly one"):
        ContactScan(poisson_ratio=0.5, **kwargs)
    with pytest.raises(ValueError, match="weights_p: expected finite weights of shape"):
        ContactScan(poisson_ratio=0.5, normal_force=0.008, **dict(kwargs, weights_p=scan.weights_p[:-1]))
    with pytest.raises(ValueError, match="shape_gap: expected shape"):
        ContactScan(poisson_ratio=0.5, normal_force=0.008, **dict(kwargs, shape_gap=scan.shape_gap[:-1]))


def test_windowed_chunked_solve_equals_the_dense_restricted_system(rng):
    """Oracle: the bordered system ``[A_CC -1; 1^T 0] [dp; d_delta] = [dh_C; 0]`` solved densely, with
    ``A`` built column by column from the compliance's products on the whole grid; the linearisation
    solves on windows around the contact sets (smaller than the grid here), in chunks."""
    n, dx = 24, 40e-6
    skin = HalfSpace(E=E, nu=0.5)
    comp = ContactCompliance(skin, (n, n), (dx, dx), False)
    sols = [solve_contact(skin, _sphere(n, dx, rng), dx, normal_force=f, tol=1e-12) for f in (0.002, 0.004, 0.003)]
    masks = np.stack([s.contact for s in sols])
    assert not masks.any(axis=0)[0].any()  # the sets leave a margin: the windows are smaller than the grid
    A = np.column_stack([comp.normal(e.reshape(n, n)).ravel() for e in np.eye(n * n)])
    rhs = rng.standard_normal((3, n, n))
    lin = ContactLinearisation(comp, masks, force_control=True, tol=1e-13, chunk=2)
    got = lin.solve(rhs)
    for k in range(3):
        c = np.flatnonzero(masks[k].ravel())
        m = c.size
        K = np.zeros((m + 1, m + 1))
        K[:m, :m], K[:m, m], K[m, :m] = A[np.ix_(c, c)], -1.0, 1.0
        sol = np.linalg.solve(K, np.concatenate([rhs[k].ravel()[c], [0.0]]))
        want = np.zeros(n * n)
        want[c] = sol[:m]
        assert np.abs(got[k].ravel() - want).max() < 1e-9 * np.abs(want).max()
    # a start at the answer converges at once; a start elsewhere to the same answer
    again = lin.solve(rhs, initial=got)
    assert lin.last_iterations <= 1 and np.abs(again - got).max() < 1e-9 * np.abs(got).max()
    other = lin.solve(rhs, initial=rng.standard_normal(rhs.shape))
    assert np.abs(other - got).max() < 1e-9 * np.abs(got).max()
    # two FFT threads: the same solves (the threads split the stack)
    two = ContactLinearisation(comp, masks, force_control=True, tol=1e-13, chunk=2, workers=2).solve(rhs)
    assert np.abs(two - got).max() < 1e-12 * np.abs(got).max()
    with pytest.raises(ValueError, match="workers: threads must be a positive integer"):
        ContactLinearisation(comp, masks, force_control=True, workers=0)
    with pytest.raises(ValueError, match="initial: expected finite values of the shape of rhs"):
        lin.solve(rhs, initial=np.zeros((2, n, n)))
    with pytest.raises(ValueError, match="chunk: right-hand sides per batched solve must be >= 1"):
        ContactLinearisation(comp, masks, force_control=True, chunk=0)


@pytest.mark.parametrize("tol", [1e-4, 1e-6, 1e-10])
def test_float32_iterations_meet_the_tolerance_in_float64(rng, tol):
    """dtype=float32: the single-precision passes are refined until the float64 residual of the
    restricted system (projected on the zero-sum fields of the set, with the dense compliance) is
    below tol, also far below float32's round-off (1e-10: several passes); started or not."""
    n, dx = 24, 40e-6
    skin = HalfSpace(E=E, nu=0.5)
    comp = ContactCompliance(skin, (n, n), (dx, dx), False)
    sols = [solve_contact(skin, _sphere(n, dx, rng), dx, normal_force=f, tol=1e-12) for f in (0.002, 0.004, 0.003)]
    masks = np.stack([s.contact for s in sols])
    A = np.column_stack([comp.normal(e.reshape(n, n)).ravel() for e in np.eye(n * n)])
    rhs = rng.standard_normal((3, n, n))
    want = ContactLinearisation(comp, masks, force_control=True, tol=1e-13).solve(rhs)
    single = ContactLinearisation(comp, masks, force_control=True, tol=tol, chunk=2, dtype=np.float32)
    for start in (None, want + 0.01 * np.abs(want).max() * rng.standard_normal(want.shape) * masks):
        got = single.solve(rhs, initial=start)
        assert got.dtype == np.float64 and not got[~masks].any()
        for k in range(3):
            c = np.flatnonzero(masks[k].ravel())
            b = rhs[k].ravel()[c] - rhs[k].ravel()[c].mean()
            r = rhs[k].ravel()[c] - A[np.ix_(c, c)] @ got[k].ravel()[c]
            assert np.linalg.norm(r - r.mean()) <= tol * np.linalg.norm(b)
            assert abs(got[k].sum()) < 1e-9 * np.abs(got[k]).sum()
        assert np.abs(got - want).max() < 1e3 * tol * np.abs(want).max()
    with pytest.raises(ValueError, match="dtype: expected float32 or float64, got float16"):
        ContactLinearisation(comp, masks, force_control=True, dtype=np.float16)
    capped = ContactLinearisation(comp, masks, force_control=True, tol=tol, max_iter=1, dtype=np.float32)
    with pytest.warns(AccuracyWarning, match="did not reach tol .* in 6 float32 passes of at most 1 iterations"):
        capped.solve(rhs)


@pytest.mark.parametrize("shape, periodic", [((64,), True), ((64,), False), ((32, 32), True)])
def test_float32_iterations_on_periodic_and_line_grids(rng, shape, periodic):
    """The float32 passes on the other products (periodic cells, 1-D grids): the float64 solve's answer
    to the tolerance (1e-8: several passes)."""
    skin = HalfSpace(E=E, nu=0.5)
    comp = ContactCompliance(skin, shape, (20e-6,) * len(shape), periodic)
    mask = rng.random(shape) < 0.6
    rhs = rng.standard_normal((3, *shape))
    want = ContactLinearisation(comp, mask, force_control=True, tol=1e-13).solve(rhs)
    got = ContactLinearisation(comp, mask, force_control=True, tol=1e-8, dtype=np.float32).solve(rhs)
    assert np.abs(got - want).max() < 1e-6 * np.abs(want).max()


def test_frames_with_one_contact_set_share_their_solves(rng):
    """At a flat surface every frame has the finger's own contact: matrix() solves one frame and
    reads it into every frame's rows (each through its own interpolation), as matvec does frame by frame."""
    scan, heights, _ = _scan(rng)
    state = scan.solve(np.zeros_like(heights))
    jac = ScanJacobian(scan, state, free=("normal_force", "friction"))
    first, which = jac._distinct()
    assert first.tolist() == [0] and np.all(which == 0)
    dense = jac.matrix()
    cols = np.column_stack([jac.matvec(e) for e in np.eye(jac.shape[1])])
    assert np.abs(dense - cols).max() < 1e-7 * np.abs(cols).max()
    assert np.abs(dense[: scan.n_out]).max() > 0 and np.abs(dense[-scan.n_out:]).max() > 0

"""Block conjugate gradients (forward/contact/block_cg.py) and the linearisation's grouped solves."""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.forward import ContactCompliance, ContactLinearisation, HalfSpace, solve_contact
from tactilab.forward.contact.block_cg import block_pcg

E, R = 1e6, 10e-3


def _sphere(n, dx, rng, rough=0.2e-6):
    x = (np.arange(n) - n // 2) * dx
    xx, yy = np.meshgrid(x, x)
    return (xx**2 + yy**2) / (2 * R) - rough * rng.standard_normal((n, n))


def test_block_pcg_equals_a_dense_solve_with_dependent_right_hand_sides(rng):
    """Oracle: ``numpy.linalg.solve`` per group; a repeated and a zero column break nothing."""
    g, s, m = 2, 5, 30
    mats = []
    for _ in range(g):
        q = rng.standard_normal((m, m))
        mats.append(q @ q.T + m * np.eye(m))
    mats = np.stack(mats)
    prec = 1.0 / np.einsum("gii->gi", mats)  # Jacobi
    b = rng.standard_normal((g, s, m))
    b[:, 3] = 2.0 * b[:, 1]  # dependent: the block's directions lose rank
    b[1, 4] = 0.0

    def apply(v, groups):
        return np.einsum("gij,gsj->gsi", mats[groups], v)

    def precondition(v, groups):
        return prec[groups][:, None, :] * v

    x, it, bad = block_pcg(apply, precondition, b, None, tol=1e-12, max_iter=200)
    want = np.stack([np.linalg.solve(mats[k], b[k].T).T for k in range(g)])
    assert bad == 0 and it <= m
    assert np.abs(x - want).max() < 1e-9 * np.abs(want).max()
    # a start at the answer needs no iteration
    again, it0, _ = block_pcg(apply, precondition, b, want, tol=1e-9, max_iter=200)
    assert it0 == 0 and np.array_equal(again, want)


def test_grouped_solves_equal_independent_ones_with_fewer_iterations(rng):
    n, dx = 32, 40e-6
    skin = HalfSpace(E=E, nu=0.5)
    comp = ContactCompliance(skin, (n, n), (dx, dx), False)
    sols = [solve_contact(skin, _sphere(n, dx, rng), dx, normal_force=f, tol=1e-12) for f in (0.006, 0.01)]
    lin = ContactLinearisation(comp, np.stack([s.contact for s in sols]), force_control=True, tol=1e-11, chunk=8)
    x = (np.arange(n) - n // 2) * dx
    xx, yy = np.meshgrid(x, x)
    # smooth fields like a sensor's kernels (6 per set), on both sets
    rhs = np.stack([np.exp(-((xx - c) ** 2 + yy**2) / (2 * (0.3e-3) ** 2)) for c in np.linspace(-3e-4, 3e-4, 6)])
    rhs = np.stack([rhs, rhs[::-1]])
    one = lin.solve(rhs.reshape(12, n, n), frames=np.repeat([0, 1], 6)).reshape(rhs.shape)
    independent = lin.last_iterations
    got = lin.solve_groups(rhs, [0, 1])  # chunk 8: one group of 6 per chunk
    assert np.abs(got - one).max() < 1e-8 * np.abs(one).max()
    assert lin.last_iterations <= independent
    assert np.all(got[0][:, ~sols[0].contact] == 0)
    assert np.abs(got.sum(axis=(-2, -1))).max() < 1e-9 * np.abs(got).sum(axis=(-2, -1)).max()
    # symmetric: <S a, b> = <a, S b> per set
    a, b = rng.standard_normal((2, 2, 3, n, n))
    sa, sb = lin.solve_groups(a, [0, 1]), lin.solve_groups(b, [0, 1])
    assert np.sum(sa * b) == pytest.approx(np.sum(a * sb), rel=1e-9)
    # a start elsewhere reaches the same answer
    other = lin.solve_groups(rhs, [0, 1], initial=rng.standard_normal(rhs.shape))
    assert np.abs(other - got).max() < 1e-8 * np.abs(one).max()


def test_grouped_solves_refuse_bad_input(rng):
    n, dx = 16, 40e-6
    skin = HalfSpace(E=E, nu=0.5)
    comp = ContactCompliance(skin, (n, n), (dx, dx), False)
    sol = solve_contact(skin, _sphere(n, dx, rng), dx, normal_force=0.003, tol=1e-12)
    lin = ContactLinearisation(comp, sol.contact, force_control=True)
    with pytest.raises(ValueError, match=r"rhs: expected finite groups of shape \(g, s"):
        lin.solve_groups(np.zeros((2, n, n)), [0, 0])
    with pytest.raises(ValueError, match=r"rhs: expected finite groups"):
        lin.solve_groups(np.full((1, 2, n, n), np.nan), [0])
    with pytest.raises(ValueError, match="initial: expected finite values of the shape of rhs"):
        lin.solve_groups(np.zeros((1, 2, n, n)), [0], initial=np.zeros((1, 3, n, n)))
    with pytest.raises(ValueError, match="frames: need 1 indices"):
        lin.solve_groups(np.zeros((1, 2, n, n)), [3])

"""The normal solver's float32 clip correction (forward/contact/single_correction.py).

Oracles: the float64 compliance product :meth:`ContactCompliance.normal` (the correction is the same
operator in single precision: within its stated error bound, periodic and isolated, 2-D and plane
strain); the dot test (symmetric to float32 round-off); ``self_compliance`` for the origin value of
the bound; and the contact solver's answer and iterations with and without the float32 corrections and the float32
direction products (they change the path by round-off, not the solution: the float64 confirmation
stays).
"""

import functools

import numpy as np
import pytest

from tactilab.data_schemas import random_rough_surface
from tactilab.forward import HalfSpace, solve_contact
from tactilab.forward.contact import ContactCompliance
from tactilab.forward.contact.preconditioned import preconditioned_cg
from tactilab.forward.contact.single_correction import RELATIVE_ERROR, SingleCorrection

SKIN = HalfSpace(1e6, 0.5)
GRIDS = [((64, 48), True), ((64, 48), False), ((256,), True), ((256,), False)]


def _sparse(shape, count, rng):
    """A clip vector: ``count`` nodes at positive pressures (Pa), zero elsewhere."""
    c = np.zeros(shape)
    c.flat[rng.choice(c.size, count, replace=False)] = rng.random(count) * 1e4
    return c


@pytest.mark.parametrize(("shape", "periodic"), GRIDS)
def test_equals_the_float64_product_within_its_bound(shape, periodic, rng):
    C = ContactCompliance(SKIN, shape, 1e-6, periodic)
    single = SingleCorrection(C)
    c = _sparse(shape, 40, rng)
    exact = C.normal(c)
    error = float(np.abs(single.apply(c) - exact).max())
    nodes = np.flatnonzero(c)
    assert error <= single.bound(c.flat[nodes])  # the bound the solver relies on
    assert error <= 1e-6 * float(np.abs(exact).max())  # float32 round-off: measured 1.0e-7 to 1.8e-7
    assert single.bound(c.flat[nodes]) == pytest.approx(RELATIVE_ERROR * C.self_compliance[0] * c.sum(), rel=1e-12)


@pytest.mark.parametrize(("shape", "periodic"), GRIDS)
def test_dot_test_symmetric(shape, periodic, rng):
    single = SingleCorrection(ContactCompliance(SKIN, shape, 1e-6, periodic))
    a, b = _sparse(shape, 30, rng), _sparse(shape, 30, rng)
    left, right = float((single.apply(a) * b).sum()), float((a * single.apply(b)).sum())
    assert left == pytest.approx(right, rel=1e-5)


@pytest.mark.parametrize("periodic", [True, False])
def test_adds_in_place_and_leaves_its_work_arrays_zero(rng, periodic):
    """``add`` accumulates into ``u``; a second call with other nodes sees none of the first's (the
    scattered input is zeroed at its nodes only: the transform must leave it as it was)."""
    C = ContactCompliance(SKIN, (32, 32), 1e-6, periodic)
    single = SingleCorrection(C)
    a, b = _sparse((32, 32), 20, rng), _sparse((32, 32), 20, rng)
    u = np.ones((32, 32))
    for c in (a, b):
        nodes = np.flatnonzero(c)
        single.add(u, nodes, c.flat[nodes])
    np.testing.assert_allclose(u, 1.0 + C.normal(a + b), rtol=0, atol=1e-6 * float(np.abs(C.normal(a + b)).max()))
    assert not single._work()["scatter"].any()
    # correction() returns A c in float32, in a kept array that the next call overwrites
    nodes = np.flatnonzero(a)
    pending = single.correction(nodes, a.flat[nodes])
    assert pending.dtype == np.float32 and pending.flags.c_contiguous
    np.testing.assert_allclose(pending, C.normal(a), rtol=0, atol=single.bound(a.flat[nodes]))


def test_bad_input():
    single = SingleCorrection(ContactCompliance(SKIN, (16, 16), 1e-6, True))
    with pytest.raises(ValueError, match=r"c: expected the grid's shape \(16, 16\), got \(8, 8\)"):
        single.apply(np.zeros((8, 8)))


@pytest.mark.parametrize("periodic", [True, False])
def test_solver_answer_and_iterations_do_not_change(periodic, rng):
    """The float32 corrections replace float64 recomputes only while their accumulated error bound stays
    a hundredth of the residual: fewer products, the answer within the tolerance, and the iterations the
    same or a few more (a round-off change of the path: 31 and 33 measured on this cold isolated start,
    the same on the periodic one)."""
    n = 128
    h = random_rough_surface((n, n), 1e-6, rms_slope=0.1, hurst=0.8, rng=rng)
    g0 = -h
    if not periodic:
        x = (np.arange(n) - n // 2) * 1e-6
        g0 = g0 + (x[None, :] ** 2 + x[:, None] ** 2) / (2 * 2e-4)
    C = ContactCompliance(SKIN, (n, n), 1e-6, periodic)
    load = dict(total=5e3 * n * n, approach=None, tol=1e-10, max_iter=500, p0=np.ones((n, n)))
    on, off = (preconditioned_cg(C, g0, **load, single_corrections=s) for s in (True, False))
    assert on.converged and off.converged
    assert off.iterations <= on.iterations <= off.iterations + 2 and on.products < off.products
    assert float(np.abs(on.pressure - off.pressure).max()) <= 1e-6 * float(off.pressure.max())


def test_a_solve_with_single_corrections_keeps_its_tolerance(rng):
    """The facade's answer with and without: equal to the solver's tolerance (1e-8 here)."""
    h = random_rough_surface((64, 64), 1e-6, rms_slope=0.1, hurst=0.8, rng=rng)
    out = [solve_contact(SKIN, -h, 1e-6, mean_pressure=5e3, periodic=True, tol=1e-8,
                         method=functools.partial(preconditioned_cg, single_corrections=s)) for s in (True, False)]
    assert out[0].converged and out[1].converged
    np.testing.assert_allclose(out[0].pressure, out[1].pressure, rtol=0, atol=1e-6 * out[1].pressure.max())


@pytest.mark.parametrize("periodic", [True, False])
def test_dense_product_equals_the_float64_product_within_its_bound(rng, periodic):
    """The mixed-precision direction product: a dense, signed pressure on a periodic or isolated grid."""
    C = ContactCompliance(SKIN, (64, 48), 1e-6, periodic)
    single = SingleCorrection(C)
    t = rng.standard_normal((64, 48)) * 1e3
    exact = C.normal(t)
    out = np.full((64, 48), np.nan)
    assert single.product(t, out) is out
    peak = float(np.abs(out).max())
    assert float(np.abs(out - exact).max()) <= single.product_bound(peak)  # measured: 3e-7 of the peak
    # its kept grid is left zero: a clip correction after it sees nothing of t
    c = _sparse((64, 48), 20, rng)
    np.testing.assert_allclose(single.apply(c), C.normal(c), rtol=0, atol=single.bound(c[c > 0]))
    s = rng.standard_normal((64, 48))
    left, right = float((single.product(t, out.copy()) * s).sum()), float((t * single.product(s, out)).sum())
    assert left == pytest.approx(right, rel=1e-5)  # the dot test, to float32 round-off


@pytest.mark.parametrize(("shape", "periodic"), GRIDS[:2])
def test_solver_path_of_the_dense_product(rng, shape, periodic):
    """The solver's path: a float32 direction transformed as it is, its product returned in float32 (no
    conversion), equal to :meth:`SingleCorrection.product` bitwise; the direction left as it was."""
    single = SingleCorrection(ContactCompliance(SKIN, shape, 1e-6, periodic))
    t = rng.standard_normal(shape) * 1e3
    t32 = t.astype(np.float32)
    fast, energy = single.transform_direction(t32)
    fast = fast.copy()  # a kept array: the next call writes it
    np.testing.assert_array_equal(t32, t.astype(np.float32))
    # <A t, t> by Parseval from t's spectrum: the real-space sum of the float32 product as the oracle (to
    # float32 round-off), both paths of the multiplier's pass
    exact = float(np.sum(ContactCompliance(SKIN, shape, 1e-6, periodic).normal(t32.astype(float)) * t32))
    assert energy == pytest.approx(exact, rel=2e-6)
    again, twin = single.transform_direction(t32, compiled=False)
    np.testing.assert_array_equal(again, fast)
    assert twin == pytest.approx(energy, rel=1e-12)
    assert fast.dtype == np.float32 and fast.shape == shape and fast.flags.c_contiguous
    np.testing.assert_array_equal(fast.astype(float), single.product(t, np.empty(shape)))


@pytest.mark.parametrize(("shape", "periodic"), GRIDS[2:])
def test_dense_product_needs_a_2d_grid(shape, periodic):
    single = SingleCorrection(ContactCompliance(SKIN, shape, 1e-6, periodic))
    assert not single.dense_2d
    with pytest.raises(ValueError, match=r"product: float32 dense products need a 2-D grid, got a 1-D one"):
        single.product(np.zeros(shape), np.zeros(shape))


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("kind", ["fft", "two_level", "isolated"])
def test_solver_with_single_products_keeps_its_answer(monkeypatch, rng, compiled, kind):
    """Float32 direction products while their error bound stays a hundredth of the residual: the answer
    within the tolerance, the same iterations or up to two more, fewer float64 products; both kernel
    paths, periodic (both preconditioners) and isolated (a rough plate under a sphere; measured here:
    the same iterations, 20 to 40 % fewer float64 products)."""
    monkeypatch.setenv("TACTILAB_JIT", "1" if compiled else "0")
    n = 128
    h = random_rough_surface((n, n), 1e-6, rms_slope=0.1, hurst=0.8, rng=rng)
    g0, periodic = -h, kind != "isolated"
    if not periodic:
        x = (np.arange(n) - n // 2) * 1e-6
        g0 = g0 + (x[None, :] ** 2 + x[:, None] ** 2) / (2 * 2e-4)
    C = ContactCompliance(SKIN, (n, n), 1e-6, periodic)
    load = dict(total=5e3 * n * n, approach=None, tol=1e-10, max_iter=500, p0=np.ones((n, n)),
                preconditioner="fft" if not periodic else kind)
    on, off = (preconditioned_cg(C, g0, **load, single_products=s) for s in (True, False))
    assert on.converged and off.converged and on.residual <= 1e-10 * float(np.ptp(g0))
    assert off.iterations <= on.iterations <= off.iterations + 2 and on.products < off.products
    assert float(np.abs(on.pressure - off.pressure).max()) <= 1e-6 * float(off.pressure.max())
    assert on.approach == pytest.approx(off.approach, rel=0, abs=1e-8 * float(np.ptp(h)))


@pytest.mark.parametrize("periodic", [True, False])
def test_float32_stiffness_equals_the_exact_one(rng, periodic):
    """The preconditioner by a float32 pair: the float64 :meth:`ContactCompliance.stiffness` as the oracle
    (float32 round-off: measured 1e-7 of the peak), symmetric to that round-off (the dot test)."""
    C = ContactCompliance(SKIN, (64, 48), 1e-6, periodic)
    single = SingleCorrection(C)
    g, s = rng.standard_normal((2, 64, 48)) * 1e-6
    out = np.full((64, 48), np.nan)
    assert single.stiffness(g, out) is out
    exact = C.stiffness(g)
    assert float(np.abs(out - exact).max()) <= 1e-6 * float(np.abs(exact).max())
    out32 = np.full((64, 48), np.nan, np.float32)  # the solver's float32 output: the same values
    assert single.stiffness(g, out32) is out32
    np.testing.assert_array_equal(out32, out.astype(np.float32))
    left, right = float((single.stiffness(g, out.copy()) * s).sum()), float((g * single.stiffness(s, out)).sum())
    assert left == pytest.approx(right, rel=1e-5)


def test_kept_per_compliance_while_small():
    """Small grids' float32 products are kept per operator (the same object for the next solve), larger ones
    made per solve; a kept one does not keep its operator alive."""
    import gc

    from tactilab.forward.contact import single_correction

    small = ContactCompliance(SKIN, (64, 64), 1e-6, True)
    assert single_correction.kept(small) is single_correction.kept(small)
    large = ContactCompliance(SKIN, (1024, 1024), 1e-6, True)  # 18 MiB > KEPT_BYTES
    assert single_correction.kept(large) is not single_correction.kept(large)
    count = len(single_correction._KEPT)
    del small
    gc.collect()
    assert len(single_correction._KEPT) == count - 1


@pytest.mark.parametrize("periodic", [True, False])
def test_float32_point_loads_equal_the_float64_summation(monkeypatch, rng, periodic):
    """A few point loads summed from float32 coefficients (the solver's beside float32 corrections): the
    float64 direct summation as the oracle, within the stated bound (measured: 1e-8 to 3e-8 of the peak
    against a bound of 1e-6); corner and edge nodes (the periodic wrap-around and the padded windows); the
    compiled kernel and its NumPy twin bitwise equal."""
    shape = (24, 40)
    C = ContactCompliance(SKIN, shape, 1e-6, periodic)
    points = SingleCorrection(C).points
    nodes = np.concatenate([[0, shape[1] - 1, C.shape[0] * shape[1] - 1], rng.choice(24 * 40, 9, replace=False)])
    values = rng.random(nodes.size) * 1e4
    exact = np.zeros(shape)
    C.add_normal_point_loads(exact, nodes, values)
    out = {}
    for compiled in ("1", "0"):
        monkeypatch.setenv("TACTILAB_JIT", compiled)
        out[compiled] = np.full(shape, 1e-9)
        points.add(out[compiled], nodes, values)
    np.testing.assert_array_equal(out["1"], out["0"])
    error = float(np.abs(out["1"] - 1e-9 - exact).max())
    assert error <= points.bound(values)
    assert points.bound(values) <= 1e-5 * float(np.abs(exact).max())  # and not a vacuous one

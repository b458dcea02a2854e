"""The fused passes of the contact loop (forward/contact/kernels.py, step_kernels.py): compiled kernels against
their NumPy twins.

Oracle: the NumPy twin (the loop's original passes). Each pass gives bitwise the same arrays both
ways and the same sums to round-off (the compiled sums add in SIMD lanes, NumPy's in blocks); the
whole loop, :func:`preconditioned_cg`, gives the same iterates both ways: the same iteration and
product counts and pressures to 1e-12 of the peak, periodic and isolated, force and approach control,
plane strain and 2-D, cold and warm started.
"""

import functools

import numpy as np
import pytest

from tactilab.data_schemas import random_rough_surface
from tactilab.forward import HalfSpace, solve_contact
from tactilab.forward.contact import ContactCompliance, kernels, step_kernels
from tactilab.forward.contact.preconditioned import preconditioned_cg

SKIN = HalfSpace(1e6, 0.5)
SHAPE = (24, 36)  # not a multiple of the SIMD width: the kernels' tails run too


def _fields(rng, shape=SHAPE):
    """Random inputs of every pass, the pressure in contact at a third of the nodes."""
    a = {name: rng.standard_normal(shape) for name in ("g0", "u", "g", "r", "t", "z", "z_old", "At")}
    a["At32"] = rng.standard_normal(shape).astype(np.float32)
    a["p"] = np.where(rng.random(shape) < 1 / 3, rng.random(shape), 0.0)
    a["S"] = rng.random(shape) < 0.4
    return a


def _both(rng, run):
    """``run(arrays, compiled)`` on two copies of the same inputs; the two copies and the two outputs."""
    seed = int(rng.integers(2**31))
    out = {}
    for compiled in (True, False):
        arrays = _fields(np.random.default_rng(seed))
        out[compiled] = (arrays, run(arrays, compiled))
    return out[True], out[False]


def _same_arrays(x, y, names):
    for name in names:
        np.testing.assert_array_equal(x[name], y[name], err_msg=name)


@pytest.mark.parametrize("factor", [1.0, 1.25])
def test_gap_pass(rng, factor):
    inside = np.empty(SHAPE, bool)
    (x, cx), (y, cy) = _both(rng, lambda a, c: kernels.gap(a["g0"], a["u"], a["p"], a["g"], inside, factor, c))
    _same_arrays(x, y, ("g", "u", "p"))
    assert cx[0] == cy[0] == np.count_nonzero(x["p"] > 0)
    assert cx[1] == pytest.approx(cy[1], rel=1e-12)
    assert cx[2] == cy[2] == 0.0  # no pending correction


@pytest.mark.parametrize("factor", [1.0, 1.25])
def test_gap_pass_adds_a_pending_correction(rng, factor):
    """The float32 clip correction left pending by the previous step, added to u before the rescaling:
    u = (u + c) factor, against the same arithmetic in float64 (float32 widens exactly)."""
    inside = np.empty(SHAPE, bool)

    def run(a, c):
        a["u0"] = a["u"].copy()
        return kernels.gap(a["g0"], a["u"], a["p"], a["g"], inside, factor, c, pending=a["At32"])

    (x, cx), (y, cy) = _both(rng, run)
    _same_arrays(x, y, ("g", "u", "p"))
    np.testing.assert_array_equal(x["u"], (x["u0"] + x["At32"].astype(float)) * factor)
    np.testing.assert_array_equal(x["g"], x["g0"] + x["u"])
    assert cx[0] == cy[0] and cx[1] == pytest.approx(cy[1], rel=1e-12)
    assert cx[2] == cy[2] == float(np.abs(x["At32"]).max())  # max |c|: the correction's bound a posteriori


def test_residual_pass(rng):
    def run(a, c):
        inside = a["p"] > 0  # as the gap pass's twin leaves it
        return kernels.residual(a["g"], 0.3, a["p"], inside, a["S"], a["r"], c)

    (x, cx), (y, cy) = _both(rng, run)
    _same_arrays(x, y, ("g", "S", "r"))
    assert cx == cy  # a maximum and a count: exact
    assert cx[0] == np.abs(x["r"]).max() and cx[1] == np.count_nonzero(x["S"])


def test_residual_pass_float32(rng):
    """The float32 residual beside float32 products: g keeps it in float64 (S applied), r its rounding,
    max |r| of the unrounded values (the convergence test's), both paths."""
    def run(a, c):
        a["r"] = a["r"].astype(np.float32)
        a["g_in"] = a["g"].copy()
        return kernels.residual(a["g"], 0.3, a["p"], a["p"] > 0, a["S"], a["r"], c)

    (x, cx), (y, cy) = _both(rng, run)
    _same_arrays(x, y, ("g", "S", "r"))
    assert cx == cy
    shifted = x["g_in"] - 0.3
    np.testing.assert_array_equal(x["S"], (shifted < 0) | (x["p"] > 0))
    np.testing.assert_array_equal(x["g"], shifted * x["S"])
    np.testing.assert_array_equal(x["r"], x["g"].astype(np.float32))
    assert cx[0] == np.abs(x["g"]).max() and cx[1] == np.count_nonzero(x["S"])


@pytest.mark.parametrize("force", [True, False])
def test_project_pass(rng, force):
    def run(a, c):
        return kernels.project(a["z"], a["S"], int(np.count_nonzero(a["S"])), a["r"], a["z_old"], force, c)

    (x, cx), (y, cy) = _both(rng, run)
    np.testing.assert_allclose(x["z"], y["z"], rtol=1e-12, atol=1e-14)  # the mean is a sum
    assert np.all(x["z"][~x["S"]] == 0)
    if force:
        assert abs(x["z"].sum()) < 1e-12 * np.abs(x["z"]).sum()  # the mean on S removed
    np.testing.assert_allclose(cx, cy, rtol=1e-12)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("beta", [0.0, 0.7])
def test_direction_pass(rng, beta, dtype):
    """float64 vectors, or float32 ones beside float32 products: computed in float64, rounded once, and
    <r, t> of the stored t, on both paths."""
    def run(a, c):
        a["t"], a["z"] = a["t"].astype(dtype), a["z"].astype(dtype)
        a["t0"] = a["t"].astype(float)
        return kernels.direction(a["t"], a["z"], a["S"], beta, a["r"], c)

    (x, cx), (y, cy) = _both(rng, run)
    _same_arrays(x, y, ("t",))
    assert x["t"].dtype == dtype
    expected = x["t0"] * beta * x["S"] + x["z"] if beta > 0 else x["z"]
    np.testing.assert_array_equal(x["t"], expected.astype(dtype))
    assert cx == pytest.approx(cy, rel=1e-12)
    assert cx == pytest.approx(float(np.sum(x["r"] * x["t"].astype(float))), rel=1e-12)


@pytest.mark.parametrize("force", [True, False])
def test_project_pass_float32(rng, force):
    """The float32 preconditioned residual: (z - mean on S) S in float64, rounded once, the products of the
    rounded values, both paths."""
    def run(a, c):
        a["z"], a["z_old"] = a["z"].astype(np.float32), a["z_old"].astype(np.float32)
        a["z0"] = a["z"].astype(float)
        return kernels.project(a["z"], a["S"], int(np.count_nonzero(a["S"])), a["r"], a["z_old"], force, c)

    (x, cx), (y, cy) = _both(rng, run)
    np.testing.assert_allclose(x["z"], y["z"], rtol=1e-6, atol=1e-7)  # the mean is a sum: one rounding apart
    assert x["z"].dtype == np.float32 and np.all(x["z"][~x["S"]] == 0)
    mean = float((x["z0"] * x["S"]).sum()) / np.count_nonzero(x["S"]) if force else 0.0
    np.testing.assert_allclose(x["z"], ((x["z0"] - mean) * x["S"]).astype(np.float32), rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(cx, cy, rtol=1e-12)
    np.testing.assert_allclose(cx, [float(np.sum(x["r"] * x["z"].astype(float))),
                                    float(np.sum(x["r"] * x["z_old"].astype(float)))], rtol=1e-12)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_dot_pass(rng, dtype):
    a, b = rng.standard_normal(SHAPE).astype(dtype), rng.standard_normal(SHAPE).astype(dtype)
    exact = float(np.sum(a.astype(float) * b.astype(float)))
    for compiled in (True, False):
        assert step_kernels.dot(a, b, compiled) == pytest.approx(exact, rel=1e-12)


@pytest.mark.parametrize("nx", [36, 35])  # an even last axis (a Nyquist column) and an odd one
def test_scale_energy_pass(rng, nx):
    """The float32 product's multiplier pass: the spectrum scaled in place (as NumPy's complex64 times
    float32) and sum(m |T|^2) over the full spectrum by Parseval: the real-space <A t, t> of a real
    multiplier's product as the oracle (float32 round-off), both paths."""
    t = rng.standard_normal((24, nx)).astype(np.float32)
    m = rng.random((24, nx // 2 + 1)).astype(np.float32)
    m = (m + m[(-np.arange(24)) % 24]) / 2  # even in ky, so that the product of a real t is real
    out = {}
    for compiled in (True, False):
        spectrum = np.fft.rfft2(t).astype(np.complex64)
        before = spectrum.copy()
        energy = step_kernels.scale_energy(spectrum, m, nx % 2 == 0, compiled)
        np.testing.assert_array_equal(spectrum, before * m)
        out[compiled] = (energy, spectrum)
    assert out[True][0] == pytest.approx(out[False][0], rel=1e-12)
    At = np.fft.irfft2(out[True][1].astype(complex), s=(24, nx))
    assert out[True][0] / t.size == pytest.approx(float(np.sum(At * t)), rel=1e-5)


@pytest.mark.parametrize("product", ["At", "At32"])  # float64 vectors, or float32 ones and product
@pytest.mark.parametrize("room", [SHAPE[0] * SHAPE[1], 3])  # every clipped node recorded; the first three
def test_descend_pass(rng, room, product):
    def run(a, c):
        nodes, values = np.full(room, -1, np.int64), np.zeros(room)
        if product == "At32":
            a["t"] = a["t"].astype(np.float32)
        a["step"] = a["p"] - a["t"].astype(float) * 0.2
        a["u_step"] = a["u"] - a[product].astype(float) * 0.2
        m, total, peak = step_kernels.descend(a["p"], a["t"], 0.2, nodes, values, np.empty(SHAPE), True, a["u"],
                                              a[product], c)
        assert peak == float(np.abs(a[product]).max())  # the float32 product's bound: max |A t|
        return m, total, nodes, values

    (x, cx), (y, cy) = _both(rng, run)
    _same_arrays(x, y, ("p", "u"))
    np.testing.assert_array_equal(x["u"], x["u_step"])  # u -= tau A t in the same pass
    negative = np.flatnonzero(x["step"] < 0)
    assert cx[0] == cy[0] == negative.size > 3
    np.testing.assert_array_equal(x["p"], np.maximum(x["step"], 0.0))
    assert cx[1] == pytest.approx(cy[1], rel=1e-12) and cx[1] == pytest.approx(x["p"].sum(), rel=1e-12)
    k = min(negative.size, room)
    for nodes, values in (cx[2:], cy[2:]):  # the first k clipped nodes, in order, and what clipping added
        np.testing.assert_array_equal(nodes[:k], negative[:k])
        np.testing.assert_array_equal(values[:k], -x["step"].reshape(-1)[negative[:k]])


def test_nan_propagates_both_ways(rng):
    for compiled in (True, False):
        a = _fields(np.random.default_rng(5))
        a["g0"][3, 4] = np.nan
        a["p"][3, 4] = 1.0
        inside = np.empty(SHAPE, bool)
        n_in, total, _ = kernels.gap(a["g0"], a["u"], a["p"], a["g"], inside, 1.0, compiled)
        assert np.isnan(total)
        a["At32"][1, 1] = np.nan  # a NaN in a pending correction: its max, the drift's bound, turns NaN
        assert np.isnan(kernels.gap(a["g0"], a["u"], a["p"], a["g"], inside, 1.0, compiled, a["At32"])[2])
        residual, _ = kernels.residual(a["g"], 0.0, a["p"], a["p"] > 0, a["S"], a["r"], compiled)
        assert np.isnan(residual)
        a["At"][2, 2] = np.nan
        a["At32"][2, 2] = np.nan
        assert np.isnan(step_kernels.dot(a["At"], a["t"], compiled))  # the step tau turns NaN
        for product in (a["At"], a["At32"]):  # and so does the float32 bound's peak
            args = (a["p"].copy(), a["t"], 0.1, np.zeros(4, np.int64), np.zeros(4), np.empty(SHAPE), True, a["u"].copy())
            assert np.isnan(step_kernels.descend(*args, product, compiled)[2])
        a["t"][0, 0] = np.nan
        assert np.isnan(kernels.direction(a["t"], a["z"], a["S"], 0.5, a["r"], compiled) if a["S"][0, 0]
                        else step_kernels.dot(a["t"], a["r"], compiled))


# -- the whole loop -----------------------------------------------------------------------------
CASES = {  # name: (shape, periodic, force control, preconditioner; "auto" picks by the path, so not here)
    "periodic 2-D, force, exact stiffness": ((48, 64), True, True, "fft"),
    "periodic 2-D, force, two-level": ((48, 64), True, True, "two_level"),
    "periodic plane strain, force": ((256,), True, True, "fft"),
    "isolated 2-D, force": ((48, 48), False, True, "fft"),
    "isolated 2-D, approach": ((48, 48), False, False, "fft"),
    "isolated plane strain, force": ((256,), False, True, "fft"),
    "isolated plane strain, approach": ((256,), False, False, "fft"),
}
#: cases solved with float64 recomputes only: a line load under approach control moves its pressures
#: by round-off more than the others (see _agree), and float32 clip corrections (their 1e-7 of a
#: correction) more than a 2e-16 change of the gap, which is the yardstick here
FLOAT64_ONLY = {"isolated plane strain, approach"}


def _scene(shape, periodic, force, rng):
    """A rough surface (under a sphere or cylinder when isolated), its compliance and the load."""
    h = random_rough_surface(shape, 1e-6, rms_slope=0.1, hurst=0.8, rng=rng)
    g0 = -h
    if not periodic:
        axes = np.meshgrid(*[(np.arange(n) - n // 2) * 1e-6 for n in shape], indexing="ij")
        g0 = g0 + sum(x**2 for x in axes) / (2 * 2e-4)
    comp = ContactCompliance(SKIN, shape, 1e-6, periodic)
    if force:
        return comp, g0, dict(total=5e3 * np.prod(shape), approach=None)  # 5 kPa mean
    return comp, g0, dict(total=None, approach=float(np.quantile(g0, 0.2)))  # a fifth of the nodes reached


def _solve(monkeypatch, compiled, comp, g0, load, p0):
    monkeypatch.setenv("TACTILAB_JIT", "1" if compiled else "0")
    return preconditioned_cg(comp, g0, tol=1e-10, max_iter=500, p0=p0, **load)


def _agree(monkeypatch, comp, g0, load, p0):
    """Solve both ways from ``p0``; the NumPy twin again on ``g0`` changed by round-off (2e-16), whose
    spread is the problem's own sensitivity to round-off: plane strain under approach control (a line
    load's logarithmic displacement) moves its pressures by up to 3e-11 of the peak."""
    a, b = (_solve(monkeypatch, c, comp, g0, load, p0) for c in (True, False))
    c = _solve(monkeypatch, False, comp, g0 * (1 + 2e-16), load, p0)
    assert a.converged and b.converged
    assert (a.iterations, a.products) == (b.iterations, b.products)
    peak = b.pressure.max()
    spread = max(1e-12 * peak, 10 * float(np.abs(c.pressure - b.pressure).max()))
    assert float(np.abs(a.pressure - b.pressure).max()) <= spread
    assert a.approach == pytest.approx(b.approach, rel=1e-12, abs=spread / peak * float(np.ptp(g0)))
    return b


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_loop_gives_the_same_iterates_both_ways(monkeypatch, rng, case):
    shape, periodic, force, kind = CASES[case]
    comp, g0, load = _scene(shape, periodic, force, rng)
    load["preconditioner"] = kind
    load["single_corrections"] = case not in FLOAT64_ONLY
    # float32 direction products turn the paths' 1e-16 differences into float32 round-off (6e-8) at
    # once; both paths with them: tests/test_contact_single_correction.py
    load["single_products"] = False
    cold = _agree(monkeypatch, comp, g0, load, np.ones(shape))
    assert cold.iterations >= 10  # a real solve, with clipping and restarts
    # warm started from the solution shifted by one node
    warm = _agree(monkeypatch, comp, g0, load, np.roll(cold.pressure, 1, axis=-1))
    assert 2 <= warm.iterations < cold.iterations


@pytest.mark.parametrize("kind", ["fft", "two_level"])
def test_a_solve_gives_one_answer_both_ways(monkeypatch, rng, kind):
    """The facade (check solve, cascade of coarse starts, error estimate) agrees to its tolerance: a
    coarse start stopped at a loose tolerance may take one iteration more or less on one path. The
    preconditioner is named: "auto" takes the two-level one only where the kernels are compiled."""
    h = random_rough_surface((64, 64), 1e-6, rms_slope=0.1, hurst=0.8, rng=rng)
    method = functools.partial(preconditioned_cg, preconditioner=kind)
    out = []
    for compiled in (True, False):
        monkeypatch.setenv("TACTILAB_JIT", "1" if compiled else "0")
        out.append(solve_contact(SKIN, -h, 1e-6, mean_pressure=5e3, periodic=True, tol=1e-10, method=method))
    assert out[0].iterations == out[1].iterations
    np.testing.assert_allclose(out[0].pressure, out[1].pressure, rtol=0, atol=1e-9 * out[1].pressure.max())

"""The periodic solver's compiled kernels (tactilab.core.jit) against their NumPy twins.

The fused multiply-add (forward/halfspace/_hotpath.py) and the small-strain check's pass
(forward/halfspace/fields.py) must give the NumPy path's results: bitwise for the facade's rows
(stress and Hooke's law: each load enters an output as a real or an imaginary term, and the sums
run in the same order), to rounding for rows that mix both, and NaN wherever the NumPy path has it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactilab.core import jit
from tactilab.forward.halfspace import _hotpath
from tactilab.forward.halfspace.fields import compliance_matrix, largest_strain
from tactilab.forward.halfspace.loads import SurfaceLoad
from tactilab.forward.halfspace.spectral import periodic_stress

COMPS = ("xx", "yy", "zz", "yz", "zx", "xy")
SHAPES = [(24, 32), (25, 33), (7, 9), (1, 5), (64,), (65,)]


def _both_paths(monkeypatch, call):
    """``call()`` with the compiled kernels, then with the NumPy twins (the compiled ones must run)."""
    assert jit.enabled(), "the test extra installs numba: the compiled path must be exercised"
    monkeypatch.setenv("TACTILAB_JIT", "1")
    compiled = call()
    monkeypatch.setenv("TACTILAB_JIT", "0")
    numpy_twin = call()
    monkeypatch.setenv("TACTILAB_JIT", "1")
    return compiled, numpy_twin


def _load(rng, shape, names=("p", "qx", "qy")) -> SurfaceLoad:
    parts = {name: rng.normal(size=shape) * 1e3 for name in names if not (name == "qy" and len(shape) == 1)}
    return SurfaceLoad(**parts, spacing=1e-4, periodic=True)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_fused_multiply_add_gives_the_numpy_result(rng, monkeypatch, shape, dtype):
    load = _load(rng, shape)
    facade_rows = np.vstack([np.eye(6), compliance_matrix(2e5, 0.3) * 2e5])  # stress and strain x E
    mixed = np.vstack([rng.normal(size=(2, 6)), np.zeros(6)])  # loads entering both ways; an empty row
    eps = np.finfo(dtype).eps
    for weights, exact in ((facade_rows, True), (mixed, False)):
        got, want = _both_paths(monkeypatch, lambda: periodic_stress(load, [3e-4, 1e-3], 0.3, weights, dtype=dtype))
        assert got.dtype == want.dtype == dtype
        if exact:
            assert np.array_equal(got, want)
        else:
            np.testing.assert_allclose(got, want, rtol=0, atol=8 * eps * np.abs(want).max())
    assert _hotpath._multiply_add.signatures  # the compiled kernel ran


@pytest.mark.parametrize("names", [("p",), ("p", "qx"), ("qx", "qy"), ("p", "qx", "qy")])
def test_fused_multiply_add_with_one_two_or_three_loads_and_at_points(rng, monkeypatch, names):
    load = _load(rng, (12, 16), names)
    pts = rng.uniform(-6e-4, 6e-4, size=(5, 2))
    for points in (None, pts):
        got, want = _both_paths(monkeypatch, lambda: periodic_stress(load, [5e-4], 0.45, np.eye(6), points=points))
        np.testing.assert_allclose(got, want, rtol=0, atol=4 * np.finfo(float).eps * np.abs(want).max())


def test_fused_tables_are_cached_and_give_bitwise_the_fresh_result(rng, monkeypatch):
    load = _load(rng, (24, 32))
    weights = np.vstack([np.eye(6), rng.normal(size=(2, 6))])
    _hotpath.clear_transfer_cache()
    miss = periodic_stress(load, [3e-4, 1e-3], 0.3, weights)
    assert all(isinstance(out, _hotpath.FusedTerms) for entry in _hotpath._TRANSFER_CACHE.values() for out in entry)
    hit = periodic_stress(load, [3e-4, 1e-3], 0.3, weights)
    monkeypatch.setattr(_hotpath, "TRANSFER_CACHE_BYTES", 0)  # built one output at a time, per call
    assert np.array_equal(miss, hit) and np.array_equal(miss, periodic_stress(load, [3e-4, 1e-3], 0.3, weights))
    # real tables: half the memory of the NumPy path's complex ones for the facade's rows
    monkeypatch.setattr(_hotpath, "TRANSFER_CACHE_BYTES", 64 * 2**20)
    sizes = {}
    for path in ("1", "0"):
        monkeypatch.setenv("TACTILAB_JIT", path)
        _hotpath.clear_transfer_cache()
        periodic_stress(load, [1e-3], 0.3, np.eye(6))
        sizes[path] = sum(_hotpath._table_bytes(entry) for entry in _hotpath._TRANSFER_CACHE.values())
    assert sizes["1"] * 2 == sizes["0"]


@pytest.mark.parametrize("shape", [(2, 6, 25, 33), (1, 6, 7), (3, 6, 1030), (1, 6, 1)])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_compiled_strain_check_gives_the_numpy_bound(rng, monkeypatch, shape, dtype):
    values = (rng.normal(size=shape) * 1e3).astype(dtype)
    for quantity, comps in [("stress", COMPS), ("strain", COMPS), ("stress", COMPS[3:]), ("stress", COMPS[:3]),
                            ("stress", ("zz", "xy")), ("strain", ("yy",))]:
        field = values[:, [COMPS.index(c) for c in comps]]
        got, want = _both_paths(monkeypatch, lambda: largest_strain(field, quantity, comps, 2e5, 0.45))
        assert got == want, (quantity, comps)
    strided = values[:, ::-1]  # not contiguous: the NumPy twin (a copy for the kernel could be large)
    got, want = _both_paths(monkeypatch, lambda: largest_strain(strided, "stress", COMPS[::-1], 2e5, 0.45))
    assert got == want


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_compiled_strain_check_flags_nan_and_inf_anywhere(monkeypatch, dtype):
    """NaN in any component, at any depth, in any block of the kernel (the last one partial) is NaN."""
    comps = COMPS
    for bad in (np.nan, -np.nan, np.inf, -np.inf):
        for k in range(6):
            for where in [(0, 0), (1, 1029), (1, 600)]:
                values = np.ones((2, 6, 1030), dtype)
                values[where[0], k, where[1]] = bad
                for quantity in ("stress", "strain"):
                    with np.errstate(invalid="ignore"):  # the NumPy twin's inf - inf
                        got, want = _both_paths(monkeypatch,
                                                lambda: largest_strain(values, quantity, comps, 1e6, 0.45))
                    if math.isnan(bad) or quantity == "stress" and k < 3:  # inf - inf in the trace is NaN
                        assert math.isnan(got) and math.isnan(want), (bad, k, where, quantity)
                    else:
                        assert got == want == math.inf, (bad, k, where, quantity)


@pytest.mark.parametrize("shape", [(20, 24), (21, 15), (48,)])
@pytest.mark.parametrize("tol", [1e-9, 1e-3])  # float64, float32
def test_the_facade_gives_the_same_answer_on_both_paths(rng, monkeypatch, shape, tol):
    from tactilab.forward import HalfSpace

    load = _load(rng, shape)
    hs = HalfSpace(E=1e6, nu=0.45)
    for quantity in ("stress", "strain"):
        def call():
            result = getattr(hs, quantity)(load, [2e-4, 1e-3], method="spectral", tol=tol)
            return result.data[quantity].values, result.error_estimate

        (got, got_err), (want, want_err) = _both_paths(monkeypatch, call)
        assert np.array_equal(got, want) and got_err == want_err, quantity

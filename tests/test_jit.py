"""The compiled-kernel switch (tactilab.core.jit): one place decides numba or NumPy."""

import numpy as np
import pytest

from tactilab.core import jit


def _axpy(a, x, y, out):
    for i in range(x.size):
        out[i] = a * x[i] + y[i]


def test_enabled_follows_the_environment(monkeypatch):
    monkeypatch.setenv("TACTILAB_JIT", "0")
    assert not jit.enabled()
    monkeypatch.setenv("TACTILAB_JIT", "1")
    assert jit.enabled() == jit.available()
    monkeypatch.delenv("TACTILAB_JIT")
    assert jit.enabled() == jit.available()


def test_njit_gives_the_numpy_result_nan_included():
    f = jit.njit(_axpy)
    x = np.array([1.0, np.nan, np.inf, -2.0])
    y = np.array([0.5, 1.0, 1.0, np.nan])
    out = np.empty(4)
    f(2.0, x, y, out)
    np.testing.assert_array_equal(out, 2.0 * x + y)  # NaN and inf propagate as in NumPy (no fastmath)


def test_without_numba_njit_returns_the_function(monkeypatch):
    monkeypatch.setattr(jit, "_numba", None)
    assert jit.njit(_axpy) is _axpy
    assert not jit.available() and not jit.enabled()


def test_the_test_environment_compiles():
    # the test extra installs numba: both paths of every kernel run in the suite
    assert jit.available()
    assert hasattr(jit.njit(_axpy), "py_func")


def _total(x):
    s = 0.0
    for i in range(x.size):
        s += x[i]
    return s


def test_reassociated_sums_agree_to_round_off_and_keep_nan(rng):
    f = jit.njit(reassociate=True)(_total)
    x = rng.standard_normal(1001)
    assert f(x) == pytest.approx(x.sum(), rel=1e-12, abs=1e-12)
    x[500] = np.nan
    assert np.isnan(f(x))  # only reassoc: no nnan flag, so NaN still propagates
    x[500] = np.inf
    assert f(x) == np.inf


def test_without_numba_reassociated_njit_returns_the_function(monkeypatch):
    monkeypatch.setattr(jit, "_numba", None)
    assert jit.njit(reassociate=True)(_total) is _total

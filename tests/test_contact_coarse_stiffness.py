"""The two-level stiffness (forward/contact/coarse_stiffness.py), the normal solver's cheap preconditioner.

Oracles: the exact periodic stiffness ``E* |k| / 2`` (:meth:`ContactCompliance.stiffness`, itself the
tested inverse of the compliance): the two-level operator is symmetric (dot test), positive definite
and spectrally equivalent to it (generalised eigenvalues of the dense matrices); its stencil's fit
against ``|k| h / pi``; the compiled kernel against its NumPy twin; and the contact solver's answer
with either preconditioner (the preconditioner changes the path, not the solution).
"""

import numpy as np
import pytest
from scipy import linalg

from tactilab.core import jit
from tactilab.data_schemas import random_rough_surface
from tactilab.forward import HalfSpace
from tactilab.forward.contact import ContactCompliance
from tactilab.forward.contact import coarse_stiffness as cs
from tactilab.forward.contact.preconditioned import preconditioned_cg

E = 1.0e6


def dense(op, shape) -> np.ndarray:
    """The matrix of a grid operator, column by column."""
    eye = np.eye(int(np.prod(shape)))
    return np.stack([op(e.reshape(shape)).ravel() for e in eye], axis=1)


@pytest.mark.parametrize("shape", [(32, 32), (48, 64)])
def test_dot_test_symmetric(shape, rng):
    K2 = cs.TwoLevelStiffness(HalfSpace(E, 0.5), shape, 1e-4)
    a, b = rng.standard_normal(shape), rng.standard_normal(shape)
    assert float((K2(a) * b).sum()) == pytest.approx(float((a * K2(b)).sum()), rel=1e-12)


@pytest.mark.parametrize("nu", [0.3, 0.5])
def test_spectrally_equivalent_to_the_exact_stiffness(nu):
    """Generalised eigenvalues of (K2, K) on a 32^2 grid: the stencil's fit (0.81) at the Nyquist
    corner, up to 1.7 on the coarse grid's long waves (block means seen as a staircase); measured
    0.813 and 1.694. K2 is therefore positive definite, as a preconditioner must be."""
    shape = (32, 32)
    C = ContactCompliance(HalfSpace(E, nu), shape, 1e-4, True)
    M, K = dense(C.preconditioner("two_level"), shape), dense(C.stiffness, shape)
    assert np.abs(M - M.T).max() <= 1e-12 * np.abs(M).max()
    ev = linalg.eigh(M, K, eigvals_only=True)
    assert 0.80 <= ev.min() and ev.max() <= 1.75


def test_stencil_fit_bounds():
    """a + b lam against |k| h / pi over |k| h >= pi / 8: within STENCIL_BOUNDS (the fit's promise)."""
    k = np.linspace(-np.pi, np.pi, 512, endpoint=False)
    kx, ky = np.meshgrid(k, k)
    band = np.hypot(kx, ky) >= np.pi / 8
    lam = 4 * np.sin(kx / 2) ** 2 + 4 * np.sin(ky / 2) ** 2
    a, b = cs.STENCIL
    ratio = (a + b * lam[band]) / (np.hypot(kx, ky)[band] / np.pi)
    lo, hi = cs.STENCIL_BOUNDS
    assert lo - 5e-3 <= ratio.min() <= lo + 5e-3 and hi - 5e-3 <= ratio.max() <= hi + 5e-3


def test_longest_waves_are_nearly_exact():
    """On the grid's longest wave the coarse correction makes the energy that of the exact stiffness to
    about 20 % (a 256^2 grid: 1.195 measured); the stencil alone would give 30x too much."""
    n = 256
    C = ContactCompliance(HalfSpace(E, 0.5), (n, n), 1e-4, True)
    wave = np.cos(2 * np.pi * np.arange(n) / n)[None, :] * np.ones((n, 1))
    ratio = float((C.preconditioner("two_level")(wave) * wave).sum() / (C.stiffness(wave) * wave).sum())
    assert 1.0 <= ratio <= 1.25


def test_compiled_kernel_equals_its_numpy_twin(monkeypatch, rng):
    K2 = cs.TwoLevelStiffness(HalfSpace(E, 0.5), (64, 40), (2e-5, 2e-5))
    r = rng.standard_normal((64, 40))
    monkeypatch.setenv("TACTILAB_JIT", "1")
    fast = K2(r)
    monkeypatch.setenv("TACTILAB_JIT", "0")
    twin = K2(r)
    assert np.allclose(fast, twin, rtol=0, atol=1e-13 * np.abs(twin).max())
    out = np.empty_like(r)
    assert K2(r, out=out) is out and np.array_equal(out, twin)


@pytest.mark.parametrize("compiled", ["1", "0"])
def test_float32_input_and_output(monkeypatch, rng, compiled):
    """The solver's float32 residual and output beside float32 products: computed in float64 from the
    float32 values and rounded once, on both paths."""
    monkeypatch.setenv("TACTILAB_JIT", compiled)
    K2 = cs.TwoLevelStiffness(HalfSpace(E, 0.5), (64, 40), (2e-5, 2e-5))
    r32 = rng.standard_normal((64, 40)).astype(np.float32)
    out32 = np.empty((64, 40), np.float32)
    assert K2(r32, out=out32) is out32
    np.testing.assert_array_equal(out32, K2(r32.astype(float)).astype(np.float32))


@pytest.mark.parametrize("shape,spacing,periodic", [((64, 64), 1e-4, False), ((64,), 1e-4, True),
                                                    ((60, 64), 1e-4, True), ((64, 64), (1e-4, 2e-4), True),
                                                    ((8, 64), 1e-4, True)])
def test_auto_keeps_the_exact_stiffness_where_two_level_does_not_apply(shape, spacing, periodic):
    C = ContactCompliance(HalfSpace(E, 0.5), shape, spacing, periodic)
    assert C.preconditioner("auto") == C.stiffness
    with pytest.raises(ValueError, match="preconditioner: 'two_level' needs a periodic 2-D grid"):
        C.preconditioner("two_level")


def test_auto_is_two_level_on_periodic_grids_when_compiled(monkeypatch):
    C = ContactCompliance(HalfSpace(E, 0.5), (64, 32), 1e-4, True)
    monkeypatch.setenv("TACTILAB_JIT", "0")  # the NumPy twin costs nearly an FFT pair: auto keeps the exact one
    assert C.preconditioner() == C.stiffness
    monkeypatch.setenv("TACTILAB_JIT", "1")
    assert isinstance(C.preconditioner(), cs.TwoLevelStiffness) == jit.available()
    assert isinstance(C.preconditioner("two_level"), cs.TwoLevelStiffness)
    assert C.preconditioner("two_level") is C.preconditioner("two_level")  # built once, kept
    assert C.preconditioner("fft") == C.stiffness


def test_bad_inputs():
    C = ContactCompliance(HalfSpace(E, 0.5), (64, 64), 1e-4, True)
    with pytest.raises(ValueError, match=r"preconditioner: must be one of \('auto', 'fft', 'two_level'\), got 'x'"):
        C.preconditioner("x")
    with pytest.raises(ValueError, match="shape, spacing: the two-level stiffness needs a 2-D grid with both sides "
                                         "multiples of 8 \\(at least 16\\) and square pixels, got shape \\(60, 64\\)"):
        cs.TwoLevelStiffness(HalfSpace(E, 0.5), (60, 64), 1e-4)
    with pytest.raises(ValueError, match="spacing: grid spacing must be finite and > 0 m"):
        cs.TwoLevelStiffness(HalfSpace(E, 0.5), (64, 64), float("nan"))
    with pytest.raises(ValueError, match=r"gap: expected shape \(64, 64\) \(the grid\), got \(64, 63\)"):
        C.preconditioner()(np.zeros((64, 63)))


def test_solver_answer_does_not_depend_on_the_preconditioner(rng):
    """A rough periodic cell at about 10 % contact: both preconditioners converge to one pressure
    (to the solver's tolerance) and the two-level one needs at most a few more iterations."""
    n, h = 128, 1e-6
    es = E / 0.75
    g0 = -random_rough_surface((n, n), h, rms_slope=0.1, hurst=0.8, rng=rng)
    C = ContactCompliance(HalfSpace(E, 0.5), (n, n), h, True)
    kw = dict(total=0.005 * es * n * n, approach=None)  # the nodes' pressures sum to it: mean 0.005 E*
    out = {kind: preconditioned_cg(C, g0, tol=1e-10, max_iter=500, p0=np.zeros((n, n)), preconditioner=kind, **kw)
           for kind in ("fft", "two_level")}
    assert all(r.converged for r in out.values())
    p_fft, p_two = out["fft"].pressure, out["two_level"].pressure
    assert np.abs(p_two - p_fft).max() <= 1e-6 * p_fft.max()
    assert 0.03 < np.count_nonzero(p_two) / p_two.size < 0.5
    assert out["two_level"].iterations <= out["fft"].iterations + 8



def test_auto_takes_the_exact_stiffness_for_a_nearly_full_start(rng):
    """A start touching every node (full contact): "auto" uses the exact stiffness, which inverts the
    periodic compliance, so the answer is the full-contact closed form p = p_mean + K h (zero-mean part)
    to round-off, not only to the solver's tolerance; the two-level one stops at the tolerance."""
    n, h = 64, 1e-6
    es = E / 0.75
    height = random_rough_surface((n, n), h, rms_height=1e-9, hurst=0.8, rng=rng)
    C = ContactCompliance(HalfSpace(E, 0.5), (n, n), h, True)
    p_mean = 0.05 * es
    kh = C.stiffness(height)
    exact = p_mean + kh - kh.mean()
    assert exact.min() > 0  # full contact
    kw = dict(total=p_mean * n * n, approach=None, tol=1e-8, max_iter=200, p0=np.full((n, n), p_mean))
    auto = preconditioned_cg(C, -height, **kw)
    assert np.abs(auto.pressure - exact).max() <= 1e-12 * exact.max() and auto.iterations <= 2
    two = preconditioned_cg(C, -height, preconditioner="two_level", **kw)
    assert two.converged and np.abs(two.pressure - exact).max() <= 1e-6 * exact.max()

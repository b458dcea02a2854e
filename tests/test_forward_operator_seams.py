"""The seam between the forward operator and the inversion: one model convention.

``LoadToSensor.dims`` is the grid shape, ``loads`` names the load components and the model
vector is load-major. The inversion's penalties act per load component, and a circulant
forward operator takes the inversion's fft path.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from tactilab.forward import HalfSpace
from tactilab.inversion import invert_linear
from tactilab.inversion.operators import FourierDiagonal, as_fourier_diagonal, model_layout
from tactilab.inversion.penalties import penalty_matrix

HS = HalfSpace(1e6, 0.5)
DX = 1e-4


def _tikhonov(a: np.ndarray, d: np.ndarray, lmat: np.ndarray, lam: float) -> np.ndarray:
    """Dense reference: argmin ||A m - d||^2 + lam ||L m||^2 from the normal equations, with the
    inversion's tiny ``eps I`` on the null space of L (1e-12 of the mean diagonal of L^T L)."""
    n = a.shape[1]
    eps = 1e-12 * np.sum(lmat**2) / n
    stacked = np.vstack([a, np.sqrt(lam) * lmat, np.sqrt(lam * eps) * np.eye(n)])
    rhs = np.concatenate([d, np.zeros(stacked.shape[0] - len(d))])
    return np.linalg.lstsq(stacked, rhs, rcond=None)[0]


def test_operator_dims_are_the_grid_and_the_model_is_load_major(rng):
    op = HS.operator((6, 5), DX, depth=3e-4, components=("zz", "zx"), loads=("p", "qx"))
    assert op.dims == (6, 5) and op.loads == ("p", "qx") and op.model_shape == (2, 6, 5)
    assert op.shape == (2 * 30, 2 * 30) and op.dimsd == (2, 30)
    p, qx = rng.normal(size=(2, 6, 5))
    only_p = HS.operator((6, 5), DX, depth=3e-4, components=("zz", "zx"), loads=("p",))
    only_qx = HS.operator((6, 5), DX, depth=3e-4, components=("zz", "zx"), loads=("qx",))
    both = op @ np.concatenate([p.ravel(), qx.ravel()])
    np.testing.assert_allclose(both, only_p @ p.ravel() + only_qx @ qx.ravel(), rtol=1e-12, atol=1e-20)
    assert model_layout(op) == ((6, 5), 2)
    assert model_layout(only_p) == ((6, 5), 1)


def test_invert_linear_with_the_forward_operator_and_a_gradient_penalty(rng):
    # was: "too many values to unpack" (dims held the load axis)
    op = HalfSpace(1e6).operator((8, 8), 1e-4)
    truth = rng.normal(size=(8, 8))
    d = op @ truth.ravel()
    result = invert_linear(op, d, penalty="gradient", lam=1e-3)
    assert result.model.shape == (8, 8)
    a = op @ np.eye(64)
    lmat = penalty_matrix("gradient", (8, 8), 1e-4).toarray()  # the 2-D grid's gradient
    np.testing.assert_allclose(result.model.ravel(), _tikhonov(a, d, lmat, 1e-3), rtol=1e-7,
                               atol=1e-9 * np.abs(truth).max())


@pytest.mark.parametrize("method", ["dense", "iterative"])
def test_gradient_penalty_acts_per_load_component(rng, method):
    n = 24
    op = HS.operator((n,), DX, depth=2e-4, components=("zz", "zx"), loads=("p", "qx"))
    lmat = penalty_matrix("gradient", op.dims, op.spacing, n_fields=2)
    # block diagonal: a uniform p beside a different uniform qx costs nothing
    # (read as a 2 x n grid, the y difference between the rows would couple them)
    flat = np.concatenate([np.full(n, 1.0), np.full(n, 5.0)])
    assert np.abs(lmat @ flat).max() == 0.0
    one = penalty_matrix("gradient", (n,), DX).toarray()
    np.testing.assert_array_equal(lmat.toarray(), sp.block_diag([sp.csr_matrix(one), sp.csr_matrix(one)]).toarray())
    truth = np.vstack([np.exp(-((np.arange(n) - 12) / 4.0) ** 2), 0.3 * np.sin(np.arange(n) / 3.0)])
    d = op @ truth.ravel() + 1e-3 * rng.normal(size=op.shape[0])
    lam = 1e-8
    result = invert_linear(op, d, penalty="gradient", lam=lam, method=method, tol=1e-12, max_iter=20000)
    assert result.model.shape == (2, n)
    want = _tikhonov(op @ np.eye(2 * n), d, lmat.toarray(), lam)
    np.testing.assert_allclose(result.model.ravel(), want, rtol=1e-6, atol=1e-6 * np.abs(want).max())


def test_circulant_forward_operator_takes_the_fft_path(rng):
    op = HS.operator((12, 10), (DX, 1.5 * DX), depth=3e-4, components=("zx",), loads=("qx",),
                     quantity="strain", periodic=True)
    fd = as_fourier_diagonal(op)
    assert isinstance(fd, FourierDiagonal) and fd.dims == op.dims
    dense = op @ np.eye(120)
    np.testing.assert_allclose(fd.todense(), dense, rtol=0, atol=1e-13 * np.abs(dense).max())  # the same map
    d = op @ rng.normal(size=120)
    lam = 1e-20  # strain per Pa ~ 1e-6 against a gradient symbol up to 4 / dx^2 ~ 4e8 m^-2
    fast = invert_linear(op, d, penalty="gradient", lam=lam)
    slow = invert_linear(op, d, penalty="gradient", lam=lam, method="dense")
    assert fast.method == "fft" and slow.method == "dense"
    # the fft path's penalty is periodic, the dense one's has free ends: compare the fft path
    # with the dense solve of the periodic penalty instead
    lmat = penalty_matrix("gradient", op.dims, op.spacing, periodic=True).toarray()
    want = _tikhonov(dense, d, lmat, lam)
    np.testing.assert_allclose(fast.model.ravel(), want, rtol=1e-7, atol=1e-7 * np.abs(want).max())
    # not circulant: several loads, sensors off the full grid, or an isolated load
    for other in (HS.operator((8,), DX, loads=("p", "qx"), periodic=True),
                  HS.operator((8,), DX, sensors=np.array([0.0, DX]), periodic=True),
                  HS.operator((8,), DX)):
        assert as_fourier_diagonal(other) is other


def test_seam_errors_name_the_argument():
    with pytest.raises(ValueError, match="fourier_multiplier: the operator is not a periodic convolution"):
        HS.operator((8,), DX).fourier_multiplier()
    with pytest.raises(ValueError, match="n_fields: need a whole number >= 1"):
        penalty_matrix("gradient", (8,), DX, n_fields=0)
    with pytest.raises(ValueError, match=r"shape: penalties act on a 1-D \(nx,\) or 2-D"):
        penalty_matrix("gradient", (2, 8, 8), DX)
    op = HS.operator((8,), DX, components=("zz", "zx"), loads=("p", "qx"))
    with pytest.raises(ValueError, match="penalty: 'tv' acts on one load component"):
        invert_linear(op, np.zeros(op.shape[0]), penalty="tv", lam=1.0)

    class Stacked:  # an operator whose dims still hold the load axis (the old convention)
        shape = (16, 16)
        dims = (2, 8)
        loads = ("p", "qx")

    with pytest.raises(ValueError, match="operator: dims"):
        model_layout(Stacked())

"""Regularisation penalties ``||L m||^2`` (Tikhonov) and ``||D m||_1`` (total variation).

Each penalty is given two ways that agree exactly on a periodic grid: a Fourier symbol
``|L(k)|^2`` (for the FFT-diagonal path and the closed-form criteria) and a sparse matrix
(for the dense and matrix-free paths, periodic or with free ends).

- ``identity``: ``L = I`` (small loads), symbol 1.
- ``gradient``: forward difference ``(m[j+1] - m[j]) / dx`` (smooth loads), symbol
  ``4 sin^2(k dx / 2) / dx^2``, unit 1/m (summed over axes in 2-D).
- ``curvature``: second difference ``(m[j+1] - 2 m[j] + m[j-1]) / dx^2`` (very smooth loads),
  symbol ``(4 sin^2(k dx / 2) / dx^2)^2``, unit 1/m^2 (2-D: the discrete Laplacian).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from tactilab.forward.halfspace import angular_wavenumbers

PENALTIES = ("identity", "gradient", "curvature")

__all__ = ["PENALTIES", "check_penalty", "penalty_symbol", "penalty_matrix", "difference_matrix"]


def check_penalty(penalty: str) -> str:
    """Validate a penalty name; raise a ValueError naming the choices."""
    if penalty not in PENALTIES:
        raise ValueError(f"penalty: unknown penalty {penalty!r}; use one of {', '.join(PENALTIES)}")
    return penalty


def _spacings(shape, spacing) -> np.ndarray:
    s = np.atleast_1d(np.asarray(spacing, dtype=float))
    if s.size == 1:
        s = np.repeat(s, len(shape))
    return s


def penalty_symbol(penalty: str, shape: tuple[int, ...], spacing) -> np.ndarray:
    """Fourier symbol ``|L(k)|^2`` of a periodic penalty on the full grid (``fftfreq`` order).

    Parameters
    ----------
    penalty : {"identity", "gradient", "curvature"}
    shape : tuple of int
        Grid shape ``(nx,)`` or ``(ny, nx)``.
    spacing : float or (float, float)
        Grid spacing in m, ``dx`` or ``(dx, dy)``.

    Returns
    -------
    ndarray, shape ``shape``
        Non-negative real symbol; 1, 1/m^2 or 1/m^4 for identity, gradient, curvature.
    """
    check_penalty(penalty)
    shape = tuple(int(s) for s in shape)
    if penalty == "identity":
        return np.ones(shape)
    ks = angular_wavenumbers(shape, spacing)
    d = _spacings(shape, spacing)
    lap = np.zeros(shape)
    for k, h in zip(ks, d):  # both x first: (xi, eta) and (dx, dy)
        lap = lap + 4.0 * np.sin(k * h / 2.0) ** 2 / h**2
    return lap if penalty == "gradient" else lap**2


def difference_matrix(n: int, dx: float, order: int, periodic: bool) -> sp.csr_matrix:
    """Sparse 1-D difference matrix of order 0, 1 or 2 divided by ``dx**order``.

    Free ends (``periodic=False``) drop the rows that would wrap: shape (n - order, n).
    """
    if order == 0:
        return sp.identity(n, format="csr")
    stencil = {1: [-1.0, 1.0], 2: [1.0, -2.0, 1.0]}[order]
    offsets = list(range(len(stencil))) if order == 1 else [-1, 0, 1]
    if periodic:
        rows = np.repeat(np.arange(n), len(stencil))
        cols = (rows + np.tile(offsets, n)) % n
        vals = np.tile(stencil, n)
        mat = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
    else:
        m = n - order
        if m < 1:
            return sp.csr_matrix((0, n))
        start = 0 if order == 1 else 1
        rows = np.repeat(np.arange(m), len(stencil))
        cols = rows + start + np.tile(offsets, m)
        vals = np.tile(stencil, m)
        mat = sp.csr_matrix((vals, (rows, cols)), shape=(m, n))
    return (mat / dx**order).tocsr()


def penalty_matrix(penalty: str, shape: tuple[int, ...], spacing, periodic: bool = False,
                   n_fields: int = 1) -> sp.csr_matrix:
    """Sparse penalty matrix ``L`` acting on the flattened model (C order).

    With ``periodic=True`` ``L.T @ L`` is the circulant matrix of :func:`penalty_symbol`.

    Parameters
    ----------
    penalty : {"identity", "gradient", "curvature"}
    shape : tuple of int
        Grid shape ``(nx,)`` or ``(ny, nx)`` (an operator's ``dims``).
    spacing : float or (float, float)
        Grid spacing in m, ``dx`` or ``(dx, dy)``.
    periodic : bool
        Wrap the differences around the grid (else free ends).
    n_fields : int
        Load components stacked load-major in the model (an operator's ``len(loads)``): the
        penalty acts on each separately (block diagonal), never across components.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n_fields * n_rows, n_fields * prod(shape))
    """
    check_penalty(penalty)
    if int(n_fields) != n_fields or n_fields < 1:
        raise ValueError(f"n_fields: need a whole number >= 1 of load components, got {n_fields!r}; e.g. len(op.loads)")
    one = _grid_penalty_matrix(penalty, shape, spacing, periodic)
    if n_fields == 1:
        return one
    return sp.block_diag([one] * int(n_fields), format="csr")


def _grid_penalty_matrix(penalty: str, shape, spacing, periodic: bool) -> sp.csr_matrix:
    shape = tuple(int(s) for s in shape)
    if len(shape) not in (1, 2):
        raise ValueError(f"shape: penalties act on a 1-D (nx,) or 2-D (ny, nx) grid, got {shape}; "
                         "pass the grid shape (an operator's dims), not the stacked model shape")
    d = _spacings(shape, spacing)
    n = int(np.prod(shape))
    if penalty == "identity":
        return sp.identity(n, format="csr")
    if len(shape) == 1:
        return difference_matrix(shape[0], d[0], 1 if penalty == "gradient" else 2, periodic)
    ny, nx = shape
    dxm = difference_matrix(nx, d[0], 1, periodic)
    dym = difference_matrix(ny, d[1], 1, periodic)
    gx = sp.kron(sp.identity(ny), dxm)
    gy = sp.kron(dym, sp.identity(nx))
    if penalty == "gradient":
        return sp.vstack([gx, gy]).tocsr()
    if periodic:
        # Laplacian = -(Gx^T Gx + Gy^T Gy) so that its symbol squared is the curvature symbol
        return (gx.T @ gx + gy.T @ gy).tocsr()
    lx = sp.kron(sp.identity(ny), difference_matrix(nx, d[0], 2, False))
    ly = sp.kron(difference_matrix(ny, d[1], 2, False), sp.identity(nx))
    return sp.vstack([lx, ly]).tocsr()

"""The dot test: does an operator's adjoint match its forward map?

For a real linear operator ``A`` and random ``x``, ``y``, ``<A x, y> = <x, A^T y>`` holds to
rounding when ``rmatvec`` is the true adjoint of ``matvec`` (PyLops' ``dottest``). Every linear
operator of the solver and the inversion is checked this way.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse.linalg import LinearOperator

__all__ = ["dottest"]


def _relative(lhs: float, rhs: float) -> float:
    scale = max(abs(lhs), abs(rhs), np.finfo(float).tiny)
    return abs(lhs - rhs) / scale


def dottest(op: LinearOperator, rng: np.random.Generator | None = None, rtol: float = 1e-10,
            n_columns: int = 3, raise_error: bool = True) -> float:
    """Dot test of a real operator's adjoint: ``|<A x, y> - <x, A^T y>| / max(|<A x, y>|, |<x, A^T y>|)``.

    Checks ``matvec``/``rmatvec`` with one pair of random vectors and, when ``n_columns > 1``,
    the batched ``matmat``/``rmatmat`` with ``n_columns`` columns (operators may implement the
    two separately).

    Parameters
    ----------
    op : LinearOperator
        Real operator of shape (m, n) with matvec and rmatvec.
    rng : numpy.random.Generator, optional
        Source of the standard normal test vectors (default: ``numpy.random.default_rng(0)``).
    rtol : float
        Largest accepted relative mismatch.
    n_columns : int
        Columns of the batched test (>= 1; 1 skips it).
    raise_error : bool
        Raise when the mismatch exceeds ``rtol`` (else only return it).

    Returns
    -------
    float
        The largest relative mismatch found (dimensionless).

    Raises
    ------
    ValueError
        ``"dottest: adjoint mismatch ..."`` when the mismatch exceeds ``rtol`` and
        ``raise_error`` is True, or when an argument is invalid.
    """
    if not hasattr(op, "shape") or len(op.shape) != 2 or not hasattr(op, "matvec") or not hasattr(op, "rmatvec"):
        raise ValueError(f"op: expected a LinearOperator with matvec and rmatvec, got {type(op).__name__}; "
                         "wrap a matrix with scipy.sparse.linalg.aslinearoperator")
    if not (np.isfinite(rtol) and rtol > 0):
        raise ValueError(f"rtol: must be finite and > 0, got {rtol!r}; e.g. 1e-10")
    if isinstance(n_columns, bool) or int(n_columns) != n_columns or n_columns < 1:
        raise ValueError(f"n_columns: must be a whole number >= 1, got {n_columns!r}; e.g. 3")
    rng = np.random.default_rng(0) if rng is None else rng
    m, n = op.shape
    x = rng.standard_normal(n)
    y = rng.standard_normal(m)
    ax, aty = np.asarray(op.matvec(x)).ravel(), np.asarray(op.rmatvec(y)).ravel()
    lhs, rhs = float(ax @ y), float(x @ aty)
    err = _relative(lhs, rhs)
    worst = (err, lhs, rhs, "matvec/rmatvec")
    if n_columns > 1:
        xs = rng.standard_normal((n, int(n_columns)))
        ys = rng.standard_normal((m, int(n_columns)))
        axs, atys = np.asarray(op.matmat(xs)), np.asarray(op.rmatmat(ys))
        for j in range(int(n_columns)):
            lhs_j, rhs_j = float(axs[:, j] @ ys[:, j]), float(xs[:, j] @ atys[:, j])
            e = _relative(lhs_j, rhs_j)
            if e > worst[0] or not np.isfinite(e):
                worst = (e, lhs_j, rhs_j, f"matmat/rmatmat column {j}")
    err, lhs, rhs, where = worst
    if raise_error and not err <= rtol:
        raise ValueError(f"dottest: adjoint mismatch {err:.3e} exceeds rtol={rtol:g} ({where}): "
                         f"<Ax,y>={lhs!r}, <x,A^T y>={rhs!r}; rmatvec is not the adjoint of matvec")
    return float(err)

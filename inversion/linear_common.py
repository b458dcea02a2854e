"""What the linear inversion paths share: the result record, the data check and the dense limit.

:mod:`tactilab.inversion.linear` (Tikhonov) and :mod:`tactilab.inversion.tv` (total variation)
both import from here, so neither needs the other at import time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .criteria import CriteriaResult

#: largest model size for which the "auto" path builds a dense matrix
DENSE_MAX = 1024

__all__ = ["DENSE_MAX", "LinearInversionResult", "check_data"]


@dataclass
class LinearInversionResult:
    """Result of :func:`invert_linear`.

    Attributes
    ----------
    model : ndarray, shape ``dims``, or ``(len(loads), *dims)`` for several load components
        Estimated model (load in Pa, or profile in m, as the operator maps).
    method : str
        Path used: ``"fft"``, ``"dense"`` or ``"iterative"``.
    penalty : str
        ``"identity"``, ``"gradient"``, ``"curvature"`` or ``"tv"``.
    lam : float
        Regularisation strength used.
    lam_source : str
        ``"given"`` or the criterion that chose it.
    criteria : CriteriaResult or None
        All criteria choices and curves (Tikhonov on the fft and dense paths).
    residual_norm : float
        ``||A m - d||`` in data units.
    iterations : int
        Solver iterations (0 for direct paths).
    converged : bool
        False when an iterative solver hit its iteration limit.
    message : str
        Human-readable account of what was done.
    factorisation : Factorisation or None
        What the Tikhonov paths factorised, kept for reuse (``factorisation.solve(lam)`` re-solves
        at another lam without refactorising; see :class:`tactilab.inversion.linear.Factorisation`);
        None for total variation.
    """

    model: np.ndarray
    method: str
    penalty: str
    lam: float
    lam_source: str
    criteria: CriteriaResult | None
    residual_norm: float
    iterations: int
    converged: bool
    message: str
    factorisation: object = None

    def __repr__(self) -> str:
        """Method, penalty, lambda, model shape and residual; never the arrays."""
        status = "" if self.converged else ", NOT converged"
        iters = f", {self.iterations} iterations" if self.iterations else ""
        return (f"LinearInversionResult(method={self.method!r}, penalty={self.penalty!r}, "
                f"lam={self.lam:.3g} ({self.lam_source}), model shape {tuple(np.shape(self.model))} "
                f"(operator's model units: Pa for loads, m for heights), residual ||Am-d|| = "
                f"{self.residual_norm:.3g} data units{iters}{status})")

    def _repr_html_(self) -> str:
        """The short repr for notebooks (escaped, monospace)."""
        import html

        return "<pre>" + html.escape(repr(self)) + "</pre>"


def check_data(data, n_expected: int, name: str = "data", shape=None) -> np.ndarray:
    """Flatten and validate data: finite reals of the expected size and shape.

    Parameters
    ----------
    data : array_like
        A 1-D array of ``n_expected`` values, or an array of exactly ``shape`` (the operator's
        ``dimsd``, e.g. a 2-D sensor grid). Any other shape is refused, naming both shapes
        (a 2-D array is never flattened silently into a 1-D operator's data).
    n_expected : int
        Number of operator outputs.
    name : str
        Argument name for the error messages.
    shape : tuple of int, optional
        The operator's data shape.

    Returns
    -------
    ndarray, shape (n_expected,)
    """
    arr = np.asarray(data)
    if arr.dtype.kind not in "biuf":
        raise ValueError(f"{name}: expected real numbers, got dtype {arr.dtype}")
    allowed = tuple(int(v) for v in shape) if shape is not None else (int(n_expected),)
    if arr.ndim > 1 and arr.shape != allowed:
        raise ValueError(f"{name}: shape {arr.shape} does not match the operator's data shape {allowed} "
                         f"({n_expected} outputs); pass a 1-D array of {n_expected} values in the operator's "
                         "output order")
    arr = arr.astype(float).ravel()
    if arr.size != n_expected:
        raise ValueError(f"{name}: size mismatch, got {arr.size} values but the operator has {n_expected} outputs")
    bad = ~np.isfinite(arr)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"{name}: must be finite, found {arr[i]} at flat index {i} ({int(bad.sum())} bad values); "
            "drop or interpolate the bad samples first"
        )
    return arr

"""How a linear inversion chooses its solving path: one function for every entry point.

:func:`choose_path` is the one place that decides; :func:`~tactilab.inversion.invert_linear`
(Tikhonov), :func:`~tactilab.inversion.tv.invert_tv` (total variation) and
:func:`~tactilab.inversion.gaussian_posterior` all call it, so one operator takes one path in
all three (as ``scipy.integrate.solve_ivp`` looks its method up in one registry):

- ``"fft"``: a :class:`~tactilab.inversion.operators.FourierDiagonal`, or a forward operator
  that is a periodic convolution (a sensor at every node of a periodic grid, one load, one
  component), which is converted to its FourierDiagonal form first: O(n log n), exact;
- ``"dense"``: an explicit matrix, or any other operator with at most :data:`DENSE_MAX` model
  values (built as a matrix);
- ``"iterative"``: any other ``scipy.sparse.linalg.LinearOperator`` (matrix-free).

A ``method`` other than ``"auto"`` forces a path; ``"fft"`` then needs a FourierDiagonal form.
"""

from __future__ import annotations

import numpy as np

from .linear_common import DENSE_MAX
from .operators import FourierDiagonal, as_fourier_diagonal

#: the solving paths, in the order "auto" tries them
PATHS = ("fft", "dense", "iterative")

__all__ = ["PATHS", "choose_path"]


def choose_path(operator, method: str = "auto"):
    """The operator in the form its path uses, and the path.

    Parameters
    ----------
    operator : FourierDiagonal, LinearOperator (e.g. a forward ``LoadToSensor``) or ndarray
        The forward map, shape (n_data, n_model).
    method : {"auto", "fft", "dense", "iterative"}
        ``"auto"``: fft for a FourierDiagonal (or a circulant forward operator), dense for a
        matrix or ``n_model <= DENSE_MAX``, else iterative. Any other value forces that path.

    Returns
    -------
    operator : FourierDiagonal, LinearOperator or ndarray
        ``operator`` itself, or its FourierDiagonal form when it is a circulant forward operator.
    path : str
        ``"fft"``, ``"dense"`` or ``"iterative"``.

    Raises
    ------
    ValueError
        For an unknown ``method``, or ``"fft"`` forced on an operator with no FourierDiagonal form.
    """
    operator = as_fourier_diagonal(operator)  # a circulant forward operator takes the fft path
    if method != "auto":
        if method not in PATHS:
            raise ValueError(f"method: unknown path {method!r}; use 'auto' or one of {', '.join(PATHS)}")
        if method == "fft" and not isinstance(operator, FourierDiagonal):
            raise ValueError(
                "method: 'fft' needs a FourierDiagonal operator (one sensor per node of a periodic grid); "
                "use method='iterative' or 'dense' for this operator"
            )
        return operator, method
    if isinstance(operator, FourierDiagonal):
        return operator, "fft"
    if isinstance(operator, np.ndarray) or operator.shape[1] <= DENSE_MAX:
        return operator, "dense"
    return operator, "iterative"

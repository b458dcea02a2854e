"""Linear operators used by the inversions: a Fourier-diagonal (circulant) operator and the dot test
(the solver's :func:`tactilab.forward.halfspace.dottest`, one implementation for both parts).

The forward map from a surface load to sensors at depth is, on a periodic grid with a sensor at
every node, a convolution: it is diagonal in Fourier space with a multiplier ``H(k)`` (the
transfer function of docs/theory.md section 2). :class:`FourierDiagonal` applies it in
O(n log n) with real FFTs and carries ``dims`` / ``dimsd`` like PyLops operators.

Fourier convention (docs/theory.md section 1): ``f~(k) = sum_x f(x) exp(-i k x)``, angular
wavenumbers ``k = 2 pi * fftfreq(n, dx)`` in rad/m. A multiplier is given on the FULL grid in
``numpy.fft.fftfreq`` order (shape equal to the model shape; wavenumbers from
:func:`tactilab.forward.halfspace.angular_wavenumbers`, x first); it must be Hermitian,
``H(-k) = conj(H(k))``, so that the operator maps real arrays to real arrays.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse.linalg import LinearOperator

from tactilab.forward.halfspace import angular_wavenumbers, transfer
from tactilab.core import rules
from tactilab.forward.halfspace import dottest as _solver_dottest

__all__ = [
    "rigid_surface_height_operator",
    "FourierDiagonal",
    "normal_pressure_to_szz_multiplier",
    "halfspace_fourier_operator",
    "dottest",
    "model_layout",
    "as_fourier_diagonal",
]


def normal_pressure_to_szz_multiplier(n: int, dx: float, depth: float) -> np.ndarray:
    """Closed-form plane-strain multiplier from normal pressure p to sigma_zz at depth.

    ``H(k) = -(1 + |k| Z) exp(-|k| Z)`` (docs/theory.md section 3, sinusoidal loads): a pressure
    ``P cos kx`` gives ``sigma_zz = -P (1 + kZ) e^{-kZ} cos kx``. Written as a product with
    ``exp`` so that it underflows harmlessly to 0 for ``|k| Z > 745`` (docs/theory.md section 5).

    Parameters
    ----------
    n : int
        Number of grid nodes (periodic).
    dx : float
        Grid spacing in m.
    depth : float
        Sensor depth Z in m, > 0.

    Returns
    -------
    ndarray, shape (n,)
        Real multiplier in ``fftfreq`` order (dimensionless: Pa of stress per Pa of pressure).
    """
    depth = rules.depth(depth)
    dx = rules.spacing(dx, 1, "dx")[0]
    (k,) = angular_wavenumbers((int(n),), dx)
    s = np.abs(k) * depth
    return -(1.0 + s) * np.exp(-s)


def halfspace_fourier_operator(shape, spacing, depth: float, nu: float = 0.5, load: str = "p",
                               component: str = "zz") -> "FourierDiagonal":
    """FourierDiagonal map from one load component to one stress component at ``depth``.

    Uses the exact multiplier :func:`tactilab.forward.halfspace.spectral.transfer` (docs/theory.md section 2)
    on the periodic grid, one sensor per node. At the Nyquist wavenumber of an even grid the
    sign of ``k`` is ambiguous; the odd (imaginary) part is dropped there so that the operator
    stays real (Hermitian multiplier).

    Parameters
    ----------
    shape : tuple of int
        ``(nx,)`` (plane strain) or ``(ny, nx)``.
    spacing : float or (float, float)
        Grid spacing in m, ``dx`` or ``(dx, dy)``.
    depth : float
        Sensor depth in m.
    nu : float
        Poisson's ratio in (-1, 0.5].
    load : {"p", "qx", "qy"}
        Load component (Pa) the model holds.
    component : str
        Stress component (Voigt name) the sensors measure, Pa.
    """
    nu = rules.poisson_ratio(nu)
    shape = tuple(int(v) for v in shape)
    ks = angular_wavenumbers(shape, spacing)
    if len(shape) == 1:
        full = transfer(ks[0], None, depth, nu, load, (component,))[0]
    else:
        xi, eta = np.broadcast_arrays(*ks)
        full = transfer(xi, eta, depth, nu, load, (component,))[0]
    full = np.array(full, dtype=complex)
    for axis, n in enumerate(shape):
        if n % 2 == 0:
            idx = [slice(None)] * len(shape)
            idx[axis] = n // 2
            full[tuple(idx)] = full[tuple(idx)].real
    return FourierDiagonal(full, spacing)


def rigid_surface_height_operator(n: int, spacing: float, depth: float, young_modulus: float,
                                  poisson_ratio: float = 0.5) -> "FourierDiagonal":
    """Plane strain: height ``H(x)`` (m) of a rigid surface in full frictionless contact with the
    skin -> ``sigma_zz`` (Pa) at ``depth`` under every node (one sensor scanned along x records the
    same values).

    Multiplier ``E |k| / (2 (1 - nu^2))`` (pressure of a small-slope relief in full contact,
    docs/theory.md section 2) times the exact pressure -> ``sigma_zz`` multiplier of
    :func:`halfspace_fourier_operator`. ``k = 0`` maps to 0: a uniform height change loads
    nothing, so heights are relative. This is the operator of the inversion demo's height profile;
    it does not describe a finite (Hertz) finger contact.
    """
    spacing = rules.spacing(spacing, 1)[0]
    depth = rules.depth(depth)
    young_modulus = rules.young_modulus(young_modulus)
    poisson_ratio = rules.poisson_ratio(poisson_ratio, "poisson_ratio")
    (k,) = angular_wavenumbers((int(n),), spacing)
    p_to_szz = halfspace_fourier_operator((int(n),), spacing, depth, poisson_ratio).multiplier
    return FourierDiagonal(p_to_szz * young_modulus * np.abs(k) / (2 * (1 - poisson_ratio**2)), spacing)


def model_layout(operator) -> tuple[tuple[int, ...], int]:
    """Grid shape and number of load components of an operator's model vector.

    The convention shared with the forward solver's
    :class:`~tactilab.forward.halfspace.LoadToSensor`: ``dims`` is the grid shape, an optional
    ``loads`` attribute names the load components, and the model vector is load-major (all
    nodes of the first load, then the next). Operators without ``dims`` (matrices, plain
    LinearOperators) are one field on a 1-D grid of ``shape[1]`` nodes.

    Returns
    -------
    dims : tuple of int
        The grid shape, ``(nx,)`` or ``(ny, nx)``.
    n_fields : int
        ``len(operator.loads)``, else 1.

    Raises
    ------
    ValueError
        When ``len(loads) * prod(dims)`` is not the operator's model size.
    """
    n_model = int(operator.shape[1])
    dims = getattr(operator, "dims", None)
    if dims is None or isinstance(operator, np.ndarray):
        return (n_model,), 1
    dims = tuple(int(v) for v in dims)
    n_fields = len(getattr(operator, "loads", ("model",)))
    if len(dims) not in (1, 2) or n_fields * int(np.prod(dims)) != n_model:
        raise ValueError(
            f"operator: dims {dims} with {n_fields} load component(s) do not make its {n_model} model values; "
            "dims must be the grid shape (nx,) or (ny, nx), with the loads stacked load-major")
    return dims, n_fields


def as_fourier_diagonal(operator):
    """The :class:`FourierDiagonal` form of an operator when it has one, else ``operator``.

    A forward :class:`~tactilab.forward.halfspace.LoadToSensor` that is circulant (periodic
    grid, a sensor at every node) with one load and one component is the same map as a
    FourierDiagonal with its exact multiplier, so the inversion can take the fft path.
    """
    if isinstance(operator, FourierDiagonal) or not getattr(operator, "circulant", False):
        return operator
    if len(operator.loads) != 1 or len(operator.components) != 1:
        return operator
    return FourierDiagonal(operator.fourier_multiplier()[0, 0], operator.spacing)


def _half(full: np.ndarray) -> np.ndarray:
    """The rfftn half of a full-grid spectrum (last axis cut to n//2 + 1)."""
    return full[..., : full.shape[-1] // 2 + 1]


def _is_hermitian(full: np.ndarray, rtol: float = 1e-10) -> bool:
    flipped = full
    for axis in range(full.ndim):
        flipped = np.roll(np.flip(flipped, axis=axis), 1, axis=axis)
    scale = max(float(np.max(np.abs(full))), np.finfo(float).tiny)
    return bool(np.max(np.abs(flipped - np.conj(full))) <= rtol * scale)


class FourierDiagonal(LinearOperator):
    """Circulant operator ``d = ifft(H * fft(m))`` on a periodic 1-D or 2-D grid.

    Parameters
    ----------
    multiplier : ndarray, shape ``dims``
        Transfer function ``H(k)`` on the full grid, ``fftfreq`` order, Hermitian
        (``H(-k) = conj(H(k))``). Units: data units per model unit.
    spacing : float or tuple of float, optional
        Grid spacing in m (kept for wavenumbers and plots), default 1.

    Attributes
    ----------
    dims, dimsd : tuple of int
        Model and data shapes (equal: one sensor per grid node).
    half_multiplier : ndarray
        ``H`` on the rfftn half grid.
    weights : ndarray
        Multiplicity of each half-grid mode in the full spectrum (1 or 2), so that
        ``sum_full f = sum_half weights * f`` for Hermitian-symmetric ``f``.
    """

    def __init__(self, multiplier, spacing=1.0):
        full = np.asarray(multiplier)
        if full.ndim not in (1, 2) or full.size < 1:
            raise ValueError(
                f"multiplier: expected a 1-D (nx,) or 2-D (ny, nx) array in fftfreq order, got shape {full.shape}"
            )
        if not np.all(np.isfinite(full)):
            raise ValueError("multiplier: transfer function must be finite (no NaN or inf); check the depth and grid")
        rules.spacing(spacing, full.ndim)
        if not _is_hermitian(full):
            raise ValueError(
                "multiplier: must be Hermitian, H(-k) = conj(H(k)), so that real loads give real data; "
                "give it on the full fftfreq grid"
            )
        self.dims = tuple(full.shape)
        self.dimsd = tuple(full.shape)
        self.spacing = spacing
        self.multiplier = full
        self.half_multiplier = _half(full).astype(complex)
        self.weights = _rfft_weights(self.dims)
        n = int(np.prod(self.dims))
        super().__init__(dtype=np.float64, shape=(n, n))

    @property
    def wavenumbers(self) -> tuple[np.ndarray, ...]:
        """Angular wavenumbers ``(xi,)`` or ``(xi, eta)`` in rad/m on the full grid, x first
        (see :func:`tactilab.forward.halfspace.angular_wavenumbers`)."""
        return angular_wavenumbers(self.dims, self.spacing)

    def _apply(self, x: np.ndarray, mult: np.ndarray) -> np.ndarray:
        cols = x.reshape(*self.dims, -1)
        axes = tuple(range(len(self.dims)))
        spec = np.fft.rfftn(cols, axes=axes) * mult[..., None]
        out = np.fft.irfftn(spec, s=self.dims, axes=axes)
        return out.reshape(x.shape)

    def _matvec(self, x):
        return self._apply(np.asarray(x, dtype=float), self.half_multiplier)

    def _rmatvec(self, x):
        return self._apply(np.asarray(x, dtype=float), np.conj(self.half_multiplier))

    def _matmat(self, X):
        return self._apply(np.asarray(X, dtype=float), self.half_multiplier)

    def _rmatmat(self, X):
        return self._apply(np.asarray(X, dtype=float), np.conj(self.half_multiplier))

    def _adjoint(self):
        return FourierDiagonal(np.conj(self.multiplier), self.spacing)

    def todense(self) -> np.ndarray:
        """Dense matrix (n, n) for small grids (oracle tests, dense path)."""
        return self.matmat(np.eye(self.shape[1]))


def _rfft_weights(shape: tuple[int, ...]) -> np.ndarray:
    """Weights of rfftn modes: 2 for modes whose mirror is not stored, 1 otherwise."""
    n_last = shape[-1]
    half = n_last // 2 + 1
    w = np.full(half, 2.0)
    w[0] = 1.0
    if n_last % 2 == 0:
        w[-1] = 1.0
    return np.broadcast_to(w, (*shape[:-1], half)).copy()


def dottest(op: LinearOperator, rng: np.random.Generator | None = None, rtol: float = 1e-10) -> float:
    """Dot test of an operator's adjoint: ``|<A x, y> - <x, A^T y>| / scale``.

    The solver's :func:`tactilab.forward.halfspace.dottest` (matvec and batched matmat), under
    the inversion's name.

    Parameters
    ----------
    op : LinearOperator
        Real operator with matvec and rmatvec.
    rng : numpy.random.Generator, optional
        Source of the random test vectors.
    rtol : float
        Relative tolerance; a ValueError is raised when the mismatch exceeds it.

    Returns
    -------
    float
        Relative mismatch.
    """
    return _solver_dottest(op, rng=rng, rtol=rtol)

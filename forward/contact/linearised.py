"""The derivative of a solved normal contact at a fixed contact set (the inversions' Jacobian).

At a solution with contact set ``C`` the gap vanishes on ``C``: ``g0 + A p - delta = 0`` there,
``p = 0`` off it (``A`` the surface compliance, ``delta`` the rigid approach). While the set does
not change, a small change of the surface heights ``dh`` (the initial gap changes by ``-dh``)
moves the pressure by the solution of the restricted system

    A_CC dp_C - d_delta = dh_C,        dp = 0 off C,

with ``sum(dp) = 0`` when the normal force (or a periodic cell's mean pressure) is given: the
rigid approach adjusts (``d_delta`` is the multiplier of the force). Off ``C`` the pressure does
not respond at all. The map ``dh -> dp`` is ``S = Z (Z^T A Z)^-1 Z^T`` with ``Z`` a basis of the
zero-sum fields on ``C``, so it is symmetric: the adjoint is the same solve.

The solve is conjugate gradients projected on those fields and preconditioned by the periodic
surface stiffness (``ContactCompliance.stiffness``, the preconditioner of the normal solver
:mod:`.preconditioned`), for a stack of right-hand sides at once, each with its own contact set:
one batched compliance product per iteration (the FFTs of all the stack's grids together).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import fft as sfft

from ..halfspace import AccuracyWarning
from .compliance import ContactCompliance

__all__ = ["ContactLinearisation"]


class ContactLinearisation:
    """Derivatives of the pressure of solved normal contacts at their (fixed) contact sets.

    Parameters
    ----------
    compliance : ContactCompliance
        The skin on the grid, as the solves used it (periodic or isolated).
    contact : ndarray of bool, shape ``grid`` or ``(m, *grid)``
        The contact set of one solution, or of ``m`` solutions on the same grid (scan frames).
    force_control : bool
        True when the normal force (a periodic cell's mean pressure) was given: the pressure
        changes sum to zero and the approach adjusts; False when the approach was given.
    tol : float
        Relative residual of the conjugate gradients, per right-hand side.
    max_iter : int, optional
        Iteration limit (default ``20 sqrt(n) + 100`` for ``n`` nodes per grid).

    Notes
    -----
    Conventions (docs/theory.md section 1): heights positive towards the skin, pressure (Pa)
    positive into it. The derivatives are exact for the discrete problem while the contact set
    stays the same (the pressure is then affine in the heights).
    """

    def __init__(self, compliance: ContactCompliance, contact, *, force_control: bool, tol: float = 1e-12,
                 max_iter: int | None = None):
        if not isinstance(compliance, ContactCompliance):
            raise ValueError(f"compliance: expected a ContactCompliance, got {type(compliance).__name__}")
        mask = np.asarray(contact)
        if mask.dtype != bool or mask.shape[-compliance.ndim:] != compliance.shape or mask.ndim > compliance.ndim + 1:
            raise ValueError(f"contact: expected a boolean mask of shape {compliance.shape} or (m, "
                             f"*{compliance.shape}), got dtype {mask.dtype} and shape {mask.shape}")
        self.compliance = compliance
        self.stacked = mask.ndim == compliance.ndim + 1
        self.mask = mask if self.stacked else mask[None]
        self.n_contact = self.mask.reshape(self.mask.shape[0], -1).sum(axis=1)
        if force_control and (self.n_contact == 0).any():
            raise ValueError("contact: a set is empty, so no pressure can carry the force; a linearisation "
                             "needs at least one node in contact in every solution")
        self.force_control = bool(force_control)
        self.tol = float(tol)
        n = int(np.prod(compliance.shape))
        self.max_iter = int(max_iter) if max_iter is not None else int(20 * math.sqrt(n)) + 100
        self._axes = tuple(range(-compliance.ndim, 0))
        self._stiffness = None
        self.last_iterations = 0

    # ---------------------------------------------------------------- the operators on stacks
    def _compliance(self, x: np.ndarray) -> np.ndarray:
        """``A x`` for a stack ``(k, *grid)`` of pressures (Pa -> m): one batched FFT pair."""
        c = self.compliance
        # the transform over the grid's own axes (the stack's first axis is not a grid axis); the same
        # layout as the compliance's spectrum (rfftn of the padded grid)
        spec = sfft.rfftn(x, s=c.fft_shape, axes=self._axes, workers=1)
        spec *= c.spectrum("uz", "p")
        out = sfft.irfftn(spec, s=c.fft_shape, axes=self._axes, workers=1)
        return out if c.periodic else out[(Ellipsis,) + tuple(slice(0, n) for n in c.shape)]

    def _project(self, x: np.ndarray, mask: np.ndarray, count: np.ndarray) -> np.ndarray:
        """Onto the admissible fields: zero off the set, zero sum on it under force control."""
        x = x * mask
        if self.force_control:
            mean = x.reshape(x.shape[0], -1).sum(axis=1) / np.maximum(count, 1)
            x -= mean.reshape((-1,) + (1,) * self.compliance.ndim) * mask
        return x

    def _precondition(self, r: np.ndarray) -> np.ndarray:
        """The periodic surface stiffness on a stack (the normal solver's preconditioner), one batched FFT pair."""
        c = self.compliance
        if self._stiffness is None:  # its spectrum: ask the compliance once, read it back by a unit impulse
            impulse = np.zeros(c.shape)
            impulse.flat[0] = 1.0
            self._stiffness = sfft.rfftn(c.stiffness(impulse), axes=self._axes, workers=1)
        spec = sfft.rfftn(r, axes=self._axes, workers=1)
        spec *= self._stiffness
        return sfft.irfftn(spec, s=c.shape, axes=self._axes, workers=1)

    def _masks(self, k: int, frames) -> tuple[np.ndarray, np.ndarray]:
        if frames is None:
            if self.mask.shape[0] not in (1, k):
                raise ValueError(f"rhs: {k} right-hand sides for {self.mask.shape[0]} contact sets; give one "
                                 "per set, or frames= naming each one's set")
            idx = np.zeros(k, dtype=int) if self.mask.shape[0] == 1 else np.arange(k)
        else:
            idx = np.asarray(frames, dtype=int).reshape(-1)
            if idx.size != k or (idx.size and (idx.min() < 0 or idx.max() >= self.mask.shape[0])):
                raise ValueError(f"frames: need {k} indices in [0, {self.mask.shape[0]}), got {frames!r}")
        return self.mask[idx], self.n_contact[idx]

    # ---------------------------------------------------------------- the solve
    def solve(self, rhs, frames=None) -> np.ndarray:
        """The pressure change for a height change (Pa per m): ``S rhs``; ``S`` is symmetric.

        Parameters
        ----------
        rhs : ndarray, shape ``grid`` or ``(k, *grid)``
            Height changes at the nodes, m (only their values on the contact set matter).
        frames : array_like of int, shape (k,), optional
            The contact set of each right-hand side (default: one per set, in order).

        Returns
        -------
        ndarray, the shape of ``rhs``: the pressure change, Pa (zero off the contact set).
        """
        b = np.asarray(rhs, dtype=float)
        single = b.ndim == self.compliance.ndim
        b = b[None] if single else b
        if b.shape[1:] != self.compliance.shape or not np.all(np.isfinite(b)):
            raise ValueError(f"rhs: expected finite values of shape {self.compliance.shape} or (k, "
                             f"*{self.compliance.shape}), got shape {np.shape(rhs)}")
        mask, count = self._masks(b.shape[0], frames)
        x = self._pcg(b, mask, count)
        return x[0] if single else x

    def force_response(self, frames=None) -> np.ndarray:
        """The pressure change per unit change of the nodal pressure sum (force control only).

        Returns
        -------
        ndarray, shape ``(m, *grid)`` (``grid`` for one set): dp with ``sum(dp) = 1`` (1/1), zero off the set;
        divide by the cell area for the change per newton.
        """
        if not self.force_control:
            raise ValueError("force_control: the force response needs a force-controlled contact "
                             "(force_control=True)")
        m = self.mask.shape[0] if frames is None else np.asarray(frames).size
        mask, count = self._masks(m, frames)
        x0 = mask / np.maximum(count, 1).reshape((-1,) + (1,) * self.compliance.ndim)
        x = x0 + self._pcg(-self._compliance(x0), mask, count)
        return x if self.stacked or frames is not None else x[0]

    def _pcg(self, b: np.ndarray, mask: np.ndarray, count: np.ndarray) -> np.ndarray:
        """Projected, preconditioned CG on the stack, each column stopped at its own tolerance."""
        k = b.shape[0]
        shape_k = (-1,) + (1,) * self.compliance.ndim
        r = self._project(b, mask, count)
        x = np.zeros_like(r)
        norm0 = np.sqrt((r * r).reshape(k, -1).sum(axis=1))
        active = norm0 > 0
        z = self._project(self._precondition(r), mask, count)
        t = z.copy()
        rz = (r * z).reshape(k, -1).sum(axis=1)
        it = 0
        for it in range(1, self.max_iter + 1):
            if not active.any():
                it -= 1
                break
            At = self._project(self._compliance(t), mask, count)
            denom = (At * t).reshape(k, -1).sum(axis=1)
            alpha = np.where(active & (denom > 0), rz / np.where(denom > 0, denom, 1.0), 0.0)
            x += alpha.reshape(shape_k) * t
            r -= alpha.reshape(shape_k) * At
            norm = np.sqrt((r * r).reshape(k, -1).sum(axis=1))
            active &= norm > self.tol * norm0
            z = self._project(self._precondition(r), mask, count)
            rz_new = (r * z).reshape(k, -1).sum(axis=1)
            beta = np.where(active, rz_new / np.where(rz > 0, rz, 1.0), 0.0)
            t = z + beta.reshape(shape_k) * t
            rz = rz_new
        self.last_iterations = it
        if active.any():
            warnings.warn(f"ContactLinearisation: conjugate gradients did not reach tol {self.tol:g} in "
                          f"{self.max_iter} iterations for {int(active.sum())} of {k} right-hand sides",
                          AccuracyWarning, stacklevel=3)
        return x

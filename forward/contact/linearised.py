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

Cost. The stack is solved in memory-bounded chunks, each on the window of the grid that holds its
contact sets (their joint bounding box, widened to a size whose padded transform is fast): an
isolated contact's compliance depends only on node differences, so the restricted operator on the
window is the same operator (exact, not an approximation); a fingertip's contact filling half of
its grid's width then costs a quarter of the padded FFT work. The padded products are pruned (the
rows of zeros are not transformed, the rows off the window not returned). A start ``initial`` (a
neighbouring frame's or an earlier iterate's solution) cuts the iterations where it is close.
Chunks are small enough to stay in cache (:data:`CHUNK_BYTES`), ``workers`` threads take whole
chunks, and ``dtype=float32`` runs the iterations in single precision (half the FFT work) in
passes on the float64 residual until that residual meets ``tol``.
"""

from __future__ import annotations

import math
import threading
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy import fft as sfft

from tactilab.core import rules

from ..halfspace import AccuracyWarning
from .compliance import ContactCompliance

__all__ = ["ContactLinearisation"]

#: bytes of work memory per chunk of right-hand sides (about ten grid-sized arrays and a padded
#: spectrum per right-hand side): small enough to stay in cache (a fingertip's 180^2 grid: 10 per
#: chunk; its Jacobian's solves took 0.6 of the time of 86 per chunk, 256 MiB)
CHUNK_BYTES = 32 * 2**20
#: the smallest relative residual a float32 pass is asked for (its round-off is about 1e-7 of the
#: products); a smaller ``tol`` takes further passes on the float64 residual
SINGLE_TOL = 1e-5
#: most float32 passes (each on the float64 residual of the last)
REFINEMENTS = 6


def _fast_size(size: int, limit: int) -> int:
    """The smallest window width >= ``size`` (at most ``limit``) whose padded transform (2 x) is fast."""
    for m in range(size, limit):
        if sfft.next_fast_len(2 * m, real=True) == 2 * m:
            return m
    return limit


class _Window:
    """One window of the grid (slices) and its operators: the isolated compliance's pruned padded
    product and the periodic stiffness of the window (the preconditioner), on stacks of float64 or
    float32 (their spectra kept in both precisions: a float32 stack is transformed in single precision)."""

    def __init__(self, compliance: ContactCompliance, slices: tuple[slice, ...]):
        self.slices = slices  # one FFT thread: the solver's threads take whole chunks
        shape = tuple(s.stop - s.start for s in slices)
        c = compliance if shape == compliance.shape else ContactCompliance(compliance.skin, shape,
                                                                           compliance.spacing, compliance.periodic)
        self.compliance, self.shape, self.ndim = c, shape, len(shape)
        self.axes = tuple(range(-self.ndim, 0))
        self.spectrum = c.spectrum("uz", "p")
        impulse = np.zeros(shape)  # the stiffness's spectrum: read back by a unit impulse
        impulse.flat[0] = 1.0
        self.stiffness = sfft.rfftn(c.stiffness(impulse), axes=self.axes)
        self.single = (self.spectrum.astype(np.complex64), self.stiffness.astype(np.complex64))

    def _spectra(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.single if x.dtype == np.float32 else (self.spectrum, self.stiffness)

    def compliance_product(self, x: np.ndarray) -> np.ndarray:
        """``A x`` for a stack ``(k, *window)`` of pressures (Pa -> m)."""
        c, spectrum = self.compliance, self._spectra(x)[0]
        if c.periodic:
            spec = sfft.rfftn(x, axes=self.axes)
            spec *= spectrum
            return sfft.irfftn(spec, s=c.shape, axes=self.axes)
        if self.ndim == 1:
            spec = sfft.rfft(x, n=c.fft_shape[0], axis=-1)
            spec *= spectrum
            return sfft.irfft(spec, n=c.fft_shape[0], axis=-1)[..., : c.shape[0]]
        # pruned: the rows along x only where the data are, the columns zero-padded by the transform
        rows = sfft.rfft(x, n=c.fft_shape[1], axis=-1)
        spec = sfft.fft(rows, n=c.fft_shape[0], axis=-2, overwrite_x=True)
        spec *= spectrum
        cols = sfft.ifft(spec, axis=-2, overwrite_x=True)[..., : c.shape[0], :]
        return sfft.irfft(cols, n=c.fft_shape[1], axis=-1)[..., : c.shape[1]]

    def precondition(self, r: np.ndarray) -> np.ndarray:
        spec = sfft.rfftn(r, axes=self.axes)
        spec *= self._spectra(r)[1]
        return sfft.irfftn(spec, s=self.shape, axes=self.axes)


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
    chunk : int, optional
        Right-hand sides per batched solve (default: as many as :data:`CHUNK_BYTES` of work memory
        hold for the grid); each chunk is solved on the window that holds its contact sets.
    workers : int
        Threads, each solving whole chunks (a stack is cut into at least this many). Default 1, as
        the contact engine; on a 2-core machine 2 solved a fingertip scan's 100 gradient solves
        1.7x faster (threads over chunks; the FFTs' own threads over one chunk: 1.3x).
    dtype : float64 or float32
        Precision of the iterations. float32 halves the FFT work; its passes run on the float64
        residual, recomputed in float64 after each (one double product), until that residual is
        below ``tol``: the tolerance holds as in float64 (at most :data:`REFINEMENTS` passes; each
        asks no more than :data:`SINGLE_TOL`, so a ``tol`` far below it costs several).

    Attributes
    ----------
    last_iterations : int
        The most iterations a chunk of the last solve needed.
    total_iterations : int
        Iterations times right-hand sides of the last solve (each right-hand side counted until
        it converged), for cost accounting.

    Notes
    -----
    Conventions (docs/theory.md section 1): heights positive towards the skin, pressure (Pa)
    positive into it. The derivatives are exact for the discrete problem while the contact set
    stays the same (the pressure is then affine in the heights).
    """

    def __init__(self, compliance: ContactCompliance, contact, *, force_control: bool, tol: float = 1e-12,
                 max_iter: int | None = None, chunk: int | None = None, workers: int = 1,
                 dtype=np.float64):
        if not isinstance(compliance, ContactCompliance):
            raise ValueError(f"compliance: expected a ContactCompliance, got {type(compliance).__name__}")
        mask = np.asarray(contact)
        if mask.dtype != bool or mask.shape[-compliance.ndim:] != compliance.shape or mask.ndim > compliance.ndim + 1:
            raise ValueError(f"contact: expected a boolean mask of shape {compliance.shape} or (m, "
                             f"*{compliance.shape}), got dtype {mask.dtype} and shape {mask.shape}")
        self.workers = rules.workers(workers)
        self.dtype = rules.float_dtype(dtype)
        if chunk is not None and int(chunk) < 1:
            raise ValueError(f"chunk: right-hand sides per batched solve must be >= 1, got {chunk!r}; or None")
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
        self.chunk = int(chunk) if chunk is not None else max(1, CHUNK_BYTES // (12 * 8 * n))
        self._windows: dict = {}  # window slices -> _Window (its kernel spectra kept)
        self._lock = threading.Lock()
        self.last_iterations = 0
        self.total_iterations = 0

    # ---------------------------------------------------------------- windows
    def _window(self, mask: np.ndarray) -> _Window:
        """The window holding every set of a chunk: their joint bounding box, widened to a fast size."""
        c = self.compliance
        if c.periodic:
            slices = tuple(slice(0, n) for n in c.shape)
        else:
            union = mask.any(axis=0)
            slices = []
            for axis, n in enumerate(c.shape):
                other = tuple(a for a in range(c.ndim) if a != axis)
                hit = np.flatnonzero(union.any(axis=other) if other else union)
                lo, hi = (int(hit[0]), int(hit[-1]) + 1) if hit.size else (0, 1)
                m = _fast_size(hi - lo, n)
                start = min(max(0, lo - (m - (hi - lo)) // 2), n - m)
                slices.append(slice(start, start + m))
            slices = tuple(slices)
        if slices not in self._windows:
            if len(self._windows) > 16:
                self._windows.pop(next(iter(self._windows)))
            self._windows[slices] = _Window(c, slices)
        return self._windows[slices]

    def _project(self, x: np.ndarray, mask: np.ndarray, count: np.ndarray) -> np.ndarray:
        """Onto the admissible fields: zero off the set, zero sum on it under force control (``mask``
        as float32 ones and zeros: no casts of booleans in the products)."""
        x = x * mask
        if self.force_control:
            mean = (x.reshape(x.shape[0], -1).sum(axis=1) / np.maximum(count, 1)).astype(x.dtype)
            x -= mean.reshape((-1,) + (1,) * self.compliance.ndim)
            x *= mask
        return x

    def _masks(self, k: int, frames) -> np.ndarray:
        if frames is None:
            if self.mask.shape[0] not in (1, k):
                raise ValueError(f"rhs: {k} right-hand sides for {self.mask.shape[0]} contact sets; give one "
                                 "per set, or frames= naming each one's set")
            return np.zeros(k, dtype=int) if self.mask.shape[0] == 1 else np.arange(k)
        idx = np.asarray(frames, dtype=int).reshape(-1)
        if idx.size != k or (idx.size and (idx.min() < 0 or idx.max() >= self.mask.shape[0])):
            raise ValueError(f"frames: need {k} indices in [0, {self.mask.shape[0]}), got {frames!r}")
        return idx

    # ---------------------------------------------------------------- the solve
    def solve(self, rhs, frames=None, initial=None) -> np.ndarray:
        """The pressure change for a height change (Pa per m): ``S rhs``; ``S`` is symmetric.

        Parameters
        ----------
        rhs : ndarray, shape ``grid`` or ``(k, *grid)``
            Height changes at the nodes, m (only their values on the contact set matter).
        frames : array_like of int, shape (k,), optional
            The contact set of each right-hand side (default: one per set, in order).
        initial : ndarray, the shape of ``rhs``, optional
            Starting pressure changes, Pa (projected on each set's admissible fields); the
            tolerance stays relative to ``rhs``.

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
        x0 = None
        if initial is not None:
            x0 = np.asarray(initial, dtype=float)
            x0 = x0[None] if single else x0
            if x0.shape != b.shape or not np.all(np.isfinite(x0)):
                raise ValueError(f"initial: expected finite values of the shape of rhs {b.shape}, got shape "
                                 f"{np.shape(initial)}")
        x = self._solve_chunks(b, self._masks(b.shape[0], frames), x0)
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
        idx = self._masks(m, frames)
        x = self._solve_chunks(None, idx, None)
        return x if self.stacked or frames is not None else x[0]

    def _solve_chunks(self, b, idx: np.ndarray, x0) -> np.ndarray:
        """Solve chunk by chunk, each on its window, ``workers`` chunks at a time (balanced chunks, at
        least one per thread); ``b`` None: the force responses."""
        out = np.zeros((idx.size, *self.compliance.shape))
        self.last_iterations, self.total_iterations = 0, 0
        shape_k = (-1,) + (1,) * self.compliance.ndim
        pieces = min(idx.size, max(-(-idx.size // self.chunk), self.workers))
        edges = np.linspace(0, idx.size, pieces + 1).round().astype(int)

        def chunk(lo: int, hi: int):
            sel = idx[lo: hi]
            with self._lock:  # the windows' cache is shared by the threads
                win = self._window(self.mask[sel])
            at = (slice(None),) + win.slices
            mask, count = self.mask[sel][at].astype(np.float32), self.n_contact[sel]
            if b is None:  # the uniform field of unit sum, corrected to zero gap change on the set
                f0 = mask / np.maximum(count, 1).reshape(shape_k)
                x = f0 + self._pcg(win, -win.compliance_product(f0), mask, count, None)
            else:
                start = None if x0 is None else x0[lo: hi][at]
                x = self._pcg(win, b[lo: hi][at], mask, count, start)
            out[(slice(lo, hi),) + win.slices] = x

        if self.workers == 1 or pieces == 1:
            for lo, hi in zip(edges[:-1], edges[1:]):
                chunk(lo, hi)
        else:  # threads over chunks: their FFTs and array arithmetic release the GIL
            with ThreadPoolExecutor(max_workers=min(self.workers, pieces)) as pool:
                list(pool.map(chunk, edges[:-1], edges[1:]))
        return out

    def _pcg(self, win: _Window, b: np.ndarray, mask: np.ndarray, count: np.ndarray, x0) -> np.ndarray:
        """Projected, preconditioned CG on a chunk to ``tol`` per column; in float32 (``dtype``) by
        refinement: single-precision CG on the float64 residual, which is then recomputed in float64
        (one product per pass), until it is below ``tol`` (so the tolerance is the true residual's)."""
        if self.dtype == np.float64:
            x, live = self._cg(win, b, mask, count, x0, self.tol)
            self._warn(live.size, b.shape[0])
            return x
        k = b.shape[0]
        r = self._project(b, mask, count)
        target = self.tol * np.sqrt((r * r).reshape(k, -1).sum(axis=1))
        x = np.zeros_like(r)
        if x0 is not None:  # the start's residual in float32: the float64 check below catches its round-off
            x = self._project(x0, mask, count)
            r -= self._project(win.compliance_product(x.astype(np.float32)), mask, count)
        for _ in range(REFINEMENTS):
            norm = np.sqrt((r * r).reshape(k, -1).sum(axis=1))
            live = np.flatnonzero(norm > target)
            if live.size == 0:
                return x
            # each pass asks single precision for no more than SINGLE_TOL: beyond, its round-off
            rtol = np.maximum(target[live] / norm[live], SINGLE_TOL)
            d, _ = self._cg(win, r[live].astype(np.float32), mask[live], count[live], None, rtol)
            x[live] += self._project(d.astype(np.float64), mask[live], count[live])  # zero sum in float64
            r[live] = self._project(b[live] - win.compliance_product(x[live]), mask[live], count[live])
        norm = np.sqrt((r * r).reshape(k, -1).sum(axis=1))
        self._warn(int(np.count_nonzero(norm > target)), k, f"{REFINEMENTS} float32 passes of at most")
        return x

    def _warn(self, failed: int, k: int, passes: str = ""):
        if failed:
            warnings.warn(f"ContactLinearisation: conjugate gradients did not reach tol {self.tol:g} in "
                          f"{passes}{' ' if passes else ''}{self.max_iter} iterations for {failed} of {k} "
                          "right-hand sides", AccuracyWarning, stacklevel=5)

    def _cg(self, win: _Window, b: np.ndarray, mask: np.ndarray, count: np.ndarray, x0,
            rtol) -> tuple[np.ndarray, np.ndarray]:
        """Projected, preconditioned CG on a chunk in ``b``'s precision, column ``i`` stopped at the
        relative residual ``rtol`` (a float, or one per column); the converged columns leave the batch
        (its products cost per column). Returns the solutions and the columns that did not converge."""
        k = b.shape[0]
        r = self._project(b, mask, count)
        norm0 = np.sqrt((r * r).reshape(k, -1).sum(axis=1))
        target = np.broadcast_to(np.asarray(rtol, dtype=r.dtype), (k,)) * norm0
        if x0 is None:
            x = np.zeros_like(r)
        else:
            x = self._project(x0, mask, count)
            r -= self._project(win.compliance_product(x), mask, count)
        out = x
        live = np.flatnonzero((norm0 > 0) & (np.sqrt((r * r).reshape(k, -1).sum(axis=1)) > target))
        if live.size == 0:
            return out, live
        x, r, mask, count, target = x[live], r[live], mask[live], count[live], target[live]
        z = self._project(win.precondition(r), mask, count)
        t = z.copy()
        rz = (r * z).reshape(live.size, -1).sum(axis=1)
        it = 0
        shape_k = (-1,) + (1,) * self.compliance.ndim
        for it in range(1, self.max_iter + 1):
            with self._lock:
                self.total_iterations += live.size
            At = self._project(win.compliance_product(t), mask, count)
            denom = (At * t).reshape(live.size, -1).sum(axis=1)
            alpha = np.where(denom > 0, rz / np.where(denom > 0, denom, 1.0), 0.0).astype(r.dtype)
            x += alpha.reshape(shape_k) * t
            r -= alpha.reshape(shape_k) * At
            active = np.sqrt((r * r).reshape(live.size, -1).sum(axis=1)) > target
            if not active.all():  # the converged columns are done: store them, drop them
                out[live[~active]] = x[~active]
                live, x, r, t, mask, count, target, rz = (a[active] for a in (live, x, r, t, mask, count, target, rz))
                if live.size == 0:
                    break
            z = self._project(win.precondition(r), mask, count)
            rz_new = (r * z).reshape(live.size, -1).sum(axis=1)
            beta = (rz_new / np.where(rz > 0, rz, 1.0)).astype(r.dtype)
            t = z + beta.reshape(shape_k) * t
            rz = rz_new
        with self._lock:
            self.last_iterations = max(self.last_iterations, it)
        if live.size:
            out[live] = x
        return out, live

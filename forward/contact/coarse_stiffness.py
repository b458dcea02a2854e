"""A cheap preconditioner for periodic 2-D contact grids: the surface stiffness as a local stencil
plus a coarse-grid correction (two levels), at a tenth to a fifth of the FFT pair of the exact one.

The exact periodic stiffness ``K(k) = E* |k| / 2`` (:meth:`ContactCompliance.stiffness`) costs an FFT
pair of the grid, as much as the compliance product itself. Here it is approximated by::

    K2 r = s (a r + b L r) + P D R r

- ``L``: the periodic 5-point Laplacian in nodes (symbol ``lam = 4 sin^2(kx h / 2) + 4 sin^2(ky h / 2)``);
  ``a``, ``b``: :data:`STENCIL`, the fit of ``a + b lam`` to ``|k| h / pi`` for ``|k| h >= pi / 8``
  (within :data:`STENCIL_BOUNDS`, 0.81 to 1.23 times it, there); ``s``: the skin's exact stiffness
  at the x Nyquist wavenumber ``pi / h`` (``E* pi / (2 h)`` for a half-space), so that any skin that
  looks like a half-space at the grid's scale gets its own.
- ``R``: the mean over blocks of :data:`FACTOR` x :data:`FACTOR` nodes; ``P``: each block's value back to
  its nodes. ``R = P^T / FACTOR^2``, so ``P D R`` is symmetric when ``D`` is.
- ``D``: on the grid of ``FACTOR`` times the spacing, the exact stiffness minus the stencil's symbol,
  tapered by ``cos^2`` to 0 at the coarse Nyquist wavenumber (where block means alias), applied by an
  FFT pair of ``1 / FACTOR^2`` of the nodes: the long waves, which no local stencil follows
  (``|k|`` is not smooth at ``k = 0``), are exact.

``K2`` is symmetric and, on the grids tested, within 0.81 to 1.7 of the exact stiffness (the tests
bound the generalised eigenvalues). As the contact solver's preconditioner on the self-affine
surfaces of docs/contact.md (Table a) it takes 2 iterations more than the exact stiffness (25, 32, 42
instead of 23, 30, 40 at 256^2, 512^2, 1024^2; 55 instead of 51 at 2048^2) for one product that
costs two passes over the grid and a tiny FFT pair instead of a full pair. It applies to periodic
2-D grids of square pixels whose sides are multiples of ``FACTOR`` (at least ``2 FACTOR``:
:func:`applies`); elsewhere the exact stiffness is used.
"""

from __future__ import annotations

import threading

import numpy as np
from scipy import fft as sfft

from tactilab.core import jit
from tactilab.core import rules as check

from ..halfspace import inverse_into, rfftn_into

#: block size of the coarse grid (nodes per side)
FACTOR = 8
#: the stencil's ``(a, b)``: ``a + b lam`` fitted to ``|k| h / pi`` over ``|k| h >= pi / 8`` (minimax of
#: the ratio's spread, then scaled so that the ratio's extremes are reciprocal)
STENCIL = (0.1274, 0.1715)
#: the bounds of the fitted stencil over ``|k| h / pi`` there (the fit's quality: a spread of 1.51)
STENCIL_BOUNDS = (0.81, 1.23)


def applies(shape: tuple[int, ...], spacing: tuple[float, ...], periodic: bool) -> bool:
    """True where the two-level stiffness is defined: a periodic 2-D grid of square pixels
    (``dx == dy`` to 1e-9) whose sides are multiples of :data:`FACTOR`, at least two blocks each (the
    coarse grid's longest wave sets the stiffness of the mean)."""
    return (periodic and len(shape) == 2 and all(n % FACTOR == 0 and n >= 2 * FACTOR for n in shape)
            and abs(spacing[0] - spacing[-1]) <= 1e-9 * spacing[0])


def preferred(shape: tuple[int, ...], spacing: tuple[float, ...], periodic: bool) -> bool:
    """The choice of ``preconditioner="auto"``: the two-level stiffness where it :func:`applies` and its
    kernels are compiled. Its NumPy twin costs 0.6 to 1.0 of the exact stiffness's FFT pair (against
    0.1 to 0.2 compiled), too much for the two iterations it adds (docs/contact.md, Cost)."""
    return applies(shape, spacing, periodic) and jit.enabled()


class TwoLevelStiffness:
    """``K2``, the two-level approximation of the periodic surface stiffness (module docstring).

    Parameters
    ----------
    skin : object
        Provides ``surface_compliance(kx, ky)`` (normal entry ``[..., 0, 0]`` in m/Pa per wave).
    shape : tuple of int
        ``(ny, nx)``, both multiples of :data:`FACTOR`.
    spacing : float or tuple of float
        The node spacing ``h`` in m, or ``(dx, dy)`` with ``dx == dy`` (square pixels).

    Calling it maps a gap (m, shape ``(ny, nx)``, float64 or float32) to a pressure (Pa; into ``out``, float64 or
    float32), like :meth:`ContactCompliance.stiffness`.
    """

    def __init__(self, skin, shape: tuple[int, int], spacing):
        shape = tuple(int(n) for n in np.atleast_1d(shape))
        spacing = check.spacing(spacing, 2)
        if not applies(shape, spacing, True):
            raise ValueError(f"shape, spacing: the two-level stiffness needs a 2-D grid with both sides multiples of "
                             f"{FACTOR} (at least {2 * FACTOR}) and square pixels, got shape {shape}, spacing "
                             f"{spacing}; use the exact stiffness (preconditioner='fft')")
        self.shape = shape
        self.spacing = spacing[0]
        h, (ny, nx) = self.spacing, self.shape
        nyquist = np.asarray(skin.surface_compliance(np.array([np.pi / h]), np.array([0.0])))
        self.scale = float(1.0 / np.real(nyquist[..., 0, 0]).item())
        a, b = STENCIL
        self.centre, self.neighbour = self.scale * (a + 4 * b), self.scale * b
        self.coarse = (ny // FACTOR, nx // FACTOR)
        H = FACTOR * h
        kx = 2 * np.pi * sfft.rfftfreq(self.coarse[1], H)[None, :]
        ky = 2 * np.pi * sfft.fftfreq(self.coarse[0], H)[:, None]
        c = np.real(np.asarray(skin.surface_compliance(kx, ky))[..., 0, 0])
        with np.errstate(divide="ignore"):
            exact = np.where(c > 0, 1.0 / np.where(c > 0, c, 1.0), 0.0)
        # k = 0: the stiffness of the grid's longest wave, as ContactCompliance.stiffness has it
        exact.flat[0] = exact[exact > 0].min() if (exact > 0).any() else 0.0
        lam = 4 * np.sin(kx * h / 2) ** 2 + 4 * np.sin(ky * h / 2) ** 2
        knyq = np.pi / H
        taper = (np.cos(np.minimum(np.abs(kx) / knyq, 1.0) * np.pi / 2) ** 2
                 * np.cos(np.minimum(np.abs(ky) / knyq, 1.0) * np.pi / 2) ** 2)
        diff = (exact - self.scale * (a + b * lam)) * taper
        self.correction = diff / FACTOR**2  # R's mean: the kernel sums the blocks
        # the coarse pair through kept per-thread arrays (scipy's calls on fresh ones cost a quarter of this
        # operator at 256^2); inverse_into leaves its 1 / rows to the multiplier
        self._scaled = (self.correction / self.coarse[0]).astype(complex)
        self._local = threading.local()

    def __call__(self, gap: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        gap = np.ascontiguousarray(gap, dtype=np.float32 if gap.dtype == np.float32 else float)  # float32: the solver's
        if gap.shape != self.shape:
            raise ValueError(f"gap: expected shape {self.shape} (the grid), got {gap.shape}")
        out = np.empty(self.shape) if out is None else out
        compiled = jit.enabled()
        work = getattr(self._local, "work", None)  # small work arrays, per thread: a kept operator may serve several
        if work is None:
            cy, cx = self.coarse
            work = self._local.work = (np.empty(self.coarse), np.empty((cy, cx // 2 + 1), complex),
                                       np.empty(self.coarse), np.empty(self.shape[1]))
        sums, spectrum, coarse, row = work
        if not compiled and gap.dtype != np.float64:
            gap = gap.astype(float)  # the NumPy twin in float64, as the kernels compute
        if compiled:
            _block_sums(gap, FACTOR, sums, row)
        else:
            sums[...] = _block_sums_numpy(gap, FACTOR)
        rfftn_into(sums, spectrum, workers=1)
        spectrum *= self._scaled
        inverse_into(spectrum, coarse, workers=1)
        if compiled:
            _stencil_plus_blocks(gap, self.centre, self.neighbour, coarse, FACTOR, out, row)
        elif out.dtype != np.float64:  # a float32 output (the solver's beside float32 products): in float64,
            # rounded once, as the compiled kernel does
            out[...] = _stencil_plus_blocks_numpy(gap, self.centre, self.neighbour, coarse, FACTOR, np.empty(self.shape))
        else:
            _stencil_plus_blocks_numpy(gap, self.centre, self.neighbour, coarse, FACTOR, out)
        return out


@jit.njit
def _block_sums(r, f, out, row):  # pragma: no cover - compiled; its twin is _block_sums_numpy
    ny, nx = r.shape
    for bi in range(ny // f):
        row[:] = 0.0
        for i in range(bi * f, bi * f + f):  # the block row's columns first: a vectorised loop
            mid = r[i]
            for j in range(nx):
                row[j] += mid[j]
        for bj in range(nx // f):
            s = 0.0
            for j in range(bj * f, bj * f + f):
                s += row[j]
            out[bi, bj] = s
    return out


def _block_sums_numpy(r: np.ndarray, f: int) -> np.ndarray:
    ny, nx = r.shape
    return r.reshape(ny // f, f, nx // f, f).sum(axis=(1, 3))


@jit.njit
def _stencil_plus_blocks(r, centre, neighbour, coarse, f, out, wide):  # pragma: no cover - compiled
    ny, nx = r.shape
    for i in range(ny):
        if i % f == 0:  # the block row's coarse values, widened to one per node
            for bj in range(nx // f):
                c = coarse[i // f, bj]
                for j in range(bj * f, bj * f + f):
                    wide[j] = c
        mid = r[i]
        above = r[i - 1] if i > 0 else r[ny - 1]
        below = r[i + 1] if i < ny - 1 else r[0]
        o = out[i]
        f64 = np.float64  # a float32 residual widened before the sums, as the NumPy twin computes
        o[0] = centre * mid[0] - neighbour * (f64(above[0]) + f64(below[0]) + f64(mid[nx - 1]) + f64(mid[1])) + wide[0]
        for j in range(1, nx - 1):  # no branch inside: vectorised
            o[j] = (centre * mid[j] - neighbour * (f64(above[j]) + f64(below[j]) + f64(mid[j - 1]) + f64(mid[j + 1]))
                    + wide[j])
        o[nx - 1] = (centre * mid[nx - 1] - neighbour * (f64(above[nx - 1]) + f64(below[nx - 1]) + f64(mid[nx - 2])
                                                         + f64(mid[0])) + wide[nx - 1])
    return out


def _stencil_plus_blocks_numpy(r, centre, neighbour, coarse, f, out):
    """The NumPy twin of the compiled kernel: the stencil by shifted slices of one scaled copy (periodic
    wrap at the edges), then the blocks' values."""
    side = neighbour * r
    np.multiply(r, centre, out=out)
    out[1:] -= side[:-1]
    out[0] -= side[-1]
    out[:-1] -= side[1:]
    out[-1] -= side[0]
    out[:, 1:] -= side[:, :-1]
    out[:, 0] -= side[:, -1]
    out[:, :-1] -= side[:, 1:]
    out[:, -1] -= side[:, 0]
    ny, nx = r.shape
    out.reshape(ny // f, f, nx // f, f)[...] += coarse[:, None, :, None]
    return out

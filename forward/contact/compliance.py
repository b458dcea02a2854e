"""Surface compliance on a grid: the operators that map surface tractions to surface displacements.

:class:`ContactCompliance` is the contact solvers' one view of the skin::

    C = ContactCompliance(skin, shape, spacing, periodic)
    uz = C.normal(p)                      # m, from p (Pa): one rfft + one irfft
    ux, uy = C.tangential(qx, qy)         # m, from qx, qy (Pa); uy (and qy) None in plane strain
    uz_q = C.normal_from_tangential(qx, qy)   # the (1 - 2 nu) coupling: uz from tangential tractions
    ux_p, uy_p = C.tangential_from_normal(p)  # and (ux, uy) from p
    uz, ux, uy = C.apply(p, qx, qy)       # all of it
    C.self_compliance                     # (Czz, Cxx, Cyy) at zero offset, m/Pa (a Jacobi scale)
    p_approx = C.stiffness(uz)            # Pa, the periodic inverse of normal (a preconditioner)
    K = C.preconditioner("auto")          # the normal solver's: stiffness, or its two-level approximation

Arrays have the grid's ``shape``: ``(nx,)`` (plane strain) or ``(ny, nx)`` (x last); node ``j``
sits at ``x_j = (j - nx // 2) dx`` as in :class:`~tactilab.forward.halfspace.SurfaceLoad`.
Conventions (docs/theory.md section 1): tractions act on the skin, ``p`` pushes into it, ``uz`` is
positive into the skin, ``qx, ux`` along +x. The full operator on ``(p, qx, qy)`` is symmetric
(Betti's reciprocity): its normal and tangential blocks are symmetric and
``normal_from_tangential`` is the adjoint of ``tangential_from_normal`` (a dot test checks it).

Two operators, chosen by ``periodic``:

- periodic (the grid is one period): the skin's ``surface_compliance(kx, ky)`` sampled at the
  grid's wavenumbers multiplies the DFT of the traction (the traction's trigonometric
  interpolant, loaded on the half-space). The ``k = 0`` mode is 0: a uniform traction gives no
  displacement, so displacements are defined up to a rigid shift, which the solver absorbs in the
  approach. At an even grid size the Nyquist entries of the odd-in-k terms (the cross terms and
  the ``xy`` term) are 0, so the operator stays real and symmetric.
- isolated (the traction is zero outside the grid): exact aperiodic convolution of the nodal
  tractions, each spread uniformly over its pixel, with the real-space influence coefficients of
  the skin's ``surface_influence`` (the exact pixel integrals of Boussinesq and Cerruti: Love's
  closed form for the normal entry), by FFT on a grid zero-padded to twice the size (DC-FFT). In
  plane strain the displacement of a line load is defined up to a constant: it is taken as zero
  at a distance of one grid length ``nx dx`` from the load. A skin without ``surface_influence``
  (a layered skin) gets its influence coefficients from its ``surface_compliance`` on a periodic
  grid ``PADDED_PERIODS`` times the zero-padded one per axis (nodal tractions, not pixels; the
  images' error is discussed in docs/theory.md section 6).

Each block's spectrum is computed on first use and kept (complex128, ``prod(padded)/2`` entries).
FFTs are ``scipy.fft`` with ``workers=1``, float64.
"""

from __future__ import annotations

import threading

import numpy as np
from scipy import fft as sfft

from tactilab.core import rules as check

from ..halfspace import fft_first_inplace, inverse_into, irfft_last_into, rfft_last_into, rfftn_into
from .coarse_stiffness import TwoLevelStiffness, applies, preferred

#: the normal solvers' preconditioners (:meth:`ContactCompliance.preconditioner`)
PRECONDITIONERS = ("auto", "fft", "two_level")

#: index of each displacement / traction component in the compliance matrices
_ROW = {"uz": 0, "ux": 1, "uy": 2}
_COL = {"p": 0, "qx": 1, "qy": 2}
#: rows of the kernel evaluated at a time (bounds the temporaries of a large grid)
_BAND = 128
#: isolated grids of skins without surface_influence: periodic grid per axis over the zero-padded one
PADDED_PERIODS = 4


class ContactCompliance:
    """Surface compliance of a skin on a regular grid, periodic or isolated (see the module docstring).

    Parameters
    ----------
    skin : object
        Provides ``surface_compliance(kx, ky)`` (periodic grids) and, for isolated grids,
        ``surface_influence(x, y, spacing, reference_length, entry=(row, column))``, as
        :class:`HalfSpace` does.
    shape : tuple of int
        ``(nx,)`` (plane strain) or ``(ny, nx)``.
    spacing : float or tuple of float
        ``dx`` or ``(dx, dy)`` in m, x first.
    periodic : bool
        True: the grid is one period; False: the traction is zero outside the grid.
    """

    def __init__(self, skin, shape, spacing, periodic: bool):
        shape = tuple(int(n) for n in np.atleast_1d(shape))
        if len(shape) not in (1, 2) or min(shape) < 1:
            raise ValueError(f"shape: expected (nx,) or (ny, nx) with at least one node per axis, got {shape}")
        if not isinstance(periodic, (bool, np.bool_)):
            raise ValueError(f"periodic: must be True or False, got {periodic!r}")
        has = {name: callable(getattr(skin, name, None)) for name in ("surface_compliance", "surface_influence")}
        if periodic and not has["surface_compliance"]:
            raise ValueError(f"skin: a periodic contact needs a skin with surface_compliance(...), got "
                             f"{type(skin).__name__}; use HalfSpace(E, nu)")
        if not periodic and not (has["surface_influence"] or has["surface_compliance"]):
            raise ValueError(f"skin: an isolated contact needs a skin with surface_influence(...) or "
                             f"surface_compliance(...), got {type(skin).__name__}; use HalfSpace(E, nu)")
        #: isolated grid of a skin without surface_influence: its influence comes from a periodic grid
        #: PADDED_PERIODS times the zero-padded one per axis (see _padded_influence)
        self.padded_periodic = not periodic and not has["surface_influence"]
        self.skin = skin
        self.shape = shape
        self.ndim = len(shape)
        self.spacing = check.spacing(spacing, self.ndim)
        self.periodic = bool(periodic)
        self.fft_shape = shape if periodic else tuple(2 * n for n in shape)
        self._axes = tuple(range(-self.ndim, 0))
        self._spectra: dict = {}  # (row, col) -> block spectrum; "stiffness" -> the preconditioner
        self._local = threading.local()  # per-thread work spectrum of the periodic 2-D products

    def __repr__(self) -> str:
        kind = "periodic" if self.periodic else "isolated"
        return f"ContactCompliance({self.skin!r}, shape={self.shape}, spacing={self.spacing}, {kind})"

    @property
    def n_components(self) -> int:
        """2 in plane strain (p, qx), 3 in 3-D (p, qx, qy)."""
        return 2 if self.ndim == 1 else 3

    # -- the kernel -------------------------------------------------------------------------
    def _block(self, key: tuple[int, int]) -> np.ndarray:
        """One entry of the compliance on the FFT grid: spectral symbol (periodic) or real-space
        influence coefficients (isolated), evaluated in bands of rows to bound the temporaries."""
        if self.periodic:
            return self._symbol(key, self.shape)
        if self.padded_periodic:
            return self._padded_influence(key)
        offsets = []
        for n, h in zip(self.shape, self.spacing[::-1] if self.ndim == 2 else self.spacing):
            idx = np.arange(2 * n)
            offsets.append(np.where(idx < n, idx, idx - 2 * n) * h)  # wrapped: index n is never read
        if self.ndim == 1:
            length = self.shape[0] * self.spacing[0]
            return np.asarray(self.skin.surface_influence(offsets[0], None, self.spacing, length, entry=key),
                              dtype=float)
        m = np.empty((len(offsets[0]), len(offsets[1])))
        for lo in range(0, len(offsets[0]), _BAND):
            m[lo:lo + _BAND] = self.skin.surface_influence(offsets[1][None, :], offsets[0][lo:lo + _BAND, None],
                                                           self.spacing, entry=key)
        return m

    def _symbol(self, key: tuple[int, int], shape: tuple[int, ...]) -> np.ndarray:
        """One entry of the skin's ``surface_compliance`` on the rfft half spectrum of a periodic grid of
        ``shape`` (this grid's spacing), with the odd terms 0 on the Nyquist column and row."""
        i, j = key
        odd = i != j  # the cross terms and xy are odd in k
        kx = 2 * np.pi * sfft.rfftfreq(shape[-1], self.spacing[0])
        if self.ndim == 1:
            m = np.array(np.asarray(self.skin.surface_compliance(kx, None))[..., i, j], dtype=complex)
            if odd and shape[0] % 2 == 0:
                m[-1] = 0.0
            return m
        ky = 2 * np.pi * sfft.fftfreq(shape[0], self.spacing[1])
        m = np.empty((len(ky), len(kx)), dtype=complex)
        for lo in range(0, len(ky), _BAND):
            band = self.skin.surface_compliance(kx[None, :], ky[lo:lo + _BAND, None])
            m[lo:lo + _BAND] = np.asarray(band)[..., i, j]
        if odd and shape[-1] % 2 == 0:
            m[:, -1] = 0.0
        if odd and shape[0] % 2 == 0:
            m[shape[0] // 2] = 0.0
        return m

    def _padded_influence(self, key: tuple[int, int]) -> np.ndarray:
        """Influence coefficients of an isolated grid for a skin known only by its ``surface_compliance``.

        The periodic influence of one node (the spectral symbol on a grid :data:`PADDED_PERIODS` times the
        zero-padded grid per axis, inverse-transformed), read at the offsets the aperiodic convolution
        uses (``|offset| < n`` nodes per axis). Its error is that of the periodic images, at least
        ``(2 PADDED_PERIODS - 1) n`` nodes away: exponentially small for layers on a rigid base (their
        influence decays over the layer thickness); for a skin on a half-space the ``k = 0`` entry is 0, so
        the coefficients are shifted by a constant (absorbed in the approach) plus a smooth remainder of
        relative size about ``(n / (2 PADDED_PERIODS n))^2`` (docs/contact.md, layered skins).
        """
        big = tuple(PADDED_PERIODS * m for m in self.fft_shape)
        g = sfft.irfftn(self._symbol(key, big), s=big, axes=self._axes, workers=1)
        index = []
        for n in self.shape:
            idx = np.arange(2 * n)
            index.append(np.where(idx < n, idx, idx - 2 * n))  # wrapped offsets, read from the big periodic grid
        return g[np.ix_(*index)] if self.ndim == 2 else g[index[0]]

    def spectrum(self, row: str, col: str) -> np.ndarray:
        """Cached rfft spectrum of one block (``row`` in uz, ux, uy; ``col`` in p, qx, qy)."""
        key = (_ROW[row], _COL[col])
        if max(key) >= self.n_components:
            raise ValueError(f"{row}/{col}: a plane-strain grid has only uz, ux and p, qx")
        if key not in self._spectra:
            m = self._block(key)
            self._spectra[key] = m if self.periodic else sfft.rfftn(m, axes=self._axes, workers=1)
        return self._spectra[key]

    @property
    def self_compliance(self) -> tuple[float, ...]:
        """Displacement at a node per unit traction at that node, ``(Czz, Cxx[, Cyy])`` in m/Pa."""
        out = []
        for name, col in (("uz", "p"), ("ux", "qx"), ("uy", "qy"))[: self.n_components]:
            s = self.spectrum(name, col)
            out.append(float(sfft.irfftn(s, s=self.fft_shape, axes=self._axes, workers=1).flat[0]))
        return tuple(out)

    def stiffness(self, gap, out: np.ndarray | None = None) -> np.ndarray:
        """The periodic surface stiffness of the grid applied to ``gap`` (m -> Pa): the inverse of the
        periodic normal compliance on the unpadded grid (``E* |k| / 2`` for a half-space; at ``k = 0``
        the value of the grid's longest wave).

        Exactly the inverse of :meth:`normal` on zero-mean fields of a periodic grid; for an isolated
        grid an approximate inverse (the solvers' preconditioner), at the cost of an unpadded FFT pair.
        """
        self.stiffness_spectrum()
        gap = self._check(gap, "gap")
        if self.ndim == 2:  # periodic or not, the stiffness acts on the unpadded grid: kept work arrays
            return self._periodic_product(gap, "stiffness", out)
        spectrum = sfft.rfftn(gap, axes=self._axes, workers=1)
        spectrum *= self._spectra["stiffness"]
        out = np.empty(self.shape) if out is None else out
        out[...] = sfft.irfftn(spectrum, s=self.shape, axes=self._axes, workers=1)
        return out

    def stiffness_spectrum(self) -> np.ndarray:
        """The multiplier of :meth:`stiffness` on the unpadded grid's rfft half spectrum, Pa/m (kept)."""
        if "stiffness" not in self._spectra:
            kx = 2 * np.pi * sfft.rfftfreq(self.shape[-1], self.spacing[0])
            if self.ndim == 1:
                c = np.real(np.asarray(self.skin.surface_compliance(kx, None))[..., 0, 0])
            else:
                ky = 2 * np.pi * sfft.fftfreq(self.shape[0], self.spacing[1])
                c = np.real(np.asarray(self.skin.surface_compliance(kx[None, :], ky[:, None]))[..., 0, 0])
            with np.errstate(divide="ignore"):
                stiff = np.where(c > 0, 1.0 / np.where(c > 0, c, 1.0), 0.0)
            # k = 0: the stiffness of the longest wave on the grid, so that a uniform gap still moves
            # the pressure (an isolated contact under a given approach); force control removes the mean
            stiff.flat[0] = stiff[stiff > 0].min() if (stiff > 0).any() else 0.0
            self._spectra["stiffness"] = stiff
        return self._spectra["stiffness"]

    def preconditioner(self, kind: str = "auto"):
        """The normal solvers' preconditioner, a callable ``(gap, out=None) -> pressure`` (m -> Pa).

        ``"fft"``: :meth:`stiffness` (an FFT pair of the unpadded grid); ``"two_level"``: the
        two-level approximation of :mod:`.coarse_stiffness` (a local stencil plus a coarse-grid
        correction, about a tenth of that pair; periodic 2-D grids of square pixels, sides multiples
        of 8, at least 16); ``"auto"``: ``"two_level"`` where it applies and its kernels are compiled
        (numba), ``"fft"`` elsewhere (isolated grids, whose pruned compliance product costs about twice
        the preconditioner's pair, keep the exact one: docs/contact.md, Cost).
        """
        if kind not in PRECONDITIONERS:
            raise ValueError(f"preconditioner: must be one of {PRECONDITIONERS}, got {kind!r}")
        if kind == "two_level" and not applies(self.shape, self.spacing, self.periodic):
            raise ValueError(f"preconditioner: 'two_level' needs a periodic 2-D grid of square pixels with sides "
                             f"multiples of 8 (at least 16), got {self!r}; use 'fft' or 'auto'")
        if kind == "fft" or (kind == "auto" and not preferred(self.shape, self.spacing, self.periodic)):
            return self.stiffness
        if "two_level" not in self._spectra:
            self._spectra["two_level"] = TwoLevelStiffness(self.skin, self.shape, self.spacing)
        return self._spectra["two_level"]

    def _periodic_product(self, value: np.ndarray, key, out: np.ndarray | None) -> np.ndarray:
        """A multiplier's product on a periodic 2-D grid, transformed into a kept work spectrum and
        straight into ``out``: fresh spectrum-sized temporaries cost as much as the FFTs at 512^2
        (page faults), so the solvers' two products per iteration reuse memory."""
        scaled = ("scaled", key)
        if scaled not in self._spectra:  # inverse_into leaves the inverse's 1 / ny to the multiplier
            self._spectra[scaled] = (self._spectra["stiffness"] if key == "stiffness"
                                     else self.spectrum(*key)) / self.shape[0]
        work = getattr(self._local, "work", None)
        if work is None:
            work = self._local.work = np.empty((self.shape[0], self.shape[1] // 2 + 1), complex)
        rfftn_into(np.ascontiguousarray(value), work, workers=1)
        work *= self._spectra[scaled]
        out = np.empty(self.shape) if out is None else out
        return inverse_into(work, out, workers=1)

    def _padded_product(self, value: np.ndarray, key: tuple[str, str], out: np.ndarray | None) -> np.ndarray:
        """A block's product on an isolated 2-D grid, pruned as :meth:`rfft` and :meth:`_inverse` are,
        through two kept per-thread work arrays instead of fresh padded temporaries (which page-fault
        on every call: 1.3 padded FFT pairs per product at 512^2 through ``scipy.fft``'s pruned
        calls, 0.8 this way, the same values to round-off).

        Passes besides the transforms: ``value`` copied into the rows' left half and their right half
        zeroed, the padding's rows of the spectrum zeroed, the multiply, the result copied out (scaled by
        the column inverse's ``1 / (2 ny)``); plain copies and fills that NumPy runs at memory speed."""
        ny, nx = self.shape
        buffers = getattr(self._local, "padded", None)
        if buffers is None:  # rows: (ny, 2 nx) real, the data and their padding; work: the padded half spectrum
            buffers = self._local.padded = (np.empty((ny, 2 * nx)), np.empty((2 * ny, nx + 1), complex))
        rows, work = buffers
        rows[:, :nx] = value
        rows[:, nx:] = 0.0  # the previous call's inverse wrote there
        rfft_last_into(rows, work[:ny], workers=1)  # only the rows that hold data
        work[ny:] = 0.0
        fft_first_inplace(work, True, workers=1)
        work *= self.spectrum(*key)
        fft_first_inplace(work, False, workers=1)
        irfft_last_into(work[:ny], rows, workers=1)  # only the rows that lie on the grid
        out = np.empty(self.shape) if out is None else out
        return np.multiply(rows[:, :nx], 1.0 / (2 * ny), out=out)

    # -- products ---------------------------------------------------------------------------
    def _check(self, value, name: str) -> np.ndarray:
        arr = np.asarray(value, dtype=float)
        if arr.shape != self.shape:
            raise ValueError(f"{name}: expected shape {self.shape} (the grid), got {arr.shape}")
        return arr

    def rfft(self, value) -> np.ndarray:
        """The (zero-padded) rfft of a grid array: the input of :meth:`product`.

        On an isolated 2-D grid the transform is pruned: the rows along x are transformed only
        where the data are (``ny`` of the ``2 ny`` padded rows, the rest are zeros), then the columns
        along y, zero-padded by the transform itself; the same spectrum as ``rfftn(value, s=padded)``
        to round-off, without building the padded array (about half the time at 512^2).
        """
        if self.periodic or self.ndim == 1:
            return sfft.rfftn(value, s=self.fft_shape, axes=self._axes, workers=1)
        rows = sfft.rfft(value, n=self.fft_shape[1], axis=1, workers=1)
        return sfft.fft(rows, n=self.fft_shape[0], axis=0, workers=1, overwrite_x=True)

    def _inverse(self, spectrum: np.ndarray) -> np.ndarray:
        """The grid's part of the inverse of :meth:`rfft` (``spectrum`` may be overwritten).

        Isolated 2-D grids: the columns' inverse along y over the whole padded spectrum, then the
        rows' inverse along x only for the ``ny`` rows that lie on the grid (pruned as :meth:`rfft`)."""
        if self.periodic:
            return sfft.irfftn(spectrum, s=self.fft_shape, axes=self._axes, workers=1)
        if self.ndim == 1:
            return sfft.irfft(spectrum, n=self.fft_shape[0], workers=1)[: self.shape[0]]
        cols = sfft.ifft(spectrum, axis=0, workers=1, overwrite_x=True)[: self.shape[0]]
        return sfft.irfft(cols, n=self.fft_shape[1], axis=1, workers=1)[:, : self.shape[1]]

    def product(self, spectra: dict[str, np.ndarray], row: str) -> np.ndarray:
        """Displacement ``row`` (m, grid shape) from traction spectra ``{"p": rfft(p), ...}``."""
        total = None
        for col, s in spectra.items():
            term = self.spectrum(row, col) * s
            total = term if total is None else total + term
        return self._inverse(total)

    def normal(self, p, out: np.ndarray | None = None) -> np.ndarray:
        """``uz`` (m, positive into the skin) from the pressure ``p`` (Pa); into ``out`` if given
        (a C-contiguous float array of the grid's shape, not ``p``)."""
        p = self._check(p, "p")
        if self.periodic and self.ndim == 2:
            return self._periodic_product(p, ("uz", "p"), out)
        if self.ndim == 2:
            return self._padded_product(p, ("uz", "p"), out)
        spectrum = self.rfft(p)
        spectrum *= self.spectrum("uz", "p")  # in place: the solvers call this every iteration
        if out is None:
            return self._inverse(spectrum)
        out[...] = self._inverse(spectrum)
        return out

    def add_normal_point_loads(self, u: np.ndarray, nodes: np.ndarray, values: np.ndarray) -> None:
        """``u += normal(c)`` in place for a pressure ``c`` that is non-zero at a few nodes only
        (``nodes``: flat indices, ``values``: Pa), by direct summation of the influence coefficients:
        one pass over the grid per node, cheaper than an FFT pair for up to about
        :attr:`direct_limit` nodes. Equal to :meth:`normal` to round-off (the same coefficients)."""
        kernel = self._centred_kernel()
        idx = np.unravel_index(nodes, self.shape)
        for k, value in enumerate(values):
            window = tuple(slice(n - int(i[k]), 2 * n - int(i[k])) for n, i in zip(self.shape, idx))
            u += value * kernel[window]

    @property
    def direct_limit(self) -> int:
        """Nodes up to which :meth:`add_normal_point_loads` is cheaper than an FFT pair (a cost model:
        an FFT pair of ``M`` points costs about ``M log2(M) / 2`` passes over the grid's nodes)."""
        m = float(np.prod(self.fft_shape))
        return int(m * np.log2(max(m, 2.0)) / (2 * np.prod(self.shape)))

    def _centred_kernel(self) -> np.ndarray:
        """The normal influence coefficients on offsets ``-n .. n - 1`` per axis (index ``n`` is offset
        0), so that node ``j``'s influence on the grid is the window ``[n - j, 2 n - j)``."""
        if "centred" not in self._spectra:
            s = self.spectrum("uz", "p")
            g = sfft.irfftn(s, s=self.fft_shape, axes=self._axes, workers=1)
            # periodic: the kernel repeats (tile it); isolated: offsets beyond the grid wrap in the padding
            self._spectra["centred"] = np.tile(g, (2,) * self.ndim) if self.periodic else \
                np.roll(g, self.shape, axis=self._axes)
        return self._spectra["centred"]

    def tangential(self, qx, qy=None) -> tuple[np.ndarray, np.ndarray | None]:
        """``(ux, uy)`` in m from the tangential tractions (Pa); ``uy`` is None in plane strain."""
        spectra = self._tangential_spectra(qx, qy)
        uy = self.product(spectra, "uy") if self.ndim == 2 else None
        return self.product(spectra, "ux"), uy

    def normal_from_tangential(self, qx, qy=None) -> np.ndarray:
        """``uz`` (m) produced by the tangential tractions alone (0 at nu = 1/2)."""
        return self.product(self._tangential_spectra(qx, qy), "uz")

    def tangential_from_normal(self, p) -> tuple[np.ndarray, np.ndarray | None]:
        """``(ux, uy)`` in m produced by the pressure alone (0 at nu = 1/2); ``uy`` None in plane strain."""
        spectra = {"p": self.rfft(self._check(p, "p"))}
        uy = self.product(spectra, "uy") if self.ndim == 2 else None
        return self.product(spectra, "ux"), uy

    def apply(self, p, qx=None, qy=None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """``(uz, ux, uy)`` in m from ``(p, qx, qy)`` in Pa (None means zero); ``uy`` None in plane strain."""
        spectra = {"p": self.rfft(self._check(p, "p"))}
        if qx is not None or qy is not None:
            spectra.update(self._tangential_spectra(qx, qy))
        uz = self.product(spectra, "uz")
        ux = self.product(spectra, "ux")
        uy = self.product(spectra, "uy") if self.ndim == 2 else None
        return uz, ux, uy

    def _tangential_spectra(self, qx, qy) -> dict[str, np.ndarray]:
        if self.ndim == 1 and qy is not None:
            raise ValueError("qy: a plane-strain grid has no y traction; give qx only")
        spectra = {}
        if qx is not None:
            spectra["qx"] = self.rfft(self._check(qx, "qx"))
        if qy is not None:
            spectra["qy"] = self.rfft(self._check(qy, "qy"))
        if not spectra:
            spectra["qx"] = self.rfft(np.zeros(self.shape))
        return spectra

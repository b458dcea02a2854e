"""The normal solver's clip correction in single precision: ``uz += A c`` for a pressure ``c`` that
is non-zero at the many nodes one step clipped, by an FFT pair in float32.

The preconditioned CG (:mod:`.preconditioned`) updates ``uz = A p`` with the step and adds the
pressure that brings each clipped node back to 0. When more nodes clip than a direct summation
affords (``ContactCompliance.direct_limit``), it used to recompute ``A p`` by a float64 FFT pair
(about a floor of the grid each, after 0.5 to 0.7 of the iterations on a periodic rough surface).
Here the correction ``A c`` is computed instead, by the same transforms in float32 through kept
work arrays: 0.5 to 0.75 of the float64 product's time (the transforms run at about half the
float64 time; the scatter, the conversion and the addition stay), with an error of 1.0e-7 to
1.8e-7 of max |A c| (float32's rounding through the transform's stages), bounded by
:meth:`SingleCorrection.bound`. The solver uses it while the accumulated bound stays below a
hundredth of the gap residual (early, when many nodes clip, the residual is large), and keeps the
exact float64 recompute every ``REFRESH`` iterations and before convergence is declared, so the
answer's tolerance is unchanged; measured on the surfaces of docs/contact.md (Table a): the same
iterations, a sixth to a third fewer float64 products (docs/contact.md, Cost). :meth:`SingleCorrection.product`
runs the solver's dense direction product ``A t`` the same way on periodic 2-D grids (docs/contact.md,
Table a3).
"""

from __future__ import annotations

import threading

import numpy as np
from scipy import fft as sfft

from ..halfspace import fft_first_inplace, inverse_into, irfft_last_into, rfft_last_into, rfftn_into

#: the correction's error bound relative to ``Czz sum(c)``, the most ``A c`` can reach (measured: 1.0e-7 to
#: 1.8e-7 of max |A c|; the tests hold it to this)
RELATIVE_ERROR = 1e-6


class SingleCorrection:
    """``uz += A c`` in float32 for a sparse pressure ``c`` (Pa), ``A`` the compliance's normal block.

    Parameters
    ----------
    compliance : ContactCompliance
        Its ``spectrum("uz", "p")`` (m/Pa per wave, on its ``fft_shape``: the grid, or the grid
        zero-padded to twice each side for an isolated contact) is kept in complex64.

    Notes
    -----
    ``add(u, nodes, values)`` adds ``A c`` (m) to ``u`` in place (float64, the grid's shape), ``c``
    being ``values`` (Pa) at the flat indices ``nodes`` and 0 elsewhere; ``apply(c)`` returns it for a
    dense ``c``. A kept float32 grid per thread holds ``c`` (zero between calls; the spectra are fresh).
    """

    def __init__(self, compliance):
        self.shape, self.fft_shape = tuple(compliance.shape), tuple(compliance.fft_shape)
        self._axes = tuple(range(-len(self.shape), 0))
        self._mode = "1-D" if len(self.shape) == 1 else "periodic" if compliance.periodic else "padded"
        spectrum = compliance.spectrum("uz", "p")
        # the 2-D inverses below leave their 1 / (rows) to the multiplier, as ContactCompliance's do
        rows = {"periodic": self.shape[0], "padded": self.fft_shape[0]}.get(self._mode, 1)
        self.spectrum = (spectrum / rows).astype(np.complex64)
        self._local = threading.local()  # each thread's kept float32 work arrays
        self._czz = _at_origin(spectrum, self.fft_shape)

    @property
    def periodic_2d(self) -> bool:
        """Whether the grid is a periodic 2-D one (the only kind :meth:`product` takes)."""
        return self._mode == "periodic"

    def bound(self, values: np.ndarray) -> float:
        """A bound on max |error| of :meth:`add` (m) for the pressures ``values`` (Pa, >= 0)."""
        return RELATIVE_ERROR * self._czz * float(np.sum(values))

    def apply(self, c: np.ndarray) -> np.ndarray:
        """``A c`` (m, float64, the grid's shape) for a dense pressure ``c`` (Pa, the grid's shape)."""
        c = np.asarray(c, dtype=float)
        if c.shape != self.shape:
            raise ValueError(f"c: expected the grid's shape {self.shape}, got {c.shape}")
        out = np.zeros(self.shape)
        nodes = np.flatnonzero(c)
        self.add(out, nodes, c.reshape(-1)[nodes])
        return out

    def product(self, t: np.ndarray, out: np.ndarray) -> np.ndarray:
        """``out[...] = A t`` (m, float64) for a dense pressure ``t`` (Pa, float64, the grid's shape) by a
        float32 FFT pair; periodic 2-D grids only (the solver's mixed-precision product, error of the
        order of :data:`RELATIVE_ERROR` of max |A t|, bounded by :meth:`product_bound`)."""
        if self._mode != "periodic":
            raise ValueError(f"product: float32 dense products need a periodic 2-D grid, got a {self._mode} "
                             "one; use the compliance's float64 product")
        buffers = getattr(self._local, "buffers", None)
        if buffers is None:
            buffers = self._local.buffers = self._buffers()
        data, spectrum = buffers
        data[...] = t
        try:
            rfftn_into(data, spectrum, workers=1)
            spectrum *= self.spectrum
            out[...] = inverse_into(spectrum, data, workers=1)
        finally:
            data[...] = 0.0  # kept zero for add()
        return out

    def product_bound(self, peak: float) -> float:
        """A bound on max |error| of :meth:`product` (m) for a result of max |A t| = ``peak`` (m)."""
        return RELATIVE_ERROR * peak

    def add(self, u: np.ndarray, nodes: np.ndarray, values: np.ndarray) -> None:
        """``u += A c`` in place, ``c`` = ``values`` (Pa) at the flat grid indices ``nodes``."""
        if self._mode == "1-D":  # plane strain: small, plain transforms
            work = np.zeros(self.shape, dtype=np.float32)
            work[nodes] = values
            spectrum = sfft.rfft(work, n=self.fft_shape[0], workers=1) * self.spectrum
            u += sfft.irfft(spectrum, n=self.fft_shape[0], workers=1)[: self.shape[0]]
            return
        buffers = getattr(self._local, "buffers", None)
        if buffers is None:
            buffers = self._local.buffers = self._buffers()
        data, spectrum = buffers
        data[np.unravel_index(nodes, self.shape)] = values
        try:
            self._transform(u, data, spectrum)
        finally:
            data[...] = 0.0  # kept zero for the next call

    def _transform(self, u: np.ndarray, data: np.ndarray, spectrum: np.ndarray) -> None:
        """``u += A c`` for ``c`` in the kept grid ``data`` (overwritten) through the work ``spectrum``."""
        if self._mode == "periodic":
            rfftn_into(data, spectrum, workers=1)
            spectrum *= self.spectrum
            u += inverse_into(spectrum, data, workers=1)
            return
        # isolated 2-D: pruned as ContactCompliance's padded product (the padding's rows never transformed)
        ny, nx = self.shape
        rfft_last_into(data, spectrum[:ny], workers=1)
        spectrum[ny:] = 0.0
        fft_first_inplace(spectrum, True, workers=1)
        spectrum *= self.spectrum
        fft_first_inplace(spectrum, False, workers=1)
        u += irfft_last_into(spectrum[:ny], data, workers=1)[:, :nx]

    def _buffers(self) -> tuple[np.ndarray, np.ndarray]:
        """The kept float32 grid (zero between calls; padded rows of twice the width when isolated) and
        the complex64 work spectrum."""
        ny, nx = self.shape
        if self._mode == "periodic":
            return np.zeros((ny, nx), np.float32), np.empty((ny, nx // 2 + 1), np.complex64)
        return np.zeros((ny, 2 * nx), np.float32), np.empty((2 * ny, nx + 1), np.complex64)


def _at_origin(spectrum: np.ndarray, shape: tuple[int, ...]) -> float:
    """The inverse rfft of ``spectrum`` at offset 0 (``ContactCompliance.self_compliance``'s Czz, m/Pa),
    from one pass over the half spectrum: the full spectrum's sum over its size, the half's columns
    other than 0 and Nyquist counted twice."""
    weights = np.full(spectrum.shape[-1], 2.0)
    weights[0] = 1.0
    if shape[-1] % 2 == 0:
        weights[-1] = 1.0
    columns = spectrum.real.sum(axis=tuple(range(spectrum.ndim - 1))) if spectrum.ndim > 1 else spectrum.real
    return float(columns @ weights) / float(np.prod(shape))

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
iterations, a sixth to a third fewer float64 products (docs/contact.md, Cost). The correction comes
back in float32 (:meth:`SingleCorrection.correction`), for the solver's next gap pass to add, and its
bound a posteriori is :meth:`SingleCorrection.product_bound` of its max. The solver's dense direction
product ``A t`` runs the same way on 2-D grids (:meth:`SingleCorrection.transform_direction`), and so
do the exact stiffness (:meth:`SingleCorrection.stiffness`) and, from float32 coefficients, the direct
summation of a few clipped nodes (:attr:`SingleCorrection.points`; docs/contact.md, Table a4).
"""

from __future__ import annotations

import threading
import weakref

import numpy as np
from scipy import fft as sfft

from tactilab.core import jit

from ..halfspace import fft_first_inplace, inverse_into, irfft_last_into, rfft_last_into, rfftn_into
from .point_loads import PointLoads
from .step_kernels import scale_energy
from .work_arrays import carve

#: the correction's error bound relative to ``Czz sum(c)``, the most ``A c`` can reach (measured: 1.0e-7 to
#: 1.8e-7 of max |A c|; the tests hold it to this)
RELATIVE_ERROR = 1e-6


#: the float32 products kept per compliance operator (the solver's operators are kept between solves:
#: starts.grid_operator) where they hold at most this many bytes (periodic grids up to 512^2, isolated up to
#: 256^2): a solve on a grid solved before skips their set-up (the float32 spectrum, the origin value, the
#: point loads' coefficients, the first touch of the work arrays: 2 floors of the grid per solve at 256^2,
#: 3 at 512^2); larger ones are made per solve (work arrays kept separately, the 512^2 one raised the peak
#: memory of a 1024^2 solve by 20 MiB, by the heap's fragmentation: now one allocation, work_arrays.carve)
KEPT_BYTES = 6 * 2**20
_KEPT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_KEPT_LOCK = threading.Lock()


def kept(compliance) -> SingleCorrection:
    """The :class:`SingleCorrection` of ``compliance``: kept while ``compliance`` lives if it holds at most
    :data:`KEPT_BYTES`, else a new one."""
    per_node = 18 if compliance.periodic or len(compliance.shape) == 1 else 64  # bytes: work, spectrum, points
    if per_node * int(np.prod(compliance.shape)) > KEPT_BYTES:
        return SingleCorrection(compliance)
    with _KEPT_LOCK:
        single = _KEPT.get(compliance)
        if single is None:
            single = _KEPT[compliance] = SingleCorrection(compliance)
        return single


class SingleCorrection:
    """``uz += A c`` in float32 for a sparse pressure ``c`` (Pa), ``A`` the compliance's normal block.

    Parameters
    ----------
    compliance : ContactCompliance
        Its ``spectrum("uz", "p")`` (m/Pa per wave, on its ``fft_shape``: the grid, or the grid
        zero-padded to twice each side for an isolated contact) is kept in float32 (real: the
        compliance is symmetric).

    Notes
    -----
    ``add(u, nodes, values)`` adds ``A c`` (m) to ``u`` in place (float64, the grid's shape), ``c``
    being ``values`` (Pa) at the flat indices ``nodes`` and 0 elsewhere; ``apply(c)`` returns it for a
    dense ``c``; :meth:`correction` returns it in float32 (a kept array). :meth:`product` computes a dense
    ``A t`` (2-D grids); the solver's float32 direction goes through :meth:`transform_direction` without
    converting. Kept float32 work arrays per thread (about 12 bytes
    per grid node periodic, 40 isolated).
    """

    def __init__(self, compliance):
        self.shape, self.fft_shape = tuple(compliance.shape), tuple(compliance.fft_shape)
        self._axes = tuple(range(-len(self.shape), 0))
        self._mode = "1-D" if len(self.shape) == 1 else "periodic" if compliance.periodic else "padded"
        spectrum = compliance.spectrum("uz", "p")
        # the 2-D inverses below leave their 1 / (rows) to the multiplier, as ContactCompliance's do
        rows = {"periodic": self.shape[0], "padded": self.fft_shape[0]}.get(self._mode, 1)
        # real: the normal compliance is symmetric (an even kernel), its spectrum real to round-off
        self.spectrum = (spectrum.real / rows).astype(np.float32)
        self._local = threading.local()  # each thread's kept float32 work arrays
        self._czz = _at_origin(spectrum, self.fft_shape)
        # the stiffness's float32 multiplier, made on first use (a weak reference: _KEPT's values must not
        # keep its keys alive)
        self._compliance, self._stiffness, self._points = weakref.ref(compliance), None, None

    @property
    def dense_2d(self) -> bool:
        """Whether the grid is a 2-D one, periodic or isolated (the kinds :meth:`product` takes)."""
        return self._mode != "1-D"

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
        """``out[...] = A t`` (m) for a dense pressure ``t`` (Pa, the grid's shape) by a float32 FFT pair;
        2-D grids only (error of the order of :data:`RELATIVE_ERROR` of max |A t|, bounded by
        :meth:`product_bound`). The solver's path is :meth:`transform_direction`, which spares the
        conversions."""
        if self._mode == "1-D":
            raise ValueError("product: float32 dense products need a 2-D grid, got a 1-D one (plane strain); use "
                             "the compliance's float64 product")
        grid = self._work()["grid"]
        grid[...] = t
        out[...] = self.transform_direction(grid)[0]
        return out

    def transform_direction(self, t: np.ndarray, compiled: bool | None = None) -> tuple[np.ndarray, float]:
        """``A t`` (m, float32, the grid's shape) for a float32 direction ``t`` (Pa, the grid's shape,
        C-contiguous; the solver's own, or the kept grid) by a float32 FFT pair, and ``<A t, t>`` (m Pa)
        by Parseval from ``t``'s spectrum in the multiplier's pass (:func:`.step_kernels.scale_energy`,
        compiled or its NumPy twin; None: compiled where numba runs); the result is a kept array, valid
        until this thread's next call of any method."""
        compiled = jit.enabled() if compiled is None else compiled
        work = self._work()
        out, spectrum = work["grid"], work["spectrum"]  # t is read before the result is written
        if self._mode == "periodic":
            rfftn_into(t, spectrum, workers=1)
            energy = scale_energy(spectrum, self.spectrum, self.shape[1] % 2 == 0, compiled)
            inverse_into(spectrum, out, workers=1)
            return out, energy / self.shape[1]
        rows = work["rows"]
        rows[:, : self.shape[1]] = t
        rows[:, self.shape[1]:] = 0.0  # the previous inverse wrote there
        energy = self._padded(rows, rows, spectrum, compiled)
        out[...] = rows[:, : self.shape[1]]
        return out, energy / self.fft_shape[1]

    def stiffness(self, gap: np.ndarray, out: np.ndarray) -> np.ndarray:
        """``out[...] = K gap`` (Pa; ``out`` float64, or float32 as the solver's beside float32 products)
        for a gap (m, the grid's shape, float64 or float32; 2-D grids): the compliance's exact stiffness
        (:meth:`ContactCompliance.stiffness`, the preconditioner of isolated grids) by a float32 FFT pair of
        the unpadded grid, to about 1e-7 of its values. A preconditioner needs no more: the convergence
        test reads the gap, not ``K``. Uses the kept float32 grid (the solver applies it before the
        direction's product)."""
        work = self._work()
        data = work["grid"]
        spectrum = work["spectrum"] if self._mode == "periodic" else work.setdefault(
            "grid_spectrum", np.empty((self.shape[0], self.shape[1] // 2 + 1), np.complex64))
        if self._stiffness is None:  # inverse_into leaves its 1 / ny to the multiplier
            self._stiffness = (self._compliance().stiffness_spectrum() / self.shape[0]).astype(np.complex64)
        if gap.dtype == np.float32 and gap.flags.c_contiguous:  # the solver's float32 residual, as it is
            rfftn_into(gap, spectrum, workers=1)
        else:
            data[...] = gap
            rfftn_into(data, spectrum, workers=1)
        spectrum *= self._stiffness
        if out.dtype == np.float32 and out.flags.c_contiguous:
            return inverse_into(spectrum, out, workers=1)
        out[...] = inverse_into(spectrum, data, workers=1)
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
        u += self.correction(nodes, values)

    @property
    def points(self) -> PointLoads:
        """The direct summation of a few point loads from float32 coefficients (:mod:`.point_loads`, 2-D
        grids), made on first use and kept with this object."""
        if self._points is None:
            self._points = PointLoads(self._compliance())
        return self._points

    def correction(self, nodes: np.ndarray, values: np.ndarray) -> np.ndarray:
        """``A c`` (m, float32, the grid's shape; 2-D grids), ``c`` = ``values`` (Pa) at the flat grid
        indices ``nodes``: a kept array, valid until this thread's next call of any method (the solver adds
        it to ``u`` in its next gap pass)."""
        work = self._work()
        scatter, spectrum, out = work["scatter"], work["spectrum"], work["grid"]
        # flat indices into the scatter grid (np.unravel_index cost up to a quarter of a floor at 256^2)
        index = nodes if self._mode == "periodic" else nodes + (nodes // self.shape[1]) * self.shape[1]
        flat = scatter.reshape(-1)
        flat[index] = values
        try:
            if self._mode == "periodic":
                rfftn_into(scatter, spectrum, workers=1)  # the input is kept: zeroed at the nodes after
                spectrum *= self.spectrum
                inverse_into(spectrum, out, workers=1)
            else:
                rows = work["rows"]
                self._padded(scatter, rows, spectrum)
                out[...] = rows[:, : self.shape[1]]
        finally:
            flat[index] = 0.0  # kept zero for the next call: only the nodes were written
        return out

    def _padded(self, data: np.ndarray, rows: np.ndarray, spectrum: np.ndarray, compiled: bool | None = None) -> float:
        """``rows`` = the padded float32 product of ``data`` (``(ny, 2 nx)``, its right half zero),
        pruned as ContactCompliance's padded product (the padding's rows never transformed); the grid's
        part is ``rows[:, :nx]``. ``data`` is read only (``rows`` may be it). With ``compiled`` (True or
        False) the multiplier's pass also returns ``sum(multiplier |spectrum|^2)`` (:func:`scale_energy`)."""
        ny = self.shape[0]
        rfft_last_into(data, spectrum[:ny], workers=1)
        spectrum[ny:] = 0.0
        fft_first_inplace(spectrum, True, workers=1)
        energy = 0.0
        if compiled is None:
            spectrum *= self.spectrum
        else:
            energy = scale_energy(spectrum, self.spectrum, True, compiled)
        fft_first_inplace(spectrum, False, workers=1)
        irfft_last_into(spectrum[:ny], rows, workers=1)
        return energy

    def _work(self) -> dict[str, np.ndarray]:
        """This thread's kept float32 work arrays: ``grid`` (the grid's shape: in turn the direction's
        product, a correction, the stiffness's input; each is used up before the next is written, in the
        solver's order), ``scatter`` (the corrections' input, zero between calls; padded
        rows of twice the width when isolated), ``spectrum`` (complex64) and, when isolated, ``rows`` (the
        padded transforms' output) and ``grid_spectrum`` (the unpadded stiffness's, made on first use)."""
        work = getattr(self._local, "work", None)
        if work is None:  # one allocation (work_arrays.carve): a large grid's is returned to the system whole
            ny, nx = self.shape
            names = ("grid", "scatter", "spectrum") if self._mode == "periodic" else ("grid", "scatter", "rows", "spectrum")
            specs = [((ny, nx), np.float32), ((ny, nx), np.float32), ((ny, nx // 2 + 1), np.complex64)] \
                if self._mode == "periodic" else [((ny, nx), np.float32), ((ny, 2 * nx), np.float32),
                                                  ((ny, 2 * nx), np.float32), ((2 * ny, nx + 1), np.complex64)]
            work = self._local.work = dict(zip(names, carve(specs)))
            work["scatter"][...] = 0.0
        return work


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

"""The periodic solver's hot path: cached transfer tables, transforms into given arrays, work buffers.

Measured (benchmarks/bench_forward.py, docs/forward_benchmark.md): at 256^2 a call of
:func:`~tactilab.forward.halfspace.spectral.periodic_stress` spent as long building its Fourier
multipliers and on fresh large temporaries (page faults when the allocator hands memory back to
the system and asks again) as on its FFTs. So

- :func:`depth_tables` keeps the complex multiplier of every (output, load) pair at a depth,
  with exp(-rho z) folded in, per (grid, spacing, dtype, nu, depth, loads, weights), within a
  memory budget :data:`TRANSFER_CACHE_BYTES` (least recently used out first; thread-safe). A
  repeated call (time series, scans over frames) then costs five elementwise passes per output
  (:func:`apply`) between its FFTs; with compiled kernels (tactilab.core.jit: numba, the ``fast``
  extra) one fused pass per output (:func:`apply_fused`) over real tables (each multiplier is
  purely real or purely imaginary: half the memory). :func:`clear_transfer_cache` frees it.
- :func:`rfftn_into` / :func:`inverse_into` write a transform straight into a given array
  (the inverse straight into the caller's output slice, its column transforms in place in the
  work spectrum, so no temporary copy of the spectrum is made). They call the transform binding
  that ``scipy.fft`` itself calls, checked once at import to give bitwise the same result as
  ``scipy.fft.rfftn`` / ``ifft`` / ``irfft``; where that binding is missing or differs (another
  scipy), they fall back to the public functions and a copy.
- :func:`work_block` keeps one block of spectrum-sized work arrays per thread (for grids whose
  block stays below :data:`BUFFER_BYTES`), so repeated calls reuse warm memory.

Where a facade call goes (``benchmarks/bench_forward.py --phases``, Table 0b of
docs/forward_benchmark.md: ``HalfSpace.stress(load, 1 mm, method="spectral")``, p + qx + qy, six
components, one depth, float64, one thread; minima over 101 interleaved repeats on the 2-core
machine shared with other jobs, in units of the FFT floor of 3 ``rfft2`` + 6 ``irfft2``, at
256^2 / 512^2): the three forward transforms 0.30 / 0.35 (the floor's own: 0.31 / 0.34), the six
inverse transforms 0.66 to 0.73 / 0.67 to 0.73 (the floor's: 0.68 / 0.65), and between them the
multiply-adds: 0.31 / 0.35 as the 30 NumPy passes of :func:`apply`, 0.14 to 0.16 / 0.12 to 0.14
as the six compiled passes of :func:`apply_fused`.
Measured and not kept (NumPy path):
tables stored for eta >= 0 only and mirrored (half the table memory, no faster: the extra
half-size calls and reversed rows cost what the smaller tables save), real tables applied through
float views or with a cast (slower than complex x complex: numpy's complex multiply is
vectorised, its broadcast over a pair axis is not), batched forward or inverse transforms over
the loads or outputs (no faster), ``np.einsum`` / ``np.vecdot`` / ``np.matmul`` over the loads
(slower), blocking the passes for cache (no faster). Each pass is memory-bound (about 17 us per
pass over a 256^2 half spectrum hot in L2), so what is left there is the number of passes, which
numpy cannot fuse: the compiled kernel does.

``workers``: None means scipy's default (1 thread unless inside ``scipy.fft.set_workers``);
results are bitwise the same for any number of workers (tests/test_forward_spectral.py).
"""

from __future__ import annotations

import collections
import importlib
import os
import threading
from typing import NamedTuple

import numpy as np
import scipy.fft as sfft

from tactilab.core import jit

#: Largest total size (bytes) of the per-thread work buffers kept between calls
BUFFER_BYTES = 32 * 2**20
_LOCAL = threading.local()


def _binding():
    """scipy.fft's own transform module if it has r2c/c2r with ``out`` and matches the public API."""
    for name in ("scipy.fft._duccfft.pyduccfft", "scipy.fft._pocketfft.pypocketfft"):
        try:
            mod = importlib.import_module(name)
        except ImportError:
            continue
        try:
            rng = np.random.default_rng(0)
            for shape in ((6, 8), (5, 7), (9,)):
                axes = tuple(range(-len(shape), 0))
                a = rng.normal(size=shape)
                spec = np.empty(shape[:-1] + (shape[-1] // 2 + 1,), complex)
                mod.r2c(a, axes, True, 0, spec, 1)
                back = np.empty(shape)
                mod.c2r(spec, axes, shape[-1], False, 2, back, 1)
                if not (np.array_equal(spec, sfft.rfftn(a, axes=axes))
                        and np.array_equal(back, sfft.irfftn(spec, s=shape, axes=axes))):
                    return None
                if len(shape) == 2:  # inverse_into: columns in place, then rows
                    cols = sfft.ifft(spec, axis=0, norm="forward")
                    mod.c2c(spec, (0,), False, 0, spec, 1)
                    rows = np.empty(shape)
                    mod.c2r(spec, (1,), shape[-1], False, 2, rows, 1)
                    if not (np.array_equal(spec, cols) and np.array_equal(rows, sfft.irfft(cols, n=shape[-1], axis=1))):
                        return None
                    ahead = sfft.fft(cols, axis=0)  # fft_first_inplace's forward transform
                    mod.c2c(cols, (0,), True, 0, cols, 1)
                    if not np.array_equal(cols, ahead):
                        return None
        except (TypeError, ValueError, AttributeError):
            return None
        return mod
    return None


_RAW = _binding()


def threads(workers: int | None) -> int:
    """scipy.fft's rule: None -> the set_workers default; negative -> counts back from all CPUs."""
    if workers is None:
        return int(sfft.get_workers())
    count = int(workers)
    if count < 0:
        count += (os.cpu_count() or 1) + 1
    if count < 1:
        raise ValueError(f"workers: must be a thread count >= 1, or negative to count back from all "
                         f"{os.cpu_count()} CPUs (-1: all), got {workers!r}; use None for scipy's default")
    return count


def rfft_last_into(values: np.ndarray, out: np.ndarray, workers: int | None = None) -> np.ndarray:
    """``out[...] = scipy.fft.rfft(values, axis=-1)`` (float -> complex), straight into ``out``.

    With :func:`fft_first_inplace` and :func:`irfft_last_into`: the transforms of :func:`rfftn_into`
    and :func:`inverse_into` one axis at a time, so that a zero-padded product transforms only the
    rows that hold data (the contact room's isolated grids)."""
    if _RAW is not None:
        return _RAW.r2c(values, (values.ndim - 1,), True, 0, out, threads(workers))
    out[...] = sfft.rfft(values, axis=-1, workers=workers)
    return out


def fft_first_inplace(spectrum: np.ndarray, forward: bool, workers: int | None = None) -> np.ndarray:
    """The complex FFT of ``spectrum`` along its first axis, in place and unnormalised both ways
    (``forward=False``: ``ifft`` times the axis' length)."""
    if _RAW is not None:
        return _RAW.c2c(spectrum, (0,), bool(forward), 0, spectrum, threads(workers))
    spectrum[...] = (sfft.fft(spectrum, axis=0, workers=workers) if forward
                     else sfft.ifft(spectrum, axis=0, norm="forward", workers=workers))
    return spectrum


def irfft_last_into(spectrum: np.ndarray, out: np.ndarray, workers: int | None = None) -> np.ndarray:
    """``out[...] = scipy.fft.irfft(spectrum, n=out.shape[-1], axis=-1)`` (complex -> float, 1/n)."""
    if _RAW is not None:
        return _RAW.c2r(spectrum, (spectrum.ndim - 1,), out.shape[-1], False, 2, out, threads(workers))
    out[...] = sfft.irfft(spectrum, n=out.shape[-1], axis=-1, workers=workers)
    return out


def rfftn_into(values: np.ndarray, out: np.ndarray, workers: int | None = None) -> np.ndarray:
    """``out[...] = scipy.fft.rfftn(values)`` over all axes of ``values`` (float -> complex)."""
    axes = tuple(range(values.ndim))
    if _RAW is not None:
        return _RAW.r2c(values, axes, True, 0, out, threads(workers))
    out[...] = sfft.rfftn(values, axes=axes, workers=workers)
    return out


def inverse_into(spectrum: np.ndarray, out: np.ndarray, workers: int | None = None) -> np.ndarray:
    """``out[...] = scipy.fft.irfftn(spectrum, s=out.shape) * ny`` (2-D), ``irfftn`` (1-D); overwrites ``spectrum``.

    In 2-D the column transforms run in place in ``spectrum`` (a complex inverse FFT along y,
    unnormalised) and the row transforms write straight into ``out`` (the real inverse along x,
    divided by nx), which spares the temporary copy of the spectrum that a 2-D ``irfftn`` makes.
    The 1/ny of the inverse along y is left to the caller: :func:`depth_tables` folds it into the
    tables (exact for ny a power of two, so the result is then bitwise that of ``irfftn``).
    """
    if out.ndim == 1:
        if _RAW is not None:
            return _RAW.c2r(spectrum, (0,), out.shape[0], False, 2, out, threads(workers))
        out[...] = sfft.irfft(spectrum, n=out.shape[0], workers=workers)
        return out
    if _RAW is not None:
        count = threads(workers)
        _RAW.c2c(spectrum, (0,), False, 0, spectrum, count)
        return _RAW.c2r(spectrum, (1,), out.shape[1], False, 2, out, count)
    spectrum[...] = sfft.ifft(spectrum, axis=0, norm="forward", workers=workers)
    out[...] = sfft.irfft(spectrum, n=out.shape[1], axis=1, workers=workers)
    return out


def work_block(spectrum_shape: tuple, cdtype, count: int) -> np.ndarray:
    """One complex array of shape ``(count, *spectrum_shape)`` (contents undefined), reused per thread.

    Its rows are the work spectra (the compiled multiply-add reads the load spectra as one stacked
    array). Only one grid's block is kept per thread (the latest), and only when it is at most
    :data:`BUFFER_BYTES`; larger grids get a fresh one.
    """
    cdtype = np.dtype(cdtype)
    key = (tuple(spectrum_shape), cdtype.str, count)
    held = getattr(_LOCAL, "buffers", None)
    if held is not None and held[0] == key:
        return held[1]
    block = np.empty((count, *spectrum_shape), cdtype)
    if block.nbytes <= BUFFER_BYTES:
        _LOCAL.buffers = (key, block)
    return block


#: Memory budget of the transfer-table cache (bytes). Tables are kept per (grid, spacing, dtype,
#: nu, depth, output row, loads present); least recently used entries go first. One 512^2 call
#: with six components from p, qx, qy holds 18 complex tables, about 38 MiB.
TRANSFER_CACHE_BYTES = 64 * 2**20
_TRANSFER_CACHE: collections.OrderedDict = collections.OrderedDict()
_CACHE_LOCK = threading.Lock()


def clear_transfer_cache() -> None:
    """Empty the transfer-table cache of ``periodic_stress`` (frees its memory)."""
    with _CACHE_LOCK:
        _TRANSFER_CACHE.clear()


def _multipliers(coefficients, g, nu: float, names: tuple, row: np.ndarray, e: np.ndarray,
                 rze: np.ndarray) -> dict:
    """{load: [(kind, real multiplier a0 e + a1 rz e)]} of one output row, loads in first-use order."""
    terms: dict = {}
    for (name, kind), (a0, a1) in coefficients(g, nu, names, row).items():
        m = np.multiply(e, a0)
        if np.ndim(a1) or a1 != 0.0:
            m += np.multiply(rze, a1)
        terms.setdefault(name, []).append((kind, m))
    return terms


def _output_tables(coefficients, g, nu: float, names: tuple, row: np.ndarray, e: np.ndarray,
                   rze: np.ndarray, cdtype) -> list:
    """[(load, complex multiplier)] of one output row at one depth, zero terms left out.

    The multiplier of a load is ``a0 e + a1 rz e`` (real coefficients from
    ``coefficients``, i.e. ``spectral._real_coefficients``),
    times 1j where the coefficient is imaginary; a load that enters both ways gets one table.
    """
    tables: dict = {}
    for name, parts in _multipliers(coefficients, g, nu, names, row, e, rze).items():
        for kind, m in parts:
            t = np.empty(m.shape, cdtype)
            if kind == "re":
                t.real, t.imag = m, 0.0
            else:
                t.real, t.imag = 0.0, m
            if name in tables:
                tables[name] += t
            else:
                tables[name] = t
    for t in tables.values():
        t.setflags(write=False)  # cached and shared between calls
    return list(tables.items())


class FusedTerms(NamedTuple):
    """One output's terms for :func:`apply_fused`: term k adds ``spectra[loads[k]] x tables[k]``,
    times 1j where ``imaginary[k]``; ``tables`` real, shape (n_terms, n_modes), half the memory of
    the complex tables (a purely imaginary multiplier is one real table and a swap of re and im)."""

    loads: np.ndarray
    imaginary: np.ndarray
    tables: np.ndarray


def _fused_tables(coefficients, g, nu: float, names: tuple, row: np.ndarray, e: np.ndarray,
                  rze: np.ndarray) -> FusedTerms:
    """The terms of one output row at one depth for :func:`apply_fused` (the NumPy path's order)."""
    loads, imaginary, tables = [], [], []
    for name, parts in _multipliers(coefficients, g, nu, names, row, e, rze).items():
        for kind, m in parts:
            loads.append(names.index(name))
            imaginary.append(kind == "im")
            tables.append(np.broadcast_to(m, e.shape).ravel())
    stacked = np.array(tables, dtype=e.dtype).reshape(len(tables), e.size)
    terms = FusedTerms(np.array(loads, dtype=np.int64), np.array(imaginary, dtype=np.bool_), stacked)
    for a in terms:
        a.setflags(write=False)  # cached and shared between calls
    return terms


def _table_bytes(tables: list) -> int:
    return sum(out.tables.nbytes if isinstance(out, FusedTerms) else sum(t.nbytes for _, t in out)
               for out in tables)


def depth_tables(g, grid_key: tuple, nu: float, names: tuple, weights: np.ndarray, z: float,
                 dtype, cdtype, coefficients, fused: bool = False):
    """Per output row, the list of (load, complex multiplier) at depth ``z`` (an iterable over rows);
    with ``fused``, the row's :class:`FusedTerms` for :func:`apply_fused` instead.

    On a 2-D grid the multipliers carry the factor 1/ny that :func:`inverse_into` leaves out.

    ``g`` is the grid's ``spectral._Geometry``, ``coefficients`` ``spectral._real_coefficients``.
    Cached per (grid, spacing, dtype, nu, depth, loads, weights) within :data:`TRANSFER_CACHE_BYTES`
    (least recently used first out). The tables of a grid too large for the budget are built one
    output at a time while the caller iterates, so only one output's tables are alive at once.
    """
    itemsize = np.dtype(dtype if fused else cdtype).itemsize
    cache = g.rho.size * len(names) * weights.shape[0] * itemsize <= TRANSFER_CACHE_BYTES
    key = (grid_key, float(nu), float(z), names, weights.tobytes(), weights.shape, fused)
    if cache:
        with _CACHE_LOCK:
            hit = _TRANSFER_CACHE.get(key)
            if hit is not None:
                _TRANSFER_CACHE.move_to_end(key)
                return hit
    rz = g.rho * dtype.type(z)
    e = np.exp(-rz)  # underflows to 0 for rho z > ~745: harmless
    rze = rz * e
    if g.rho.ndim == 2:  # the 1/ny of the inverse FFT along y (see inverse_into), exact for ny = 2^k
        e *= dtype.type(1.0 / g.rho.shape[0])
        rze *= dtype.type(1.0 / g.rho.shape[0])
    def build(row):
        if fused:
            return _fused_tables(coefficients, g, nu, names, row, e, rze)
        return _output_tables(coefficients, g, nu, names, row, e, rze, cdtype)

    if not cache:  # lazily, one output at a time (memory: see docs/forward_benchmark.md, Table 4)
        return (build(row) for row in weights)
    tables = [build(row) for row in weights]
    if _table_bytes(tables) <= TRANSFER_CACHE_BYTES:
        with _CACHE_LOCK:
            _TRANSFER_CACHE[key] = tables
            total = sum(_table_bytes(entry) for entry in _TRANSFER_CACHE.values())
            while total > TRANSFER_CACHE_BYTES:
                _, old = _TRANSFER_CACHE.popitem(last=False)
                total -= _table_bytes(old)
    return tables


def apply(tables: list, spectra: dict, acc: np.ndarray, term: np.ndarray) -> np.ndarray:
    """Spectrum of one output: sum over loads of (complex multiplier) x L~, into ``acc``.

    Five memory-bound passes for three loads (numpy has no fused multiply-add); blocking the
    rows for cache, mirror-symmetric half tables and BLAS diagonal products were measured and
    were not faster.
    """
    if not tables:
        acc.fill(0)
        return acc
    (name, t), rest = tables[0], tables[1:]
    np.multiply(spectra[name], t, out=acc)
    for name, t in rest:
        np.multiply(spectra[name], t, out=term)
        acc += term
    return acc


def apply_fused(terms: FusedTerms, spectra: np.ndarray, acc: np.ndarray) -> np.ndarray:
    """The compiled twin of :func:`apply`: one pass over the spectrum, straight into ``acc``.

    ``spectra`` holds the load spectra stacked, shape (n_loads, *acc.shape), in the order of
    ``terms.loads``. Gives :func:`apply`'s result (bitwise where no load enters an output both as
    a real and an imaginary term; otherwise to rounding), with a third of its memory traffic.
    """
    if terms.loads.size == 0:
        acc.fill(0)
        return acc
    real = acc.real.dtype
    _multiply_add(spectra.reshape(spectra.shape[0], -1).view(real), terms.loads, terms.imaginary,
                  terms.tables, acc.reshape(-1).view(real))
    return acc


@jit.njit
def _term(spectrum, imaginary, i):  # pragma: no cover - compiled by numba
    """(re, im) of mode i of a spectrum (float view), times 1j if ``imaginary``: (a + ib) i = -b + ia."""
    a, b = spectrum[2 * i], spectrum[2 * i + 1]
    if imaginary:
        return -b, a
    return a, b


@jit.njit
def _multiply_add(spectra, loads, imaginary, tables, acc):  # pragma: no cover - compiled by numba
    """acc = sum_k spectra[loads[k]] x tables[k] (x 1j where imaginary[k]), on float views
    (re at 2i, im at 2i + 1), summed in the order given (the NumPy path's sums).

    Up to three terms in one pass (a loop per count, so that each vectorises: one inner loop over
    any number of terms ran 2.5x slower, and (n, 2) views of the spectra 2x slower); further terms
    (a load entering both as real and imaginary) are added one pass each.
    """
    n, count = tables.shape[1], loads.shape[0]
    s0, t0, j0 = spectra[loads[0]], tables[0], imaginary[0]
    if count == 1:
        for i in range(n):
            a, b = _term(s0, j0, i)
            acc[2 * i], acc[2 * i + 1] = a * t0[i], b * t0[i]
    elif count == 2:
        s1, t1, j1 = spectra[loads[1]], tables[1], imaginary[1]
        for i in range(n):
            a, b = _term(s0, j0, i)
            c, d = _term(s1, j1, i)
            acc[2 * i], acc[2 * i + 1] = a * t0[i] + c * t1[i], b * t0[i] + d * t1[i]
    else:
        s1, t1, j1 = spectra[loads[1]], tables[1], imaginary[1]
        s2, t2, j2 = spectra[loads[2]], tables[2], imaginary[2]
        for i in range(n):
            a, b = _term(s0, j0, i)
            c, d = _term(s1, j1, i)
            e, f = _term(s2, j2, i)
            acc[2 * i] = a * t0[i] + c * t1[i] + e * t2[i]
            acc[2 * i + 1] = b * t0[i] + d * t1[i] + f * t2[i]
    for k in range(3, count):
        s, t, j = spectra[loads[k]], tables[k], imaginary[k]
        for i in range(n):
            a, b = _term(s, j, i)
            acc[2 * i] += a * t[i]
            acc[2 * i + 1] += b * t[i]

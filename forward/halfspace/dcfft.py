"""Method 3: non-periodic zero-padded convolution with the kernel sampled at depth (DC-FFT).

For an isolated contact, the stress at the grid nodes is the discrete convolution of the
sampled load (each node's traction times its cell area, a concentrated force) with the
closed-form point kernel (Boussinesq/Cerruti; the line kernel, Flamant/antiplane, for a 1-D
plane-strain load) sampled on the ``(2 ny - 1) x (2 nx - 1)`` grid of node offsets at depth Z.
The convolution is computed with real FFTs on a zero-padded grid of at least ``2 n - 1``
points per axis, so there are no periodic images: the result equals the direct sum over nodes
(``tactilab.forward.halfspace.kernels.direct_stress``) to rounding. Each kernel is even or odd in x and
in y, so its spectrum is a real cosine/sine transform (DCT-I/DST-I) of the quadrant of
non-negative offsets: a quarter of the data of a full FFT.

What the sampling costs: a load that is smooth on the grid scale is integrated against the
kernel with the trapezoid rule. By Poisson summation its error is the kernel spectrum at the
alias wavenumbers ``2 pi m / h``, which decays like ``exp(-2 pi Z / h)``; see
:func:`dcfft_error_estimate`. At depths below about the grid spacing the kernel is not
resolved and the estimate says so (it exceeds 1e-2 for ``h / Z > 1``).

Memory: the load FFTs (one per non-zero load component) are computed once and reused for all
depths and components; one quadrant buffer and one accumulator are reused
across the (depth, component) loop, and the kernel geometry at the quadrant of offsets is computed once per depth,
so the peak is about ``output + (n_load + 3)`` padded spectra (measured in docs/forward_methods.md).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
import scipy.fft as sfft

from .kernel_formulas import line_geometry, line_unit, point_geometry, point_unit
from tactilab.core import rules as check
from .kernels import COMPONENTS, active_pairs
from .loads import SurfaceLoad

__all__ = ["dcfft_stress", "dcfft_error_estimate", "padded_shape", "dcfft_kernel_spectrum", "dcfft_convolve",
           "dcfft_correlate"]

# load component name -> direction of the force it applies
_LOAD_DIRECTION = {"qx": "x", "qy": "y", "p": "z"}
_ROW_BLOCK = 1 << 16  # kernel samples evaluated per block: bounds the formula's temporaries


def padded_shape(shape: Sequence[int]) -> tuple[int, ...]:
    """FFT grid of the linear convolution: the smallest even fast length >= 2 n - 1 per axis.

    Even, so that the kernel's reflection symmetry maps onto real cosine and sine transforms.
    """
    out = []
    for n in shape:
        m = sfft.next_fast_len(max(2 * n - 1, 4), real=True)
        while m % 2:
            m = sfft.next_fast_len(m + 1, real=True)
        out.append(m)
    return tuple(out)


def _is_odd(comp: str, direction: str, axis: str) -> bool:
    """Whether the Green's function changes sign under reflection of one surface axis.

    Each index equal to ``axis`` in the stress component, and a force along it, flip the sign.
    """
    return bool((comp.count(axis) + (direction == axis)) % 2)


def _quadrant_geometry(shape: tuple[int, ...], spacing: tuple[float, ...], depth: float) -> tuple[np.ndarray, ...]:
    """Direction cosines and 1/(2 pi R^2) (point) or 1/(pi r) (line) at the non-negative
    node offsets, computed once per depth and shared by every (component, direction) kernel."""
    x = np.arange(shape[-1]) * spacing[0]
    if len(shape) == 1:
        return line_geometry(x, depth)
    geometry = tuple(np.empty(shape) for _ in range(4))
    block = max(1, _ROW_BLOCK // shape[-1])
    for j0 in range(0, shape[0], block):
        y = np.arange(j0, min(shape[0], j0 + block))[:, None] * spacing[1]
        for target, values in zip(geometry, point_geometry(x, y, depth)):
            target[j0:j0 + y.shape[0]] = values
    return geometry


def _sample_quadrant(quad: np.ndarray, geometry: tuple[np.ndarray, ...], comp: str, direction: str,
                     area: float, nu: float) -> None:
    """Kernel times cell area at the non-negative node offsets into the first columns of
    ``quad`` (the columns past the grid stay zero), in row blocks to bound temporaries."""
    n = geometry[0].shape[-1]
    if quad.ndim == 1:
        np.multiply(line_unit(comp, direction, *geometry, nu), area, out=quad[:n])
        return
    block = max(1, _ROW_BLOCK // n)
    for j0 in range(0, quad.shape[0], block):
        rows = slice(j0, j0 + block)
        values = point_unit(comp, direction, *(g[rows] for g in geometry), nu)
        np.multiply(values, area, out=quad[rows, :n])


def _symmetric_spectrum(quad: np.ndarray, odd: Sequence[bool], rows: np.ndarray | None,
                        n_rows: int, workers) -> tuple[np.ndarray, tuple[int, ...]]:
    """Real factor R of the kernel's DFT on the padded grid, non-negative frequencies.

    On the full padded grid (wrap-around order, period M per axis) the kernel is even or odd
    along each axis, so its DFT there is ``(-i)^(number of odd axes) * R`` with R real: a
    DCT-I (even axis, frequencies 0..M/2) or DST-I (odd axis: the kernel vanishes at offsets 0
    and M/2, frequencies 1..M/2-1) of the quadrant of non-negative offsets, a quarter of the
    data of a full complex FFT. Returns R and, per axis, the first frequency it covers.

    ``quad`` holds the quadrant in its first ``n_rows`` rows and zeros beyond ``nx`` columns
    (shape ``(n_rows, Mx/2 + 1)``); ``rows`` is a zero-padded ``(My/2 + 1, Mx/2 + 1)`` buffer
    whose rows past ``n_rows`` stay zero.
    """
    if odd[-1]:
        spec = sfft.dst(quad[..., 1:-1], type=1, axis=-1, workers=workers)
    else:
        spec = sfft.dct(quad, type=1, axis=-1, workers=workers)
    if quad.ndim == 1:
        return spec, (int(odd[-1]),)
    width = spec.shape[1]
    rows[:n_rows, :width] = spec
    if odd[0]:
        spec = sfft.dst(rows[1:-1, :width], type=1, axis=0, workers=workers)
    else:
        spec = sfft.dct(rows[:, :width], type=1, axis=0, workers=workers)
    return spec, (int(odd[0]), int(odd[-1]))


def _accumulate(acc: np.ndarray, load_hat: np.ndarray, real: np.ndarray, phase: complex, first: bool) -> None:
    """acc (+)= phase * load_hat * real, in row blocks so the temporary stays small."""
    if first:
        np.multiply(load_hat, real, out=acc)
        if phase != 1:
            np.multiply(acc, phase, out=acc)  # exact: phase is +-1 or +-i
        return
    rows = max(1, _ROW_BLOCK // max(1, acc.shape[-1])) if acc.ndim == 2 else acc.shape[0]
    for i in range(0, acc.shape[0], rows):
        block = load_hat[i:i + rows] * real[i:i + rows]
        if phase != 1:
            block *= phase
        acc[i:i + rows] += block


def _add_kernel_product(acc: np.ndarray, load_hat: np.ndarray, real: np.ndarray,
                        start: tuple[int, ...], odd: Sequence[bool], first: bool) -> None:
    """acc (+)= kernel spectrum * load spectrum, the kernel given by R and its phase.

    Frequencies outside R (0 and M/2 along an odd axis) carry no kernel: zeroed when
    ``first``. In 2-D the rfft layout holds all ky: rows ky > My/2 are the reflection
    -ky = My - ky of R's rows, where an odd-in-y kernel flips sign.
    """
    phase = (-1j) ** sum(odd)
    c0 = start[-1]
    cols = slice(c0, c0 + real.shape[-1])
    if acc.ndim == 1:
        if first and c0:
            acc[[0, -1]] = 0.0
        _accumulate(acc[cols], load_hat[cols], real, phase, first)
        return
    r0 = start[0]
    half = acc.shape[0] // 2 + 1  # My/2 + 1 rows: ky = 0..My/2 (My is even)
    if first and c0:
        acc[:, [0, -1]] = 0.0
    if first and r0:
        acc[[0, half - 1], :] = 0.0
    top = slice(r0, r0 + real.shape[0])
    _accumulate(acc[top, cols], load_hat[top, cols], real, phase, first)
    mirrored = real[half - 2 - r0::-1][:acc.shape[0] - half]  # R at j = My - ky, ky >= My/2 + 1
    _accumulate(acc[half:, cols], load_hat[half:, cols], mirrored, -phase if odd[0] else phase, first)


def _load_spectrum(values: np.ndarray, padded: tuple[int, ...], workers) -> np.ndarray:
    """rfft of the zero-padded load; in 2-D the x transforms run on the loaded rows only."""
    spectrum = sfft.rfft(values, n=padded[-1], axis=-1, workers=workers)
    if values.ndim == 2:
        spectrum = sfft.fft(spectrum, n=padded[0], axis=0, workers=workers, overwrite_x=True)
    return spectrum


def _inverse_crop(acc: np.ndarray, padded: tuple[int, ...], shape: tuple[int, ...], workers) -> np.ndarray:
    """Inverse rfft of ``acc`` cropped to the load grid; overwrites ``acc`` (rebuilt each time).

    In 2-D the y transform runs in place and the x transforms only on the rows kept.
    """
    if acc.ndim == 2:
        columns = sfft.ifft(acc, axis=0, workers=workers, overwrite_x=True)
        return sfft.irfft(columns[:shape[0]], n=padded[-1], axis=-1, workers=workers)[:, :shape[1]]
    return sfft.irfft(acc, n=padded[-1], workers=workers)[:shape[0]]


def dcfft_stress(load: SurfaceLoad, depths: Sequence[float], nu: float = 0.5,
                 components: Sequence[str] = COMPONENTS, dtype=np.float64,
                 workers: int | None = None) -> np.ndarray:
    """Stress on the load grid at given depths by zero-padded convolution (method 3, DC-FFT).

    Parameters
    ----------
    load : SurfaceLoad
        Tractions in Pa on a 1-D (plane strain, line kernels) or 2-D grid (point kernels);
        each node carries its traction times the cell area as a concentrated force.
    depths : sequence of float
        Depths Z > 0 in m.
    nu : float
        Poisson's ratio in (-1, 0.5]; 0.5 is exact.
    components : sequence of str
        Names from ``COMPONENTS`` (Voigt order ``xx, yy, zz, yz, zx, xy``, tensor shear).
    dtype : float64 or float32
        Output and FFT precision (float32 computes in complex64: relative error about 1e-6).
    workers : int, optional
        Passed to ``scipy.fft`` (default: one thread).

    Returns
    -------
    ndarray, shape ``(len(depths), len(components), *load.shape)``
        Stress in Pa (tension positive) at the load's grid nodes.

    Notes
    -----
    Accuracy against the continuous load is :func:`dcfft_error_estimate`; against the sum of
    point forces over the nodes it is exact to rounding (about 1e-15 relative in float64).
    The kernel's spectrum comes from real cosine/sine transforms of its quadrant of
    non-negative offsets (the kernel is even or odd in x and in y), the load spectra from one
    real FFT each, computed once for all depths and components.
    """
    if not isinstance(load, SurfaceLoad):
        raise ValueError(f"load: expected a SurfaceLoad, got {type(load).__name__}; build one with SurfaceLoad(p=..., spacing=...)")
    return nodal_dcfft_stress(load, check.depths(depths, "depths"), check.poisson_ratio(nu),
                              check.components(components), check.float_dtype(dtype), workers)


def nodal_dcfft_stress(load: SurfaceLoad, depth_values: np.ndarray, nu: float, components: tuple[str, ...],
                       dtype: np.dtype, workers: int | None = None) -> np.ndarray:
    """:func:`dcfft_stress` on inputs already checked by the caller (the facade's methods)."""
    shape = load.shape
    out = np.zeros((depth_values.size, len(components)) + shape, dtype=dtype)
    arrays = {name: a for name, a in load.components.items() if a.any()}
    if not arrays:
        return out
    padded = padded_shape(shape)
    # Load spectra: once per non-zero load component, reused for every depth and component.
    spectra = {_LOAD_DIRECTION[name]: _load_spectrum(a.astype(dtype), padded, workers)
               for name, a in arrays.items()}
    pairs = active_pairs(components, list(spectra), load.ndim)
    spectrum_shape = next(iter(spectra.values())).shape
    # Reused real buffers: the kernel quadrant (zero-padded along x) and, in 2-D, the
    # zero-padded rows for the y transform.
    quad = np.zeros(shape[:-1] + (padded[-1] // 2 + 1,), dtype=dtype)
    rows = np.zeros((padded[0] // 2 + 1, padded[1] // 2 + 1), dtype=dtype) if load.ndim == 2 else None
    acc = np.empty(spectrum_shape, dtype=np.result_type(dtype, np.complex64))
    axis_names = ("y", "x") if load.ndim == 2 else ("x",)
    area = load.cell_area
    for d, depth in enumerate(depth_values):
        geometry = _quadrant_geometry(shape, load.spacing, float(depth))
        for c, comp in enumerate(components):
            directions = [direction for cc, direction in pairs if cc == comp]
            for k, direction in enumerate(directions):
                _sample_quadrant(quad, geometry, comp, direction, area, nu)
                odd = [_is_odd(comp, direction, name) for name in axis_names]
                real, start = _symmetric_spectrum(quad, odd, rows, shape[0], workers)
                _add_kernel_product(acc, spectra[direction], real, start, odd, k == 0)
                del real
            if directions:
                out[d, c] = _inverse_crop(acc, padded, shape, workers)
        del geometry
    return out


def dcfft_kernel_spectrum(shape: Sequence[int], spacing: Sequence[float], depth: float, nu: float,
                    weights: np.ndarray, directions: Sequence[str], dtype=np.float64,
                    workers: int | None = None) -> np.ndarray:
    """Spectra of the sampled kernels on the padded grid: the engine's precomputed operator.

    The same sampling, padding (:func:`padded_shape`) and symmetric transforms as
    :func:`dcfft_stress`, for maps that are applied many times (the load-to-sensor operator,
    batched scan maps): output ``o`` at depth ``depth`` per unit traction along ``direction``
    at a node, ``weights[o] @ sigma_voigt`` of the point (1-D: line) kernel times the cell area.

    Parameters
    ----------
    shape : (nx,) or (ny, nx)
        Load grid shape.
    spacing : (dx,) or (dx, dy)
        Grid spacing in m, x first.
    depth : float
        Depth Z > 0 in m.
    nu : float
        Poisson's ratio.
    weights : ndarray, shape (n_out, 6)
        Output rows over the Voigt stress (identity rows: stress in Pa; Hooke rows: strain).
    directions : sequence of {"x", "y", "z"}
        Force direction of each load component (qx, qy, p).
    dtype : float64 or float32
        Precision.
    workers : int, optional
        Passed to ``scipy.fft``.

    Returns
    -------
    ndarray, complex, shape ``(n_out, len(directions), *padded[:-1], padded[-1] // 2 + 1)``
        The rfftn spectra of the kernels on the zero-padded grid (see :func:`dcfft_convolve`).
    """
    shape = tuple(int(n) for n in shape)
    spacing = check.spacing(spacing, len(shape))
    depth = check.depth(depth)
    nu = check.poisson_ratio(nu)
    dtype = check.float_dtype(dtype)
    weights = np.atleast_2d(np.asarray(weights, dtype=float))
    padded = padded_shape(shape)
    spectrum_shape = (*padded[:-1], padded[-1] // 2 + 1)
    cdtype = np.result_type(dtype, np.complex64)
    out = np.zeros((weights.shape[0], len(directions), *spectrum_shape), dtype=cdtype)
    quad = np.zeros(shape[:-1] + (padded[-1] // 2 + 1,), dtype=dtype)
    rows = np.zeros((padded[0] // 2 + 1, padded[1] // 2 + 1), dtype=dtype) if len(shape) == 2 else None
    ones = np.ones(spectrum_shape, dtype=cdtype)
    acc = np.empty(spectrum_shape, dtype=cdtype)
    axis_names = ("y", "x") if len(shape) == 2 else ("x",)
    geometry = _quadrant_geometry(shape, spacing, float(depth))
    for k, direction in enumerate(directions):
        for j, comp in enumerate(COMPONENTS):
            col = weights[:, j]
            if not np.any(col) or not active_pairs([comp], [direction], len(shape)):
                continue
            _sample_quadrant(quad, geometry, comp, direction, float(np.prod(spacing)), nu)
            odd = [_is_odd(comp, direction, name) for name in axis_names]
            real, start = _symmetric_spectrum(quad, odd, rows, shape[0], workers)
            _add_kernel_product(acc, ones, real, start, odd, True)
            for o in np.flatnonzero(col):
                out[o, k] += col[o] * acc
    return out


def _crop(full: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    return full[(Ellipsis, *[slice(0, n) for n in shape])]


def dcfft_convolve(spectrum: np.ndarray, values: np.ndarray, workers: int | None = None) -> np.ndarray:
    """Apply :func:`dcfft_kernel_spectrum`: the isolated field of nodal tractions on the load grid.

    Parameters
    ----------
    spectrum : ndarray, shape (n_out, n_dir, ...)
        From :func:`dcfft_kernel_spectrum`.
    values : ndarray, shape (..., n_dir, *shape)
        Tractions in Pa per direction (leading axes are batches, e.g. frames).

    Returns
    -------
    ndarray, shape (..., n_out, *shape)
        Outputs at the grid nodes (linear convolution: no periodic images).
    """
    ndim = spectrum.ndim - 2
    shape = values.shape[-ndim:]
    padded = padded_shape(shape)
    axes = tuple(range(-ndim, 0))
    spec = sfft.rfftn(values, s=padded, axes=axes, workers=workers)
    mixed = _mix(spectrum, spec, ndim)
    return _crop(sfft.irfftn(mixed, s=padded, axes=axes, workers=workers), shape)


def dcfft_correlate(spectrum: np.ndarray, data: np.ndarray, workers: int | None = None) -> np.ndarray:
    """The adjoint of :func:`dcfft_convolve`: outputs (..., n_out, *shape) -> tractions (..., n_dir, *shape)."""
    ndim = spectrum.ndim - 2
    shape = data.shape[-ndim:]
    padded = padded_shape(shape)
    axes = tuple(range(-ndim, 0))
    spec = sfft.rfftn(data, s=padded, axes=axes, workers=workers)
    mixed = _mix(np.conj(np.swapaxes(spectrum, 0, 1)), spec, ndim)
    return _crop(sfft.irfftn(mixed, s=padded, axes=axes, workers=workers), shape)


def _mix(spectrum: np.ndarray, spec: np.ndarray, ndim: int) -> np.ndarray:
    """out[..., o, k] = sum_l spectrum[o, l, k] * spec[..., l, k]."""
    n_out, n_in = spectrum.shape[:2]
    out = np.zeros(spec.shape[:-ndim - 1] + (n_out,) + spec.shape[-ndim:], dtype=np.result_type(spectrum, spec))
    rest = (slice(None),) * ndim
    for o in range(n_out):
        for i in range(n_in):
            out[(Ellipsis, o) + rest] += spectrum[o, i] * spec[(Ellipsis, i) + rest]
    return out


def _alias_terms(s: np.ndarray, c: float) -> np.ndarray:
    """Error per alias wavenumber k (s = |k| Z) for a load of Gaussian width w, c = (Z / w)^2.

    Every entry of the half-space transfer function of docs/theory.md section 2 is bounded, per
    unit load, by B(s) = (2 + s) exp(-s). A load of width w spreads its spectrum over
    |kappa| ~ 1/w, and the alias term is the average of B(|k - kappa| Z) over that spectrum:
    for a Gaussian load this tilts the exponent, giving (2 + s - c) exp(-s + c/2) while
    s >= c; beyond that (load narrower than sqrt(Z h / 2 pi)) the load's own aliasing
    2 exp(-k^2 w^2 / 2) dominates. The two branches meet continuously at s = c.
    """
    smooth = s >= c
    out = np.empty_like(s)
    out[smooth] = (2.0 + s[smooth] - c) * np.exp(-s[smooth] + 0.5 * c)
    out[~smooth] = 2.0 * np.exp(-0.5 * s[~smooth] ** 2 / c)
    return out


def dcfft_error_estimate(spacing, depth: float, dtype=np.float64, load_width: float | None = None) -> float:
    """Relative error of DC-FFT from sampling the kernel at grid spacing h, at depth Z.

    For a load that is smooth on the grid scale, summing the sampled kernel over the nodes is
    the trapezoid rule for the convolution integral. Poisson summation gives its error as the
    sum of the kernel spectrum over the alias wavenumbers ``k_m = 2 pi m / h`` (m != 0),
    bounded per unit load by ``(2 + s) exp(-s)`` with ``s = |k_m| Z``, and tilted by the
    width w of the load (its spectrum shifts the effective alias wavenumber):

        E = sum_{m != 0} (2 + s_m - c) exp(-s_m + c / 2) + 30 eps(dtype),   c = (Z / w)^2

    (1-D: over m = +-1, +-2, ...; 2-D: over the lattice ``(m_x / dx, m_y / dy)``). The last
    term is the rounding floor of the FFT convolution. E is the max |error| over the grid
    divided by the peak of ``|p| + |qx| + |qy|``. Measured against converged references on
    Gaussian loads it bounds the error and overestimates it by at most a factor 3 where the
    load has a normal or in-plane tangential part (see docs/forward_methods.md).

    Parameters
    ----------
    spacing : float or tuple of float
        ``(dx,)`` for a 1-D (plane-strain) grid, ``(dx, dy)`` for 2-D, in m (``load.spacing``);
        a bare float means a 2-D grid with dx = dy.
    depth : float
        Depth Z > 0 in m.
    dtype : float64 or float32
        Precision of the computation (sets the rounding floor).
    load_width : float, optional
        Length in m over which the load varies (the standard deviation of a Gaussian bump,
        about a third of a Hertz contact radius). Default: ``depth``, i.e. a load smooth on
        the depth scale. Narrower loads raise the estimate.

    Returns
    -------
    float
        Estimated relative error (Pa per Pa of peak traction). Values near or above 1 mean
        the depth is not resolved by the grid (Z below about h).
    """
    if np.ndim(spacing) == 0:
        spacing = (spacing, spacing)
    h = check.spacing(spacing, np.size(spacing))
    if len(h) not in (1, 2):
        raise ValueError(f"spacing: expected (dx,) or (dx, dy), finite and > 0 m, got {spacing!r}")
    depth = check.depth(depth)
    width = depth if load_width is None else check.positive(load_width, "load_width", "m",
                                                             "give the length over which the load varies, in m")
    return alias_error(h, depth, check.float_dtype(dtype), width)


def alias_error(h: tuple[float, ...], depth: float, dtype: np.dtype, width: float) -> float:
    """:func:`dcfft_error_estimate` on inputs already checked by the caller (cached: the facade
    asks once to choose and once to report, and the lattice sum can reach 801^2 terms)."""
    return _alias_error(tuple(float(v) for v in h), float(depth), np.dtype(dtype), float(width))


@functools.lru_cache(maxsize=256)
def _alias_error(h: tuple[float, ...], depth: float, dtype: np.dtype, width: float) -> float:
    h = np.asarray(h, dtype=float)
    c = (depth / width) ** 2
    floor = 30.0 * np.finfo(dtype).eps
    a = 2.0 * np.pi * depth / h  # s per unit lattice step along each axis
    # Terms below exp(-45) ~ 3e-20 do not matter; a cap keeps absurd h/Z cheap (E >> 1 there).
    reach = 45.0 + 0.5 * c + np.sqrt(90.0 * c)
    m_max = np.minimum(np.ceil(reach / a).astype(int) + 1, 400)
    if h.size == 1:
        m = np.arange(1, m_max[0] + 1)
        return float(2.0 * np.sum(_alias_terms(a[0] * m, c)) + floor)
    mx = np.arange(-m_max[0], m_max[0] + 1)[None, :]
    my = np.arange(-m_max[1], m_max[1] + 1)[:, None]
    terms = _alias_terms(np.hypot(a[0] * mx, a[1] * my), c)
    terms[m_max[1], m_max[0]] = 0.0  # m = 0 is the exact integral, not an error
    return float(np.sum(terms) + floor)

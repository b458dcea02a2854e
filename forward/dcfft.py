"""Method 3: non-periodic zero-padded convolution with the kernel sampled at depth (DC-FFT).

For an isolated contact, the stress at the grid nodes is the discrete convolution of the
sampled load (each node's traction times its cell area, a concentrated force) with the
closed-form point kernel (Boussinesq/Cerruti; the line kernel, Flamant/antiplane, for a 1-D
plane-strain load) sampled on the ``(2 ny - 1) x (2 nx - 1)`` grid of node offsets at depth Z.
The convolution is computed with real FFTs on a zero-padded grid of at least ``2 n - 1``
points per axis, so there are no periodic images: the result equals the direct sum over nodes
(``tactilab.forward.kernels.direct_stress``) to rounding.

What the sampling costs: a load that is smooth on the grid scale is integrated against the
kernel with the trapezoid rule. By Poisson summation its error is the kernel spectrum at the
alias wavenumbers ``2 pi m / h``, which decays like ``exp(-2 pi Z / h)``; see
:func:`dcfft_error_estimate`. At depths below about the grid spacing the kernel is not
resolved and the estimate says so (it exceeds 1e-2 for ``h / Z > 1``).

Memory: the load FFTs (one per non-zero load component) are computed once and reused for all
depths and components; one kernel buffer, one kernel spectrum and one accumulator are reused
across the (depth, component) loop, so the peak is about
``output + (n_load + 3) x padded grid`` (measured in docs/forward_methods.md).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.fft as sfft

from .kernels import (
    COMPONENTS,
    _line_geometry,
    _line_unit,
    _point_geometry,
    _point_unit,
    active_pairs,
    check_components,
    check_nu,
)
from .loads import SurfaceLoad

__all__ = ["dcfft_stress", "dcfft_error_estimate", "padded_shape"]

# load component name -> direction of the force it applies
_LOAD_DIRECTION = {"qx": "x", "qy": "y", "p": "z"}
_ROW_BLOCK = 1 << 16  # kernel samples evaluated per block: bounds the formula's temporaries


def padded_shape(shape: Sequence[int]) -> tuple[int, ...]:
    """FFT grid of the linear convolution: ``next_fast_len(2 n - 1)`` per axis."""
    return tuple(sfft.next_fast_len(2 * n - 1, real=True) for n in shape)


def _check_depths(depths) -> np.ndarray:
    try:
        values = np.asarray(depths, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"depths: expected a sequence of depths in m, got {depths!r}") from None
    values = np.atleast_1d(values)
    if values.ndim != 1 or values.size == 0:
        raise ValueError(f"depths: expected a non-empty 1-D sequence of depths in m, got shape {values.shape}")
    if not np.all(np.isfinite(values)):
        raise ValueError(f"depths: depths must be finite (in m), got {depths!r}")
    if np.any(values <= 0):
        raise ValueError(
            f"depths: depth must be > 0 m (inside the skin), got {float(values.min())!r}; "
            "at z = 0 the stress is the surface traction itself"
        )
    return values


def _check_dtype(dtype) -> np.dtype:
    try:
        value = np.dtype(dtype)
    except TypeError:
        raise ValueError(f"dtype: expected float32 or float64, got {dtype!r}") from None
    if value not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ValueError(f"dtype: expected float32 or float64, got {value}; use float64 for tolerances below 1e-6")
    return value


def _parity(comp: str, direction: str, axis: str) -> float:
    """Sign of the Green's function under reflection of one surface axis.

    Each index equal to ``axis`` in the stress component, and a force along it, flip the sign.
    """
    return -1.0 if (comp.count(axis) + (direction == axis)) % 2 else 1.0


def _sample_kernel(buf: np.ndarray, comp: str, direction: str, depth: float,
                   spacing: tuple[float, ...], shape: tuple[int, ...], nu: float) -> None:
    """Write the kernel times the cell area on the node-offset grid into ``buf``'s corner.

    Offset ``(i - (n - 1)) h`` sits at index ``i`` (natural order); only the quadrant of
    non-negative offsets is evaluated, the rest follows from the kernel's parity.
    """
    area = float(np.prod(spacing))
    nx = shape[-1]
    x = np.arange(nx) * spacing[0]
    sign_x = _parity(comp, direction, "x")
    if len(shape) == 1:
        quad = _line_unit(comp, direction, *_line_geometry(x, depth), nu) * area
        buf[nx - 1:2 * nx - 1] = quad
        np.multiply(quad[:0:-1], sign_x, out=buf[:nx - 1])
        return
    ny = shape[0]
    block = max(1, _ROW_BLOCK // nx)
    for j0 in range(0, ny, block):
        y = np.arange(j0, min(ny, j0 + block))[:, None] * spacing[1]
        quad = _point_unit(comp, direction, *_point_geometry(x, y, depth), nu)
        quad *= area
        rows = slice(ny - 1 + j0, ny - 1 + j0 + quad.shape[0])
        buf[rows, nx - 1:2 * nx - 1] = quad
        np.multiply(quad[:, :0:-1], _parity(comp, direction, "x"), out=buf[rows, :nx - 1])
    np.multiply(buf[2 * ny - 2:ny - 1:-1, :2 * nx - 1], _parity(comp, direction, "y"),
                out=buf[:ny - 1, :2 * nx - 1])


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
    """
    if not isinstance(load, SurfaceLoad):
        raise ValueError(f"load: expected a SurfaceLoad, got {type(load).__name__}; build one with SurfaceLoad(p=..., spacing=...)")
    depth_values = _check_depths(depths)
    nu = check_nu(nu)
    components = check_components(components)
    dtype = _check_dtype(dtype)
    shape = load.shape
    out = np.zeros((depth_values.size, len(components)) + shape, dtype=dtype)
    arrays = {name: a for name, a in load.components.items() if a.any()}
    if not arrays:
        return out
    padded = padded_shape(shape)
    axes = tuple(range(-len(shape), 0))
    # Load spectra: once per non-zero load component, reused for every depth and component.
    spectra = {_LOAD_DIRECTION[name]: sfft.rfftn(a.astype(dtype), s=padded, axes=axes, workers=workers)
               for name, a in arrays.items()}
    pairs = active_pairs(components, list(spectra), load.ndim)
    buf = np.zeros(padded, dtype=dtype)  # kernel samples; the zero padding stays zero
    acc = np.empty(next(iter(spectra.values())).shape, dtype=np.result_type(dtype, np.complex64))
    crop = tuple(slice(n - 1, 2 * n - 1) for n in shape)
    for d, depth in enumerate(depth_values):
        for c, comp in enumerate(components):
            directions = [direction for cc, direction in pairs if cc == comp]
            for k, direction in enumerate(directions):
                _sample_kernel(buf, comp, direction, float(depth), load.spacing, shape, nu)
                kernel_hat = sfft.rfftn(buf, axes=axes, workers=workers)
                if k == 0:
                    np.multiply(kernel_hat, spectra[direction], out=acc)
                else:
                    kernel_hat *= spectra[direction]
                    acc += kernel_hat
                del kernel_hat
            if directions:
                # acc is rebuilt from scratch next time, so the inverse may overwrite it.
                field = sfft.irfftn(acc, s=padded, axes=axes, workers=workers, overwrite_x=True)
                out[d, c] = field[crop]
                del field
    return out


def _alias_terms(s: np.ndarray, c: float) -> np.ndarray:
    """Error per alias wavenumber k (s = |k| Z) for a load of Gaussian width w, c = (Z / w)^2.

    Every entry of the half-space transfer function of physics.md section 2 is bounded, per
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
    try:
        h = np.asarray(spacing, dtype=float)
    except (TypeError, ValueError):
        h = np.array([np.nan])
    if h.ndim != 1 or h.size not in (1, 2) or not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise ValueError(f"spacing: expected (dx,) or (dx, dy), finite and > 0 m, got {spacing!r}")
    depth = float(_check_depths([depth])[0])
    width = depth if load_width is None else float(load_width)
    if not np.isfinite(width) or width <= 0:
        raise ValueError(f"load_width: must be a finite length > 0 m, got {load_width!r}")
    c = (depth / width) ** 2
    floor = 30.0 * np.finfo(_check_dtype(dtype)).eps
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

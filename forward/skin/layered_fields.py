"""Stress and strain of a layered skin: the periodic spectral method, and isolated loads on a padded grid.

A periodic load (``load.periodic``) is solved exactly: one forward FFT per load component, the
cached multipliers of :mod:`.layered_multipliers`, one inverse FFT per output.

An isolated load (zero outside its grid) is placed on a zero-padded grid ``padding`` times larger
per axis and solved as periodic: the field then carries the load's periodic images, one padded
period away. Their effect is estimated from the load itself: the field of a coarsened copy of the
load (blocks of nodes summed, the total force and its low moments kept) is computed on the padded
period ``P`` and on ``2 P``; their difference is the change in the images' field, and the estimate
is ``2 max|f_P - f_2P| / max|f|`` (the images' field falls at least like 1/r, so the images at
``2 P`` carry at most half of those at ``P``; tests find it 1x to 5x the true error). ``padding="auto"`` doubles the padding, from 2
up to :data:`MAX_PADDING`, until that estimate meets ``tol``. On a rigid base the images fall off
exponentially with their distance over the layer thickness; on a half-space base like the
half-space's own images (``~ (depth / padded length)^2``).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import scipy.fft as sfft
import xarray as xr

from tactilab.core import rules as check
from tactilab.data_schemas.plausibility import check_plausible_at_entry, check_small_strain
from tactilab.forward.halfspace import (SHEAR_CONVENTION, AccuracyWarning, FieldResult, SurfaceLoad,
                                        compliance_matrix, label, largest_strain)

from .layered_multipliers import VOIGT, output_multipliers

#: the largest padding ``"auto"`` tries (padded grid per axis over the load grid)
MAX_PADDING = 16
#: nodes per axis of the coarsened load of the truncation estimate
_COARSE_NODES = 32


def output_weights(skin, quantity: str, comps: tuple[str, ...], z: float) -> np.ndarray:
    """Rows mapping Voigt stress at depth ``z`` to the outputs: identity rows, or the compliance of the layer there."""
    idx = [VOIGT.index(c) for c in comps]
    if quantity == "stress":
        return np.eye(6)[idx]
    if quantity == "strain":
        E, nu = skin.material_at(z)
        return compliance_matrix(E, nu)[idx]
    raise ValueError(f"quantity: must be 'stress' or 'strain', got {quantity!r}")


def point_phases(shape, spacing, points: np.ndarray):
    """Fourier phases of off-grid points for an rfft half spectrum of a grid of ``shape`` (node ``j`` at
    ``(j - n // 2) h``): ``(Ex (n_kx, n), Ey (ny, n) or None)``, the rfft weights and ``1 / N`` in ``Ex``."""
    nx = shape[-1]
    xi = 2 * np.pi * sfft.rfftfreq(nx, spacing[0])
    ex = np.exp(1j * np.outer(xi, points[:, 0] + (nx // 2) * spacing[0]))
    weight = np.full(len(xi), 2.0)
    weight[0] = 1.0
    if nx % 2 == 0:
        weight[-1] = 1.0  # the Nyquist column: its real part only (the average of +-k)
    ex *= (weight / math.prod(shape))[:, None]
    if len(shape) == 1:
        return ex, None
    eta = 2 * np.pi * sfft.fftfreq(shape[0], spacing[1])
    return ex, np.exp(1j * np.outer(eta, points[:, 1] + (shape[0] // 2) * spacing[1]))


def evaluate_at_points(spectrum: np.ndarray, phases, shape) -> np.ndarray:
    """The exact trigonometric interpolant of an rfft half spectrum at the points of ``phases``."""
    ex, ey = phases
    if ey is None:
        return (spectrum @ ex).real
    return np.einsum("yp,yp->p", ey, spectrum @ ex).real


def rfft_transpose(half: np.ndarray, shape) -> np.ndarray:
    """``Re(sum over the half spectrum of v_k exp(-i k . x_j))`` at every node ``j``: the transpose of the
    rfft (a real-linear map), by one full inverse FFT of ``conj(v)`` placed on its half of the spectrum."""
    full = np.zeros(shape, dtype=complex)
    full[..., :half.shape[-1]] = np.conj(half)
    return (sfft.ifftn(full) * math.prod(shape)).real


def periodic_outputs(skin, load: SurfaceLoad, depths, comps, quantity: str, points=None) -> np.ndarray:
    """Outputs of one period, shape ``(n_depth, n_out, *load.shape)``, or ``(n_depth, n_out, n)`` at
    ``points`` (m, shape (n, ndim): the exact trigonometric interpolant there)."""
    shape = load.shape
    axes = tuple(range(-load.ndim, 0))
    names = tuple(sorted(load.components))
    spectra = {n: sfft.rfftn(load.components[n], axes=axes) for n in names}
    phases = None if points is None else point_phases(shape, load.spacing, points)
    out = np.empty((len(depths), len(comps), *(shape if points is None else (len(points),))))
    for d, z in enumerate(depths):
        table = output_multipliers(skin, shape, load.spacing, float(z), output_weights(skin, quantity, comps, z), names)
        for o in range(len(comps)):
            acc = table[names[0]][o] * spectra[names[0]]
            for n in names[1:]:
                acc += table[n][o] * spectra[n]
            out[d, o] = sfft.irfftn(acc, s=shape, axes=axes) if phases is None else \
                evaluate_at_points(acc, phases, shape)
    return out


def padded_load(load: SurfaceLoad, factor: int) -> tuple[SurfaceLoad, tuple[slice, ...]]:
    """The load on a zero-padded periodic grid ``factor`` times larger per axis, and where it sits there."""
    big = tuple(factor * n for n in load.shape)
    where = tuple(slice(m // 2 - n // 2, m // 2 - n // 2 + n) for n, m in zip(load.shape, big))
    arrays = {}
    for name, a in load.components.items():
        b = np.zeros(big)
        b[where] = a
        arrays[name] = b
    return SurfaceLoad(**arrays, spacing=load.spacing, periodic=True), where


def _coarse(load: SurfaceLoad) -> SurfaceLoad:
    """The load summed over blocks of nodes (force kept) onto at most about ``_COARSE_NODES`` per axis."""
    blocks = [max(1, math.ceil(n / _COARSE_NODES)) for n in load.shape]
    if all(b == 1 for b in blocks):
        return load
    arrays = {}
    for name, a in load.components.items():
        padded = np.zeros([b * math.ceil(n / b) for n, b in zip(load.shape, blocks)])
        padded[tuple(slice(0, n) for n in load.shape)] = a
        if load.ndim == 1:
            arrays[name] = padded.reshape(-1, blocks[0]).mean(axis=1)
        else:
            arrays[name] = padded.reshape(padded.shape[0] // blocks[0], blocks[0],
                                          padded.shape[1] // blocks[1], blocks[1]).mean(axis=(1, 3))
    spacing = tuple(h * b for h, b in zip(load.spacing, blocks[::-1]))
    return SurfaceLoad(**arrays, spacing=spacing)


def truncation_error(skin, load: SurfaceLoad, depths, comps, quantity: str, factor: int, peak: float) -> float:
    """Estimated max error of the padded-grid field of an isolated load, relative to ``peak`` (see the module)."""
    if peak == 0.0 or load.is_zero():
        return 0.0
    coarse = _coarse(load)
    near, where = padded_load(coarse, factor)
    far, where2 = padded_load(coarse, 2 * factor)
    f1 = periodic_outputs(skin, near, depths, comps, quantity)[(slice(None), slice(None), *where)]
    f2 = periodic_outputs(skin, far, depths, comps, quantity)[(slice(None), slice(None), *where2)]
    return 2.0 * float(np.abs(f1 - f2).max()) / peak


def _labelled(values: np.ndarray, quantity: str, comps, depths, load: SurfaceLoad, points, attrs: dict) -> xr.Dataset:
    """The Dataset of a result (the half-space's labelling, whose coordinates are cached between calls)."""
    ds = label(values, quantity, comps, np.asarray(depths, float), load.x, load.y, points).to_dataset()
    ds.attrs.update(attrs)
    return ds


def check_points(points, load: SurfaceLoad):
    """Sensor points (m, shape (n, ndim)) and their grid indices when every one sits on a node (else None)."""
    pts = np.asarray(points, dtype=float)
    pts = pts[:, None] if pts.ndim == 1 else pts
    if pts.ndim != 2 or pts.shape[1] != load.ndim or len(pts) == 0 or not np.all(np.isfinite(pts)):
        raise ValueError(f"points: expected finite positions of shape (n, {load.ndim}) in m, got {np.shape(points)}")
    idx = [pts[:, 0] / load.dx + load.shape[-1] // 2]
    if load.ndim == 2:
        idx.insert(0, pts[:, 1] / load.dy + load.shape[0] // 2)
    idx = np.array(idx)
    rounded = np.rint(idx)
    inside = np.all(idx >= -1e-9) and np.all(idx <= np.array(load.shape)[:, None] - 1 + 1e-9)
    if not load.periodic and not inside:
        raise ValueError("points: an isolated load's sensors must lie within its grid (the truncation estimate "
                         "covers that region); enlarge the grid with zero tractions")
    if inside and np.all(np.abs(idx - rounded) <= 1e-9):
        return pts, tuple(rounded.astype(int))
    return pts, None


def _load_error(skin, load: SurfaceLoad, values: np.ndarray, depths, quantity: str) -> float:
    """The load's own error (``SurfaceLoad.error_estimate``, relative to its peak traction) relative to the
    field's peak: the field is linear in the tractions, so a traction error moves it by about that stress
    (times the compliance 1 / E for a strain; the softest material among the depths, the larger bound)."""
    if not load.error_estimate:
        return 0.0
    peak_field = float(np.abs(values).max())
    if peak_field == 0.0:
        return load.error_estimate
    peak_traction = float(sum(np.abs(a) for a in load.components.values()).max())
    scale = 1.0 if quantity == "stress" else 1.0 / min(skin.material_at(float(z))[0] for z in depths)
    return load.error_estimate * peak_traction * scale / peak_field


def layered_field(skin, load, depth, points, components, tol, padding, quantity: str) -> FieldResult:
    """The body of :meth:`LayeredHalfSpace.stress` / ``strain`` (see there)."""
    if not isinstance(load, SurfaceLoad):
        raise ValueError(f"load: a layered skin takes a SurfaceLoad (nodal tractions in Pa), got "
                         f"{type(load).__name__}; sample a continuous load on a grid first")
    if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not math.isfinite(tol) or tol <= 0:
        raise ValueError(f"tol: must be a finite relative tolerance > 0, got {tol!r} (e.g. 1e-6)")
    depths = check.depths(depth)
    for z in depths:
        check_plausible_at_entry(float(z), "depth", "m", stacklevel=3)  # 1.25 meant as mm warns
        skin.material_at(float(z))  # refuses a depth in the rigid base
    comps = check.components(components)
    pts, index = (None, None) if points is None else check_points(points, load)
    if padding != "auto" and (isinstance(padding, bool) or not isinstance(padding, (int, np.integer)) or padding < 1):
        raise ValueError(f"padding: must be 'auto' or an integer >= 1 (padded grid over load grid per axis), "
                         f"got {padding!r}")
    off_grid = pts if (pts is not None and index is None) else None
    if load.periodic:
        values = periodic_outputs(skin, load, depths, comps, quantity, off_grid)
        method, err, factor = "layered-periodic", 0.0, 1
    else:
        factor = 2 if padding == "auto" else int(padding)
        while True:
            big, where = padded_load(load, factor)
            values = periodic_outputs(skin, big, depths, comps, quantity, off_grid)
            if off_grid is None:
                values = values[(slice(None), slice(None), *where)]
            err = truncation_error(skin, load, depths, comps, quantity, factor, float(np.abs(values).max()))
            if padding != "auto" or err <= tol or factor >= MAX_PADDING:
                break
            factor *= 2
        method = "layered-padded"
        if err > tol:
            warnings.warn(f"the padded grid ({factor}x the load grid per axis) leaves an estimated truncation error "
                          f"{err:.1e} above tol={tol:.0e}; enlarge the load grid (more zero margin) or loosen tol",
                          AccuracyWarning, stacklevel=3)
    largest = max(largest_strain(values[d:d + 1], quantity, comps, *skin.material_at(float(z)))
                  for d, z in enumerate(depths))
    check_small_strain(largest, f"LayeredHalfSpace.{quantity}", stacklevel=3)
    rounding = 30.0 * np.finfo(float).eps * math.log2(max(values[0, 0].size * factor ** load.ndim, 2))
    err = float(err + rounding + _load_error(skin, load, values, depths, quantity))
    if index is not None:
        values = values[(slice(None), slice(None), *index)]
    covers = "method" if load.periodic else "method+truncation"
    attrs = dict(method=method, error_estimate=err, error_covers=covers + ("+load" if load.error_estimate else ""),
                 padding=factor, skin=repr(skin), shear_convention=SHEAR_CONVENTION)
    reason = "periodic load: exact per wavenumber" if load.periodic else \
        f"isolated load on a grid padded {factor}x per axis (truncation estimate {err:.1e})"
    return FieldResult(lambda: _labelled(values, quantity, comps, depths, load, pts, attrs), method, err, reason)

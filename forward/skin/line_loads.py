"""Plane-strain strain of tangential line loads on a layered skin, at any points (the tractor array's shapes).

Line loads ``w_c`` (N/m, along +x) at ``x_c`` on the surface give, at depth Z, the strain

    eps(x) = (1 / 2 pi) int T(k) Q(k) exp(i k x) dk,    Q(k) = sum_c w_c exp(-i k x_c),

with ``T(k)`` the layered skin's exact multiplier (docs/theory.md section 6) from a tangential
traction to strain at Z. The integral is summed as a Fourier series of period ``L`` (the loads'
periodic images ``L`` apart) over ``k_j = 2 pi j / L`` up to ``40 / Z`` (beyond it ``T`` has fallen
below ``e^-40``): up to 32 points directly, else by one inverse FFT onto a grid of spacing at most
Z / 128 and a cubic spline between its nodes (the field varies on the scale Z; measured: within
2e-9 of the peak of the direct sum). The default ``L`` is four times the largest ``|x|`` of loads
and points plus 40 times the larger of the depth and the layers' thickness, rounded up to a power
of two times 1 mm (so that calls share cached multipliers): on bone the images' field then falls
like ``exp(-L / H)``; on a half-space base like a tangential dipole's, ``(span / L)^2`` (tests
compare it with the half-space's closed form).

:func:`tractor_phi_psi` returns the shapes ``S_Phi = pi E eps_xx / 3`` and ``S_Psi = pi E gamma_zx / 3``
per unit line load (``E`` of the layer at Z, engineering shear ``gamma = 2 eps_zx``) that the
tactile-synthesis design (:mod:`tactilab.forward.synthesis`, docs/theory.md 4a) compares with its
target; on a half-space with nu = 1/2 they are the closed-form ``S_Phi, S_Psi``.
"""

from __future__ import annotations

import collections
import math

import numpy as np
from scipy.interpolate import CubicSpline

from tactilab.core import rules as check
from tactilab.forward.halfspace import HalfSpace, compliance_matrix

from .layered import Layer, LayeredHalfSpace
from .layered_multipliers import transfer_matrix

_CACHE: collections.OrderedDict = collections.OrderedDict()
_CACHE_ENTRIES = 32
#: up to this many points the series is summed directly (cheaper than the grid and the spline)
_DIRECT_POINTS = 32


def as_layered(skin) -> LayeredHalfSpace:
    """A LayeredHalfSpace for ``skin``: itself, or a half-space as one layer of its own material on itself."""
    if isinstance(skin, LayeredHalfSpace):
        return skin
    if isinstance(skin, HalfSpace):
        return LayeredHalfSpace([Layer(1e-3, skin.E, skin.nu)], base=skin)
    raise ValueError(f"skin: expected a HalfSpace or a LayeredHalfSpace, got {type(skin).__name__}; "
                     "e.g. LayeredHalfSpace([Layer(4e-3, 1e5, 0.5)])")


def _strain_multipliers(skin: LayeredHalfSpace, depth: float, period: float, n_modes: int) -> np.ndarray:
    """(eps_xx, gamma_zx) per unit qx spectrum at k_j = 2 pi j / period, j = 0..n_modes - 1; cached."""
    key = (repr(skin), depth, period, n_modes)
    if key in _CACHE:
        _CACHE.move_to_end(key)
        return _CACHE[key]
    k = 2 * np.pi * np.arange(n_modes) / period
    stress = transfer_matrix(skin, k, np.zeros_like(k), depth)[..., 1]  # (K, 6) Voigt stress per unit qx
    strain = stress @ compliance_matrix(*skin.material_at(depth)).T
    out = np.stack([strain[:, 0], 2.0 * strain[:, 4]])
    _CACHE[key] = out
    while len(_CACHE) > _CACHE_ENTRIES:
        _CACHE.popitem(last=False)
    return out


def tangential_line_strain(skin, x, sources, weights, depth: float, period: float | None = None):
    """``(eps_xx, gamma_zx)`` at points ``x`` and depth ``depth`` from tangential line loads.

    Parameters
    ----------
    skin : LayeredHalfSpace or HalfSpace
    x : array_like
        Points along x, m.
    sources : array_like, shape (m,)
        Line load positions, m.
    weights : array_like, shape (m,)
        Line loads along +x, N/m.
    depth : float
        Depth Z, m.
    period : float, optional
        Period of the Fourier series, m (default in the module docstring).

    Returns
    -------
    eps_xx, gamma_zx : ndarray, shape of ``x``
        Normal strain and ENGINEERING shear strain (dimensionless).
    """
    layered = as_layered(skin)
    depth = check.depth(depth)
    xs = check.finite_array(x, "x", "m")
    src = check.finite_array(sources, "sources", "m").ravel()
    w = check.finite_array(weights, "weights", "N/m").ravel()
    if src.shape != w.shape:
        raise ValueError(f"weights: need one weight per source, got {w.shape} for {src.shape}")
    span = float(max(np.abs(xs).max(initial=0.0), np.abs(src).max(initial=0.0)))
    if period is None:  # rounded up to a power of two times 1 mm, so that calls share the cached multipliers
        L = 1e-3 * 2.0 ** math.ceil(math.log2((4 * span + 40 * max(depth, layered.thickness)) / 1e-3))
    else:
        L = check.positive(period, "period", "m", "give the Fourier period in m, longer than the loads' span")
    n_modes = int(math.ceil(40.0 / depth * L / (2 * np.pi))) + 1
    T = _strain_multipliers(layered, depth, L, n_modes)
    k = 2 * np.pi * np.arange(n_modes) / L
    Q = (np.exp(-1j * np.outer(k, src)) * w).sum(axis=1)  # (K,) the loads' spectrum (a product-sum: no BLAS threads)
    flat = xs.ravel()
    if flat.size <= _DIRECT_POINTS:  # a few points: the series summed exactly
        scale = np.full(n_modes, 2.0 / L)
        scale[0] = 1.0 / L  # the mean mode counts once
        out = ((T * (Q * scale)) @ np.exp(1j * np.outer(k, flat))).real
        return out[0].reshape(xs.shape), out[1].reshape(xs.shape)
    # the series on a uniform grid of spacing <= Z / 128 by one inverse FFT, then a cubic spline: the field
    # varies on the scale Z, so the spline's error is about (h / Z)^4 / 384 (measured: below 2e-9 of the peak)
    m = 2 * max(n_modes, int(2 ** math.ceil(math.log2(128 * L / depth / 2))))
    h = L / m
    spectrum = np.zeros((2, m // 2 + 1), dtype=complex)
    spectrum[:, :n_modes] = T * Q
    grid = np.fft.irfft(spectrum, n=m, axis=-1) * (m / L)  # f(x_n), x_n = n h, periodic
    lo = int(math.floor(flat.min(initial=0.0) / h)) - 4
    hi = int(math.ceil(flat.max(initial=0.0) / h)) + 5
    nodes = np.arange(lo, hi)
    out = np.empty((2, flat.size))
    for i in range(2):
        spline = CubicSpline(nodes * h, grid[i][nodes % m])
        out[i] = spline(flat)
    return out[0].reshape(xs.shape), out[1].reshape(xs.shape)


def tractor_phi_psi(skin, x, sources, weights, depth: float) -> tuple[np.ndarray, np.ndarray]:
    """``S_Phi, S_Psi`` (1/m) of line loads on ``skin``: ``pi E / 3`` times ``eps_xx`` and ``gamma_zx``
    per N/m, ``E`` of the material at ``depth`` (see the module docstring)."""
    eps, gamma = tangential_line_strain(skin, x, sources, weights, depth)
    E = as_layered(skin).material_at(depth)[0]
    return np.pi * E / 3.0 * eps, np.pi * E / 3.0 * gamma

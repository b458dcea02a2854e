"""Strain under a row of line tractors (plane strain, nu = 1/2) and the drive gain.

Physics brief 4a: a tractor that pushes the skin along +x with a line load ``q`` (N/m, the
traction in Pa times the tractor's contact width along x) is Flamant's tangential line load.
With nu = 1/2 (incompressible skin) Hooke's law gives, at depth Z and ``u = x - x_n``,
``r^2 = u^2 + Z^2``::

    eps_xx = (3 q / (pi E)) * phi(u),   phi(u) = -u (u^2 - Z^2) / (2 r^4)
    eps_zz = -eps_xx
    eps_xz = (3 q / (pi E)) * psi(u) / 2,  psi(u) = -2 u^2 Z / r^4   (tensor shear;
                                                 engineering gamma_zx = 2 eps_xz)

A pair ``q [-delta(x + d) + delta(x - d)]`` sums to the brief's Phi and Psi; an array is the
superposition over its tractors. Strains here use the TENSOR shear eps_xz throughout.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["line_tractor_kernels", "line_tractor_strain", "sliding_surface_strain_amplitude",
           "strain_gain_line_load"]


def line_tractor_kernels(x_m, tractor_x_m, depth_m: float, young_modulus_pa: float
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Strain per unit line load: ``(K_xx, K_xz)``, each shape (n_points, n_tractors), 1/(N/m).

    ``eps_xx(x_i) = sum_n K_xx[i, n] q_n`` and ``eps_xz(x_i) = sum_n K_xz[i, n] q_n`` (tensor
    shear) at depth ``depth_m`` for line loads ``q_n`` (N/m, along +x) at ``tractor_x_m``.
    """
    u = np.asarray(x_m, dtype=float)[:, None] - np.asarray(tractor_x_m, dtype=float)[None, :]
    z2 = depth_m * depth_m
    r4 = (u * u + z2) ** 2
    scale = 3.0 / (math.pi * young_modulus_pa)
    k_xx = scale * (-0.5 * u * (u * u - z2) / r4)
    k_xz = scale * (-u * u * depth_m / r4)
    return k_xx, k_xz


def line_tractor_strain(x_m, tractor_x_m, line_load_n_per_m, depth_m: float,
                        young_modulus_pa: float) -> tuple[np.ndarray, np.ndarray]:
    """Strain at depth under line tractors.

    Parameters
    ----------
    x_m : ndarray, shape (n_points,)
        Where to evaluate, m.
    tractor_x_m : ndarray, shape (n_tractors,)
        Tractor positions, m.
    line_load_n_per_m : ndarray, shape (..., n_tractors)
        Tangential line loads along +x, N/m.
    depth_m : float
        Depth Z > 0, m.
    young_modulus_pa : float
        Skin Young's modulus E, Pa (nu = 1/2).

    Returns
    -------
    eps_xx, eps_xz : ndarray, shape (..., n_points)
        Normal strain along x (eps_zz = -eps_xx) and TENSOR shear strain (gamma_zx = 2 eps_xz).
    """
    k_xx, k_xz = line_tractor_kernels(x_m, tractor_x_m, depth_m, young_modulus_pa)
    q = np.asarray(line_load_n_per_m, dtype=float)
    return q @ k_xx.T, q @ k_xz.T


def sliding_surface_strain_amplitude(amplitude_m: float, pitch_m: float, depth_m: float) -> float:
    """Amplitude of eps_xx (and of the tensor shear eps_xz) under a sliding sinusoidal surface.

    ``4 pi^2 A Z / p^2 exp(-2 pi Z / p)`` (physics brief 4a; independent of E). The
    engineering shear amplitude is twice this.
    """
    return 4 * math.pi**2 * amplitude_m * depth_m / pitch_m**2 * math.exp(-2 * math.pi * depth_m / pitch_m)


def strain_gain_line_load(tractor_x_m, column_pitch_m: float, *, pitch_m: float, depth_m: float,
                          young_modulus_pa: float, n_phases: int = 16) -> float:
    """Line load (N/m) per m of virtual height that matches the sliding surface's strain.

    The drive ``q_n = g sin(2 pi x_n / p + phase)`` is compared with the surface
    ``H = sin(2 pi x / p + phase)`` (A = 1 m) sliding on the skin. ``g`` makes the mean squared
    Frobenius norm of the deviatoric strain tensor at depth Z (``2 eps_xx^2 + 2 eps_xz^2``)
    equal for both, averaged over the skin under the array (from half a column pitch before
    the first column to half after the last) and over ``n_phases`` phases of the scan. The
    surface's value is ``2 c^2`` with ``c`` from :func:`sliding_surface_strain_amplitude`.

    Returns
    -------
    float
        ``g`` in N/m per m (multiply by the height in m for a line load in N/m).
    """
    x_n = np.asarray(tractor_x_m, dtype=float)
    resolution = min(depth_m, column_pitch_m, pitch_m) / 16.0
    lo, hi = x_n.min() - column_pitch_m / 2, x_n.max() + column_pitch_m / 2
    n_points = int(min(4001, max(65, math.ceil((hi - lo) / resolution) + 1)))
    x = np.linspace(lo, hi, n_points)
    phases = 2 * np.pi * np.arange(n_phases) / n_phases
    drive = np.sin(2 * np.pi * x_n[None, :] / pitch_m + phases[:, None])  # (phases, tractors)
    eps_xx, eps_xz = line_tractor_strain(x, x_n, drive, depth_m, young_modulus_pa)
    array_power = float(np.mean(2 * eps_xx**2 + 2 * eps_xz**2))
    c = sliding_surface_strain_amplitude(1.0, pitch_m, depth_m)
    return math.sqrt(2 * c * c / array_power)

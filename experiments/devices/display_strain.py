"""Strain under rows of tractors (plane strain, nu = 1/2) and the drive gain.

docs/theory.md 4a: a tractor that pushes the skin along +x with a line load ``q`` (N/m, the
traction in Pa times the tractor's contact width along x) is Flamant's tangential line load,
spread over the tractor's width. The strain comes from the forward model,
:func:`tactilab.forward.tractors.tractor_row_strain` (closed form for a uniform strip; a pair
of line tractors sums to the Phi and Psi of docs/theory.md 4a). Strains here use the TENSOR shear
``eps_xz`` (engineering ``gamma_zx = 2 eps_xz``); with nu = 1/2, ``eps_zz = -eps_xx``.
"""

from __future__ import annotations

import math

import numpy as np

from tactilab.core import rules
from tactilab.forward.tractors import tractor_row_strain

__all__ = ["row_strain", "sliding_surface_strain_amplitude", "strain_gain_line_load"]


def row_strain(x_m, tractor_x_m, line_load_n_per_m, depth_m: float, young_modulus_pa: float,
               footprint_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Strain at depth under one row of tractors (incompressible skin, plane strain).

    Parameters
    ----------
    x_m : ndarray, shape (n_points,)
        Where to evaluate, m.
    tractor_x_m : ndarray, shape (n_tractors,)
        Tractor centres, m.
    line_load_n_per_m : ndarray, shape (..., n_tractors)
        Tangential line loads along +x, N/m.
    depth_m : float
        Depth Z > 0, m.
    young_modulus_pa : float
        Skin Young's modulus E, Pa (nu = 1/2).
    footprint_m : float
        Tractor contact width along x, m (0: line loads).

    Returns
    -------
    eps_xx, eps_xz : ndarray, shape (..., n_points)
        Normal strain along x (eps_zz = -eps_xx) and TENSOR shear strain (gamma_zx = 2 eps_xz).
    """
    voigt = tractor_row_strain(x_m, depth_m, tractor_x_m, line_load_n_per_m, young_modulus_pa,
                               0.5, footprint=footprint_m)
    return voigt[..., 0], voigt[..., 4]


def sliding_surface_strain_amplitude(amplitude_m: float, pitch_m: float, depth_m: float) -> float:
    """Amplitude of eps_xx (and of the tensor shear eps_xz) under a sliding sinusoidal surface.

    ``4 pi^2 A Z / p^2 exp(-2 pi Z / p)`` (docs/theory.md 4a; independent of E). The
    engineering shear amplitude is twice this. ``amplitude_m`` (finite), ``pitch_m`` and
    ``depth_m`` (finite, > 0) in m.
    """
    if isinstance(amplitude_m, bool) or not math.isfinite(float(amplitude_m)):
        raise ValueError(f"amplitude_m: must be a finite number in m, got {amplitude_m!r}")
    pitch_m, depth_m = rules.positive(pitch_m, "pitch_m", "m"), rules.depth(depth_m, "depth_m")
    return 4 * math.pi**2 * amplitude_m * depth_m / pitch_m**2 * math.exp(-2 * math.pi * depth_m / pitch_m)


def strain_gain_line_load(tractor_x_m, column_pitch_m: float, *, pitch_m: float, depth_m: float,
                          young_modulus_pa: float, footprint_m: float = 0.0, n_phases: int = 16) -> float:
    """Line load (N/m) per m of virtual height that matches the sliding surface's strain.

    The drive ``q_n = g sin(2 pi x_n / p + phase)`` is compared with the surface
    ``H = sin(2 pi x / p + phase)`` (A = 1 m) sliding on the skin. ``g`` makes the mean squared
    Frobenius norm of the deviatoric strain tensor at depth Z, tractors of width
    ``footprint_m`` (``2 eps_xx^2 + 2 eps_xz^2``)
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
    eps_xx, eps_xz = row_strain(x, x_n, drive, depth_m, young_modulus_pa, footprint_m)
    array_power = float(np.mean(2 * eps_xx**2 + 2 * eps_xz**2))
    c = sliding_surface_strain_amplitude(1.0, pitch_m, depth_m)
    return math.sqrt(2 * c * c / array_power)

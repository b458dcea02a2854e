"""Random rough surfaces: periodic, self-affine height maps with an exactly prescribed spectrum.

:func:`random_rough_surface` draws the heights on a grid; the ``random_rough`` surface kind of the
scenes (:class:`~.lab_surfaces.RandomRoughSurface`) and the contact engine use it.
"""

from __future__ import annotations

import numpy as np

from tactilab.core import rules


def _grid_spacing(shape, spacing) -> tuple[tuple[int, ...], tuple[float, ...]]:
    """Validate a grid ``shape`` ((nx,) or (ny, nx)) and its ``spacing`` (dx or (dx, dy), m), x first."""
    try:
        shape = tuple(int(n) for n in np.atleast_1d(shape))
    except (TypeError, ValueError):
        raise ValueError(f"shape: expected (nx,) or (ny, nx) integers, got {shape!r}") from None
    if len(shape) not in (1, 2) or min(shape) < 4:
        raise ValueError(f"shape: expected (nx,) for a profile or (ny, nx) for a surface, at least 4 nodes "
                         f"per axis, got {shape}; give e.g. (256, 256)")
    return shape, rules.spacing(spacing, len(shape))


def random_rough_surface(shape, spacing, *, rms_height: float | None = None, rms_slope: float | None = None,
                         hurst: float = 0.8, long_cutoff: float | None = None,
                         short_cutoff: float | None = None, rng: np.random.Generator) -> np.ndarray:
    """A periodic, self-affine random surface with an exactly prescribed spectrum and rms.

    The Fourier amplitude of every mode is deterministic, ``|H(q)| = sqrt(C(q))`` up to one scale,
    and only the phases are random (those of the FFT of white noise drawn from ``rng``, so the
    surface is real), so the discrete PSD is exact by construction, not only on average. The power
    spectral density is the self-affine power law between the cut-offs and flat below the long one
    (the usual roll-off)::

        C(q) = C0 (q / q_L)^(-2 (1 + H))   for q_L <= |q| <= q_S   (surface, shape (ny, nx))
        C(q) = C0 (q / q_L)^(-(1 + 2 H))   for the same band       (profile, shape (nx,))
        C(q) = C0 below q_L,   0 above q_S and at q = 0 (zero mean)

    with q the angular wavenumber (rad/m), q_L = 2 pi / long_cutoff and q_S = 2 pi / short_cutoff
    (the 1-D exponent is that of a profile of a self-affine surface of the same Hurst exponent H).
    The Nyquist modes (wavenumber index n/2 of an even axis) are left out so that the derivative
    is defined. C0 is set so that the requested rms equals the result's to rounding:

    - ``rms_height``: sqrt(mean(h^2)) (Parseval on the discrete spectrum);
    - ``rms_slope``: sqrt(mean(|grad h|^2)) with the exact (spectral) derivative of the band-limited
      surface, |grad h|^2 = h_x^2 + h_y^2. Periodic forward differences (h[i+1] - h[i]) / dx see each
      mode through 2 sin(q dx / 2) / dx instead of q, so they read a lower rms slope, by at most the
      factor sin(pi dx / short_cutoff) / (pi dx / short_cutoff) (0.64 at the default cut-off 2 dx,
      0.90 at 4 dx, 0.97 at 8 dx).

    Parameters
    ----------
    shape : (nx,) or (ny, nx)
        Grid shape, at least 4 nodes per axis; a 1-D shape is a profile along x.
    spacing : float or (float, float)
        Node spacing in m, ``dx`` or ``(dx, dy)`` (x first, as in ``SurfaceLoad``).
    rms_height : float, optional
        Requested rms height in m (> 0). Give exactly one of ``rms_height`` and ``rms_slope``.
    rms_slope : float, optional
        Requested rms slope, dimensionless (> 0).
    hurst : float
        Hurst exponent H in (0, 1]; 0.8 is typical of ground and worn surfaces.
    long_cutoff : float, optional
        Roll-off wavelength in m (the PSD is flat for longer wavelengths); default the grid's
        longest side (no flat part).
    short_cutoff : float, optional
        Shortest wavelength in m (no roughness below it); default 2 nodes (the grid's Nyquist
        wavelength), at least 2 nodes along the coarser axis.
    rng : numpy.random.Generator
        Source of the random phases (the same seed gives the same surface).

    Returns
    -------
    ndarray, shape ``shape``
        Heights in m, positive towards the skin, zero mean, periodic over the grid.

    Raises
    ------
    ValueError
        For a bad shape or spacing, not exactly one of ``rms_height`` / ``rms_slope``, a value that is
        not positive and finite, ``hurst`` outside (0, 1], cut-offs out of order or outside the grid's
        band, or ``rng`` that is not a ``numpy.random.Generator``.
    """
    shape, spacing = _grid_spacing(shape, spacing)
    if (rms_height is None) == (rms_slope is None):
        raise ValueError(f"rms_height, rms_slope: give exactly one of them, got rms_height={rms_height!r}, "
                         f"rms_slope={rms_slope!r}; e.g. rms_height=2e-6 (m) or rms_slope=0.1")
    if rms_height is not None:
        target = rules.positive(rms_height, "rms_height", "m", "give the rms height in m, e.g. 2e-6")
    else:
        target = rules.positive(rms_slope, "rms_slope", "1", "give the rms slope, e.g. 0.1")
    if not (isinstance(hurst, (int, float, np.floating, np.integer)) and 0 < hurst <= 1):
        raise ValueError(f"hurst: the Hurst exponent must be in (0, 1], got {hurst!r}; 0.8 is typical")
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}; "
                         "pass numpy.random.default_rng(seed)")
    lengths = [n * d for n, d in zip(reversed(shape), spacing)]  # (Lx, Ly)
    long_cutoff = max(lengths) if long_cutoff is None else long_cutoff
    short_cutoff = 2.0 * max(spacing) if short_cutoff is None else short_cutoff
    long_cutoff = rules.positive(long_cutoff, "long_cutoff", "m", "give a wavelength in m")
    short_cutoff = rules.positive(short_cutoff, "short_cutoff", "m", "give a wavelength in m")
    if short_cutoff < 2.0 * max(spacing) * (1 - 1e-12):
        raise ValueError(f"short_cutoff: {short_cutoff!r} m is below 2 node spacings ({2 * max(spacing)!r} m), "
                         "the shortest wavelength the grid carries; give at least that, or a finer spacing")
    if short_cutoff >= long_cutoff:
        raise ValueError(f"short_cutoff: must be shorter than long_cutoff, got {short_cutoff!r} m >= "
                         f"{long_cutoff!r} m; swap them or widen the band")
    # angular wavenumbers, axes as the array: (qx,) or (qy, qx); the Nyquist index (-n/2) left out
    axes = [2 * np.pi * np.fft.fftfreq(n, d) for n, d in zip(shape, reversed(spacing))]
    keep = [np.fft.fftfreq(n) != -0.5 for n in shape]
    grids = np.meshgrid(*axes, indexing="ij")
    q = np.sqrt(sum(g**2 for g in grids))
    q_long, q_short = 2 * np.pi / long_cutoff, 2 * np.pi / short_cutoff
    exponent = -(1 + 2 * hurst) if len(shape) == 1 else -2 * (1 + hurst)
    band = (q > 0) & (q <= q_short * (1 + 1e-12)) & np.logical_and.reduce(np.meshgrid(*keep, indexing="ij"))
    if not band.any():
        raise ValueError(f"short_cutoff: {short_cutoff!r} m leaves no mode on a grid of {shape} nodes at {spacing} m; "
                         "give a shorter cut-off or a larger grid")
    psd = np.where(band, (np.maximum(q, q_long) / q_long) ** exponent, 0.0)
    weight = psd if rms_height is not None else psd * q**2
    n_total = int(np.prod(shape))
    # Parseval: mean(h^2) = sum |H|^2 / N^2 (numpy's unnormalised FFT); the same for each derivative
    amplitude = np.sqrt(psd) * (target * n_total / np.sqrt(weight.sum()))
    phase = np.angle(np.fft.fftn(rng.standard_normal(shape)))  # Hermitian: the surface comes out real
    return np.fft.ifftn(amplitude * np.exp(1j * phase)).real

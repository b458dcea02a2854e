"""Surfaces a finger touches (or a display renders): gratings, isolated defects, height maps.

Every surface is a record with a ``kind`` tag and a height profile ``height_at(x, y)`` in m
(positive = raised towards the finger), in the WORLD frame: x along the scan, y across it.
``Surface`` is the tagged union used in scenes; files name the kind with ``kind = "..."``.

Kinds
-----
``flat``                 no relief (plain indentation).
``sinusoidal_grating``   H(x) = A sin(2 pi x / period + phase).
``square_wave_grating``  H(x) = A T(x), T = +-1 on elements of width ``element_width_m``:
                         alternating (``pattern="regular"``, period = 2 element widths) or drawn
                         at random from ``seed`` (``pattern="random"``, finite ``length_m``).
``defect``               one bump (smooth, raised-cosine), dot (flat-top disc) or edge step.
``height_map``           samples on a regular grid, linearly interpolated, 0 outside.
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Field, model_validator
from scipy.interpolate import RegularGridInterpolator

from tactilab.core import rules

from .base import Record, at_least, finite, float_array, positive

Finite = Annotated[float, finite()]


def _xy(x, y) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x, dtype=float)
    y = np.zeros_like(x) if y is None else np.asarray(y, dtype=float)
    try:
        x, y = np.broadcast_arrays(x, y)
    except ValueError:
        raise ValueError(
            f"x and y must broadcast together, got shapes {np.shape(x)} and {np.shape(y)}; "
            "give arrays of the same shape (or y=None for a profile along x)"
        ) from None
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("x, y: surface points must be finite (no NaN or inf), in m")
    return x, y


class FlatSurface(Record):
    """A flat surface: no relief."""

    kind: Literal["flat"] = "flat"

    def height_at(self, x, y=None) -> np.ndarray:
        """Height (m) at points (x, y) in m: zero everywhere."""
        x, _ = _xy(x, y)
        return np.zeros_like(x)


class SinusoidalGrating(Record):
    """A sinusoidal grating with ridges along y: H(x) = amplitude sin(2 pi x / period + phase).

    Parameters
    ----------
    period_m : float, m
        Spatial period, > 0.
    amplitude_m : float, m
        Peak height A, > 0.
    phase_rad : float, rad
        Phase at x = 0.
    """

    kind: Literal["sinusoidal_grating"] = "sinusoidal_grating"
    period_m: Annotated[float, positive("the grating spacing")]
    amplitude_m: Annotated[float, positive("the peak height of the relief")]
    phase_rad: Finite = 0.0

    @property
    def wavenumber_per_m(self) -> float:
        """Angular wavenumber k = 2 pi / period (rad/m)."""
        return 2.0 * np.pi / self.period_m

    def height_at(self, x, y=None) -> np.ndarray:
        """Height (m) at points (x, y) in m."""
        x, _ = _xy(x, y)
        return self.amplitude_m * np.sin(self.wavenumber_per_m * x + self.phase_rad)


class SquareWaveGrating(Record):
    """A square-wave grating T(x) = +-1 of height +-``amplitude_m``, regular or random.

    Parameters
    ----------
    pattern : {"regular", "random"}
        ``"regular"``: raised and lowered elements alternate (period = 2 element widths,
        raised on [start_m, start_m + element_width_m)). ``"random"``: each element is +1 or -1
        with probability 1/2, drawn with ``numpy.random.default_rng(seed)``.
    element_width_m : float, m
        Width of one raised or lowered element (bar), > 0.
    amplitude_m : float, m
        Height of the raised elements (lowered ones are at -amplitude), > 0.
    start_m : float, m
        x position where the first element begins.
    length_m : float or None, m
        Extent along x (height 0 outside [start_m, start_m + length_m)); required for
        ``"random"``, ``None`` (endless) allowed for ``"regular"``.
    seed : int or None
        Seed of the random pattern; required for ``"random"``, must be None for ``"regular"``.
    """

    kind: Literal["square_wave_grating"] = "square_wave_grating"
    pattern: Literal["regular", "random"] = "regular"
    element_width_m: Annotated[float, positive("the width of one bar")]
    amplitude_m: Annotated[float, positive("the height of the bars")]
    start_m: Finite = 0.0
    length_m: Annotated[float, positive("the extent of the grating")] | None = None
    seed: Annotated[int, at_least(0, "a numpy seed")] | None = None

    @model_validator(mode="after")
    def _pattern_needs(self) -> SquareWaveGrating:
        if self.pattern == "random":
            if self.seed is None:
                raise ValueError("seed is missing for pattern = 'random' (it fixes the pattern); "
                                 "give an integer seed >= 0")
            if self.length_m is None:
                raise ValueError("length_m is missing for pattern = 'random' (a random grating is "
                                 "finite); give its extent along x in m")
        elif self.seed is not None:
            raise ValueError(f"seed = {self.seed} is given but pattern = 'regular' has no randomness; "
                             "remove seed or set pattern = 'random'")
        return self

    @property
    def period_m(self) -> float:
        """Spatial period of the regular pattern, 2 element widths (m)."""
        return 2.0 * self.element_width_m

    @property
    def n_elements(self) -> int | None:
        """Number of elements within ``length_m`` (None when endless)."""
        if self.length_m is None:
            return None
        return int(np.ceil(self.length_m / self.element_width_m - 1e-9))

    def signs(self) -> np.ndarray:
        """The element signs T_k = +-1, shape (n_elements,); needs a finite ``length_m``."""
        n = self.n_elements
        if n is None:
            raise ValueError("signs() needs a finite length_m, got None; give length_m in m")
        if self.pattern == "regular":
            return np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
        rng = np.random.default_rng(self.seed)
        return np.where(rng.random(n) < 0.5, 1.0, -1.0)

    def height_at(self, x, y=None) -> np.ndarray:
        """Height (m) at points (x, y) in m."""
        x, _ = _xy(x, y)
        k = np.floor((x - self.start_m) / self.element_width_m)
        if self.length_m is None:
            return self.amplitude_m * np.where(k % 2 == 0, 1.0, -1.0)
        inside = (x >= self.start_m) & (x < self.start_m + self.length_m)
        signs = self.signs()
        idx = np.clip(k, 0, len(signs) - 1).astype(int)
        return np.where(inside, self.amplitude_m * signs[idx], 0.0)


class IsolatedDefect(Record):
    """One small defect on an otherwise flat surface.

    Parameters
    ----------
    shape : {"bump", "dot", "edge_step"}
        ``"bump"``: smooth raised-cosine dome of base diameter ``size_m``;
        ``"dot"``: flat-top disc of diameter ``size_m``;
        ``"edge_step"``: a step along y at x = x0, rising from 0 to ``height_m`` over a ramp of
        width ``size_m`` centred on x0.
    size_m : float, m
        Diameter (bump, dot) or ramp width (edge step), > 0.
    height_m : float, m
        Height of the defect, non-zero (negative for a pit or a step down).
    position_m : (float, float), m
        Centre (x0, y0) of the defect in the world frame.
    """

    kind: Literal["defect"] = "defect"
    shape: Literal["bump", "dot", "edge_step"] = "bump"
    size_m: Annotated[float, positive("the diameter or ramp width of the defect")]
    height_m: Annotated[float, finite()]
    position_m: tuple[Finite, Finite] = (0.0, 0.0)

    @model_validator(mode="after")
    def _height_not_zero(self) -> IsolatedDefect:
        if self.height_m == 0:
            raise ValueError("height_m must not be 0 (a defect has relief), got 0.0; give its height in m "
                             "(negative for a pit)")
        return self

    def height_at(self, x, y=None) -> np.ndarray:
        """Height (m) at points (x, y) in m."""
        x, y = _xy(x, y)
        x0, y0 = self.position_m
        if self.shape == "edge_step":
            s = np.clip((x - x0) / self.size_m + 0.5, 0.0, 1.0)
            return self.height_m * (0.5 - 0.5 * np.cos(np.pi * s))
        r = np.hypot(x - x0, y - y0)
        radius = self.size_m / 2.0
        if self.shape == "dot":
            return np.where(r <= radius, self.height_m, 0.0)
        return np.where(r < radius, self.height_m * 0.5 * (1.0 + np.cos(np.pi * r / radius)), 0.0)


class HeightMap(Record):
    """An arbitrary surface given by height samples on a regular grid.

    Parameters
    ----------
    heights_m : array_like, shape (nx,) or (ny, nx), m
        Heights; a 1-D array is a profile along x (the same for every y). At least 2 samples
        along each axis. Between samples the height is linearly interpolated; outside the
        grid it is 0.
    spacing_x_m, spacing_y_m : float, m
        Sample spacing along x and y (> 0); ``spacing_y_m`` is required for a 2-D map.
    origin_m : (float, float), m
        Position (x, y) of sample ``heights_m[0, 0]`` (or ``heights_m[0]``).
    """

    kind: Literal["height_map"] = "height_map"
    heights_m: float_array(reason="surface heights")
    spacing_x_m: Annotated[float, positive("the distance between samples")]
    spacing_y_m: Annotated[float, positive("the distance between samples")] | None = None
    origin_m: tuple[Finite, Finite] = (0.0, 0.0)

    @model_validator(mode="after")
    def _grid_shape(self) -> HeightMap:
        shape = self.heights_m.shape
        if len(shape) not in (1, 2):
            raise ValueError(f"heights_m must have shape (nx,) or (ny, nx), got {shape}; "
                             "give a profile or a 2-D map")
        if min(shape) < 2:
            raise ValueError(f"heights_m needs at least 2 samples along each axis to interpolate, "
                             f"got shape {shape}; sample the surface more finely")
        if len(shape) == 2 and self.spacing_y_m is None:
            raise ValueError(f"spacing_y_m is missing but heights_m is a 2-D map of shape {shape}; "
                             "give the row spacing spacing_y_m in m")
        return self

    @property
    def x_m(self) -> np.ndarray:
        """x coordinates of the sample columns, shape (nx,), m."""
        nx = self.heights_m.shape[-1]
        return self.origin_m[0] + np.arange(nx) * self.spacing_x_m

    @property
    def y_m(self) -> np.ndarray:
        """y coordinates of the sample rows, shape (ny,), m (one row for a profile)."""
        if self.heights_m.ndim == 1:
            return np.array([self.origin_m[1]])
        return self.origin_m[1] + np.arange(self.heights_m.shape[0]) * self.spacing_y_m

    def height_at(self, x, y=None) -> np.ndarray:
        """Height (m) at points (x, y) in m: linear interpolation, 0 outside the grid."""
        x, y = _xy(x, y)
        if self.heights_m.ndim == 1:
            return np.interp(x, self.x_m, self.heights_m, left=0.0, right=0.0)
        interp = RegularGridInterpolator((self.y_m, self.x_m), self.heights_m,
                                         bounds_error=False, fill_value=0.0)
        points = np.stack([y.ravel(), x.ravel()], axis=-1)
        return interp(points).reshape(x.shape)


Surface = Annotated[
    Union[FlatSurface, SinusoidalGrating, SquareWaveGrating, IsolatedDefect, HeightMap],
    Field(discriminator="kind"),
]
"""Any surface; the ``kind`` field picks the model."""

SURFACE_KINDS: dict[str, type[Record]] = {
    "flat": FlatSurface,
    "sinusoidal_grating": SinusoidalGrating,
    "square_wave_grating": SquareWaveGrating,
    "defect": IsolatedDefect,
    "height_map": HeightMap,
}
"""Surface models by their ``kind`` tag."""


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

"""Touched surfaces: gratings, random textures, isolated defects, height maps.

A surface is a height field ``h(x, y)`` in m in the SURFACE frame (x along the scanning
direction, y across it); positive heights stick out towards the skin. Each feature below
is mostly its formula; :class:`Surface` places features on a finite rectangle and checks
that every isolated defect lies on it.

Two ways turn heights into loads on the skin:

- :func:`rigid_surface_pressure`: a frictionless rigid surface sliding over the skin in full
  contact prescribes the normal displacement; the pressure is
  ``P~ = E rho H~ / (2 (1 - nu^2))`` (docs/theory.md section 2), zero-mean and periodic.
- :meth:`Surface.modulation`: in the biomimetic-finger model (docs/theory.md 4b) the texture
  modulates the interfacial stress of the fingertip contact multiplicatively,
  ``p_eff = p (1 + h / h_ref)`` (clipped at 0, as the skin cannot be pulled); a +-A square
  wave with ``h_ref = A`` is the T = +-1 grating of the paper, and a small defect of height
  ``h`` is a concentrated load of strength ``S_d = iint h / h_ref dA`` (m^2).
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass, field

import numpy as np

from .halfspace import pressure_from_deflection


def _pos(value, name: str, unit: str = "m") -> float:
    value = float(value)
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name}: must be finite and > 0 {unit}, got {value!r}; give it in SI ({unit})")
    return value


def _finite(value, name: str, unit: str = "m") -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name}: must be finite ({unit}), got {value!r}")
    return value


def _xy(x, y):
    x = np.asarray(x, dtype=float)
    y = np.zeros_like(x) if y is None else np.asarray(y, dtype=float)
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("x, y: surface points must be finite (no NaN or inf), in m")
    return np.broadcast_arrays(x, y)


class Feature(abc.ABC):
    """A height field in m. Subclasses supply :meth:`height` and, if isolated, :meth:`bounds`."""

    @abc.abstractmethod
    def height(self, x, y=None) -> np.ndarray:
        """Height in m at surface points (x, y) in m (y defaults to 0)."""

    def bounds(self) -> tuple[float, float, float, float] | None:
        """``(xmin, xmax, ymin, ymax)`` in m of an isolated defect; None for an extended texture."""
        return None

    def integral(self) -> float:
        """``iint h dA`` in m^3 for an isolated feature (0 for a periodic one)."""
        return 0.0


@dataclass(frozen=True)
class SinusoidalGrating(Feature):
    """``h = A sin(2 pi (x cos t + y sin t) / period + phase)``; A, period in m, t = orientation in rad."""

    period: float
    amplitude: float
    phase: float = 0.0
    orientation: float = 0.0

    def __post_init__(self):
        _pos(self.period, "period")
        _finite(self.amplitude, "amplitude")
        _finite(self.phase, "phase", "rad")
        _finite(self.orientation, "orientation", "rad")

    def height(self, x, y=None):
        x, y = _xy(x, y)
        s = x * math.cos(self.orientation) + y * math.sin(self.orientation)
        return self.amplitude * np.sin(2 * math.pi * s / self.period + self.phase)


@dataclass(frozen=True)
class SquareWaveGrating(Feature):
    """A regular +-amplitude square wave along x: ``+A`` on a fraction ``duty`` of each period."""

    period: float
    amplitude: float
    duty: float = 0.5
    offset: float = 0.0

    def __post_init__(self):
        _pos(self.period, "period")
        _finite(self.amplitude, "amplitude")
        if not 0.0 < float(self.duty) < 1.0:
            raise ValueError(f"duty: the ridge fraction must lie in (0, 1), got {self.duty!r}")
        _finite(self.offset, "offset")

    def height(self, x, y=None):
        x, _ = _xy(x, y)
        phase = np.mod(x - self.offset, self.period) / self.period
        return np.where(phase < self.duty, self.amplitude, -self.amplitude)


@dataclass(frozen=True)
class RandomSquareWaveGrating(Feature):
    """A random +-amplitude square wave along x, one fair coin per bit of length ``bit_length``.

    The bit sequence repeats with period ``n_bits * bit_length`` (so scans never run off it),
    starting at ``x = start``. Build it with :meth:`from_rng`; all randomness comes from ``rng``.
    """

    bit_length: float
    amplitude: float
    bits: np.ndarray
    start: float = 0.0

    def __post_init__(self):
        _pos(self.bit_length, "bit_length")
        _finite(self.amplitude, "amplitude")
        bits = np.asarray(self.bits, dtype=float)
        if bits.ndim != 1 or bits.size < 2 or not np.all(np.abs(bits) == 1):
            raise ValueError(f"bits: need a 1-D array of at least 2 values, each +1 or -1, got shape "
                             f"{bits.shape}; build it with RandomSquareWaveGrating.from_rng")
        bits.setflags(write=False)
        object.__setattr__(self, "bits", bits)

    @classmethod
    def from_rng(cls, rng: np.random.Generator, n_bits: int, bit_length: float, amplitude: float,
                 start: float = 0.0) -> "RandomSquareWaveGrating":
        """Draw ``n_bits`` fair +-1 bits from ``rng`` (a numpy Generator)."""
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}; "
                             "use numpy.random.default_rng(seed)")
        if int(n_bits) != n_bits or n_bits < 2:
            raise ValueError(f"n_bits: must be an integer >= 2, got {n_bits!r}")
        bits = rng.choice(np.array([-1.0, 1.0]), size=int(n_bits))
        return cls(bit_length=bit_length, amplitude=amplitude, bits=bits, start=start)

    def height(self, x, y=None):
        x, _ = _xy(x, y)
        index = np.floor((x - self.start) / self.bit_length).astype(np.int64) % self.bits.size
        return self.amplitude * self.bits[index]


@dataclass(frozen=True)
class Bump(Feature):
    """An isolated dot: a raised-cosine cap of diameter ``size`` and ``height`` centred at (x, y), m."""

    x: float
    y: float
    size: float
    height_m: float

    def __post_init__(self):
        _finite(self.x, "x")
        _finite(self.y, "y")
        _pos(self.size, "size")
        _finite(self.height_m, "height")

    def height(self, x, y=None):
        x, y = _xy(x, y)
        r = np.hypot(x - self.x, y - self.y) / (self.size / 2)
        return np.where(r < 1.0, 0.5 * self.height_m * (1.0 + np.cos(math.pi * np.minimum(r, 1.0))), 0.0)

    def bounds(self):
        h = self.size / 2
        return (self.x - h, self.x + h, self.y - h, self.y + h)

    def integral(self) -> float:
        # iint 0.5 h (1 + cos(pi r / b)) 2 pi r dr over r < b = h b^2 (pi/2 - 2/pi)
        b = self.size / 2
        return self.height_m * b * b * (math.pi / 2 - 2 / math.pi)


@dataclass(frozen=True)
class Step(Feature):
    """An edge across the scan at ``x``: the height rises by ``height_m`` over a ramp ``width`` (m; 0 = sharp)."""

    x: float
    height_m: float
    width: float = 0.0

    def __post_init__(self):
        _finite(self.x, "x")
        _finite(self.height_m, "height")
        if not math.isfinite(self.width) or self.width < 0:
            raise ValueError(f"width: the ramp width must be finite and >= 0 m, got {self.width!r}")

    def height(self, x, y=None):
        x, _ = _xy(x, y)
        if self.width == 0:
            return np.where(x >= self.x, self.height_m, 0.0)
        t = np.clip((x - self.x) / self.width + 0.5, 0.0, 1.0)
        return self.height_m * t * t * (3 - 2 * t)

    def bounds(self):
        return (self.x - self.width / 2, self.x + self.width / 2, -math.inf, math.inf)


@dataclass(frozen=True)
class HeightMap(Feature):
    """An arbitrary height map ``heights[iy, ix]`` in m on a grid of ``spacing`` (dx, dy) from ``origin``.

    Bilinear interpolation inside; 0 outside the map. A 1-D array is a profile along x.
    """

    heights: np.ndarray
    spacing: tuple[float, float] | float
    origin: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self):
        h = np.asarray(self.heights, dtype=float)
        if h.ndim == 1:
            h = h[None, :]
        if h.ndim != 2 or h.shape[-1] < 2:
            raise ValueError(f"heights: need shape (nx,) or (ny, nx) with nx >= 2, got {np.shape(self.heights)}")
        if not np.all(np.isfinite(h)):
            raise ValueError("heights: the height map contains NaN or inf; fill the gaps first")
        sp = np.atleast_1d(np.asarray(self.spacing, dtype=float))
        sp = np.repeat(sp, 2) if sp.size == 1 else sp
        for v, nm in zip(sp, ("dx", "dy")):
            _pos(v, f"spacing ({nm})")
        h.setflags(write=False)
        object.__setattr__(self, "heights", h)
        object.__setattr__(self, "spacing", (float(sp[0]), float(sp[1])))

    def height(self, x, y=None):
        x, y = _xy(x, y)
        ny, nx = self.heights.shape
        fx = (x - self.origin[0]) / self.spacing[0]
        fy = (y - self.origin[1]) / self.spacing[1] if ny > 1 else np.zeros_like(x)
        inside = (fx >= 0) & (fx <= nx - 1) & (fy >= 0) & (fy <= ny - 1)
        ix = np.clip(np.floor(fx).astype(np.int64), 0, max(nx - 2, 0))
        iy = np.clip(np.floor(fy).astype(np.int64), 0, max(ny - 2, 0))
        tx = np.clip(fx - ix, 0.0, 1.0)
        h = self.heights
        if ny == 1:
            val = (1 - tx) * h[0, ix] + tx * h[0, ix + 1]
        else:
            ty = np.clip(fy - iy, 0.0, 1.0)
            val = ((1 - ty) * ((1 - tx) * h[iy, ix] + tx * h[iy, ix + 1])
                   + ty * ((1 - tx) * h[iy + 1, ix] + tx * h[iy + 1, ix + 1]))
        return np.where(inside, val, 0.0)



@dataclass(frozen=True)
class Surface:
    """Features on a finite rectangle ``x in [x_start, x_start + length]``, ``|y| <= width / 2`` (m).

    Raises
    ------
    ValueError
        If an isolated feature (a defect, step or height map) lies outside the surface.
    """

    length: float
    width: float = 20e-3
    features: tuple = field(default_factory=tuple)
    x_start: float = 0.0

    def __post_init__(self):
        _pos(self.length, "length")
        _pos(self.width, "width")
        _finite(self.x_start, "x_start")
        feats = tuple(self.features)
        x0, x1 = self.x_start, self.x_start + self.length
        for i, f in enumerate(feats):
            if not isinstance(f, Feature):
                raise ValueError(f"features[{i}]: expected a surface Feature (Bump, Step, grating, "
                                 f"HeightMap), got {type(f).__name__}")
            b = f.bounds()
            if b is None:
                continue
            # infinite y-bounds (steps, profiles) span the whole width by construction
            half, tol = self.width / 2, 1e-12
            ylo = b[2] if math.isfinite(b[2]) else -half
            yhi = b[3] if math.isfinite(b[3]) else half
            if b[0] < x0 - tol or b[1] > x1 + tol or ylo < -half - tol or yhi > half + tol:
                raise ValueError(
                    f"features[{i}]: {getattr(f, 'label', type(f).__name__)} spans x in [{b[0]:.6g}, {b[1]:.6g}] m, "
                    f"y in [{b[2]:.6g}, {b[3]:.6g}] m, outside the surface x in [{x0:.6g}, {x1:.6g}] m, "
                    f"|y| <= {self.width / 2:.6g} m; move the defect onto the surface or enlarge length/width"
                )
        object.__setattr__(self, "features", feats)

    def height(self, x, y=None) -> np.ndarray:
        """Total height in m at surface points (x, y) in m; 0 off the surface."""
        x, y = _xy(x, y)
        total = np.zeros(x.shape)
        for f in self.features:
            total = total + f.height(x, y)
        on = (x >= self.x_start) & (x <= self.x_start + self.length) & (np.abs(y) <= self.width / 2)
        return np.where(on, total, 0.0)

    def modulation(self, x, y=None, *, reference_height: float) -> np.ndarray:
        """Interfacial-stress factor ``max(0, 1 + h / h_ref)`` (dimensionless) at surface points.

        ``reference_height`` (m, > 0) is the height that doubles the local interfacial stress.
        """
        h_ref = _pos(reference_height, "reference_height")
        return np.clip(1.0 + self.height(x, y) / h_ref, 0.0, None)


def rigid_surface_pressure(heights, spacing, young_modulus: float, poisson_ratio: float = 0.5) -> np.ndarray:
    """Pressure (Pa) that a frictionless rigid surface in full contact imposes on the skin.

    The surface prescribes the normal displacement ``H`` (m, periodic on the grid); in Fourier
    space ``P~ = E rho H~ / (2 (1 - nu^2))`` (docs/theory.md section 2). The rho = 0 mode is 0:
    the result is the zero-mean part, to which the mean contact pressure adds.

    Parameters
    ----------
    heights : ndarray, shape (nx,) or (ny, nx)
        Surface height (skin indentation) in m; 1-D is a plane-strain profile.
    spacing : float or (float, float)
        Grid spacing dx (or (dx, dy)) in m.
    young_modulus : float
        E in Pa.
    poisson_ratio : float
        nu in [0, 0.5].

    Returns
    -------
    ndarray, same shape as ``heights``, Pa.
    """
    h = np.asarray(heights, dtype=float)
    if h.ndim not in (1, 2) or not np.all(np.isfinite(h)):
        raise ValueError(f"heights: need a finite array of shape (nx,) or (ny, nx) in m, got shape {h.shape}")
    E = _pos(young_modulus, "young_modulus", "Pa")
    nu = float(poisson_ratio)
    if not 0.0 <= nu <= 0.5:
        raise ValueError(f"poisson_ratio: must lie in [0, 0.5], got {poisson_ratio!r}")
    sp = np.atleast_1d(np.asarray(spacing, dtype=float))
    sp = np.repeat(sp, h.ndim) if sp.size == 1 else sp
    if sp.size != h.ndim:
        raise ValueError(f"spacing: need {h.ndim} value(s) in m for heights of shape {h.shape}, got {spacing!r}")
    for v in sp:
        _pos(v, "spacing")
    # the spectral module owns the transfer function (and its rho = 0 and Nyquist rules)
    return pressure_from_deflection(h, tuple(float(v) for v in sp) if h.ndim == 2 else float(sp[0]),
                                    E, nu).p

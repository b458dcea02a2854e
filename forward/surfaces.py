"""The physics of touched surfaces: heights on the skin's scan strip, and the loads they make.

The surface MODEL is the data_schemas records (:mod:`tactilab.data_schemas.surface`:
``FlatSurface``, ``SinusoidalGrating``, ``SquareWaveGrating``, ``IsolatedDefect``, ``HeightMap``,
``RandomRoughSurface``, ``MeasuredSurface``),
heights in m in the world frame (x along the scan, y across it; positive heights stick out
towards the skin). This module holds what the forward model does with them:

- :class:`RecordFeature`: a record on a :class:`Surface`, with its extent (isolated defects),
  peak height and height integral;
- :class:`RandomSquareWaveGrating`: a random +-1 texture drawn from an ``rng`` and repeating
  periodically, the input of the Wiener-kernel identification (docs/theory.md 4b);
- :class:`Surface`: features on a finite rectangle; it checks that every isolated defect lies
  on it.

Two ways turn heights into loads on the skin:

- :func:`rigid_surface_pressure`: a frictionless rigid surface sliding over the skin in full
  contact prescribes the normal displacement; the pressure is
  ``P~ = E rho H~ / (2 (1 - nu^2))`` (docs/theory.md section 2), zero-mean and periodic: a
  ``SurfaceLoad`` marked ``periodic=True``.
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

from tactilab.data_schemas import surface as _surface_records

from .halfspace import SurfaceLoad, pressure_from_deflection
from tactilab.core import rules as check


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
        check.positive(self.bit_length, "bit_length")
        check.finite(self.amplitude, "amplitude", "m")
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


class RecordFeature(Feature):
    """A data_schemas surface record (``kind`` and ``height_at``) as a feature of a :class:`Surface`.

    Parameters
    ----------
    record : FlatSurface, SinusoidalGrating, SquareWaveGrating, IsolatedDefect or HeightMap
        From :mod:`tactilab.data_schemas`; heights in m, world frame.
    """

    def __init__(self, record):
        if not hasattr(record, "height_at") or not hasattr(record, "kind"):
            raise ValueError(f"surface: expected a data_schemas surface record (with kind and height_at), "
                             f"got {type(record).__name__}")
        self.record = record
        shape = getattr(record, "shape", None)
        self.label = f"{record.kind} {shape}" if isinstance(shape, str) else str(record.kind)

    def height(self, x, y=None):
        """Height in m at surface points (x, y) in m (y defaults to 0)."""
        x, y = _xy(x, y)
        return self.record.height_at(x, y)

    def bounds(self):
        """``(xmin, xmax, ymin, ymax)`` in m of an isolated defect (an edge spans all y); else None."""
        r = self.record
        if r.kind == "defect":
            x0, y0 = r.position_m
            h = r.size_m / 2
            if r.shape == "edge_step":
                return (x0 - h, x0 + h, -math.inf, math.inf)
            return (x0 - h, x0 + h, y0 - h, y0 + h)
        return None  # extended textures (gratings, height maps) may exceed the scanned strip

    def peak(self) -> float:
        """Largest |height| in m (the default reference height)."""
        r = self.record
        if r.kind in ("sinusoidal_grating", "square_wave_grating"):
            return float(r.amplitude_m)
        if r.kind == "defect":
            return abs(float(r.height_m))
        if r.kind in ("height_map", "random_rough"):
            return float(np.max(np.abs(r.heights_m)))
        if r.kind == "measured":
            return float(np.max(np.abs(r.height_map.heights_m)))
        return 0.0

    def coverage(self) -> tuple[float, float, float, float] | None:
        """``(xmin, xmax, ymin, ymax)`` in m where a measured surface is known; None where heights are
        defined everywhere (every other kind). A scan must stay inside it."""
        return self.record.extent() if self.record.kind == "measured" else None

    def integral(self) -> float:
        """``iint h dA`` in m^3 of a bump or dot defect (0 for other kinds)."""
        r = self.record
        if r.kind == "defect" and r.shape == "bump":
            # iint 0.5 h (1 + cos(pi r / b)) 2 pi r dr over r < b = h b^2 (pi/2 - 2/pi)
            b = r.size_m / 2
            return r.height_m * b * b * (math.pi / 2 - 2 / math.pi)
        if r.kind == "defect" and r.shape == "dot":
            return r.height_m * math.pi * (r.size_m / 2) ** 2
        return 0.0


def as_feature(item) -> Feature:
    """A :class:`Feature` as is, or a data_schemas surface record wrapped in :class:`RecordFeature`."""
    return item if isinstance(item, Feature) else RecordFeature(item)


@dataclass(frozen=True)
class Surface:
    """Features on a finite rectangle ``x in [x_start, x_start + length]``, ``|y| <= width / 2`` (m).

    ``features`` holds data_schemas surface records (wrapped in :class:`RecordFeature`) or
    :class:`Feature` objects such as :class:`RandomSquareWaveGrating`.

    Raises
    ------
    ValueError
        If an isolated feature (a defect or an edge) lies outside the surface.
    """

    length: float
    width: float = 20e-3
    features: tuple = field(default_factory=tuple)
    x_start: float = 0.0

    def __post_init__(self):
        check.positive(self.length, "length", "m")
        check.positive(self.width, "width")
        check.finite(self.x_start, "x_start", "m")
        feats = []
        for i, f in enumerate(self.features):
            try:
                feats.append(as_feature(f))
            except ValueError:
                raise ValueError(f"features[{i}]: expected a data_schemas surface record or a surface Feature "
                                 f"(e.g. RandomSquareWaveGrating), got {type(f).__name__}") from None
        feats = tuple(feats)
        x0, x1 = self.x_start, self.x_start + self.length
        for i, f in enumerate(feats):
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
        on = (x >= self.x_start) & (x <= self.x_start + self.length) & (np.abs(y) <= self.width / 2)
        total = np.zeros(x.shape)
        for f in self.features:  # evaluated on the surface only: a measured map need not cover more
            total[on] += f.height(x[on], y[on])
        return total

    def modulation(self, x, y=None, *, reference_height: float) -> np.ndarray:
        """Interfacial-stress factor ``max(0, 1 + h / h_ref)`` (dimensionless) at surface points.

        ``reference_height`` (m, > 0) is the height that doubles the local interfacial stress.
        """
        h_ref = check.positive(reference_height, "reference_height")
        return np.clip(1.0 + self.height(x, y) / h_ref, 0.0, None)


def rigid_surface_pressure(heights, spacing, young_modulus: float, poisson_ratio: float = 0.5) -> SurfaceLoad:
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
        nu in (-1, 0.5]; 0.5 (incompressible) is exact.

    Returns
    -------
    SurfaceLoad
        The periodic load (``periodic=True``: the grid is one period of the surface) whose ``p``
        (Pa, the shape of ``heights``) is the pressure; pass it to :class:`~tactilab.forward.HalfSpace`
        as it is (rewrapped as an isolated load it loses its periodic images and the fields are wrong).
    """
    h = np.asarray(heights, dtype=float)
    if h.ndim not in (1, 2) or not np.all(np.isfinite(h)):
        raise ValueError(f"heights: need a finite array of shape (nx,) or (ny, nx) in m, got shape {h.shape}")
    E = check.young_modulus(young_modulus, "young_modulus")
    nu = check.poisson_ratio(poisson_ratio, "poisson_ratio")
    sp = check.spacing(spacing, h.ndim)
    # the spectral module owns the transfer function (and its rho = 0 and Nyquist rules)
    return pressure_from_deflection(h, sp if h.ndim == 2 else sp[0], E, nu)


def random_rough_surface(shape, spacing, *, rms_height: float | None = None, rms_slope: float | None = None,
                         hurst: float = 0.8, long_cutoff: float | None = None,
                         short_cutoff: float | None = None, rng: np.random.Generator) -> np.ndarray:
    """A periodic, self-affine random surface (heights in m, shape ``shape``) with an exact spectrum and rms.

    The same function as :func:`tactilab.data_schemas.random_rough_surface` (defined there, where the
    scenes' surface records use it), offered here beside the contact solver that presses on it; see
    that docstring for the spectrum, the rms conventions and the errors raised.
    """
    return _surface_records.random_rough_surface(shape, spacing, rms_height=rms_height, rms_slope=rms_slope,
                                                 hurst=hurst, long_cutoff=long_cutoff,
                                                 short_cutoff=short_cutoff, rng=rng)

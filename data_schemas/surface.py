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
``height_map``           samples on a regular grid given inline, linearly interpolated, 0 outside
                         (:mod:`.height_map_record`).
``random_rough``         a self-affine random surface generated once on its own grid from a seed,
                         interpolated and repeated periodically (:mod:`.lab_surfaces`).
``measured``             a topography file next to the scene file, read by ``read_height_map``
                         (:mod:`.lab_surfaces`).
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Field, model_validator

from tactilab.core import rules

from .base import Record, at_least, finite, positive
from .height_map_record import HeightMap
from .lab_surfaces import MeasuredSurface, RandomRoughSurface
from .rough_surface import random_rough_surface
from .surface_points import surface_points as _xy

__all__ = ["FlatSurface", "SinusoidalGrating", "SquareWaveGrating", "IsolatedDefect", "HeightMap",
           "RandomRoughSurface", "MeasuredSurface", "Surface", "SURFACE_KINDS", "random_rough_surface"]

Finite = Annotated[float, finite()]


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


Surface = Annotated[
    Union[FlatSurface, SinusoidalGrating, SquareWaveGrating, IsolatedDefect, HeightMap, RandomRoughSurface,
          MeasuredSurface],
    Field(discriminator="kind"),
]
"""Any surface; the ``kind`` field picks the model."""

SURFACE_KINDS: dict[str, type[Record]] = {
    "flat": FlatSurface,
    "sinusoidal_grating": SinusoidalGrating,
    "square_wave_grating": SquareWaveGrating,
    "defect": IsolatedDefect,
    "height_map": HeightMap,
    "random_rough": RandomRoughSurface,
    "measured": MeasuredSurface,
}
"""Surface models by their ``kind`` tag."""

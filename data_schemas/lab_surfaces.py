"""Surfaces a lab has: a random rough plate (``random_rough``) and a measured topography (``measured``).

``random_rough``
    A self-affine random surface (:func:`~.rough_surface.random_rough_surface`) generated ONCE on
    its own grid (``spacing_m``, ``size_m``) from ``seed``, then read by bilinear interpolation and
    repeated periodically over the plane (the generated surface is periodic). The surface is the
    interpolant of its own nodes, so a simulation grid of any spacing sees the same surface.
``measured``
    A topography file next to the scene file, read by
    :func:`~.height_map.read_height_map` (``.npy`` and plain ``.csv`` with ``spacing`` and
    ``height_unit`` given here; labelled ``.csv`` and netCDF with their own coordinates; the
    profilometer formats through the optional extra ``topography``). The map is read once, when
    the record is built, into a :class:`~.height_map_record.HeightMap` (the ``height_map`` kind,
    which holds samples given inline): ``measured`` is a ``height_map`` whose samples live in a
    file. The path is relative to the scene file's folder and must stay inside it
    (:func:`~.paths.file_inside`). A map larger than the scanned strip is only read where the
    finger touches (cropped); a scan that leaves the map is refused by the forward model
    (``tactilab.forward.scanned_surface``), naming both sizes.
"""

from __future__ import annotations

import pathlib
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import PrivateAttr, ValidationInfo, model_validator

from .base import Record, at_least, finite, positive
from .height_map import MAX_HEIGHT_MAP_NODES, read_height_map
from .height_map_record import HeightMap
from .paths import file_inside
from .rough_surface import random_rough_surface
from .surface_points import surface_points

Positive = Annotated[float, positive()]
Finite = Annotated[float, finite()]


def _bilinear_periodic(heights: np.ndarray, spacing: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of ``heights`` (ny, nx; node (j, i) at (i, j) * spacing), periodic in both axes."""
    ny, nx = heights.shape
    fx, fy = x / spacing, y / spacing
    fx, fy = (np.where(np.abs(f - np.round(f)) < 1e-9, np.round(f), f) for f in (fx, fy))  # a node reads its node
    i0, j0 = np.floor(fx), np.floor(fy)
    tx, ty = fx - i0, fy - j0
    i0, j0 = i0.astype(np.int64) % nx, j0.astype(np.int64) % ny
    i1, j1 = (i0 + 1) % nx, (j0 + 1) % ny
    return ((1 - ty) * ((1 - tx) * heights[j0, i0] + tx * heights[j0, i1])
            + ty * ((1 - tx) * heights[j1, i0] + tx * heights[j1, i1]))


class RandomRoughSurface(Record):
    """A self-affine random plate, generated once on its own grid and repeated periodically.

    Parameters
    ----------
    rms_height_m : float, m, optional
        Root-mean-square height (> 0). Give exactly one of ``rms_height_m`` and ``rms_slope``.
    rms_slope : float, optional
        Root-mean-square slope, dimensionless (> 0), of the exact (spectral) gradient.
    hurst : float
        Hurst exponent in (0, 1]; 0.8 is typical of ground surfaces.
    long_cutoff_m, short_cutoff_m : float, m, optional
        Roll-off and shortest wavelengths (the spectrum is flat above ``long_cutoff_m`` and empty
        below ``short_cutoff_m``); defaults the longer side of ``size_m`` and 2 ``spacing_m``.
    seed : int
        Seed of the random phases (``numpy.random.default_rng(seed)``): the same seed gives the
        same surface.
    spacing_m : float, m
        The surface's own node spacing (> 0).
    size_m : (float, float), m
        Its period (Lx, Ly), each a whole number of ``spacing_m`` and at least 4 nodes.

    Raises
    ------
    ValueError
        Not exactly one rms, ``hurst`` outside (0, 1], a size that is not a whole number of nodes or
        too large (above ``MAX_HEIGHT_MAP_NODES`` nodes), cut-offs out of order or outside the grid's band.
    """

    kind: Literal["random_rough"] = "random_rough"
    rms_height_m: Positive | None = None
    rms_slope: Positive | None = None
    hurst: float = 0.8
    long_cutoff_m: Positive | None = None
    short_cutoff_m: Positive | None = None
    seed: Annotated[int, at_least(0, "a numpy seed")]
    spacing_m: Annotated[float, positive("the surface's own node spacing")]
    size_m: tuple[Positive, Positive]
    _heights: np.ndarray = PrivateAttr()

    @model_validator(mode="after")
    def _generate(self) -> RandomRoughSurface:
        if (self.rms_height_m is None) == (self.rms_slope is None):
            raise ValueError(f"rms_height_m, rms_slope: give exactly one of them, got rms_height_m={self.rms_height_m!r}, "
                             f"rms_slope={self.rms_slope!r}; e.g. rms_height = \"5um\" or rms_slope = 0.1")
        counts = []
        for axis, length in zip("xy", self.size_m):
            n = round(length / self.spacing_m)
            if n < 4 or abs(n * self.spacing_m - length) > 1e-6 * self.spacing_m:
                raise ValueError(f"size_m: the {axis} side {length!r} m must be a whole number (>= 4) of "
                                 f"spacing_m = {self.spacing_m!r} m; give e.g. {max(n, 4) * self.spacing_m!r} m")
            counts.append(n)
        if counts[0] * counts[1] > MAX_HEIGHT_MAP_NODES:
            raise ValueError(f"size_m: {counts[0]} x {counts[1]} nodes, above the limit {MAX_HEIGHT_MAP_NODES} "
                             "(memory); give a smaller size or a coarser spacing_m")
        heights = random_rough_surface((counts[1], counts[0]), self.spacing_m, rms_height=self.rms_height_m,
                                       rms_slope=self.rms_slope, hurst=self.hurst, long_cutoff=self.long_cutoff_m,
                                       short_cutoff=self.short_cutoff_m, rng=np.random.default_rng(self.seed))
        heights.setflags(write=False)
        self._heights = heights
        return self

    @property
    def heights_m(self) -> np.ndarray:
        """The generated heights, shape (ny, nx), m (read-only); node (j, i) sits at (i, j) * spacing_m."""
        return self._heights

    def height_at(self, x, y=None) -> np.ndarray:
        """Height (m) at points (x, y) in m: bilinear between the surface's nodes, periodic over ``size_m``."""
        x, y = surface_points(x, y)
        return _bilinear_periodic(self._heights, self.spacing_m, x, y)


class MeasuredSurface(Record):
    """A measured topography read from a file next to the scene file.

    Parameters
    ----------
    path : str
        The file, relative to the scene file's folder (no ``..``, no symlink): ``.npy``, ``.csv``,
        ``.nc`` or a profilometer format (``.x3p``, ``.datx``, ``.gwy``, ...; the optional extra
        ``topography``). Built from Python, the folder is the current one.
    spacing_m : float or (float, float), m, optional
        Node spacing (dx or (dx, dy)) for files without coordinates (``.npy``, a plain ``.csv``).
    height_unit : str, optional
        Unit of the heights in those files (``"um"``, ``"nm"``, ``"mm"``, ``"m"``).
    origin_m : (float, float), m, optional
        World position (x, y) of the map's first node; default the file's own coordinates
        (0 for files without them).
    level : {"none", "mean", "plane"}
        ``"none"`` keeps the heights as measured; ``"mean"`` subtracts their mean; ``"plane"`` the
        least-squares plane (a profile: line), as profilometer software does for a tilted sample.

    Raises
    ------
    ValueError
        A path outside the scene's folder or through a symlink, a file the reader refuses (NaN, a
        wrong or missing unit, a non-uniform grid: the message names the file).
    """

    kind: Literal["measured"] = "measured"
    path: str
    spacing_m: Positive | tuple[Positive, Positive] | None = None
    height_unit: str | None = None
    origin_m: tuple[Finite, Finite] | None = None
    level: Literal["none", "mean", "plane"] = "none"
    _map: HeightMap = PrivateAttr()
    _folder: pathlib.Path = PrivateAttr()

    @model_validator(mode="after")
    def _read(self, info: ValidationInfo) -> MeasuredSurface:
        folder = (info.context or {}).get("folder") if info is not None else None
        self._folder = pathlib.Path.cwd() if folder is None else pathlib.Path(folder)
        target = file_inside(self._folder, self.path, key="path", owner="scene", what="topography file")
        raw = read_height_map(target, spacing=self.spacing_m, height_unit=self.height_unit)
        heights = _levelled(raw.heights_m, self.level)
        origin = raw.origin_m if self.origin_m is None else self.origin_m
        self._map = HeightMap(heights_m=heights, spacing_x_m=raw.spacing_x_m, spacing_y_m=raw.spacing_y_m,
                              origin_m=origin)
        return self

    @property
    def height_map(self) -> HeightMap:
        """The map as read (levelled, placed at ``origin_m``): a ``height_map`` record, heights in m."""
        return self._map

    def extent(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)`` in m covered by the map (a profile covers every y)."""
        m = self._map
        x = m.x_m
        if m.heights_m.ndim == 1:
            return float(x[0]), float(x[-1]), -np.inf, np.inf
        y = m.y_m
        return float(x[0]), float(x[-1]), float(y[0]), float(y[-1])

    def height_at(self, x, y=None) -> np.ndarray:
        """Height (m) at points (x, y) in m, linear between samples; points off the map are refused."""
        x, y = surface_points(x, y)
        x0, x1, y0, y1 = self.extent()
        tol = 1e-9 * max(abs(x1 - x0), 1e-12)
        outside = (x < x0 - tol) | (x > x1 + tol) | (y < y0 - tol) | (y > y1 + tol)
        if outside.any():
            i = np.flatnonzero(outside.ravel())[0]
            raise ValueError(f"{self.path}: the point ({x.ravel()[i]:.6g}, {y.ravel()[i]:.6g}) m lies off the measured "
                             f"map (x in [{x0:.6g}, {x1:.6g}] m, y in [{y0:.6g}, {y1:.6g}] m); move the scan onto "
                             "the map or set origin_m")
        return self._map.height_at(np.clip(x, x0, x1), np.clip(y, y0, y1) if np.isfinite(y0) else y)

    def replace(self, **changes: Any) -> MeasuredSurface:
        """A copy with some fields changed, read again from the same folder."""
        data = {k: getattr(self, k) for k in type(self).model_fields}
        data.update(changes)
        return type(self).model_validate(data, context={"folder": self._folder})


def _levelled(heights: np.ndarray, level: str) -> np.ndarray:
    """Heights less nothing, their mean, or their least-squares plane (line for a profile)."""
    if level == "none":
        return heights
    if level == "mean":
        return heights - heights.mean()
    grids = np.meshgrid(*[np.arange(n, dtype=float) for n in heights.shape], indexing="ij")
    design = np.stack([np.ones(heights.size)] + [g.ravel() for g in grids], axis=1)
    coeffs, *_ = np.linalg.lstsq(design, heights.ravel(), rcond=None)
    return heights - (design @ coeffs).reshape(heights.shape)

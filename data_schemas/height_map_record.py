"""The ``height_map`` surface kind: heights sampled on a regular grid, given inline (m)."""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import model_validator
from scipy.interpolate import RegularGridInterpolator

from .base import Record, finite, float_array, positive
from .surface_points import surface_points

Finite = Annotated[float, finite()]


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
        x, y = surface_points(x, y)
        if self.heights_m.ndim == 1:
            return np.interp(x, self.x_m, self.heights_m, left=0.0, right=0.0)
        interp = RegularGridInterpolator((self.y_m, self.x_m), self.heights_m,
                                         bounds_error=False, fill_value=0.0)
        points = np.stack([y.ravel(), x.ravel()], axis=-1)
        return interp(points).reshape(x.shape)

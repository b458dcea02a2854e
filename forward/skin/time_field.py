"""A field at depth over time: the answer of the viscoelastic half-space's stress and strain."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import xarray as xr


@dataclass(frozen=True)
class TimeFieldResult:
    """Stress (Pa) or TENSOR strain at depth, at each requested time.

    Attributes
    ----------
    values : ndarray, shape (n_times, n_depths, n_components, *grid) or (n_times, n_depths, n_components, n_points)
        The field: the elastic solver's layout with a leading time axis.
    times : ndarray, shape (n_times,)
        Times in s.
    quantity : {"stress", "strain"}
    method : str
        The elastic method that computed the spatial field, and how time entered, e.g.
        ``"spectral + creep convolution"``.
    error_estimate : float
        The elastic method's estimate, relative to the field's peak (the recursive convolution is
        exact for the piecewise linear histories it is given; a steady state is exact per mode).
    base : FieldResult
        The elastic solver's answer for one time: its labels (depth, component, y, x or point)
        label every time's field.
    """

    values: np.ndarray = field(repr=False)
    times: np.ndarray
    quantity: str
    method: str
    error_estimate: float
    base: object = field(repr=False)

    def __post_init__(self) -> None:
        self.values.setflags(write=False)

    @functools.cached_property
    def data(self) -> xr.Dataset:
        """``xarray.Dataset`` with the field named ``quantity``, dims ``("time", *template.dims)``."""
        template = self.base.data[self.quantity]
        coords = {name: c for name, c in template.coords.items()}
        coords["time"] = ("time", np.asarray(self.times), {"units": "s", "long_name": "time since the load began"})
        da = xr.DataArray(self.values, dims=("time",) + template.dims, coords=coords, name=self.quantity,
                          attrs=dict(template.attrs))
        ds = da.to_dataset()
        ds.attrs.update({k: v for k, v in self.base.data.attrs.items() if k in ("nu", "shear_convention", "dtype")})
        ds.attrs.update(method=self.method, error_estimate=self.error_estimate)
        return ds

    def __repr__(self) -> str:
        dims = "x".join(str(n) for n in self.values.shape)
        return (f"TimeFieldResult({self.quantity} (time, depth, component, ...) = {dims}, method={self.method!r}, "
                f"est. rel. error {self.error_estimate:.1e})")

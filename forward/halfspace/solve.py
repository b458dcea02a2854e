"""The solver's shared steps: check the points, solve on a nodal load, package the result.

Both paths of :class:`~.facade.HalfSpace` call these: the nodal-load path in the facade and the
continuous-load path (:mod:`.sampled`, which solves on several grids). Neither calls the other's
private methods, and this module imports neither of them.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field

import math

import numpy as np
import xarray as xr

from tactilab.data_schemas.plausibility import check_small_strain

from .fields import SHEAR_CONVENTION, compliance_matrix, invariants, label, largest_strain, output_weights
from .loads import SurfaceLoad
from .methods import Method, Problem, select_method, user_stacklevel

#: tolerances from this one up are computed in float32
FLOAT32_TOL = 1e-4


@dataclass(frozen=True)
class Solution:
    """One solve on a nodal load: the values and how they were chosen."""

    values: np.ndarray
    chosen: Method
    reason: str
    candidates: dict
    err: float
    quantity: str
    reduced: bool
    dtype: str


@dataclass(frozen=True)
class FieldResult:
    """A computed field with its provenance.

    Attributes
    ----------
    data : xarray.Dataset
        ``stress`` (Pa) and/or ``strain`` (tensor shear) with dims (depth, component, y, x),
        (depth, component, x) in 1-D, or (depth, component, point) at sensor points; plus
        invariants when asked. Labelled on first access (the solve itself never waits for
        xarray), then kept.
    method : str
        The method that ran.
    error_estimate : float
        Estimated max error relative to the field's peak magnitude; ``data.attrs["error_covers"]``
        says what it covers: ``"method"`` (a nodal ``SurfaceLoad``: the method's error for the
        values as given), ``"method+load"`` (a ``SurfaceLoad`` with its own ``error_estimate``, as a
        solved contact's load carries: that error too) or ``"method+sampling"`` (a
        ``ContinuousLoad``: also its sampling).
    reason : str
        Why this method was chosen.
    candidates : dict
        Per method: (error_estimate, cost) or the reason it could not run.
    """

    source: xr.Dataset | Callable[[], xr.Dataset] = field(repr=False)
    method: str
    error_estimate: float
    reason: str
    candidates: dict = field(default_factory=dict)

    @functools.cached_property
    def data(self) -> xr.Dataset:
        """The labelled fields (see the class docstring); built from ``source`` once, on first access."""
        return self.source if isinstance(self.source, xr.Dataset) else self.source()

    def __repr__(self) -> str:
        """Method, error estimate and the fields' shapes and units; never the arrays."""
        parts = []
        for name, var in self.data.data_vars.items():
            unit = var.attrs.get("units", "")
            unit = {"1": "strain", "": "strain" if "strain" in str(name) else ""}.get(unit, unit)
            dims = ", ".join(f"{d}={n}" for d, n in var.sizes.items())
            parts.append(f"{name} ({dims}) [{unit}]" if unit else f"{name} ({dims})")
        covers = self.data.attrs.get("error_covers")
        covers = f" ({covers})" if covers else ""
        return (f"FieldResult(method={self.method!r}, est. rel. error {self.error_estimate:.1e}{covers}; "
                + "; ".join(parts) + ")")

    def _repr_html_(self) -> str:
        """The short repr for notebooks (escaped, monospace)."""
        import html

        return "<pre>" + html.escape(repr(self)) + "</pre>"


def check_points(points, load: SurfaceLoad) -> np.ndarray | None:
    """Sensor points as an (n, 1) or (n, 2) float array in m (None: the load grid), checked against the load."""
    if points is None:
        return None
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 1:
        pts = pts[:, None]
    if pts.ndim != 2 or pts.shape[1] not in (1, 2) or len(pts) == 0:
        raise ValueError(f"points: expected shape (n, 2) of (x, y) in m (or (n,) of x for a 1-D load), got {np.shape(points)}")
    if load.ndim == 2 and pts.shape[1] != 2:
        raise ValueError(f"points: a 2-D load needs (x, y) per point, shape (n, 2); got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points: coordinates must be finite (no NaN or inf), in m")
    return pts


def load_error(load: SurfaceLoad, values: np.ndarray, stress_scale: float) -> float:
    """The load's own error (``SurfaceLoad.error_estimate``, relative to its peak traction) relative to the field's peak.

    The field is linear in the tractions, so a traction error of ``e`` times the peak traction
    moves the field by about that much stress (the scaling of ``Method.field_error``)."""
    if not load.error_estimate:
        return 0.0
    peak_traction = float(sum(np.abs(a) for a in load.components.values()).max())
    peak_field = float(np.abs(values).max()) * stress_scale
    if peak_field == 0.0:
        return load.error_estimate
    return load.error_estimate * peak_traction / peak_field


def _float32_scale(load: SurfaceLoad) -> float:
    """The power of 2 nearest the load's peak traction (1 for a zero load): float32 holds only about
    1e-38 to 3e38, so a float32 solve runs on the load divided by it (exact: a power of 2) and its
    rounding stays about eps32 of the field's peak at any magnitude (1e-40 Pa lost 1e-4 of it, 1e38 Pa
    overflowed)."""
    peak = float(sum(np.abs(a) for a in load.components.values()).max())
    return 2.0 ** round(math.log2(peak)) if 0.0 < peak < math.inf else 1.0


def _scaled_back(values: np.ndarray, scale: float) -> np.ndarray:
    """``values * scale``: exact in float32 while the result stays in its normal range, else float64."""
    info = np.finfo(np.float32)
    peak = float(np.abs(values).max()) * scale
    if values.dtype == np.float32 and info.tiny < scale < info.max and (
            peak == 0.0 or info.tiny / info.eps < peak < info.max / 2):
        return values * np.float32(scale)
    return values.astype(np.float64) * scale


def solve(E: float, nu: float, load: SurfaceLoad, depths, comps, pts, method, tol: float, quantity: str,
          want_invariants: bool) -> Solution:
    """Choose a method and compute on a nodal load; values have the load's grid (or points).

    ``E`` (Pa), ``nu``, ``depths`` (m) and ``comps`` come checked by the facade's rules.
    """
    reduced = load.periodic and load.ndim == 2 and not load.varies_in_y()
    work_load = load.row() if reduced else load
    work_pts = pts[:, :1] if (reduced and pts is not None) else pts
    dtype = np.dtype(np.float32 if tol >= FLOAT32_TOL else np.float64)
    scale = _float32_scale(work_load) if dtype == np.float32 else 1.0
    if scale != 1.0:  # the field is linear in the load: solve on a unit peak, scale the field back
        work_load = work_load.scaled(1.0 / scale)
    weight_quantity = "stress" if want_invariants else quantity
    weights = output_weights(weight_quantity, comps, E, nu)
    problem = Problem(work_load, depths, nu, weights, work_pts, dtype)
    chosen, reason, candidates = select_method(problem, tol, method)
    if chosen.name == "closed_form" and dtype == np.float32:
        problem = Problem(work_load, depths, nu, weights, work_pts, np.dtype(np.float64))
    values = chosen.compute(problem)
    stress_scale = E if weight_quantity == "strain" else 1.0
    err = chosen.field_error(problem, values, stress_scale) + load_error(work_load, values, stress_scale)
    if scale != 1.0:
        values = _scaled_back(values, scale)
    if reduced and pts is None:  # broadcast the plane-strain row over y
        values = np.broadcast_to(values[..., None, :], values.shape[:-1] + load.shape).copy()
    return Solution(values, chosen, reason, candidates, float(err), weight_quantity, reduced, str(problem.dtype))


def package(E: float, nu: float, load, sol: Solution, depths, comps, pts, want_invariants: bool, error_covers: str,
            sampling_estimate: float | None = None, extra: dict | None = None) -> FieldResult:
    """The result; its xarray Dataset is built on the first access of ``FieldResult.data``.

    A field whose largest strain exceeds the small-strain limit warns here, once per answer
    (:func:`tactilab.data_schemas.plausibility.check_small_strain`; one max over the field).
    """
    check_small_strain(largest_strain(sol.values, sol.quantity, comps, E, nu), f"HalfSpace.{sol.quantity}",
                       stacklevel=user_stacklevel())
    err = sol.err if sampling_estimate is None else sol.err + sampling_estimate
    attrs = dict(method=sol.chosen.name, error_estimate=err, error_covers=error_covers,
                 method_error_estimate=sol.err, reason=sol.reason, E_pa=E, nu=nu,
                 reduced_to_1d=int(sol.reduced), dtype=sol.dtype, shear_convention=SHEAR_CONVENTION)
    if sampling_estimate is not None:
        attrs["sampling_error_estimate"] = sampling_estimate
    attrs.update(extra or {})
    x, y = load.x, load.y
    depths = np.array(depths, dtype=float)  # private copies: the caller may reuse its arrays before
    pts = None if pts is None else np.array(pts, dtype=float)  # the first access labels them

    def build() -> xr.Dataset:
        da = label(sol.values, sol.quantity, comps, depths, x, y, pts)
        ds = da.to_dataset()  # the DataArray is named sol.quantity (fields.label); 5x cheaper than Dataset({...})
        if want_invariants:
            strain_vals = np.einsum("ij,dj...->di...", compliance_matrix(E, nu), sol.values)
            strain = label(strain_vals, "strain", comps, depths, x, y, pts)
            ds["strain"] = strain
            ds = ds.merge(invariants(strain, da))
        ds.attrs.update(attrs)
        return ds

    return FieldResult(build, sol.chosen.name, err, sol.reason, sol.candidates)

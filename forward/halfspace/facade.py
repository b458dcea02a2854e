"""The elastic half-space facade: one entry point, a registry of methods behind it.

>>> hs = HalfSpace(E=1e6, nu=0.5)                       # Pa, dimensionless
>>> result = hs.strain(load, depth=[1e-3, 2e-3], components=("zz", "zx"))
>>> result.method, result.error_estimate, result.data["strain"]

``method="auto"`` picks, among the methods whose error estimate meets ``tol``, the one
with the lowest cost model; a user can force one by name or class (``solve_ivp`` style).
Only what was asked for is computed: the requested components (strain components are
combined in Fourier space, not derived from all six), depths and points; 1-D when a
periodic 2-D load does not vary in y; float32 when ``tol >= 1e-4``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from tactilab.core import rules as check
from .fields import SHEAR_CONVENTION, compliance_matrix, invariants, label, output_weights
from .loads import SurfaceLoad
from .methods import AccuracyWarning, Problem, select_method  # noqa: F401  (AccuracyWarning: re-export)
from .spectral import pressure_from_deflection
from .surface_compliance import pixel_influence, surface_compliance
from .continuous import ContinuousLoad
from .sampled import Solution, continuous_field

FLOAT32_TOL = 1e-4


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


def _check_points(points, load: SurfaceLoad) -> np.ndarray | None:
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


def _load_error(load: SurfaceLoad, values: np.ndarray, stress_scale: float) -> float:
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


class HalfSpace:
    """An isotropic linear elastic half-space z > 0 (the skin).

    Parameters
    ----------
    E : float
        Young's modulus in Pa (> 0).
    nu : float
        Poisson's ratio in (-1, 0.5]; 0.5 (incompressible) is exact.
    """

    def __init__(self, E: float, nu: float = 0.5):
        self.E = check.young_modulus(E, "E")
        self.nu = check.poisson_ratio(nu)

    def __repr__(self) -> str:
        return f"HalfSpace(E={self.E!r}, nu={self.nu!r})"

    @classmethod
    def from_material(cls, material) -> "HalfSpace":
        """Build from a record with ``young_modulus_pa`` and ``poisson_ratio`` (data_schemas)."""
        return cls(E=material.young_modulus_pa, nu=material.poisson_ratio)

    # -- public entry points -------------------------------------------------------------
    def stress(self, load: SurfaceLoad, depth, points=None, components=None, method="auto",
               tol: float = 1e-6) -> FieldResult:
        """Stress (Pa, tension positive) at depth.

        Parameters
        ----------
        load : SurfaceLoad or ContinuousLoad
            Tractions on the surface (Pa); ``load.periodic`` says whether the grid repeats. A
            ``SurfaceLoad`` is nodal values: the error estimate is for those values as given
            (``attrs["error_covers"] == "method"``). A ``ContinuousLoad`` (``HertzContact.load``,
            ``TractionField``, ``DeflectionLoad``) is sampled on its grid, and the estimate covers
            that sampling too (``"method+sampling"``); with ``method="auto"`` the grid is refined
            until the estimate meets ``tol``, or an ``AccuracyWarning`` names the spacing that would.
        depth : float or sequence of float
            Depths z > 0 in m.
        points : ndarray, shape (n, 2), optional
            Sensor positions (x, y) in m; (n,) of x for a 1-D load. Default: the load grid.
        components : sequence of str, optional
            Voigt names from ("xx", "yy", "zz", "yz", "zx", "xy"); default all six.
        method : {"auto", "closed_form", "spectral", "dcfft"} or Method subclass
        tol : float
            Requested max error relative to the largest magnitude of the requested field.

        Returns
        -------
        FieldResult
            ``error_estimate`` is relative to the largest magnitude of the requested field;
            ``data.attrs["error_covers"]`` says what it covers.
        """
        return self._field(load, depth, points, components, method, tol, "stress", False)

    def strain(self, load: SurfaceLoad, depth, points=None, components=None, method="auto",
               tol: float = 1e-6, invariants: bool = False) -> FieldResult:
        """Strain (dimensionless, TENSOR shear eps_ij) at depth; same arguments as :meth:`stress`.

        With ``invariants=True`` (all six components) the Dataset also holds the stress, the
        volumetric and deviatoric parts, the von Mises equivalent strain, the strain energy
        density, the principal strains and the maximum shear.
        """
        return self._field(load, depth, points, components, method, tol, "strain", invariants)

    def pressure_from_deflection(self, deflection: np.ndarray, spacing) -> SurfaceLoad:
        """Pressure (Pa) imposing a normal deflection (m) on a frictionless periodic surface;
        the load is marked periodic (see :func:`pressure_from_deflection`)."""
        return pressure_from_deflection(deflection, spacing, self.E, self.nu)

    def surface_compliance(self, kx, ky=None) -> np.ndarray:
        """Surface tractions to surface displacements per wavenumber (the contact solver's skin protocol).

        Parameters
        ----------
        kx : array_like
            Angular wavenumbers along x, rad/m.
        ky : array_like, optional
            Angular wavenumbers along y, rad/m (broadcast with ``kx``); ``None`` for plane strain.

        Returns
        -------
        ndarray, complex, shape ``(..., 3, 3)`` or ``(..., 2, 2)`` in plane strain, m/Pa per unit
            Fourier amplitude: rows ``(uz, ux, uy)`` (``uz`` positive into the skin), columns
            ``(p, qx, qy)``; ``2 / (E* |k|)`` on the normal diagonal, cross terms proportional to
            ``1 - 2 nu``; 0 at ``k = 0`` (a rigid shift). See
            :mod:`tactilab.forward.halfspace.surface_compliance`.
        """
        return surface_compliance(kx, ky, self.E, self.nu)

    def surface_influence(self, x, y, spacing, reference_length: float | None = None,
                          entry: tuple[int, int] | None = None) -> np.ndarray:
        """Surface displacement (m/Pa) at offsets ``(x, y)`` (m) from one pixel of unit uniform traction.

        The exact integral of Boussinesq's and Cerruti's surface displacements over the pixel
        (Love's closed form for the normal entry); ``y=None`` gives the plane-strain strip, whose
        displacement is zero at ``reference_length`` (m). Rows and columns as in
        :meth:`surface_compliance`; ``entry=(row, column)`` computes that entry alone. Isolated
        contacts use it (exact aperiodic convolution).
        """
        return pixel_influence(x, y, spacing, self.E, self.nu, reference_length, entry)

    def operator(self, shape, spacing, sensors=None, depth: float = 1e-3, components=("zz",),
                 loads=("p",), quantity: str = "stress", periodic: bool = False):
        """The linear load-to-sensor map as a ``scipy.sparse.linalg.LinearOperator``.

        See :class:`tactilab.forward.halfspace.operator.LoadToSensor` for the arguments.
        """
        from .operator import LoadToSensor

        return LoadToSensor(self, shape, spacing, sensors=sensors, depth=depth, components=components,
                            loads=loads, quantity=quantity, periodic=periodic)

    # -- machinery -------------------------------------------------------------------------
    def _field(self, load, depth, points, components, method, tol, quantity, want_invariants) -> FieldResult:
        continuous = isinstance(load, ContinuousLoad)
        if not (continuous or isinstance(load, SurfaceLoad)):
            raise ValueError(f"load: expected a SurfaceLoad or a ContinuousLoad (HertzContact.load(...), "
                             f"TractionField, DeflectionLoad), got {type(load).__name__}; build one with "
                             "SurfaceLoad(p=..., spacing=...)")
        if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not math.isfinite(tol) or tol <= 0:
            raise ValueError(f"tol: must be a finite relative tolerance > 0, got {tol!r} (e.g. 1e-6)")
        depths = check.depths(depth)
        comps = check.components(components)
        if want_invariants and comps != check.COMPONENTS:
            raise ValueError("invariants: need all six components; call with components=None")
        if continuous:
            return continuous_field(self, load, depths, points, comps, method, tol, quantity, want_invariants)
        pts = _check_points(points, load)
        sol = self._solve(load, depths, comps, pts, method, tol, quantity, want_invariants)
        return self._package(load, sol, depths, comps, pts, want_invariants, error_covers="method+load" if load.error_estimate else "method")

    def _solve(self, load, depths, comps, pts, method, tol, quantity, want_invariants) -> Solution:
        """Choose a method and compute on a nodal load; values have the load's grid (or points)."""
        reduced = load.periodic and load.ndim == 2 and not load.varies_in_y()
        work_load = load.row() if reduced else load
        work_pts = pts[:, :1] if (reduced and pts is not None) else pts
        dtype = np.dtype(np.float32 if tol >= FLOAT32_TOL else np.float64)
        weight_quantity = "stress" if want_invariants else quantity
        weights = output_weights(weight_quantity, comps, self.E, self.nu)
        problem = Problem(work_load, depths, self.nu, weights, work_pts, dtype)
        chosen, reason, candidates = select_method(problem, tol, method)
        if chosen.name == "closed_form" and dtype == np.float32:
            problem = Problem(work_load, depths, self.nu, weights, work_pts, np.dtype(np.float64))
        values = chosen.compute(problem)
        stress_scale = self.E if weight_quantity == "strain" else 1.0
        err = chosen.field_error(problem, values, stress_scale) + _load_error(load, values, stress_scale)
        if reduced and pts is None:  # broadcast the plane-strain row over y
            values = np.broadcast_to(values[..., None, :], values.shape[:-1] + load.shape).copy()
        return Solution(values, chosen, reason, candidates, float(err), weight_quantity, reduced, str(problem.dtype))

    def _package(self, load, sol: Solution, depths, comps, pts, want_invariants, error_covers: str,
                 sampling_estimate: float | None = None, extra: dict | None = None) -> FieldResult:
        """The result; its xarray Dataset is built on the first access of ``FieldResult.data``."""
        err = sol.err if sampling_estimate is None else sol.err + sampling_estimate
        attrs = dict(method=sol.chosen.name, error_estimate=err, error_covers=error_covers,
                     method_error_estimate=sol.err, reason=sol.reason, E_pa=self.E, nu=self.nu,
                     reduced_to_1d=int(sol.reduced), dtype=sol.dtype, shear_convention=SHEAR_CONVENTION)
        if sampling_estimate is not None:
            attrs["sampling_error_estimate"] = sampling_estimate
        attrs.update(extra or {})
        x, y, E, nu = load.x, load.y, self.E, self.nu
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

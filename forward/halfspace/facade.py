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

import math

import numpy as np

from tactilab.core import rules as check
from tactilab.data_schemas.plausibility import check_plausible_at_entry

from .continuous import ContinuousLoad
from .loads import SurfaceLoad
from .methods import AccuracyWarning, user_stacklevel  # noqa: F401  (AccuracyWarning: re-exported, the solver's door names it here)
from .sampled import continuous_field
from .solve import FLOAT32_TOL, FieldResult, check_points, package, solve  # noqa: F401  (re-exports)
from .spectral import pressure_from_deflection
from .surface_compliance import pixel_influence, surface_compliance


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
        """Build from a record with ``young_modulus_pa`` and ``poisson_ratio`` (data_schemas).

        A ``SkinMaterial`` with layers is refused and a viscoelastic one warns that it enters with its
        relaxed modulus (``SkinMaterial.half_space_constants``); ``tactilab.forward.skin_from_material``
        builds the skin model such a material describes."""
        constants = getattr(material, "half_space_constants", None)
        if callable(constants):
            E, nu = constants("HalfSpace.from_material (use tactilab.forward.skin_from_material for its skin model)")
            return cls(E=E, nu=nu)
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
            Voigt names from ``COMPONENTS`` (xx, yy, zz, yz, zx, xy; aliases xz, zy, yx); default all six.
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
        spacing = check.spacing(spacing, 1 if y is None else 2)
        if y is None:
            reference_length = check.positive(reference_length, "reference_length", "m",
                                              "give the distance at which a line load's displacement is zero")
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
        for z in depths:  # the rule the options and the files follow: 1.25 meant as mm warns
            check_plausible_at_entry(float(z), "depth", "m", stacklevel=user_stacklevel())
        comps = check.components(components)
        if want_invariants and comps != check.COMPONENTS:
            raise ValueError("invariants: need all six components; call with components=None")
        if continuous:
            return continuous_field(self.E, self.nu, load, depths, points, comps, method, tol, quantity,
                                    want_invariants)
        pts = check_points(points, load)
        sol = solve(self.E, self.nu, load, depths, comps, pts, method, tol, quantity, want_invariants)
        return package(self.E, self.nu, load, sol, depths, comps, pts, want_invariants, error_covers="method+load" if load.error_estimate else "method")

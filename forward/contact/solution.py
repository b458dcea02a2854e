"""The result of a contact solve: tractions, zones, totals and the error promise.

Conventions (docs/theory.md section 1): tractions act on the skin, in Pa; ``pressure`` pushes
into the skin, ``qx`` and ``qy`` act along +x and +y. Arrays have the gap's shape, ``(nx,)``
(plane strain) or ``(ny, nx)``, with node ``j`` at ``x_j = (j - nx // 2) dx`` as in
:class:`~tactilab.forward.halfspace.SurfaceLoad`.
"""

from __future__ import annotations

import pathlib
from dataclasses import dataclass, field

import numpy as np

from ..halfspace import SurfaceLoad


@dataclass(frozen=True)
class ContactSolution:
    """A solved contact between the skin and a rigid surface.

    Attributes
    ----------
    pressure : ndarray, shape (nx,) or (ny, nx)
        Normal traction on the skin, Pa (>= 0, pushes into the skin).
    qx, qy : ndarray or None
        Tangential tractions on the skin along +x, +y, Pa; ``qy`` is None in plane strain.
    contact, stick, slip : ndarray of bool
        Nodes in contact; of those, the ones that stick and the ones that slip (frictionless
        and sliding contacts slip everywhere in contact; a stuck one sticks everywhere).
    gap : ndarray
        The final gap between skin and surface, m (>= 0; 0 in contact).
    spacing : tuple of float
        ``(dx,)`` or ``(dx, dy)`` in m.
    periodic : bool
        Whether the grid is one period of a repeating contact.
    area : float
        Contact area, m^2 (m per unit length in plane strain): contact nodes times cell area.
    contact_fraction : float
        Contact nodes over all nodes.
    normal_force : float
        Total normal force on the skin, N (N/m in plane strain).
    approach : float
        Rigid approach delta in m (``g = g0 + uz - delta``); for a periodic contact it is relative
        to the zero-mean displacement (the half-space's mean displacement is unbounded).
    iterations : int
        Iterations on the full grid: the normal solver's, plus the tangential solver's for
        ``"partial"`` and ``"stuck"``, summed over the coupling rounds at nu < 1/2 (the check solve
        on the grid of twice the spacing is not counted).
    converged : bool
        Whether the solver met ``tol``.
    error_estimate : float
        A bound on max |pressure error| / peak pressure: ``error_parts["solver"] +
        error_parts["discretisation"]``.
    error_parts : dict
        ``"solver"``: the residual's bound; ``"discretisation"``: from the solve on the grid
        of twice the spacing (Richardson with order 1/2, the edge's square root).
    coupling : dict
        Relative change of ``"force"`` and ``"area"`` that the normal-tangential coupling made
        against the uncoupled solve (0 at nu = 1/2 and without friction).
    method, condition : str
        The solver that ran and the friction condition.
    friction : float
        The Coulomb coefficient mu.
    """

    pressure: np.ndarray
    qx: np.ndarray
    qy: np.ndarray | None
    contact: np.ndarray
    stick: np.ndarray
    slip: np.ndarray
    gap: np.ndarray
    spacing: tuple
    periodic: bool
    normal_force: float
    approach: float
    iterations: int
    converged: bool
    error_estimate: float
    error_parts: dict = field(default_factory=dict)
    coupling: dict = field(default_factory=dict)
    method: str = "preconditioned_cg"
    condition: str = "frictionless"
    friction: float = 0.0

    def __post_init__(self) -> None:
        for name in ("pressure", "qx", "qy", "contact", "stick", "slip", "gap"):
            value = getattr(self, name)
            if value is not None:
                value.setflags(write=False)

    @property
    def shape(self) -> tuple[int, ...]:
        """Grid shape: ``(nx,)`` or ``(ny, nx)``."""
        return self.pressure.shape

    @property
    def cell_area(self) -> float:
        """m^2 per node (m in plane strain)."""
        return float(np.prod(self.spacing))

    @property
    def area(self) -> float:
        """Contact area in m^2 (m per unit length in plane strain)."""
        return float(np.count_nonzero(self.contact)) * self.cell_area

    @property
    def contact_fraction(self) -> float:
        """Contact nodes over all nodes."""
        return float(np.count_nonzero(self.contact)) / self.contact.size

    @property
    def x(self) -> np.ndarray:
        """Node x coordinates, m."""
        nx = self.shape[-1]
        return (np.arange(nx) - nx // 2) * self.spacing[0]

    @property
    def y(self) -> np.ndarray | None:
        """Node y coordinates, m (None in plane strain)."""
        if len(self.shape) == 1:
            return None
        ny = self.shape[0]
        return (np.arange(ny) - ny // 2) * self.spacing[1]

    def load(self) -> SurfaceLoad:
        """The tractions as a :class:`SurfaceLoad` (same spacing and periodic flag).

        It carries ``error_estimate``, so a field computed from it reports an error that covers
        the contact's error too (``FieldResult.data.attrs["error_covers"] == "method+load"``).
        """
        return SurfaceLoad(p=self.pressure, qx=self.qx, qy=self.qy, spacing=self.spacing, periodic=self.periodic,
                           error_estimate=self.error_estimate)

    def __repr__(self) -> str:
        unit = "m" if len(self.shape) == 1 else "m^2"
        force = "N/m" if len(self.shape) == 1 else "N"
        return (f"ContactSolution(shape={self.shape}, {self.condition}, force {self.normal_force:.4g} {force}, "
                f"area {self.area:.4g} {unit} ({100 * self.contact_fraction:.3g} %), peak pressure "
                f"{float(self.pressure.max()):.4g} Pa, {self.iterations} iterations, "
                f"est. rel. error {self.error_estimate:.1e})")

    def to_dataset(self):
        """An ``xarray.Dataset`` with CF-style attributes (units, long_name); masks as 0/1 bytes."""
        import xarray as xr

        dims = ("x",) if len(self.shape) == 1 else ("y", "x")
        coords = {"x": ("x", self.x, {"units": "m", "long_name": "position along the scanning direction"})}
        if len(dims) == 2:
            coords["y"] = ("y", self.y, {"units": "m", "long_name": "position across the scanning direction"})
        data = {
            "pressure": (self.pressure, "Pa", "normal traction on the skin (positive into the skin)"),
            "qx": (self.qx, "Pa", "tangential traction on the skin along +x"),
            "qy": (self.qy, "Pa", "tangential traction on the skin along +y"),
            "gap": (self.gap, "m", "gap between the deformed skin and the rigid surface"),
            "contact": (self.contact, "1", "node in contact (1) or not (0)"),
            "stick": (self.stick, "1", "node in contact that sticks (1)"),
            "slip": (self.slip, "1", "node in contact that slips (1)"),
        }
        variables = {}
        for name, (value, units, long_name) in data.items():
            if value is None:
                continue
            arr = value.astype(np.uint8) if value.dtype == bool else value
            variables[name] = (dims, arr, {"units": units, "long_name": long_name})
        attrs = dict(normal_force=self.normal_force, normal_force_units="N/m" if len(dims) == 1 else "N",
                     approach_m=self.approach, area=self.area, area_units="m" if len(dims) == 1 else "m2",
                     contact_fraction=self.contact_fraction, iterations=self.iterations,
                     converged=int(self.converged), error_estimate=self.error_estimate,
                     method=self.method, condition=self.condition, friction=self.friction,
                     periodic=int(self.periodic), spacing_m=list(self.spacing),
                     conventions="tractions on the skin; pressure pushes into the skin; docs/theory.md section 1")
        attrs.update({f"error_{k}": v for k, v in self.error_parts.items()})
        attrs.update({f"coupling_{k}": v for k, v in self.coupling.items()})
        return xr.Dataset(variables, coords=coords, attrs=attrs)

    def plot(self, path) -> pathlib.Path:
        """Save a PNG of the pressure (kPa) and the stick/slip zones, axes in mm; returns the path."""
        from .plots import plot_solution

        return plot_solution(self, pathlib.Path(path))

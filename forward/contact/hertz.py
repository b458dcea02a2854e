"""Fingertip contact: Hertz interfacial pressure and the tangential traction of friction.

Conventions (docs/theory.md section 1): tractions are applied TO the skin, in Pa; ``p`` pushes
into the skin, ``qx`` acts along +x (the scanning direction). Coordinates are in the
finger's frame, in m, with the centre of contact at the origin.

Normal contact (Hertz, a rigid flat or large-radius surface against an elastic finger
of radius ``R``, modulus ``E`` and Poisson ratio ``nu``; ``E* = E / (1 - nu^2)``):

- 3-D (sphere, force ``F`` in N): ``a = (3 F R / (4 E*))^(1/3)``, ``p0 = 3 F / (2 pi a^2)``,
  ``p(r) = p0 sqrt(1 - r^2/a^2)``.
- 2-D (cylinder, line contact, force per unit length ``F`` in N/m):
  ``a = sqrt(4 F R / (pi E*))``, ``p0 = 2 F / (pi a)``, ``p(x) = p0 sqrt(1 - x^2/a^2)``.

Tangential traction, from frictionless to fully adhesive (``friction`` = mu, tangential
force ``Q`` along +x; one continuum, Cattaneo--Mindlin):

- ``"frictionless"``: ``qx = 0``.
- ``"sliding"`` (gross slip, local Amontons law): ``qx = mu p`` (``Q = mu F``).
- ``"partial"`` (``0 <= Q <= mu F``): a central stick zone of radius ``c`` with
  ``c/a = (1 - Q/(mu F))^(1/3)`` in 3-D and ``(1 - Q/(mu F))^(1/2)`` in 2-D;
  ``qx = mu p0 [sqrt(1 - r^2/a^2) - (c/a) sqrt(1 - r^2/c^2)]`` (second term only inside c).
  ``Q = 0`` gives no traction, ``Q = mu F`` gives sliding.
- ``"stuck"`` (fully adhesive, mu -> infinity at fixed Q, Mindlin's no-slip solution):
  ``qx = Q / (2 pi a sqrt(a^2 - r^2))`` in 3-D and ``Q / (pi sqrt(a^2 - x^2))`` in 2-D; the
  edge singularity is integrable, and grids sample it by its exact cell average (1-D) or a
  sub-cell quadrature (2-D) so that the total force stays Q.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tactilab.core import rules as check
from tactilab.core.rules import positive
from tactilab.data_schemas.plausibility import check_plausible_at_entry

from ..halfspace import ContinuousLoad, SurfaceLoad

CONDITIONS = ("frictionless", "sliding", "partial", "stuck")


@dataclass(frozen=True)
class HertzContact:
    """Hertz contact of an elastic fingertip pressed on a rigid flat surface.

    Parameters
    ----------
    normal_force : float
        Normal force in N (3-D) or force per unit length in N/m (``line=True``). > 0.
    finger_radius : float
        Radius of curvature of the fingertip, m.
    young_modulus : float
        Skin (elastomer) Young's modulus ``E``, Pa.
    poisson_ratio : float
        ``nu`` in (-1, 0.5]; 0.5 (incompressible) is exact.
    line : bool
        True for the 2-D line (cylinder) contact of a plane-strain model.

    Raises
    ------
    ValueError
        For a force, radius or modulus that is not finite and positive, or ``nu`` outside (-1, 0.5].
    """

    normal_force: float
    finger_radius: float = 0.1
    young_modulus: float = 2e6
    poisson_ratio: float = 0.5
    line: bool = False

    def __post_init__(self) -> None:
        unit = "N/m" if self.line else "N"
        positive(self.normal_force, "normal_force", unit,
                  "a finger pressing on a surface has a positive normal force (a pull is not a Hertz contact)")
        positive(self.finger_radius, "finger_radius", "m", "give the fingertip radius of curvature in metres")
        check_plausible_at_entry(self.finger_radius, "finger_radius", "m", stacklevel=3)  # 10 meant as mm warns
        check.young_modulus(self.young_modulus)
        check.poisson_ratio(self.poisson_ratio, "poisson_ratio")

    @property
    def effective_modulus(self) -> float:
        """Plane-strain modulus ``E* = E / (1 - nu^2)`` in Pa."""
        return self.young_modulus / (1.0 - self.poisson_ratio ** 2)

    @property
    def contact_radius(self) -> float:
        """Hertz contact radius ``a`` (half-width for a line contact) in m."""
        F, R, Es = self.normal_force, self.finger_radius, self.effective_modulus
        if self.line:
            return math.sqrt(4.0 * F * R / (math.pi * Es))
        return (3.0 * F * R / (4.0 * Es)) ** (1.0 / 3.0)

    @property
    def peak_pressure(self) -> float:
        """Pressure at the centre of contact ``p0`` in Pa."""
        a = self.contact_radius
        if self.line:
            return 2.0 * self.normal_force / (math.pi * a)
        return 3.0 * self.normal_force / (2.0 * math.pi * a * a)

    def pressure(self, x, y=None) -> np.ndarray:
        """Hertz pressure ``p`` in Pa at points ``x`` (and ``y`` for 3-D), in m; 0 outside contact."""
        rho2 = self._rho2(x, y)
        return self.peak_pressure * np.sqrt(np.clip(1.0 - rho2 / self.contact_radius ** 2, 0.0, None))

    def load(self, *, friction: float = 0.0, condition: str = "sliding", tangential_force: float | None = None,
             spacing: float | None = None, half_width: float | None = None) -> "ContactLoad":
        """This contact's tractions as a continuous load for :meth:`HalfSpace.stress` / ``strain``.

        Parameters
        ----------
        friction, condition, tangential_force
            As :func:`interfacial_traction`.
        spacing : float, optional
            Default grid spacing in m (a / 16); with ``method="auto"`` the solver refines it
            until its error estimate, which covers the sampling, meets ``tol``.
        half_width : float, optional
            Half-width of the grid in m (2 a).
        """
        return ContactLoad(self, friction=friction, condition=condition, tangential_force=tangential_force,
                           spacing=spacing, half_width=half_width)

    def _rho2(self, x, y) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if not np.all(np.isfinite(x)) or (y is not None and not np.all(np.isfinite(np.asarray(y, float)))):
            raise ValueError("x, y: contact points must be finite (no NaN or inf), in m")
        if self.line:
            if y is not None:
                raise ValueError("y: a line contact (line=True) is independent of y; call pressure(x) only")
            return x * x
        if y is None:
            raise ValueError("y: a 3-D contact needs both x and y (m); pass y, or use line=True")
        y = np.asarray(y, dtype=float)
        return x * x + y * y


def stick_radius(contact: HertzContact, friction: float, tangential_force: float) -> float:
    """Cattaneo--Mindlin stick-zone radius ``c`` in m for ``0 <= |Q| <= mu F``.

    Parameters
    ----------
    contact : HertzContact
        The Hertz contact (normal force F in N, or N/m for a line contact).
    friction : float
        Friction coefficient mu >= 0 (dimensionless; inf: fully stuck, c = a).
    tangential_force : float
        Total tangential force Q in N (N/m for a line contact), finite, |Q| <= mu F.

    Returns
    -------
    float
        ``a (1 - |Q| / (mu F))^(1/3)`` (3-D) or ``^(1/2)`` (line contact), m.
    """
    mu, Q = _check_friction(friction), float(tangential_force)
    if not math.isfinite(Q):  # NaN compared False with the friction limit and gave a radius
        raise ValueError(f"tangential_force: must be finite (N, or N/m for a line contact), got {tangential_force!r}")
    if mu == 0.0:
        return 0.0 if Q == 0.0 else _too_much(Q, mu, contact)
    if math.isinf(mu):
        return contact.contact_radius
    limit = mu * contact.normal_force
    # mu F underflows to 0 for a subnormal mu: divide in two steps then (no ZeroDivisionError)
    ratio = abs(Q) / limit if limit > 0 else abs(Q) / mu / contact.normal_force
    if ratio > 1.0 + 1e-12:
        _too_much(Q, mu, contact)
    power = 0.5 if contact.line else 1.0 / 3.0
    return contact.contact_radius * max(0.0, 1.0 - ratio) ** power


def _check_friction(friction: float) -> float:
    mu = float(friction)
    if math.isnan(mu) or mu < 0:
        raise ValueError(f"friction: the friction coefficient must be >= 0 (or inf for a stuck contact), "
                         f"got {friction!r}; use 0 for a frictionless contact")
    return mu


def _too_much(Q: float, mu: float, contact: HertzContact) -> float:
    raise ValueError(
        f"tangential_force: |Q| = {abs(Q):g} exceeds the friction limit mu F = {mu * contact.normal_force:g} "
        f"(mu = {mu:g}); the contact would slide: use condition='sliding', or lower Q / raise friction"
    )


def interfacial_traction(contact: HertzContact, x, y=None, *, friction: float = 0.0,
                         condition: str = "sliding", tangential_force: float | None = None,
                         cell: tuple[float, ...] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Normal pressure and tangential traction on the skin at grid points.

    Parameters
    ----------
    contact : HertzContact
        The normal contact.
    x, y : array_like
        Points in the finger frame, m (``y`` only for a 3-D contact); broadcast together.
    friction : float
        Coefficient of friction mu >= 0 (``inf`` allowed for ``"stuck"``).
    condition : {"frictionless", "sliding", "partial", "stuck"}
        Contact condition; see the module docstring.
    tangential_force : float, optional
        Total tangential force ``Q`` along +x, N (N/m for a line contact); needed for
        ``"partial"`` and ``"stuck"``. Negative values reverse the traction.
    cell : tuple of float, optional
        Grid spacing ``(dx,)`` or ``(dx, dy)`` in m. When given, the singular stuck traction
        is cell-averaged so that its sum times the cell area equals ``Q``.

    Returns
    -------
    p, qx : ndarray
        Pressure and tangential traction along +x, Pa, shape of the broadcast points.
    """
    if condition not in CONDITIONS:
        raise ValueError(f"condition: must be one of {CONDITIONS}, got {condition!r}")
    mu = _check_friction(friction)
    p = contact.pressure(x, y)
    if condition == "frictionless":
        return p, np.zeros_like(p)
    if condition == "sliding":
        if math.isinf(mu):
            raise ValueError("friction: a sliding contact needs a finite friction coefficient, got inf; "
                             "use condition='stuck' for an adhesive contact")
        return p, mu * p
    if tangential_force is None:
        raise ValueError(f"tangential_force: condition={condition!r} needs the total tangential force Q "
                         f"(N, or N/m for a line contact); pass tangential_force=...")
    Q = float(tangential_force)
    if not math.isfinite(Q):
        raise ValueError(f"tangential_force: must be finite, got {tangential_force!r}")
    a = contact.contact_radius
    rho2 = contact._rho2(x, y)
    if condition == "stuck":
        return p, Q * stuck_shape(contact, x, y, rho2, cell)
    if math.isinf(mu):
        raise ValueError("friction: condition='partial' needs a finite friction coefficient, got inf; "
                         "use condition='stuck' for mu -> infinity")
    c = stick_radius(contact, mu, Q)
    p0 = contact.peak_pressure
    q = mu * p
    if c > 0:
        q = q - mu * p0 * (c / a) * np.sqrt(np.clip(1.0 - rho2 / (c * c), 0.0, None))
    return p, math.copysign(1.0, Q) * q


def stuck_shape(contact: HertzContact, x, y, rho2, cell) -> np.ndarray:
    """Mindlin no-slip traction per unit Q (1/m^2 or 1/m), cell-averaged when ``cell`` is given."""
    a = contact.contact_radius
    if cell is None:
        with np.errstate(divide="ignore", invalid="ignore"):
            if contact.line:
                shape = 1.0 / (math.pi * np.sqrt(a * a - rho2))
            else:
                shape = 1.0 / (2.0 * math.pi * a * np.sqrt(a * a - rho2))
        return np.where(rho2 < a * a, shape, 0.0)
    if contact.line:
        dx = float(cell[0])
        x = np.asarray(x, dtype=float)
        lo = np.clip((x - dx / 2) / a, -1.0, 1.0)
        hi = np.clip((x + dx / 2) / a, -1.0, 1.0)
        # exact cell average of 1 / (pi sqrt(a^2 - x^2)): the arcsine difference
        return (np.arcsin(hi) - np.arcsin(lo)) / (math.pi * dx)
    dx, dy = float(cell[0]), float(cell[1])
    x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
    # the radial integral of r / sqrt(a^2 - r^2) is exact; integrate the cell in polar strips
    # with a sub-cell midpoint rule on the smooth potential a - sqrt(a^2 - r^2)
    n = 8
    offs = (np.arange(n) + 0.5) / n - 0.5
    total = np.zeros(x.shape)
    for oy in offs:
        for ox in offs:
            r2 = (x + ox * dx) ** 2 + (y + oy * dy) ** 2
            total += np.where(r2 < a * a, 1.0 / np.sqrt(np.clip(a * a - r2, 1e-300, None)), 0.0)
    avg = total / (n * n)
    # renormalise so that the sampled field carries exactly Q: the sub-cell rule misses part
    # of the integrable edge singularity, a deficit that shrinks with the cell size
    weight = avg.sum() * dx * dy * (1.0 / (2.0 * math.pi * a))
    if weight <= 0:
        raise ValueError(f"cell: the grid (dx={dx:g} m, dy={dy:g} m) does not resolve the contact "
                         f"radius a={a:g} m; use a finer grid or a larger domain")
    return avg / (2.0 * math.pi * a) / weight


class ContactLoad(ContinuousLoad):
    """A contact's tractions as a continuous load (:class:`ContinuousLoad`): the solver samples it
    on its grid and its error estimate covers that sampling (``error_covers="method+sampling"``).

    Build it with :meth:`HertzContact.load`. ``sample(shape, spacing)`` returns
    :func:`interfacial_traction` at the nodes (the stuck traction cell-averaged).
    """

    def __init__(self, contact: HertzContact, *, friction: float = 0.0, condition: str = "sliding",
                 tangential_force: float | None = None, spacing: float | None = None,
                 half_width: float | None = None):
        a = contact.contact_radius
        self.contact, self.friction, self.condition = contact, friction, condition
        self.tangential_force = tangential_force
        h = a / 16 if spacing is None else positive(spacing, "spacing", "m", "give the grid spacing in m")
        w = 2 * a if half_width is None else positive(half_width, "half_width", "m",
                                                      "give the half-width of the loaded grid in m")
        n = 2 * math.ceil(w / h) + 1
        self.shape = (n,) if contact.line else (n, n)
        self.spacing = (h,) if contact.line else (h, h)
        self.sample(tuple(min(s, 5) for s in self.shape), self.spacing)  # validate the condition now

    def __repr__(self) -> str:
        return (f"ContactLoad(a={self.contact.contact_radius:.3g} m, condition={self.condition!r}, "
                f"friction={self.friction!r}; shape={self.shape}, spacing={self.spacing[0]:.3g} m)")

    def sample(self, shape, spacing) -> SurfaceLoad:
        template = SurfaceLoad(p=np.zeros(tuple(shape)), spacing=spacing)
        if template.ndim != len(self.shape):
            raise ValueError(f"shape: this contact needs a {len(self.shape)}-D grid, got shape {tuple(shape)}")
        if self.contact.line:
            p, qx = interfacial_traction(self.contact, template.x, friction=self.friction, condition=self.condition,
                                         tangential_force=self.tangential_force, cell=template.spacing)
        else:
            xx, yy = np.meshgrid(template.x, template.y)
            p, qx = interfacial_traction(self.contact, xx, yy, friction=self.friction, condition=self.condition,
                                         tangential_force=self.tangential_force, cell=template.spacing)
        return SurfaceLoad(p=p, qx=qx, spacing=template.spacing)

"""Biomimetic finger (docs/theory.md 4b): a Hertz contact, friction, fingerprints, sensors at depth.

Frames. Sensor positions and the contact live in the FINGER frame (origin at the centre of
contact, m). The surface lives in the WORLD frame; when the contact centre is at world
``(u, 0)``, a surface point at world ``(x_w, y_w)`` touches the skin at finger ``(x_w - u, y_w)``.

Transduction is linear (docs/theory.md 4b): a sensor at ``(x_i, y_i, Z)`` reads
``sigma(x_i, y_i) = iint qx(x, y) G_x(x_i - x, y_i - y) + p(x, y) G_z(x_i - x, y_i - y) dx dy``
with ``G`` the Cerruti (tangential) and Boussinesq (normal) point-load stress at depth Z
(:func:`tactilab.forward.halfspace.kernels.point_green`, Pa per N). Strain sensors apply Hooke's law
(tensor shear eps_ij; engineering gamma = 2 eps).

Interface. While sliding, ``qx = D mu p`` (local Amontons law; traction applied TO the skin),
with ``D = friction_direction``. The default ``D = +1`` is docs/theory.md 4b's ``p_x = mu_d p_z``
(also the convention of ``tactilab.inversion``'s defect model): the surface drags the skin
towards +x, as when the finger moves towards -x relative to the surface. A finger sliding
towards +x over a fixed surface (the direction of data_schemas scans) is dragged backwards:
``D = -1``. ``adhesion`` in [0, 1] blends this with the fully adhesive (no-slip, Mindlin)
distribution carrying the same total tangential force: ``qx = D [(1 - a) mu p + a mu F s(x, y)]``
with ``s`` the unit Mindlin traction (:mod:`.contact`); or, with ``slip_ratio``, the
Cattaneo--Mindlin partial-slip traction of tangential force ``D slip_ratio mu F``. A fingerprint (square-wave ridges of
period lambda, contrast c) multiplies both by ``1 + c T(x)``, T = +-1 (force preserved on average).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tactilab.data_schemas.sensors import SensorArray

from .contact import HertzContact, stuck_shape, interfacial_traction
from .halfspace import output_weights
from .halfspace import COMPONENTS, point_green


MAX_GRID_NODES_PER_AXIS = 2049  # 4.2e6 contact nodes; finer grids exhaust memory in the scan maps
MAX_WORK_VALUES = 2**28  # 2 GiB of float64 work arrays for the scan operator


@dataclass(frozen=True)
class Fingerprint:
    """Fingerprint ridges along y with period ``period`` (m) and contrast in [0, 1]; the ridge
    pattern ``1 + contrast * T(x)`` (T = +1 on ridges, -1 in grooves) multiplies the interfacial
    stress; ``offset`` (m) shifts the first ridge."""

    period: float = 0.5e-3
    contrast: float = 1.0
    offset: float = 0.0

    def __post_init__(self):
        if not math.isfinite(self.period) or self.period <= 0:
            raise ValueError(f"fingerprint period: must be finite and > 0 m, got {self.period!r}; "
                             "human ridges are about 0.5e-3 m apart")
        if not 0.0 <= self.contrast <= 1.0:
            raise ValueError(f"fingerprint contrast: must lie in [0, 1] (1 = grooves carry no load), "
                             f"got {self.contrast!r}")

    def factor(self, x) -> np.ndarray:
        """Dimensionless stress factor ``1 + c T(x)`` at finger-frame x (m)."""
        phase = np.mod(np.asarray(x, dtype=float) - self.offset, self.period) / self.period
        return 1.0 + self.contrast * np.where(phase < 0.5, 1.0, -1.0)


@dataclass(frozen=True)
class BiomimeticFinger:
    """A fingertip contact sensed by an array of sensors at depth.

    Parameters
    ----------
    contact : HertzContact
        3-D Hertz contact (force in N, radius in m, E in Pa, nu).
    sensors : SensorArray
        Sensor positions (finger frame, m), depth (m), quantity and components (data_schemas).
    friction : float
        Sliding friction coefficient mu_d >= 0.
    adhesion : float
        0 = sliding (qx = D mu p), 1 = fully adhesive (Mindlin no-slip), in between a blend with
        the same total tangential force mu F.
    fingerprint : Fingerprint or None
        Ridges on the skin, or None for smooth skin.
    grid_spacing : float or None
        Node spacing (m) of the contact grid; default ``min(a / 25, Z / 5, lambda / 10)``.
    slip_ratio : float or None
        If given, use the Cattaneo--Mindlin partial-slip traction instead of the adhesion blend:
        tangential force ``Q = slip_ratio mu F`` with slip_ratio in [0, 1] (0: no tangential
        load, 1: gross sliding); needs ``adhesion = 0``.
    """

    contact: HertzContact
    sensors: SensorArray
    friction: float = 0.0
    adhesion: float = 0.0
    fingerprint: Fingerprint | None = None
    grid_spacing: float | None = None
    slip_ratio: float | None = None
    friction_direction: float = 1.0

    def __post_init__(self):
        if self.friction_direction not in (1.0, -1.0):
            raise ValueError(f"friction_direction: must be +1 (docs/theory.md p_x = +mu p_z) or -1 (finger sliding "
                             f"towards +x over a fixed surface), got {self.friction_direction!r}")
        if not isinstance(self.contact, HertzContact) or self.contact.line:
            raise ValueError("contact: expected a 3-D HertzContact (line=False); the finger is a 3-D contact")
        if not isinstance(self.sensors, SensorArray):
            raise ValueError(f"sensors: expected a data_schemas SensorArray, got {type(self.sensors).__name__}; "
                             "build one with SensorArray.grid(...) or SensorArray(positions_m=..., ...)")
        mu = float(self.friction)
        if not math.isfinite(mu) or mu < 0:
            raise ValueError(f"friction: the friction coefficient must be finite and >= 0, got {self.friction!r}; "
                             "use 0 for a frictionless contact (adhesion=1 for a stuck one)")
        if not 0.0 <= float(self.adhesion) <= 1.0:
            raise ValueError(f"adhesion: must lie in [0, 1] (0 sliding, 1 fully adhesive), got {self.adhesion!r}")
        if self.slip_ratio is not None:
            if not 0.0 <= float(self.slip_ratio) <= 1.0:
                raise ValueError(f"slip_ratio: Q / (mu F) must lie in [0, 1] (1 = gross sliding), got {self.slip_ratio!r}")
            if self.adhesion != 0:
                raise ValueError(f"slip_ratio: partial slip (Cattaneo--Mindlin) replaces the adhesion blend; "
                                 f"give adhesion=0, got adhesion={self.adhesion!r}")
        if self.grid_spacing is not None and (not math.isfinite(self.grid_spacing) or self.grid_spacing <= 0):
            raise ValueError(f"grid_spacing: must be finite and > 0 m (or None for automatic), got {self.grid_spacing!r}")
        # a typo such as 1e-12mm, or sensors a few nm deep (automatic spacing = depth / 5), would
        # otherwise ask numpy for terabytes (MemoryError deep in the scan)
        a, h = self.contact.contact_radius, self.spacing
        n = 2 * (int(math.ceil(a / h)) + 1) + 1
        if n > MAX_GRID_NODES_PER_AXIS:
            coarsest = a / ((MAX_GRID_NODES_PER_AXIS - 3) // 2)
            if self.grid_spacing is not None:
                raise ValueError(
                    f"grid_spacing: {self.grid_spacing!r} m gives {n} contact-grid nodes per axis over the contact "
                    f"radius {a:.4g} m, above the limit {MAX_GRID_NODES_PER_AXIS} (memory); give a spacing of at "
                    f"least {coarsest:.3g} m, or None for automatic")
            raise ValueError(
                f"grid_spacing: the automatic spacing {h:.3g} m (contact radius / 25, sensor depth "
                f"{self.depth:.3g} m / 5, fingerprint period / 10) gives {n} contact-grid nodes per axis, above "
                f"the limit {MAX_GRID_NODES_PER_AXIS} (memory); give grid_spacing >= {coarsest:.3g} m, or place "
                "the sensors deeper")

    # ---------------------------------------------------------------- construction
    @classmethod
    def from_scene(cls, scene, grid_spacing: float | None = None) -> "BiomimeticFinger":
        """Build from a data_schemas ``Scene`` with a ``contact`` (SI fields)."""
        if scene.contact is None:
            raise ValueError("scene.contact: the scene has no finger contact; a biomimetic-finger "
                             "simulation needs [contact] with normal_force and finger_radius")
        c = scene.contact
        if c.normal_force_n is None:
            raise ValueError("scene.contact: a periodic cell (mean_pressure) has no finger; a biomimetic-finger "
                             "simulation needs normal_force and finger_radius (tactilab.forward.scene_models runs cells)")
        E, nu = scene.material.half_space_constants("the biomimetic finger's scan")
        contact = HertzContact(c.normal_force_n, c.finger_radius_m, E, nu)
        fp = Fingerprint(c.fingerprint_period_m) if c.fingerprint_period_m is not None else None
        return cls(contact, scene.sensors, c.friction_coefficient, c.adhesion, fp, grid_spacing)

    # ---------------------------------------------------------------- properties
    @property
    def depth(self) -> float:
        """Sensor depth Z in m."""
        return float(self.sensors.depth_m)

    @property
    def tangential_force(self) -> float:
        """Magnitude of the total tangential force, mu F in N (along ``friction_direction``)."""
        return self.friction * self.contact.normal_force

    @property
    def spacing(self) -> float:
        """Contact-grid node spacing in m."""
        if self.grid_spacing is not None:
            return float(self.grid_spacing)
        h = min(self.contact.contact_radius / 25, self.depth / 5)
        if self.fingerprint is not None:
            h = min(h, self.fingerprint.period / 10)
        return h

    def grid(self) -> tuple[np.ndarray, np.ndarray]:
        """Node coordinates (x, y) in m, each shape (n,), centred on 0, covering the contact."""
        h = self.spacing
        half = int(math.ceil(self.contact.contact_radius / h)) + 1
        x = np.arange(-half, half + 1) * h
        return x, x.copy()

    # ---------------------------------------------------------------- tractions
    def traction(self, x, y, cell: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Interfacial pressure ``p`` and tangential traction ``qx`` (Pa) at finger-frame points (m).

        With ``cell`` (dx, dy) the points must be a full grid covering the contact: the singular
        adhesive part is then cell-averaged so that its total is exactly ``adhesion mu F``.
        """
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        if self.slip_ratio is not None:
            p, q = interfacial_traction(self.contact, x, y, friction=self.friction, condition="partial",
                                        tangential_force=self.slip_ratio * self.tangential_force)
        else:
            p = self.contact.pressure(x, y)
            q = (1.0 - self.adhesion) * self.friction * p
            if self.adhesion > 0 and self.friction > 0:
                q = q + self.adhesion * self.tangential_force * stuck_shape(
                    self.contact, x, y, x * x + y * y, cell)
        q = self.friction_direction * q
        if self.fingerprint is not None:
            f = self.fingerprint.factor(x)
            p, q = p * f, q * f
        return p, q

    # ---------------------------------------------------------------- sensor response
    def output_labels(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(sensor ids, components) in the order of the output axes."""
        return self.sensors.ids, tuple(self.sensors.components)

    def _weights(self) -> np.ndarray:
        E, nu = self.contact.young_modulus, self.contact.poisson_ratio
        return output_weights(self.sensors.quantity, self.sensors.components, E, nu)

    def point_response(self, xs, ys, fx, fz) -> np.ndarray:
        """Sensor outputs for point forces on the skin at finger-frame (xs, ys) (m).

        Parameters
        ----------
        xs, ys, fx, fz : array_like, broadcast together, shape S
            Force positions (m) and forces on the skin (N): fx along +x, fz pushing in.

        Returns
        -------
        ndarray, shape S + (n_sensors, n_components): Pa (stress) or strain (tensor).
        """
        xs, ys, fx, fz = np.broadcast_arrays(*(np.asarray(v, float) for v in (xs, ys, fx, fz)))
        for name, v, unit in (("xs", xs, "m"), ("ys", ys, "m"), ("fx", fx, "N"), ("fz", fz, "N")):
            if not np.all(np.isfinite(v)):
                raise ValueError(f"{name}: point forces and their positions must be finite (no NaN or inf), in {unit}")
        W = self._weights()
        pos = self.sensors.positions_m
        dx = pos[:, 0] - xs[..., None]
        dy = pos[:, 1] - ys[..., None]
        out = np.zeros(xs.shape + (pos.shape[0], W.shape[0]))
        nu = self.contact.poisson_ratio
        for v, comp in enumerate(COMPONENTS):
            if not np.any(W[:, v]):
                continue
            g = fx[..., None] * point_green(comp, "x", dx, dy, self.depth, nu) \
                + fz[..., None] * point_green(comp, "z", dx, dy, self.depth, nu)
            out += g[..., None] * W[:, v]
        return out

    def receptive_field(self, positions, defect_x: float, defect_y: float = 0.0,
                        strength: float = 1e-8) -> np.ndarray:
        """Exploratory receptive field of every sensor for a small isolated defect (docs/theory.md 4b).

        The defect at world ``(defect_x, defect_y)`` adds a concentrated force ``strength`` times
        the local interfacial traction: ``(fx, fz) = S_d (qx, p)`` at finger ``(defect_x - u, defect_y)``.

        Parameters
        ----------
        positions : array_like, shape (n_u,)
            World x of the contact centre (finger position u), m.
        defect_x, defect_y : float
            Defect position in the world frame, m.
        strength : float
            Defect strength S_d in m^2 (``iint h / h_ref dA``; the footprint of a bump whose
            height is the reference height). May be negative (a pit).

        Returns
        -------
        ndarray, shape (n_u, n_sensors, n_components): Pa or strain (tensor shear eps_ij; engineering
        gamma_ij = 2 eps_ij) per finger position.
        """
        u = np.atleast_1d(np.asarray(positions, dtype=float))
        if u.ndim != 1 or not np.all(np.isfinite(u)):
            raise ValueError(f"positions: need a finite 1-D array of finger positions in m, got shape {u.shape}")
        for name, v in (("defect_x", defect_x), ("defect_y", defect_y), ("strength", strength)):
            if not math.isfinite(float(v)):
                raise ValueError(f"{name}: must be finite, got {v!r}")
        xs = float(defect_x) - u
        ys = np.full_like(xs, float(defect_y))
        p, q = self.traction(xs, ys)
        return self.point_response(xs, ys, strength * q, strength * p)

    def node_weights(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The scan operator: per-node weights ``W`` so that outputs = ``modulation @ W``.

        Returns
        -------
        X, Y : ndarray, shape (n_nodes,)
            Finger-frame node coordinates (m) of the loaded nodes (interfacial stress > 0).
        W : ndarray, shape (n_nodes, n_sensors * n_components)
            Output per unit surface modulation at each node: the node's force (traction times
            cell area, N) times the point-load response (Pa/N or tensor-shear strain/N).
        """
        x, y = self.grid()
        h = self.spacing
        X, Y = np.meshgrid(x, y)
        p, q = self.traction(X, Y, cell=(h, h))
        keep = (p != 0) | (q != 0)
        X, Y, p, q = X[keep], Y[keep], p[keep], q[keep]
        n_sensors, n_components = self.sensors.n_sensors, self.sensors.n_components
        size = X.size * n_sensors * (n_components + 3)  # point_response's work arrays
        if size > MAX_WORK_VALUES:
            raise ValueError(
                f"sensors: {n_sensors} sensors x {n_components} components over {X.size} loaded contact nodes "
                f"need ~{size * 8 / 2**30:.3g} GiB of work arrays, above the limit {MAX_WORK_VALUES * 8 / 2**30:.3g} GiB; "
                "use fewer sensors or components, or a coarser grid_spacing")
        W = self.point_response(X, Y, q * h * h, p * h * h)
        return X, Y, W.reshape(X.size, -1)

    def operator(self):
        """The scan as a linear operator: surface modulation at the loaded nodes -> sensor outputs.

        Returns a ``scipy.sparse.linalg.LinearOperator`` of shape (n_sensors * n_components,
        n_nodes) (nodes as in :meth:`node_weights`), with its adjoint; outputs in Pa or strain
        (tensor shear eps_ij) per unit modulation.
        """
        from scipy.sparse.linalg import LinearOperator

        _, _, W = self.node_weights()
        return LinearOperator(shape=(W.shape[1], W.shape[0]), dtype=float,
                              matvec=lambda m: W.T @ np.ravel(m), rmatvec=lambda y: W @ np.ravel(y))

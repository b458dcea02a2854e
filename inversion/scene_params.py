"""The defect-localisation model and the check of its scene-parameter priors (docs/theory.md section 4b).

A small isolated defect at world ``(x0, y0)`` under a Hertz fingertip contact that scans along
+x adds a concentrated load ``S_d (q_x, 0, p)`` (``S_d`` in m^2, the defect's effective area, times
the local interfacial traction) at the defect. A sensor at finger-frame ``(xs, ys)`` and depth Z
sees, when the contact centre is at world x = u,

    sigma_c(u) = S_d [ p(x0 - u, y0) g_c^z(xs - (x0 - u), ys - y0, Z)
                       + mu p(x0 - u, y0) g_c^x(xs - (x0 - u), ys - y0, Z) ]

with ``g`` the Boussinesq (normal) and Cerruti (tangential) point-load Green's functions
(:func:`tactilab.forward.halfspace.kernels.point_green`, Pa per N) and ``p`` the Hertz pressure of
:class:`tactilab.forward.contact.HertzContact`. The tangential traction is ``+mu p`` along +x
(sign fixed by the sliding direction; negate the signal for the opposite one).

A defect of finite size (``footprint``: its normalised height profile h / iint h dA as a
quadrature, :func:`defect_footprint`) replaces ``p(x0 - u, y0)`` by the pressure averaged over
the footprint, ``sum_k w_k p(x0 + xi_k - u, y0 + eta_k)``: the Hertz pressure changes steeply
near the contact edge, so a defect that straddles it is loaded unevenly (a point model then
puts the defect where that load is centred, biased by a fraction of its size). The Green's
functions stay at the centre (their change over the footprint is of order (size / Z)^2).

``S_d`` enters linearly: :mod:`tactilab.inversion.mcmc` integrates it out exactly under a
Gaussian prior. The nonlinear parameters are ``x0, y0`` (m), ``friction`` (mu_d), ``depth`` (m),
``young_modulus`` (Pa) and ``normal_force`` (N); each is either fixed (a float) or sampled
(a prior object).
"""

from __future__ import annotations

import numpy as np

from tactilab.forward.halfspace import output_weights, point_geometry, point_unit
from tactilab.core import rules

from .priors import PRIORS, LogNormal, Normal, Uniform

NONLINEAR = ("x0", "y0", "friction", "depth", "young_modulus", "normal_force")
#: the nonlinear parameters that must be > 0 (m, Pa, N); x0, y0 and friction may take any sign
POSITIVE = ("depth", "young_modulus", "normal_force")

__all__ = ["Uniform", "Normal", "LogNormal", "DefectScanModel", "NONLINEAR", "check_prior", "defect_footprint"]


def check_prior(name: str, value):
    """A prior object or a finite float (fixed parameter)."""
    if isinstance(value, PRIORS):
        return value
    if isinstance(value, (int, float, np.floating)) and np.isfinite(value):
        return float(value)
    raise ValueError(f"{name}: expected a prior ({', '.join(p.__name__ for p in PRIORS)}) or a finite fixed value, "
                     f"got {value!r}")


def _check_footprint(footprint) -> tuple[np.ndarray, np.ndarray]:
    try:
        offsets, weights = footprint
    except (TypeError, ValueError):
        raise ValueError(f"footprint: expected (offsets of shape (K, 2) in m, weights of shape (K,)), got "
                         f"{footprint!r}; build it with defect_footprint(surface)") from None
    offsets, weights = np.asarray(offsets, dtype=float), np.asarray(weights, dtype=float)
    if offsets.ndim != 2 or offsets.shape[1] != 2 or weights.shape != (offsets.shape[0],) or weights.size < 1 \
            or not (np.all(np.isfinite(offsets)) and np.all(np.isfinite(weights))):
        raise ValueError(f"footprint: expected finite offsets of shape (K, 2) in m and weights of shape (K,), got "
                         f"shapes {offsets.shape} and {weights.shape}; build it with defect_footprint(surface)")
    if np.any(weights < 0) or abs(weights.sum() - 1.0) > 1e-9:
        raise ValueError(f"footprint: weights must be >= 0 and sum to 1 (a normalised height profile), got sum "
                         f"{weights.sum()!r}; divide them by their sum")
    return offsets, weights


def defect_footprint(surface, n_radial: int = 6, n_angles: int = 16):
    """Quadrature of an isolated round defect's normalised height profile h / iint h dA.

    Parameters
    ----------
    surface : tactilab.data_schemas IsolatedDefect
        ``shape`` "bump" (raised cosine) or "dot" (flat disc), ``size_m`` its base diameter;
        its ``height_at`` gives the profile.
    n_radial, n_angles : int
        Gauss-Legendre nodes in r on [0, size_m / 2] (weights times h(r) r) and equally spaced
        angles (>= 1 and >= 3).

    Returns
    -------
    (offsets, weights) or None
        Offsets from the centre, shape (n_radial * n_angles, 2), m; weights summing to 1.
        None for an edge step (no centre: not an isolated defect).
    """
    if getattr(surface, "kind", None) != "defect":
        raise ValueError(f"surface: expected an isolated defect (kind 'defect'), got {getattr(surface, 'kind', None)!r}")
    if not (isinstance(n_radial, int) and n_radial >= 1 and isinstance(n_angles, int) and n_angles >= 3):
        raise ValueError(f"n_radial, n_angles: need whole numbers >= 1 and >= 3, got {n_radial!r}, {n_angles!r}")
    if surface.shape == "edge_step":
        return None
    b = surface.size_m / 2
    t, wt = np.polynomial.legendre.leggauss(n_radial)
    r = 0.5 * b * (t + 1.0)
    x0, y0 = surface.position_m
    w_r = wt * r * np.abs(surface.height_at(x0 + r, np.full_like(r, y0)))
    angles = (np.arange(n_angles) + 0.5) * 2 * np.pi / n_angles
    offsets = np.stack([np.outer(r, np.cos(angles)).ravel(), np.outer(r, np.sin(angles)).ravel()], axis=1)
    weights = np.repeat(w_r / w_r.sum() / n_angles, n_angles)
    return offsets, weights / weights.sum()


class DefectScanModel:
    """Signal of a point defect scanned under a Hertz contact, per unit defect area.

    Parameters
    ----------
    scan_positions : array_like, shape (n_times,)
        World x of the contact centre at each sample, m.
    sensors : array_like, shape (n_sensors, 2)
        Finger-frame sensor positions (x, y), m.
    components : sequence of str
        Components observed (Voigt names, e.g. ``("zz",)`` or ``("zx", "zz")``; the aliases ``xz``,
        ``zy``, ``yx`` are accepted, None means all six: the project's component rule).
    finger_radius : float
        Fingertip radius of curvature, m.
    poisson_ratio : float
        Skin nu in (-1, 0.5].
    quantity : {"stress", "strain"}
        What the sensors record: stress (Pa) or TENSOR strain (dimensionless, eps_ij; engineering
        shear is 2 eps_ij). Strain is the stress at the sensor through the compliance rows of
        :func:`tactilab.forward.halfspace.output_weights`, with the walker's ``young_modulus``.
    footprint : (ndarray shape (K, 2), ndarray shape (K,)), optional
        A finite defect: quadrature offsets (xi, eta) from its centre, m, and weights summing
        to 1 (its normalised height profile, :func:`defect_footprint`); the interfacial pressure
        is averaged over it. None (default): a point defect.

    Notes
    -----
    :meth:`design` returns ``g(theta)``, shape ``(n_walkers, n_times * n_sensors * n_components)``
    in Pa (stress) or strain per m^2 of defect area, ordered (time, sensor, component) like a
    Recording's values.
    """

    def __init__(self, scan_positions, sensors, components=("zz",), finger_radius: float = 0.01,
                 poisson_ratio: float = 0.5, quantity: str = "stress", footprint=None):
        u = np.asarray(scan_positions, dtype=float).ravel()
        if u.size < 1 or not np.all(np.isfinite(u)):
            raise ValueError(f"scan_positions: need at least one finite position in m, got {scan_positions!r}")
        s = np.asarray(sensors, dtype=float)
        if s.ndim != 2 or s.shape[1] != 2 or s.shape[0] < 1 or not np.all(np.isfinite(s)):
            raise ValueError(f"sensors: expected finite (x, y) positions in m with shape (n_sensors, 2), got shape {s.shape}")
        comps = rules.components(components)
        finger_radius = rules.positive(finger_radius, "finger_radius", "m", "give the fingertip radius in m")
        poisson_ratio = rules.poisson_ratio(poisson_ratio, "poisson_ratio")
        if quantity not in ("stress", "strain"):
            raise ValueError(f"quantity: must be 'stress' (Pa) or 'strain' (tensor strain), got {quantity!r}")
        self.quantity = quantity
        self.footprint = None if footprint is None else _check_footprint(footprint)
        # stress -> output rows with E = 1 Pa (strain rows scale as 1/E, applied per walker)
        self._weights = output_weights(quantity, comps, 1.0, float(poisson_ratio))
        self.scan_positions = u
        self.sensors = s
        self.components = comps
        self.finger_radius = float(finger_radius)
        self.poisson_ratio = float(poisson_ratio)

    @property
    def n_data(self) -> int:
        return self.scan_positions.size * self.sensors.shape[0] * len(self.components)

    @property
    def data_shape(self) -> tuple[int, int, int]:
        return (self.scan_positions.size, self.sensors.shape[0], len(self.components))

    def design(self, params: dict) -> np.ndarray:
        """Signal per unit defect area, vectorised over walkers (checked: use it from outside).

        Parameters
        ----------
        params : dict
            Every name of ``NONLINEAR`` -> ndarray shape (n_walkers,) (or scalar), SI units;
            finite, with depth (m), young_modulus (Pa) and normal_force (N) > 0.

        Returns
        -------
        ndarray, shape (n_walkers, n_data), Pa per m^2
        """
        missing = [k for k in NONLINEAR if k not in params]
        if missing:
            raise ValueError(f"params: missing {missing}; give every name of {NONLINEAR} (SI units)")
        for k in NONLINEAR:
            v = np.asarray(params[k], dtype=float)
            if v.ndim > 1 or not np.all(np.isfinite(v)) or (k in POSITIVE and np.any(v <= 0)):
                rule = "finite and > 0" if k in POSITIVE else "finite"
                raise ValueError(f"params[{k!r}]: must be a scalar or a 1-D array (one value per walker), {rule}, "
                                 f"got {params[k]!r}")
        try:
            np.broadcast_shapes(*(np.shape(np.atleast_1d(params[k])) for k in NONLINEAR))
        except ValueError:
            raise ValueError(f"params: the arrays must have one length (walkers) or be scalars, got lengths "
                             f"{ {k: np.size(params[k]) for k in NONLINEAR} }") from None
        return self._design(params)

    def _design(self, params: dict) -> np.ndarray:
        """:meth:`design` without its checks: the likelihood's inner loop, whose parameters lie in
        the priors' support (checked once, by :func:`~tactilab.inversion.mcmc.sample_scene_posterior`).
        The Green's functions share one geometry per call (the unchecked solver formulas)."""
        p = {k: np.atleast_1d(np.asarray(params[k], dtype=float)) for k in NONLINEAR}
        w = np.broadcast_shapes(*(v.shape for v in p.values()))[0]
        p = {k: np.broadcast_to(v, (w,))[:, None, None] for k, v in p.items()}
        nu = self.poisson_ratio
        e_star = p["young_modulus"] / (1.0 - nu * nu)
        radius = (3.0 * p["normal_force"] * self.finger_radius / (4.0 * e_star)) ** (1.0 / 3.0)
        p0 = 3.0 * p["normal_force"] / (2.0 * np.pi * radius * radius)
        # defect in the finger frame at each time: (x0 - u, y0); shapes (W, T, 1)
        xd = p["x0"] - self.scan_positions[None, :, None]
        yd = p["y0"]
        if self.footprint is None:
            pressure = p0 * np.sqrt(np.clip(1.0 - (xd * xd + yd * yd) / (radius * radius), 0.0, None))
        else:  # the pressure averaged over the footprint: a trailing axis of K quadrature points
            (xi, eta), wk = self.footprint[0].T, self.footprint[1]
            rel = ((xd + xi) ** 2 + (yd + eta) ** 2) / (radius * radius)  # (W, T, K)
            pressure = p0 * (np.sqrt(np.clip(1.0 - rel, 0.0, None)) @ wk)[..., None]
        dx = self.sensors[None, None, :, 0] - xd
        dy = self.sensors[None, None, :, 1] - yd
        z = np.broadcast_to(p["depth"], dx.shape)
        geometry = point_geometry(dx, dy, z)  # depth > 0, so R > 0
        needed = [j for j in range(6) if np.any(self._weights[:, j] != 0.0)]
        stress = {}
        for j in needed:
            gz = point_unit(rules.COMPONENTS[j], "z", *geometry, nu)
            gx = point_unit(rules.COMPONENTS[j], "x", *geometry, nu)
            stress[j] = pressure * (gz + p["friction"] * gx)
        out = [sum(self._weights[c, j] * stress[j] for j in needed if self._weights[c, j] != 0.0)
               for c in range(len(self.components))]
        sig = np.stack(out, axis=-1)  # (W, T, S, C)
        if self.quantity == "strain":
            sig = sig / p["young_modulus"][..., None]
        return sig.reshape(w, -1)

    def simulate(self, params: dict, area: float) -> np.ndarray:
        """Noise-free signal for one parameter set, shape ``data_shape`` (Pa, or strain)."""
        return (area * self.design(params)[0]).reshape(self.data_shape)

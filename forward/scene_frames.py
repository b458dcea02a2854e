"""A scene's scan as frames on one contact grid: gaps for the exact model, tractions for the cheap ones.

The grid lives in the finger frame (docs/scenes.md): node ``j`` at ``x_j = (j - nx // 2) h``. At
frame ``i`` the contact centre is at world ``x = u_i`` and the surface point under node ``x`` is the
world point ``x + u_i``. Two kinds of scene:

- a **finger** (``normal_force`` and ``finger_radius``): an isolated contact on a square grid of
  3 Hertz radii, the spacing of :func:`~.scanning.scene_finger` (it resolves the contact, the depth
  and the surface's relief); the gap is ``r^2 / (2 R) - h(x + u, y) - ridges(x)``;
- a **periodic cell** (``mean_pressure``): the nominally flat skin on one period of the surface
  (a sinusoid or a regular square wave: 256 nodes per period unless a spacing is given, in plane
  strain; a ``random_rough`` plate: its own 2-D period on its own nodes, or on a grid spacing that
  cuts each side into an even number of nodes); the gap is ``-h(x + u) - ridges(x)``.

The cheap models' tractions (SI, on the skin; ``D`` is the scenes' friction direction, +1):

- ``"linear"``: the smooth finger's pressure plus the texture's full-contact pressure
  ``E* |k| H~ / 2`` (ridges included) inside the finger's contact, clipped at 0; the tangential
  traction is the finger's, scaled by the same ratio (``D mu p`` while sliding);
- ``"modulation"``: the finger's traction times ``max(0, 1 + h / h_ref)`` (docs/theory.md 4b).

On a layered skin (:mod:`.scene_layered`) the smooth finger's traction is its contact solved on the
layers, the texture's full-contact pressure is ``h~(k) / C_zz(k)``, and ``"modulation"`` is refused.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from tactilab.core import rules as check
from tactilab.data_schemas.material import SkinMaterial

from .finger import BiomimeticFinger, Fingerprint
from .halfspace import HalfSpace, pressure_from_deflection
from .scanning import reference_height, scanned_surface, scene_finger
from .scene_contact import finger_gap, ridge_heights, solve_scan
from .scene_readout import SensorReadout
from .scene_layered import layered_deflection_pressure, layered_skin, refuse_layered_modulation, softest

#: finger grid half-width in Hertz contact radii (a rough contact spreads a little beyond a)
GRID_RADII = 1.5
#: nodes per period of a periodic cell when no spacing is given
CELL_NODES = 256
#: the surface kinds a periodic cell accepts, with their period along x (random_rough: its size, 2-D)
_PERIODIC = {"sinusoidal_grating": "period_m", "square_wave_grating": "period_m", "random_rough": "size_m"}


@dataclass
class SceneFrames:
    """The frames of a scene's scan on one contact grid (build with :meth:`from_scene`).

    Attributes
    ----------
    scene : data_schemas Scene
    skin : HalfSpace or LayeredHalfSpace
        The skin the contact is solved on and the sensors read through.
    periodic : bool
        True for a periodic cell.
    shape : (nx,) or (ny, nx)
    spacing : tuple of float
        m, x first.
    positions : ndarray, shape (n_frames,)
        World x of the contact centre per frame, m.
    shifts : ndarray of int or None
        Nodes the surface moves along +x in the finger frame per frame (None: not on nodes).
    slip_ratios : ndarray, shape (n_frames,)
        Q / (mu F) per frame (1: full sliding).
    e_star : float
        Plane-strain modulus E / (1 - nu^2), Pa (a layered skin: of its softest material, which sizes
        the finger's grid).
    """

    scene: object
    skin: HalfSpace
    periodic: bool
    shape: tuple
    spacing: tuple
    positions: np.ndarray
    shifts: np.ndarray | None
    slip_ratios: np.ndarray
    e_star: float
    finger: BiomimeticFinger | None = None
    _surface: object = None
    _h_ref: float = 1.0
    _cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        self.spacing = check.spacing(self.spacing, len(self.shape))

    # ---------------------------------------------------------------- construction
    @classmethod
    def from_scene(cls, scene, grid_spacing: float | None = None) -> "SceneFrames":
        """The frames of ``scene`` (a data_schemas Scene with a ``contact``); ``grid_spacing`` in m."""
        c, m, s = scene.contact, scene.material, scene.scan
        if c is None:
            raise ValueError("scene.contact: the interface models need a finger or a periodic cell ([contact]); "
                             "a display scene is simulated by the display model")
        if m.is_layered:
            skin, (E, nu) = layered_skin(scene), softest(m)
        else:
            E, nu = m.half_space_constants("the scene's interface models (contact and sensor readout)")
            skin = HalfSpace(E=E, nu=nu)
        e_star = E / (1 - nu**2)
        u = s.positions_m
        ratios = s.slip_ratios
        if s.speed_m_per_s == 0 and c.adhesion > 0:  # a static press: adhesion is Q / (mu F)
            ratios = np.full(u.size, float(c.adhesion))
        elif c.adhesion > 0 and c.friction_coefficient > 0:  # said, never dropped silently
            warnings.warn(f"contact.adhesion: {c.adhesion:g} is not used by the solved contact (models exact and "
                          f"linear) of a finger sliding at {s.speed_m_per_s * 1e3:g} mm/s, which is in full sliding; "
                          "adhesion is Q / (mu F) of a static press (speed 0), and [scan] onset ramps a scan's "
                          "tangential load in partial slip (the modulation model keeps its blend)",
                          UserWarning, stacklevel=2)
        if c.periodic:
            return cls._cell(scene, skin, e_star, u, ratios, grid_spacing)
        finger = scene_finger(scene if not m.is_layered else scene.model_copy(
            update={"material": SkinMaterial(young_modulus_pa=E, poisson_ratio=nu)}), grid_spacing)
        h = finger.spacing
        half, reach = grid_reach(finger)
        # the strip the grid reads is the strip the check covers: a defect outside it, or a measured
        # map smaller than it, is refused naming both sizes (not met later as a point off the map)
        strip = scanned_surface(scene.surface, u, finger, reach=reach)
        return cls(scene, skin, False, (2 * half, 2 * half), (h, h), u, _shifts(u, h), ratios, e_star, finger,
                   strip, reference_height(strip))

    @classmethod
    def _cell(cls, scene, skin, e_star, u, ratios, grid_spacing):
        rec = scene.surface
        attr = _PERIODIC.get(rec.kind)
        if attr is None or (rec.kind == "square_wave_grating" and rec.pattern != "regular"):
            raise ValueError(f"contact.mean_pressure: a periodic cell needs a periodic surface ({sorted(_PERIODIC)}, "
                             f"square waves regular), got kind {rec.kind!r}; press a finger (normal_force, "
                             "finger_radius) on it instead")
        if rec.kind == "random_rough":  # a 2-D cell: the plate's own period, on its own nodes unless a spacing is given
            nx, ny = _tiling(rec, grid_spacing)
            lx, ly = (float(v) for v in rec.size_m)
            peak = float(np.abs(rec.heights_m).max())
            return cls(scene, skin, True, (ny, nx), (lx / nx, ly / ny), u, _shifts(u, lx / nx), ratios, e_star, None,
                       rec, peak)
        period = float(getattr(rec, attr))
        n = CELL_NODES if grid_spacing is None else max(8, 2 * int(round(period / grid_spacing / 2)))
        h = period / n
        peak = float(rec.amplitude_m)
        return cls(scene, skin, True, (n,), (h,), u, _shifts(u, h), ratios, e_star, None, rec, peak)

    # ---------------------------------------------------------------- geometry
    @property
    def layered(self) -> bool:
        """True on a layered skin (models exact and linear only)."""
        return not isinstance(self.skin, HalfSpace)

    @property
    def cheap_models(self) -> tuple[str, ...]:
        """The models cheaper than the exact one that this skin takes (in the order the reports list them)."""
        return ("linear",) if self.layered else ("linear", "modulation")

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.positions.size)

    @property
    def x(self) -> np.ndarray:
        """Finger-frame x of the nodes, m."""
        n = self.shape[-1]
        return (np.arange(n) - n // 2) * self.spacing[0]

    @property
    def y(self) -> np.ndarray | None:
        """Finger-frame y of the nodes, m (None in plane strain)."""
        if len(self.shape) == 1:
            return None
        return (np.arange(self.shape[0]) - self.shape[0] // 2) * self.spacing[1]

    @property
    def friction(self) -> float:
        """mu."""
        return float(self.scene.contact.friction_coefficient)

    @property
    def direction(self) -> float:
        """The scenes' friction direction D (+1: docs/theory.md 4b's q = +mu p; see docs/scenes.md, Limits)."""
        return 1.0 if self.finger is None else float(self.finger.friction_direction)

    @property
    def load(self) -> dict:
        """``solve_contact``'s load keyword: the finger's ``normal_force`` (N) or the cell's ``mean_pressure`` (Pa)."""
        c = self.scene.contact
        return {"mean_pressure": float(c.mean_pressure_pa)} if self.periodic else {"normal_force": float(c.normal_force_n)}

    @property
    def mean_pressure(self) -> float:
        """The contact's mean pressure p_bar in Pa (a finger: F / (pi a^2) of its Hertz contact)."""
        if self.periodic:
            return float(self.scene.contact.mean_pressure_pa)
        a = self.finger.contact.contact_radius
        return self.finger.contact.normal_force / (math.pi * a * a)

    def _mesh(self):
        if "mesh" not in self._cache:
            y = self.y
            self._cache["mesh"] = (self.x, None) if y is None else np.meshgrid(self.x, y)
        return self._cache["mesh"]

    def _world(self, i: int):
        X, Y = self._mesh()
        return X + self.positions[i], Y

    def heights(self, i: int) -> np.ndarray:
        """The surface's heights under the grid at frame ``i`` (m, positive towards the skin)."""
        X, Y = self._world(i)
        if self.periodic:
            return self._surface.height_at(X) if Y is None else self._surface.height_at(X, Y)
        return self._surface.height(X, Y)

    def ridges(self) -> np.ndarray:
        """The fingerprint ridges as heights of the skin (m; 0 without ``fingerprint_height``)."""
        c = self.scene.contact
        if c.fingerprint_height_m is None:
            return np.zeros(self.shape)
        X, _ = self._mesh()
        return np.broadcast_to(ridge_heights(X, c.fingerprint_period_m, c.fingerprint_height_m), self.shape)

    def gap(self, i: int) -> np.ndarray:
        """``solve_contact``'s gap at frame ``i`` (m)."""
        g = -self.heights(i) - self.ridges()
        if not self.periodic:
            g = g + finger_gap(self.shape, self.spacing, self.finger.contact.finger_radius)
        return g

    # ---------------------------------------------------------------- the cheap models' tractions
    def texture_pressure(self, i: int) -> np.ndarray:
        """The full-contact pressure of the texture and the ridges, ``E* |k| H~ / 2`` (Pa, zero mean)."""
        h = self.heights(i) + self.ridges()
        if self.periodic:
            return self._deflection_pressure(h)
        pad = [(n // 2, n - n // 2) for n in h.shape]  # mirrored margins: no wrap-around of an isolated window
        p = self._deflection_pressure(np.pad(h, pad, mode="reflect"))
        return p[tuple(slice(a, a + n) for (a, _), n in zip(pad, h.shape))]

    def _deflection_pressure(self, h: np.ndarray) -> np.ndarray:
        if self.layered:
            return layered_deflection_pressure(self.skin, h, self.spacing)
        spacing = self.spacing[0] if len(self.spacing) == 1 else self.spacing
        return pressure_from_deflection(h, spacing, self.skin.E, self.skin.nu).p

    def _finger_tractions(self, ratio: float, fingerprint: bool):
        key = ("finger", ratio, fingerprint)
        if key not in self._cache and self.layered:
            self._cache[key] = self._smooth_contact(ratio)
        if key not in self._cache:
            f = self.finger
            fp = f.fingerprint if fingerprint else None
            if ratio < 1 and self.friction > 0:
                f = BiomimeticFinger(f.contact, f.sensors, f.friction, 0.0, fp, f.grid_spacing, slip_ratio=ratio,
                                     friction_direction=f.friction_direction)
            else:
                f = BiomimeticFinger(f.contact, f.sensors, f.friction, f.adhesion, fp, f.grid_spacing,
                                     friction_direction=f.friction_direction)
            X, Y = self._mesh()
            self._cache[key] = f.traction(X, Y, cell=self.spacing)
        return self._cache[key]

    def _smooth_contact(self, ratio: float) -> tuple[np.ndarray, np.ndarray]:
        """The smooth finger's ``(p, qx)`` (Pa) solved on a layered skin at the slip ratio ``ratio`` (the
        Hertz tractions stand for it on a half-space)."""
        gap = finger_gap(self.shape, self.spacing, self.finger.contact.finger_radius)
        sol = solve_scan(self.skin, gap[None], self.spacing, friction=self.friction,
                         slide_direction=(self.direction, 0.0), warm_start=False, tol=1e-10,
                         slip_ratio=ratio if ratio < 1 and self.friction > 0 else None,
                         **self.load)
        return sol.pressure[0], sol.qx[0]

    def tractions(self, model: str, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """``(p, qx, qy)`` of the cheap ``model`` ("linear" or "modulation") at frame ``i``, Pa."""
        ratio = float(self.slip_ratios[i])
        if model not in ("linear", "modulation"):
            raise ValueError(f"model: tractions() computes 'linear' or 'modulation', got {model!r}; the exact "
                             "model is solved by solve_scan")
        if self.layered and model == "modulation":
            refuse_layered_modulation(model)
        if self.periodic:
            pbar = self.mean_pressure
            if model == "linear":
                p = np.maximum(pbar + self.texture_pressure(i), 0.0)
            else:
                p = pbar * np.clip(1.0 + self.heights(i) / self._h_ref, 0.0, None)
                if self.scene.contact.fingerprint_period_m is not None:
                    p = p * Fingerprint(self.scene.contact.fingerprint_period_m).factor(self.x)
            return p, self.direction * ratio * self.friction * p, None
        X, Y = self._world(i)
        if model == "modulation":
            p0, q0 = self._finger_tractions(ratio, fingerprint=True)
            m = self._surface.modulation(X, Y, reference_height=self._h_ref)
            return p0 * m, q0 * m, np.zeros(self.shape)
        p0, q0 = self._finger_tractions(ratio, fingerprint=False)
        inside = p0 > 0
        p = np.where(inside, np.maximum(p0 + self.texture_pressure(i), 0.0), 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            q = np.where(inside, q0 * p / np.where(inside, p0, 1.0), 0.0)
        return p, q, np.zeros(self.shape)

    # ---------------------------------------------------------------- sensors
    def readout(self) -> SensorReadout:
        """The scene's sensors over the window the contacts occupy (built once)."""
        if "readout" not in self._cache:
            window = None
            if not self.periodic:  # the Hertz disc and a margin: a rough contact spreads a little
                a = self.finger.contact.contact_radius
                half = min(self.shape[0] // 2, int(math.ceil(1.25 * a / self.spacing[0])) + 8)
                mid = self.shape[0] // 2
                window = (slice(mid - half, mid + half), slice(mid - half, mid + half))
            loads = ("p", "qx") if self.periodic else ("p", "qx", "qy")
            sliding = None  # every frame slides (q = D mu p in every model): fold q into the weights
            if np.all(self.slip_ratios >= 1) and (self.scene.contact.adhesion == 0 or self.friction == 0):
                sliding = (self.friction, (self.direction, 0.0))
            self._cache["readout"] = SensorReadout(self.skin, self.shape, self.spacing, self.scene.sensors,
                                                   periodic=self.periodic, window=window, loads=loads,
                                                   sliding=sliding)
        return self._cache["readout"]


def grid_reach(finger: BiomimeticFinger) -> tuple[int, float]:
    """The finger's contact grid for the exact and linear models: ``(half, reach)``.

    The grid has ``2 half`` nodes per axis, ``half = ceil(GRID_RADII a / h)`` (a the Hertz radius,
    h the finger's spacing), at ``(j - half) h``: it reads the surface within ``reach = half h`` (m)
    of the contact centre. :meth:`SceneFrames.from_scene` checks and builds the scanned strip with
    this one reach (:func:`~.scanning.scanned_surface`).
    """
    h = finger.spacing
    half = int(math.ceil(GRID_RADII * finger.contact.contact_radius / h))
    return half, half * h


def _tiling(rec, grid_spacing: float | None) -> tuple[int, int]:
    """Nodes (nx, ny) of a random_rough cell: its period ``size_m`` cut by ``grid_spacing`` (default the
    plate's own ``spacing_m``) into an even whole number (>= 8) of nodes per side (the periodic contact
    solve needs even counts); any other spacing is refused rather than silently stretched."""
    step = float(rec.spacing_m if grid_spacing is None else grid_spacing)
    counts = []
    for axis, length in zip("xy", (float(v) for v in rec.size_m)):
        n = int(round(length / step))
        if n < 8 or n % 2 or abs(n * step - length) > 1e-6 * step:
            own = [int(round(v / rec.spacing_m)) for v in rec.size_m]  # whole by the record's own rule
            fix = rec.spacing_m if all(k >= 8 and k % 2 == 0 for k in own) else rec.spacing_m / 2
            raise ValueError(
                f"grid_spacing: a random_rough periodic cell is the plate's period size_m = ({rec.size_m[0]!r}, "
                f"{rec.size_m[1]!r}) m, so its grid must cut each side into an even whole number (>= 8) of nodes; "
                f"{step!r} m {'(the plate spacing_m) ' if grid_spacing is None else ''}gives {length / step:.6g} "
                f"nodes along {axis}; give a grid_spacing that does, e.g. {fix!r} m")
        counts.append(n)
    return counts[0], counts[1]


def _shifts(u: np.ndarray, h: float) -> np.ndarray | None:
    """Nodes the surface moves (along +x, finger frame) between frames, when the steps land on nodes."""
    steps = np.diff(u, prepend=u[0]) / h
    if np.allclose(steps, np.round(steps), rtol=0.0, atol=1e-6):
        return -np.round(steps).astype(np.int64)
    return None


"""The stimulus the finger feels: a physical grating pressed by a fingertip, through the solved contact.

A :class:`FingerContact` is the finger of ``TransductionModel(source="contact")``: a fingertip of
radius ``R`` pressed with a normal force ``F`` on a rigid grating (the Stimulus's waveform,
amplitude and pitch as surface heights), sliding over it with Coulomb friction ``mu`` (full
sliding: ``q = mu p`` on the skin along the grating's motion), on skin of modulus ``E`` and
Poisson's ratio ``nu``. For each of ``n_phases`` offsets of the grating over one period (the
grating slides under the finger, so every offset is felt) the contact is solved
(:func:`tactilab.forward.solve_contact`, the gap ``r^2 / (2 R) - h(x + s)``, an isolated contact on
a grid that holds it), and the strain at depth is the half-space field of the solved tractions
(``HalfSpace.strain``) at the receptors: the grid nodes of the scan line through the contact
centre within the smooth finger's Hertz radius. The surface source (the sliding-sinusoid formula)
is the limit of a surface the skin follows everywhere; this one has the finger's own pressure and
friction in it, and the partial contact of deep gratings.

What a receptor reads of the grating is the texture's part of the strain: the strain under the
grating minus the strain under a smooth surface pressed and slid alike (on the same grid), so a
blank (amplitude 0) reads 0, as for the other sources; :meth:`FingerContact.strain` gives it,
:meth:`FingerContact.total_strain` the whole field. Solutions are cached per stimulus (and the
strain per stimulus and depths), so the models that read one finger share its contact solves.
"""

from __future__ import annotations

import math

import numpy as np

from tactilab.core import rules
from tactilab.data_schemas.experiment import Stimulus
from tactilab.forward import HalfSpace, HertzContact, solve_contact

__all__ = ["FingerContact"]


class FingerContact:
    """A fingertip pressed on a grating stimulus and sliding over it, solved as a contact.

    Parameters
    ----------
    finger_radius : float
        Fingertip radius of curvature R, m (> 0).
    normal_force : float
        Normal force F, N (> 0).
    friction : float
        Coulomb coefficient mu >= 0 (0: frictionless).
    young_modulus : float
        Skin Young's modulus E, Pa (> 0).
    poisson_ratio : float
        Skin Poisson's ratio nu in (-1, 0.5].
    nodes_per_period : int
        Grid nodes per period of the grating (>= 8); the spacing is also at most a tenth of the
        Hertz radius.
    n_phases : int
        Offsets of the grating over one period at which the contact is solved (>= 1).
    max_nodes : int
        Largest number of nodes per grid axis (the grid is square); a stimulus that needs more
        (a fine pitch under a large contact) is refused.
    tol : float
        Relative gap residual of the contact solves (``solve_contact``'s ``tol``).

    Raises
    ------
    ValueError
        For a value outside its rule (named, with the fix).
    """

    def __init__(self, finger_radius: float = 10e-3, normal_force: float = 0.5, friction: float = 0.5, *,
                 young_modulus: float = 1e6, poisson_ratio: float = 0.5, nodes_per_period: int = 16,
                 n_phases: int = 8, max_nodes: int = 256, tol: float = 1e-8) -> None:
        self.finger_radius = rules.positive(finger_radius, "finger_radius", "m")
        self.normal_force = rules.positive(normal_force, "normal_force", "N")
        mu = float(friction)
        if not (math.isfinite(mu) and mu >= 0):
            raise ValueError(f"friction: must be a finite Coulomb coefficient >= 0, got {friction!r}; e.g. 0.5")
        self.friction = mu
        self.skin = HalfSpace(E=young_modulus, nu=poisson_ratio)
        for name, value, least in (("nodes_per_period", nodes_per_period, 8), ("n_phases", n_phases, 1),
                                   ("max_nodes", max_nodes, 16)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
                raise ValueError(f"{name}: must be a whole number >= {least}, got {value!r}")
        self.nodes_per_period, self.n_phases, self.max_nodes = int(nodes_per_period), int(n_phases), int(max_nodes)
        self.tol = rules.positive(tol, "tol", "")
        self.hertz = HertzContact(normal_force=self.normal_force, finger_radius=self.finger_radius,
                                  young_modulus=self.skin.E, poisson_ratio=self.skin.nu)
        self._solutions: dict = {}  # stimulus -> solutions per offset; (stimulus, "smooth") -> baseline
        self._strain: dict[tuple, np.ndarray] = {}

    @classmethod
    def from_config(cls, config, **options) -> FingerContact:
        """The finger a protocol's ``[finger]`` table describes (``data_schemas.FingerConfig``)."""
        return cls(config.finger_radius_m, config.normal_force_n, config.friction,
                   young_modulus=config.young_modulus_pa, poisson_ratio=config.poisson_ratio, **options)

    @property
    def young_modulus(self) -> float:
        """Skin Young's modulus E, Pa."""
        return self.skin.E

    @property
    def poisson_ratio(self) -> float:
        """Skin Poisson's ratio nu."""
        return self.skin.nu

    def __repr__(self) -> str:
        return (f"FingerContact(finger_radius={self.finger_radius:g} m, normal_force={self.normal_force:g} N, "
                f"friction={self.friction:g}, young_modulus={self.skin.E:g} Pa, poisson_ratio={self.skin.nu:g})")

    # ----- geometry ---------------------------------------------------------------------------
    def grid(self, stimulus: Stimulus) -> tuple[np.ndarray, float]:
        """Node positions x (m, shape (n,), node j at ``(j - n // 2) dx``) and the spacing dx (m).

        The grid holds the Hertz disc and every crest the finger could touch (within
        ``sqrt(a^2 + 4 R A)``), with a margin; the same nodes serve y.

        Raises
        ------
        ValueError
            If the stimulus needs more than ``max_nodes`` nodes per axis.
        """
        a = self.hertz.contact_radius
        dx = min(stimulus.pitch_m / self.nodes_per_period, a / 10)
        half = 1.3 * math.sqrt(a * a + 4 * self.finger_radius * abs(stimulus.amplitude_m))
        n = 2 * math.ceil(half / dx)
        if n > self.max_nodes:
            raise ValueError(
                f"stimulus: pitch {stimulus.pitch_m * 1e3:.3g} mm under a {2 * half * 1e3:.3g} mm contact needs {n} "
                f"nodes per axis at {self.nodes_per_period} per period, above max_nodes = {self.max_nodes}; raise "
                "max_nodes (memory and time grow as its square) or use a coarser pitch")
        return (np.arange(n) - n // 2) * dx, dx

    def heights(self, stimulus: Stimulus, x: np.ndarray, offset: float) -> np.ndarray:
        """Grating heights h(x + offset), m (positive towards the skin), as the surface source's H."""
        phase = 2 * np.pi * (x + offset) / stimulus.pitch_m + stimulus.phase_rad
        wave = np.sin(phase) if stimulus.surface == "sinusoid" else np.sign(np.sin(phase))
        return stimulus.amplitude_m * wave

    def receptors(self, stimulus: Stimulus) -> np.ndarray:
        """Receptor (x, y) positions, m, shape (n, 2): the scan line's nodes within the Hertz radius."""
        x, _ = self.grid(stimulus)
        inside = x[np.abs(x) <= self.hertz.contact_radius]
        return np.column_stack([inside, np.zeros_like(inside)])

    # ----- mechanics --------------------------------------------------------------------------
    def solutions(self, stimulus: Stimulus) -> list:
        """The contact solved at each offset of the grating over one period (cached per stimulus)."""
        if not isinstance(stimulus, Stimulus):
            raise ValueError(f"stimulus: expected a data_schemas Stimulus, got {type(stimulus).__name__}")
        if stimulus not in self._solutions:
            x, dx = self.grid(stimulus)
            xx, yy = np.meshgrid(x, x)
            finger = (xx**2 + yy**2) / (2 * self.finger_radius)
            self._solutions[stimulus] = [self._solve(stimulus, finger - self.heights(stimulus, xx, offset), dx)
                                         for offset in np.arange(self.n_phases) * stimulus.pitch_m / self.n_phases]
            self._solutions[(stimulus, "smooth")] = self._solve(stimulus, finger, dx)
        return self._solutions[stimulus]

    def smooth_solution(self, stimulus: Stimulus):
        """The contact of the same finger on a smooth surface, on the stimulus's grid (the baseline)."""
        self.solutions(stimulus)
        return self._solutions[(stimulus, "smooth")]

    def _solve(self, stimulus: Stimulus, gap: np.ndarray, dx: float):
        # the grating moves along -x (its pattern at time t is H(x + V t)): friction drags the skin along -x
        direction = (-1.0 if stimulus.speed_m_per_s >= 0 else 1.0, 0.0)
        condition = "sliding" if self.friction > 0 else "frictionless"
        return solve_contact(self.skin, gap, dx, normal_force=self.normal_force, friction=self.friction,
                             condition=condition, slide_direction=direction, tol=self.tol)

    def strain(self, stimulus: Stimulus, depths) -> np.ndarray:
        """The texture's part of the strain at the receptors, at every offset: the strain under the
        grating minus that under the smooth surface (cached); the shape of :meth:`total_strain`."""
        z = tuple(float(d) for d in rules.depths(depths))
        key = (stimulus, z, "texture")
        if key not in self._strain:
            smooth = self._field(self.smooth_solution(stimulus), z, self.receptors(stimulus))
            self._strain[key] = self.total_strain(stimulus, z) - np.tile(smooth, (1, self.n_phases, 1))
        return self._strain[key]

    def _field(self, solution, depths: tuple, points: np.ndarray) -> np.ndarray:
        # 1e-4 of the field: far below what a threshold resolves, and met by the closed form at any grid
        field = self.skin.strain(solution.load(), list(depths), points=points, tol=1e-4).data["strain"]
        return field.transpose("depth", "point", "component").values

    def total_strain(self, stimulus: Stimulus, depths) -> np.ndarray:
        """Strain at the receptors under the solved contact at every offset (cached).

        Parameters
        ----------
        stimulus : Stimulus
        depths : sequence of float
            Receptor depths, m.

        Returns
        -------
        ndarray, shape (n_depths, n_phases * n_receptors, 6)
            Voigt strain (xx, yy, zz, yz, zx, xy) with TENSOR shear, dimensionless.
        """
        z = tuple(float(d) for d in rules.depths(depths))
        key = (stimulus, z)
        if key not in self._strain:
            points = self.receptors(stimulus)
            self._strain[key] = np.concatenate([self._field(sol, z, points) for sol in self.solutions(stimulus)],
                                               axis=1)
        return self._strain[key]

    def contact_fraction(self, stimulus: Stimulus) -> float:
        """Fraction of the smooth finger's Hertz disc in contact, averaged over the offsets (1: full contact)."""
        x, _ = self.grid(stimulus)
        xx, yy = np.meshgrid(x, x)
        disc = np.hypot(xx, yy) < self.hertz.contact_radius
        return float(np.mean([sol.contact[disc].mean() for sol in self.solutions(stimulus)]))

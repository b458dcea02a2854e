"""Time-stepped frictionless normal contact of a viscoelastic skin (generalised Maxwell) with a rigid body.

The skin's surface displacement is that of the glassy elastic skin (modulus E(0)) under a
*pseudo-pressure* ``w``, and the real pressure is its hereditary integral with the normalised
relaxation modulus (Lee and Radok's correspondence, written in relaxation form)::

    uz(t) = C_{E(0)}[w(t)],        p(t) = int_0^t (E(t - s) / E(0)) dw(s).

With ``w`` linear in time over a step (:mod:`.hereditary`), ``p_n = gain w_n + memory_n``, where
``memory_n`` holds the past only. Eliminating ``w_n``::

    uz_n = C_{E_n}[p_n] - C_{E_n}[memory_n],    E_n = gain E(0),

so each step is an elastic contact (:func:`solve_contact`) of a half-space of modulus ``E_n``
whose gap carries the history as an extra term, ``g0_n - C_{E_n}[memory_n]``. The step's
complementarity (``p_n >= 0``, ``g_n >= 0``, ``p_n g_n = 0``) is the real one, on the real
pressure: the contact can only be as large as the current state allows, which is why the contact
radius under a constant load cannot overshoot the relaxed elastic one (a scheme that puts the
complementarity on the pseudo-pressure instead loses that bound). The first step is the glassy
elastic contact (gain 1, no memory); a load held for long relaxes to the elastic contact of E_inf.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..contact import ContactCompliance, ContactSolution, solve_contact
from ..halfspace import HalfSpace, SurfaceLoad
from .hereditary import HereditaryIntegral, check_times
from .viscoelastic import ViscoelasticHalfSpace


@dataclass(frozen=True)
class ViscoelasticContactHistory:
    """A solved time-stepped contact: per-step totals, kept pressures and the last solution.

    Attributes
    ----------
    times : ndarray, shape (n_times,)
        Step times in s.
    normal_force : ndarray, shape (n_times,)
        Total force on the skin, N (N/m in plane strain).
    approach : ndarray, shape (n_times,)
        Rigid approach, m (relative to the zero-mean displacement for a periodic contact).
    area : ndarray, shape (n_times,)
        Contact area, m^2 (m in plane strain).
    tangential_force : ndarray, shape (n_times, 2) or (n_times, 1)
        The force the normal pressure exerts ON THE SKIN along x (and y) through the slope of the
        rigid surface, ``sum p grad(gap) dA`` (N; N/m), small-slope: a rigid body sliding over the
        skin drags it along (positive along the motion) when the skin's pressure leads.
    iterations : ndarray of int, shape (n_times,)
    converged : ndarray of bool, shape (n_times,)
    error_estimate : ndarray, shape (n_times,)
        Each step's elastic solve's estimate (max pressure error / peak pressure).
    kept_times : ndarray
        Times of the kept pressures.
    pressures : ndarray, shape (n_kept, *grid)
        Pressure on the skin, Pa, at ``kept_times``.
    last : ContactSolution
        The last step's solution: the real pressure, approach and gap.
    pseudo_pressure : ndarray, shape grid
        The last step's pseudo-pressure ``w`` (Pa): the skin's displacement, and so its strain at
        any depth, is that of the glassy elastic skin (E(0)) under ``w``; the stress is that of
        the real pressure (the correspondence principle at constant nu).
    """

    times: np.ndarray
    normal_force: np.ndarray
    approach: np.ndarray
    area: np.ndarray
    tangential_force: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    error_estimate: np.ndarray
    kept_times: np.ndarray
    pressures: np.ndarray = field(repr=False)
    last: ContactSolution = field(repr=False)
    pseudo_pressure: np.ndarray = field(repr=False, default=None)

    def strain(self, skin, depth, components=None, tol: float = 1e-6):
        """TENSOR strain at depth at the last step: the glassy elastic strain of :attr:`pseudo_pressure`.

        Parameters
        ----------
        skin : ViscoelasticHalfSpace
            The skin that was solved.
        depth, components, tol
            As :meth:`HalfSpace.strain`.

        Returns
        -------
        FieldResult
        """
        load = SurfaceLoad(p=self.pseudo_pressure, spacing=self.last.spacing, periodic=self.last.periodic,
                           error_estimate=self.last.error_estimate)
        return skin.instantaneous.strain(load, depth, components=components, tol=tol)

    @property
    def contact_radius(self) -> np.ndarray:
        """Radius of the disc of the contact's area, m (3-D); the half-width in plane strain."""
        if self.pressures.ndim == 2:
            return self.area / 2.0
        return np.sqrt(self.area / math.pi)

    def __repr__(self) -> str:
        unit = "m" if self.pressures.ndim == 2 else "m^2"
        return (f"ViscoelasticContactHistory({len(self.times)} steps to {self.times[-1]:.4g} s, area "
                f"{self.area[0]:.4g} -> {self.area[-1]:.4g} {unit}, {len(self.kept_times)} pressures kept)")


def _per_step(value, name: str, n: int):
    if value is None:
        return None
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"{name}: give one value (held) or one per time, shape ({n},), got shape {arr.shape}")
    return arr


def _gradient(g: np.ndarray, spacing: tuple, periodic: bool) -> list[np.ndarray]:
    """Central differences of the gap along x (and y), m/m; periodic wraps, isolated is one-sided at the edges."""
    axes = [g.ndim - 1] if g.ndim == 1 else [1, 0]
    if periodic:
        return [(np.roll(g, -1, axis=a) - np.roll(g, 1, axis=a)) / (2 * h) for a, h in zip(axes, spacing)]
    return [np.gradient(g, h, axis=a) for a, h in zip(axes, spacing)]


def solve_viscoelastic_contact(skin, gap, spacing, times, *, normal_force=None, mean_pressure=None, approach=None,
                               periodic: bool = False, tol: float = 1e-8, max_iter=None,
                               keep_every: int | None = 1) -> ViscoelasticContactHistory:
    """Frictionless normal contact of a viscoelastic skin with a rigid body, stepped in time.

    Parameters
    ----------
    skin : ViscoelasticHalfSpace
        The skin (its Prony series and constant Poisson's ratio).
    gap : ndarray or callable
        The initial separation (m) of :func:`solve_contact`, shape (nx,) or (ny, nx): one array for
        a body that does not move, or ``gap(t)`` returning the array at time ``t`` (s), e.g. a
        fingertip's ``r^2 / (2 R) - h(x + X(t), y)`` over a texture that slides by ``X(t)``.
    spacing : float or (float, float)
        Grid spacing in m, x first.
    times : sequence of float, shape (n_times,)
        Step times in s, strictly increasing, >= 0; the skin is at rest before the first (which is
        a step: the glassy elastic contact).
    normal_force, mean_pressure, approach : float or ndarray of shape (n_times,)
        Exactly one, held or per step, as :func:`solve_contact` takes it.
    periodic, tol, max_iter
        As :func:`solve_contact`.
    keep_every : int or None
        Keep the pressure of every ``keep_every``-th step (and the last); None keeps the last only.

    Returns
    -------
    ViscoelasticContactHistory
    """
    if not isinstance(skin, ViscoelasticHalfSpace):
        raise ValueError(f"skin: expected a ViscoelasticHalfSpace, got {type(skin).__name__}; for an elastic skin "
                         "call solve_contact")
    times = check_times(times)
    n = len(times)
    if keep_every is not None and (isinstance(keep_every, bool) or not isinstance(keep_every, (int, np.integer))
                                   or keep_every < 1):
        raise ValueError(f"keep_every: must be a positive integer or None, got {keep_every!r}")
    loads = {"normal_force": _per_step(normal_force, "normal_force", n),
             "mean_pressure": _per_step(mean_pressure, "mean_pressure", n),
             "approach": _per_step(approach, "approach", n)}
    gap_at: Callable = gap if callable(gap) else (lambda t, g=np.asarray(gap, dtype=float): g)
    first = np.asarray(gap_at(float(times[0])), dtype=float)
    prony = skin.prony
    E0 = prony.E_0
    state = HereditaryIntegral((prony.E_inf / E0, prony.moduli / E0, prony.taus), first.shape)
    operators: dict[float, ContactCompliance] = {}
    record = {k: np.empty(n) for k in ("normal_force", "approach", "area", "error_estimate")}
    iterations, converged = np.empty(n, dtype=int), np.empty(n, dtype=bool)
    tangential = np.empty((n, first.ndim))
    kept, kept_t = [], []
    previous, sol = float(times[0]), None
    first_warnings: dict = {}
    for i, t in enumerate(times):
        dt = float(t) - previous
        gain, memory = state.split(dt)
        E_n = gain * E0
        elastic = HalfSpace(E_n, skin.nu)
        g0 = first if i == 0 else np.asarray(gap_at(float(t)), dtype=float)
        if g0.shape != first.shape:
            raise ValueError(f"gap: gap(t) must keep one grid, shape {first.shape} at t = {float(times[0]):g} s, got "
                             f"{g0.shape} at t = {float(t):g} s; return the same grid at every time")
        step_gap = g0
        if np.any(memory):
            if E_n not in operators:
                operators.clear()  # one modulus per step size: keep the current one only
                operators[E_n] = ContactCompliance(elastic, g0.shape, spacing, bool(periodic))
            step_gap = g0 - operators[E_n].normal(memory)
        kwargs = {k: float(v[i]) for k, v in loads.items() if v is not None}
        start = sol if (sol is not None and sol.pressure.shape == g0.shape) else None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            sol = solve_contact(elastic, step_gap, spacing, periodic=periodic, tol=tol, max_iter=max_iter,
                                initial=start, **kwargs)
        for w in caught:  # once per kind, at the end: a thousand steps must not print a thousand lines
            key = (w.category, str(w.message).split(";")[0])
            w0, t0, count = first_warnings.get(key, (w, float(t), 0))
            first_warnings[key] = (w0, t0, count + 1)
        p = np.asarray(sol.pressure)
        state.advance(dt, (p - memory) / gain)  # the pseudo-pressure w_n
        cell = sol.cell_area
        record["normal_force"][i], record["approach"][i] = sol.normal_force, sol.approach
        record["area"][i], record["error_estimate"][i] = sol.area, sol.error_estimate
        iterations[i], converged[i] = sol.iterations, sol.converged
        tangential[i] = [float(np.sum(p * d)) * cell for d in _gradient(g0, sol.spacing, bool(periodic))]
        if (keep_every is not None and i % keep_every == 0) or i == n - 1:
            kept.append(p.copy())
            kept_t.append(float(t))
        previous = float(t)
    for w, t0, count in first_warnings.values():
        warnings.warn(f"{w.message} (at t = {t0:g} s, first of {count} steps that warned)", w.category, stacklevel=2)
    return ViscoelasticContactHistory(times=times, normal_force=record["normal_force"], approach=record["approach"],
                                      area=record["area"], tangential_force=tangential, iterations=iterations,
                                      converged=converged, error_estimate=record["error_estimate"],
                                      kept_times=np.array(kept_t), pressures=np.array(kept), last=sol,
                                      pseudo_pressure=state.previous.copy())

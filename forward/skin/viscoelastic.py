"""A linear viscoelastic half-space at constant Poisson's ratio, by the correspondence principle.

At constant ``nu`` every elastic field scales with ``1/E`` or not at all, so time and space
separate (docs/theory.md section 7):

- **prescribed tractions** (a force-controlled finger, a tractor display): the stress at depth is
  the elastic one at each instant (it does not depend on E); the strain is the elastic strain of
  unit modulus convolved in time with the creep compliance, ``eps(t) = int J(t - s) d(E eps_el)(s)``;
- **prescribed surface deflection** (a rigid surface in full frictionless contact): displacements
  and strains are the elastic ones at each instant; the pressure and the stress follow by the
  relaxation modulus, ``sigma(t) = int E(t - s) d(sigma_el / E)(s)``;
- **steady sliding** of a rigid periodic surface at speed V in full contact: per Fourier mode of
  wavenumber ``kx`` the material sees the frequency ``omega = kx V``, so the pressure and the
  stress of that mode are the elastic ones times ``E*(-kx V) / E(0)`` (a gain and a phase lead of
  the pressure over the deflection), the strain is unchanged.

Time histories are sampled at strictly increasing ``times`` (s), zero before the first (which is
a step) and linear between samples; the hereditary integrals run by recursive convolution
(:mod:`.hereditary`), O(terms) per time step and exact for such histories.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.fft as sfft

from tactilab.core import rules as check

from ..halfspace import HalfSpace, SurfaceLoad, angular_wavenumbers
from .hereditary import check_times, convolve
from .prony import Prony, as_prony
from .time_field import TimeFieldResult


class ViscoelasticHalfSpace:
    """A linear viscoelastic half-space z > 0 (the skin) with a Prony relaxation modulus.

    Parameters
    ----------
    prony : Prony
        The tensile relaxation modulus E(t) (Pa, s).
    nu : float
        Poisson's ratio, constant in time, in (-1, 0.5]; 0.5 (incompressible) is exact.
    """

    def __init__(self, prony: Prony, nu: float = 0.5):
        self.prony = as_prony(prony)
        self.nu = check.poisson_ratio(nu)
        self.instantaneous = HalfSpace(self.prony.E_0, self.nu)  #: the elastic skin at t = 0+ (glassy)
        self.relaxed = HalfSpace(self.prony.E_inf, self.nu)  #: the elastic skin at t = inf

    def __repr__(self) -> str:
        return f"ViscoelasticHalfSpace({self.prony!r}, nu={self.nu!r})"

    @property
    def E(self) -> float:
        """The instantaneous Young's modulus E(0) in Pa (the modulus a fast load sees)."""
        return self.prony.E_0

    def at(self, time: float) -> HalfSpace:
        """The elastic half-space of modulus ``1 / J(time)``: it gives the displacements and strains of
        a traction applied at t = 0 and held until ``time`` (s; 0 instantaneous, ``inf`` relaxed)."""
        t = float(self.prony._times(time, "time"))
        return HalfSpace(1.0 / float(self.prony.creep_compliance(t)), self.nu)

    # -- prescribed tractions ----------------------------------------------------------------
    def stress(self, load, depth, times, history=None, points=None, components=None, method="auto",
               tol: float = 1e-6) -> TimeFieldResult:
        """Stress (Pa, tension positive) at depth under prescribed tractions: the elastic stress at each time.

        Parameters
        ----------
        load : SurfaceLoad or sequence of SurfaceLoad
            One traction pattern (Pa) scaled by ``history``, or one load per time (then no ``history``).
        depth : float or sequence of float
            Depths z > 0 in m.
        times : sequence of float, shape (n_times,)
            Sample times in s, strictly increasing, >= 0; the load is zero before the first.
        history : sequence of float, shape (n_times,), optional
            The load's amplitude at each time (default 1: a step at ``times[0]``, then held).
        points, components, method, tol
            As :meth:`HalfSpace.stress`.

        Returns
        -------
        TimeFieldResult
            ``values`` of shape ``(n_times, n_depths, n_components, *grid)``.
        """
        return self._traction_field(load, depth, times, history, points, components, method, tol, "stress")

    def strain(self, load, depth, times, history=None, points=None, components=None, method="auto",
               tol: float = 1e-6) -> TimeFieldResult:
        """TENSOR strain at depth under prescribed tractions: the elastic strain of modulus E(0) times
        ``E(0)`` convolved with the creep compliance J(t); same arguments as :meth:`stress`.

        Under a step traction it is the instantaneous elastic strain times ``J(t) / J(0)``."""
        return self._traction_field(load, depth, times, history, points, components, method, tol, "strain")

    def _traction_field(self, load, depth, times, history, points, components, method, tol, quantity):
        times = check_times(times)
        loads, amplitude = _loads_and_history(load, times, history)
        hs = self.instantaneous
        solve = hs.stress if quantity == "stress" else hs.strain
        results = [solve(one, depth, points=points, components=components, method=method, tol=tol) for one in loads]
        fields = np.stack([r.data[quantity].values for r in results])
        if quantity == "strain":  # E(0) J convolved with the elastic strain of modulus E(0)
            fields = self.prony.E_0 * _convolve(self.prony.kernel("creep"), times, fields, amplitude)
            how = "creep convolution"
        else:
            fields = fields * amplitude.reshape((-1,) + (1,) * (fields.ndim - 1)) if amplitude is not None else fields
            how = "elastic at each time"
        err = max(r.error_estimate for r in results)
        return TimeFieldResult(fields, times, quantity, f"{results[0].method} + {how}", err, results[0])

    # -- prescribed surface deflection -------------------------------------------------------
    def pressure_from_deflection(self, deflection, spacing, times, history=None) -> np.ndarray:
        """Pressure (Pa) that holds a prescribed normal deflection (m) of a frictionless periodic surface.

        Parameters
        ----------
        deflection : ndarray, shape (nx,) or (ny, nx)
            The surface deflection into the skin in m (one period of a rigid profile in full contact).
        spacing : float or (float, float)
            Grid spacing in m.
        times, history
            As :meth:`stress`: the deflection times ``history`` at each time.

        Returns
        -------
        ndarray, shape (n_times, *deflection.shape)
            The zero-mean pressure at each time: the glassy elastic pressure times
            ``int E(t - s) da(s) / E(0)``, ``a`` the history.
        """
        times = check_times(times)
        p0 = self.instantaneous.pressure_from_deflection(deflection, spacing).p
        gain = self._relaxation_gain(times, history)
        return gain.reshape((-1,) + (1,) * p0.ndim) * p0

    def stress_from_deflection(self, deflection, spacing, depth, times, history=None, points=None, components=None,
                               method="auto", tol: float = 1e-6) -> TimeFieldResult:
        """Stress (Pa) at depth under a prescribed periodic deflection (m): the glassy elastic stress
        times ``int E(t - s) da(s) / E(0)``; arguments as :meth:`pressure_from_deflection` and :meth:`stress`."""
        return self._deflection_field(deflection, spacing, depth, times, history, points, components, method, tol,
                                      "stress")

    def strain_from_deflection(self, deflection, spacing, depth, times, history=None, points=None, components=None,
                               method="auto", tol: float = 1e-6) -> TimeFieldResult:
        """TENSOR strain at depth under a prescribed periodic deflection (m): the elastic strain at each
        time (independent of the modulus); arguments as :meth:`stress_from_deflection`."""
        return self._deflection_field(deflection, spacing, depth, times, history, points, components, method, tol,
                                      "strain")

    def _relaxation_gain(self, times, history) -> np.ndarray:
        amplitude = _amplitude(history, times)
        return convolve(self.prony.kernel("relaxation"), times, amplitude) / self.prony.E_0

    def _deflection_field(self, deflection, spacing, depth, times, history, points, components, method, tol, quantity):
        times = check_times(times)
        hs = self.instantaneous
        load = hs.pressure_from_deflection(deflection, spacing)
        solve = hs.stress if quantity == "stress" else hs.strain
        base = solve(load, depth, points=points, components=components, method=method, tol=tol)
        gain = self._relaxation_gain(times, history) if quantity == "stress" else _amplitude(history, times)
        values = gain.reshape((-1,) + (1,) * base.data[quantity].ndim) * base.data[quantity].values
        how = "relaxation convolution" if quantity == "stress" else "elastic at each time"
        return TimeFieldResult(values, times, quantity, f"{base.method} + {how}", base.error_estimate, base)

    # -- steady sliding ----------------------------------------------------------------------
    def sliding_pressure(self, height, spacing, speed: float, time: float = 0.0) -> SurfaceLoad:
        """The steady pressure (Pa) under a rigid periodic surface sliding at ``speed`` in full contact.

        Parameters
        ----------
        height : ndarray, shape (nx,) or (ny, nx)
            One period of the surface's deflection of the skin in m (into the skin), at time 0.
        spacing : float or (float, float)
            Grid spacing in m.
        speed : float
            Speed of the surface along +x relative to the skin, m/s (any sign; 0 gives the relaxed skin).
        time : float
            Time in s at which the deflection is ``height(x - speed time)``.

        Returns
        -------
        SurfaceLoad
            Periodic, zero-mean: per mode ``E*(-kx speed) rho H~ / (2 (1 - nu^2))``.
        """
        spectrum, kx, rho = self._sliding_spectrum(height, spacing, speed, time)
        factor = self.prony.complex_modulus(-kx * speed) * rho / (2.0 * (1.0 - self.nu ** 2))
        h = np.asarray(height, dtype=float)
        axes = tuple(range(-h.ndim, 0))
        p = sfft.irfftn(spectrum * factor, s=h.shape, axes=axes)
        return SurfaceLoad(p=p, spacing=spacing, periodic=True)

    def _sliding_spectrum(self, height, spacing, speed, time):
        _, _, spectrum, kx, rho = sliding_spectrum(height, spacing, speed, time)
        return spectrum, kx, rho

    def steady_sliding(self, height, spacing, speed: float, depth, quantity: str = "stress", time: float = 0.0,
                       points=None, components=None, method="auto", tol: float = 1e-6):
        """Stress (Pa) or TENSOR strain at depth under a rigid periodic surface sliding in full contact.

        The stress is the elastic stress of :meth:`sliding_pressure` (each harmonic with the gain and
        phase of ``E*(kx speed)``); the strain is the elastic strain of the deflection, whatever the
        speed. Arguments as :meth:`sliding_pressure` and :meth:`HalfSpace.stress`.

        Returns
        -------
        FieldResult
        """
        if quantity not in ("stress", "strain"):
            raise ValueError(f"quantity: must be 'stress' or 'strain', got {quantity!r}")
        hs = self.instantaneous
        if quantity == "stress":
            return hs.stress(self.sliding_pressure(height, spacing, speed, time), depth, points=points,
                             components=components, method=method, tol=tol)
        spectrum, _, _ = self._sliding_spectrum(height, spacing, speed, time)
        h = np.asarray(height, dtype=float)
        moved = sfft.irfftn(spectrum, s=h.shape, axes=tuple(range(-h.ndim, 0)))
        return hs.strain(hs.pressure_from_deflection(moved, spacing), depth, points=points, components=components,
                         method=method, tol=tol)

    # -- the contact solver's protocol -------------------------------------------------------
    def surface_compliance(self, kx, ky=None, time: float = 0.0) -> np.ndarray:
        """Surface compliance (m/Pa per unit Fourier amplitude) ``time`` s after a traction was applied and
        held: the elastic compliance of modulus ``1 / J(time)``. The default 0 is the instantaneous
        (glassy) skin, which :func:`solve_contact` then sees (a load faster than the fastest
        relaxation); ``inf`` is the relaxed skin. Rows and columns as :meth:`HalfSpace.surface_compliance`;
        the time-stepped :func:`solve_viscoelastic_contact` uses each step's own compliance."""
        return self.at(time).surface_compliance(kx, ky)

    def surface_influence(self, x, y, spacing, reference_length: float | None = None,
                          entry: tuple[int, int] | None = None, time: float = 0.0) -> np.ndarray:
        """Real-space surface influence (m/Pa) at ``time``, as :meth:`HalfSpace.surface_influence`."""
        return self.at(time).surface_influence(x, y, spacing, reference_length, entry)

    def operator(self, shape, spacing, times, sensors=None, depth: float = 1e-3, components=("zz",), loads=("p",),
                 quantity: str = "stress", periodic: bool = False):
        """The linear map from a traction history to a sensor history (``scipy.sparse.linalg.LinearOperator``).

        Model: tractions of shape ``(n_times, len(loads), *shape)`` flattened (time-major, then as
        :class:`LoadToSensor`); data: ``(n_times, len(components), n_sensors)`` flattened. Stress is
        the elastic operator at each time; strain adds the creep convolution over ``times`` (s).
        Other arguments as :meth:`HalfSpace.operator`.
        """
        from .viscoelastic_operator import HistoryOperator

        return HistoryOperator(self, shape, spacing, times, sensors=sensors, depth=depth, components=components,
                               loads=loads, quantity=quantity, periodic=periodic)



def sliding_spectrum(height, spacing, speed: float, time: float):
    """The rfft half spectrum of a periodic deflection (m) moved by ``speed * time`` along +x.

    Returns ``(h, spacing, spectrum, kx, rho)``: the checked height array and spacing (m), the shifted
    spectrum, and the half grid's ``kx`` and ``|k|`` (rad/m; ``kx`` of shape (nx//2 + 1,) or
    (1, nx//2 + 1), broadcasting with ``rho``)."""
    h = check.finite_array(height, "height", "m")
    if h.ndim not in (1, 2):
        raise ValueError(f"height: expected shape (nx,) or (ny, nx), got {h.shape}")
    speed = check.finite(speed, "speed", "m/s")
    time = check.finite(time, "time", "s")
    spacing = check.spacing(spacing, h.ndim)
    waves = angular_wavenumbers(h.shape, spacing, half=True)
    kx = waves[0]  # (nx//2 + 1,) or (1, nx//2 + 1): broadcast with eta's (ny, 1)
    rho = np.abs(kx) if h.ndim == 1 else np.hypot(kx, waves[1])
    spectrum = sfft.rfftn(h, axes=tuple(range(-h.ndim, 0)))
    if time != 0.0:  # the profile moved by speed * time along +x: exact for its trigonometric interpolant
        shift = np.exp(-1j * kx * speed * time)
        if h.shape[-1] % 2 == 0:
            shift = np.where(np.arange(kx.shape[-1]) == kx.shape[-1] - 1, np.cos(kx * speed * time), shift)
        spectrum = spectrum * shift
    return h, spacing, spectrum, kx, rho

# ------------------------------------------------------------------------------------ histories
def _amplitude(history, times: np.ndarray) -> np.ndarray:
    if history is None:
        return np.ones(len(times))
    a = check.finite_array(history, "history", "1")
    if a.shape != times.shape:
        raise ValueError(f"history: needs one amplitude per time, shape {times.shape}, got {a.shape}")
    return a


def _loads_and_history(load, times: np.ndarray, history):
    """``([load], amplitude)`` for one pattern, ``(loads, None)`` for one load per time."""
    if isinstance(load, SurfaceLoad):
        return [load], _amplitude(history, times)
    if isinstance(load, Sequence) and load and all(isinstance(one, SurfaceLoad) for one in load):
        if history is not None:
            raise ValueError("history: give it with one SurfaceLoad (a pattern to scale), not with one load per "
                             "time; fold the amplitudes into the loads")
        if len(load) != len(times):
            raise ValueError(f"load: one SurfaceLoad per time needs {len(times)} loads, got {len(load)}")
        return list(load), None
    raise ValueError(f"load: expected a SurfaceLoad or a sequence of SurfaceLoad (one per time), got "
                     f"{type(load).__name__}; build one with SurfaceLoad(p=..., spacing=...)")


def _convolve(kernel, times, fields: np.ndarray, amplitude) -> np.ndarray:
    """Hereditary integral of one pattern times a history (the history alone is convolved) or of
    one field per time (every field, recursively)."""
    if amplitude is not None:
        c = convolve(kernel, times, amplitude)
        return c.reshape((-1,) + (1,) * (fields.ndim - 1)) * fields
    return convolve(kernel, times, fields)

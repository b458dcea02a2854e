"""Viscoelastic layers: a layered skin whose layers relax (the pulp on bone is both layered and viscous).

>>> pulp = Layer(4e-3, Prony(0.2e6, [(1.0e6, 4e-3), (0.5e6, 0.07), (0.3e6, 1.4)]), nu=0.5)   # m, Pa, s
>>> skin = ViscoelasticLayeredHalfSpace([pulp], base="rigid")
>>> skin.steady_sliding(grating, spacing, speed=0.05, depth=1e-3, components=("zz",))   # a scan
>>> skin.strain(load, 1e-3, times=[0.0, 0.1, 1.0])      # a held traction (one relaxation shape)

What is supported (docs/theory.md section 7, "Viscoelastic layers"):

- **harmonic steady states, any layers**: per Fourier mode the layers answer with their complex
  moduli ``E*_j(omega)``, exact per wavenumber (:mod:`.layered_harmonic`): a rigid periodic surface
  sliding in full contact (:meth:`~ViscoelasticLayeredHalfSpace.steady_sliding`), a periodic
  traction pattern travelling over the skin (:meth:`~ViscoelasticLayeredHalfSpace.moving_load`),
  and the multipliers at any frequency (:meth:`~ViscoelasticLayeredHalfSpace.transfer`);
- **time histories under prescribed tractions** when every layer (and a half-space base) relaxes
  with one shape, ``E_j(t) = c_j E_1(t)``: the stress is the elastic stress of the layers at each
  instant, the strain the instantaneous elastic strain convolved with ``E_1(0) J_1(t)``
  (the correspondence principle). Layers that relax differently have no such separation; a time
  history on them is refused (use the harmonic steady states);
- **a traction applied at t = 0 and held**: :meth:`~ViscoelasticLayeredHalfSpace.at` gives the
  elastic layers of its stress and strain, the glassy and the relaxed layers at 0 and inf for any
  layers, and in between for one relaxation shape.
"""

from __future__ import annotations

import collections

import numpy as np
import scipy.fft as sfft

from tactilab.core import rules as check
from tactilab.data_schemas.plausibility import check_plausible_at_entry

from ..halfspace import HalfSpace, SurfaceLoad
from .hereditary import check_times
from .layered import Layer, LayeredHalfSpace, as_layers
from .layered_fields import _labelled
from .layered_harmonic import point_multipliers, sliding_multipliers
from .prony import Prony
from .propagator import Stack
from .time_field import TimeFieldResult
from .viscoelastic import ViscoelasticHalfSpace, _convolve, _loads_and_history, sliding_spectrum

#: relative tolerance within which two Prony series count as one relaxation shape
SHAPE_RTOL = 1e-12


class ViscoelasticLayeredHalfSpace:
    """Layers, top first, each elastic or viscoelastic (a :class:`Layer` whose ``E`` is a :class:`Prony`).

    Parameters
    ----------
    layers : sequence of Layer
        At least one layer; each has a constant Poisson's ratio (0.5 exact).
    base : "rigid", HalfSpace or ViscoelasticHalfSpace
        What the last layer is bonded to: bone (rigid), an elastic or a viscoelastic half-space.
    """

    def __init__(self, layers, base="rigid"):
        layers = as_layers(layers)
        if not (isinstance(base, (HalfSpace, ViscoelasticHalfSpace)) or (isinstance(base, str) and base == "rigid")):
            raise ValueError(f"base: must be 'rigid', a HalfSpace(E, nu) or a ViscoelasticHalfSpace(prony, nu), got "
                             f"{base!r}")
        self.layers, self.base = layers, base
        self._nu = np.array([layer.nu for layer in layers])
        self._thickness = np.array([layer.thickness for layer in layers])
        self.instantaneous = self._elastic("instantaneous")  #: the elastic skin of every E(0) (glassy)
        self.relaxed = self._elastic("relaxed")  #: the elastic skin of every E_inf

    def __repr__(self) -> str:
        return f"ViscoelasticLayeredHalfSpace(layers={list(self.layers)!r}, base={self.base!r})"

    def _elastic(self, limit: str) -> LayeredHalfSpace:
        base = self.base
        if isinstance(base, ViscoelasticHalfSpace):
            base = base.instantaneous if limit == "instantaneous" else base.relaxed
        return LayeredHalfSpace([layer.elastic(limit) for layer in self.layers], base=base)

    @property
    def thickness(self) -> float:
        """Total thickness of the layers, m."""
        return float(self._thickness.sum())

    # -- moduli -----------------------------------------------------------------------------------
    def _base_modulus(self, omega) -> np.ndarray:
        if isinstance(self.base, ViscoelasticHalfSpace):
            return self.base.prony.complex_modulus(omega)
        return np.full(np.shape(omega), complex(self.base.E))

    def stack_at(self, omega: float) -> Stack:
        """The layers' arrays with complex shear moduli ``G*(omega)`` (Pa) at angular frequency ``omega`` (rad/s)."""
        G = np.array([complex(layer.complex_modulus(omega)) for layer in self.layers]) / (2.0 * (1.0 + self._nu))
        base = None
        if not isinstance(self.base, str):
            nu_b = self.base.nu
            base = (complex(self._base_modulus(omega)) / (2.0 * (1.0 + nu_b)), nu_b)
        return Stack(self._thickness, G, self._nu, base)

    def _index(self, depth: float) -> int:
        self.instantaneous.material_at(depth)  # refuses a depth in the rigid base
        return self.instantaneous._stack.locate(depth)

    def complex_modulus_at(self, depth: float, omega) -> np.ndarray:
        """E*(omega) (Pa, complex) of the material at ``depth`` (m) at angular frequencies ``omega`` (rad/s)."""
        j = self._index(depth)
        if j < len(self.layers):
            return self.layers[j].complex_modulus(omega)
        return self._base_modulus(omega)

    def nu_at(self, depth: float) -> float:
        """Poisson's ratio of the material at ``depth`` (m)."""
        return self.instantaneous.material_at(depth)[1]

    # -- per-wavenumber multipliers ----------------------------------------------------------------
    def transfer(self, kx, ky, depth: float, omega=0.0, quantity: str = "stress") -> np.ndarray:
        """Exact multipliers from surface tractions to stress or strain at ``depth`` in a harmonic steady state.

        Parameters
        ----------
        kx, ky : array_like
            Angular wavenumbers, rad/m (broadcast together with ``omega``).
        depth : float
            Depth in m.
        omega : float or array_like
            Angular frequency of the steady state, rad/s (a mode sliding at V along +x: ``-kx V``);
            0 is the relaxed skin.
        quantity : {"stress", "strain"}

        Returns
        -------
        ndarray, complex, shape ``(*broadcast, 6, 3)``
            Voigt components ``(xx, yy, zz, yz, zx, xy)`` per load ``(p, qx, qy)``: Pa per Pa, or per Pa.
        """
        return self._point(kx, ky, depth, omega, quantity, per_deflection=False)

    def deflection_transfer(self, kx, ky, depth: float, omega=0.0, quantity: str = "stress") -> np.ndarray:
        """As :meth:`transfer`, per unit normal surface deflection (m) of a frictionless full contact:
        shape ``(*broadcast, 6)``, Pa/m or 1/m; the ``k = 0`` mode is 0 (an approach)."""
        return self._point(kx, ky, depth, omega, quantity, per_deflection=True)

    def _point(self, kx, ky, depth, omega, quantity, per_deflection):
        depth = check.depth(depth)
        self.instantaneous.material_at(depth)  # refuses a depth in the rigid base
        kx = check.finite_array(kx, "kx", "rad/m")
        ky = check.finite_array(ky, "ky", "rad/m")
        omega = check.finite_array(omega, "omega", "rad/s")
        _quantity(quantity)
        return point_multipliers(self, kx, ky, depth, omega, per_deflection, quantity == "strain")

    def surface_compliance(self, kx, ky=None, omega=None) -> np.ndarray:
        """Surface tractions to surface displacements per wavenumber (m/Pa), as
        :meth:`LayeredHalfSpace.surface_compliance`.

        ``omega=None`` (default): the instantaneous (glassy) elastic skin, which :func:`solve_contact`
        then sees; a frequency in rad/s: the harmonic steady state's complex compliance (not Hermitian).
        """
        if omega is None:
            return self.instantaneous.surface_compliance(kx, ky)
        omega = check.finite(omega, "omega", "rad/s")
        return _ComplexLayers(self, omega).surface_compliance(kx, ky)

    # -- steady sliding -------------------------------------------------------------------------
    def sliding_pressure(self, height, spacing, speed: float, time: float = 0.0) -> SurfaceLoad:
        """The steady zero-mean pressure (Pa) under a rigid periodic surface sliding at ``speed`` (m/s) along
        +x in full frictionless contact; arguments as :meth:`ViscoelasticHalfSpace.sliding_pressure`."""
        h, spacing, spectrum, _, rho, omega = self._sliding_spectrum(height, spacing, speed, time)
        from .layered_harmonic import deflection_gain

        gain = deflection_gain(self, rho, omega)
        if h.shape[-1] % 2 == 0:
            gain[..., -1] = gain[..., -1].real
        p = sfft.irfftn(spectrum * gain, s=h.shape, axes=tuple(range(-h.ndim, 0)))
        return SurfaceLoad(p=p, spacing=spacing, periodic=True)

    def steady_sliding(self, height, spacing, speed: float, depth, quantity: str = "stress", time: float = 0.0,
                       components=None):
        """Stress (Pa) or TENSOR strain at depth under a rigid periodic surface sliding in full contact.

        Parameters
        ----------
        height : ndarray, shape (nx,) or (ny, nx)
            One period of the deflection of the skin by the surface, m (into the skin), at time 0.
        spacing : float or (float, float)
            Grid spacing in m.
        speed : float
            Speed of the surface along +x, m/s (any sign; 0: the relaxed skin).
        depth : float or sequence of float
            Depths in m, within the layers on a rigid base.
        quantity : {"stress", "strain"}
        time : float
            Time in s (the surface has moved by ``speed * time``).
        components : sequence of str, optional
            Voigt names; default all six.

        Returns
        -------
        FieldResult
            Exact per mode (method ``"layered-harmonic"``).
        """
        h, spacing, spectrum, _, _, _ = self._sliding_spectrum(height, spacing, speed, time)
        return self._field({"p": spectrum}, h.shape, spacing, depth, components, quantity, speed, True)

    def moving_load(self, load: SurfaceLoad, speed: float, depth, quantity: str = "stress", components=None):
        """Stress (Pa) or TENSOR strain at depth under a periodic traction pattern travelling at ``speed``
        (m/s) along +x (a tractor display's travelling wave, a force-controlled sliding finger), steady.

        ``load`` is the pattern at time 0 (``SurfaceLoad(..., periodic=True)``, Pa); other arguments as
        :meth:`steady_sliding`.
        """
        if not isinstance(load, SurfaceLoad) or not load.periodic:
            raise ValueError(f"load: a moving load is one period of a periodic pattern, "
                             f"SurfaceLoad(..., periodic=True), got {load!r}")
        speed = check.finite(speed, "speed", "m/s")
        axes = tuple(range(-load.ndim, 0))
        spectra = {n: sfft.rfftn(a, axes=axes) for n, a in load.components.items()}
        return self._field(spectra, load.shape, load.spacing, depth, components, quantity, speed, False)

    def _sliding_spectrum(self, height, spacing, speed, time):
        h, spacing, spectrum, kx, rho = sliding_spectrum(height, spacing, speed, time)
        return h, spacing, spectrum, kx, rho, np.broadcast_to(-kx * float(speed), rho.shape)

    def _field(self, spectra, shape, spacing, depth, components, quantity, speed, per_deflection):
        _quantity(quantity)
        depths = check.depths(depth)
        for z in depths:
            check_plausible_at_entry(float(z), "depth", "m", stacklevel=3)  # 1.25 meant as mm warns
            self.instantaneous.material_at(float(z))
        comps = check.components(components)
        names = tuple(sorted(spectra))
        axes = tuple(range(-len(shape), 0))
        values = np.empty((len(depths), len(comps), *shape))
        for d, z in enumerate(depths):
            table = sliding_multipliers(self, shape, spacing, float(z), comps, quantity, names, speed, per_deflection)
            for o in range(len(comps)):
                acc = sum(table[n][o] * spectra[n] for n in names)
                values[d, o] = sfft.irfftn(acc, s=shape, axes=axes)
        coords = SurfaceLoad(p=np.zeros(shape), spacing=spacing, periodic=True)
        err = 30.0 * np.finfo(float).eps * np.log2(max(values[0, 0].size, 2))
        attrs = dict(method="layered-harmonic", error_estimate=err, error_covers="method", skin=repr(self),
                     speed_m_per_s=speed)
        from ..halfspace import FieldResult

        return FieldResult(lambda: _labelled(values, quantity, comps, depths, coords, None, attrs), "layered-harmonic",
                           err, f"steady state at {speed!r} m/s: exact per wavenumber at complex moduli")

    # -- time histories under prescribed tractions ----------------------------------------------
    def relaxation_shape(self) -> Prony | None:
        """The one relaxation modulus every material scales (``E_j(t) = c_j E(t)``), or None when all are elastic.

        Raises
        ------
        ValueError
            When the materials relax differently (then time and space do not separate).
        """
        moduli = [layer.E for layer in self.layers]
        if not isinstance(self.base, str):
            moduli.append(self.base.prony if isinstance(self.base, ViscoelasticHalfSpace) else self.base.E)
        if not any(isinstance(m, Prony) for m in moduli):
            return None
        first = next(m for m in moduli if isinstance(m, Prony))
        ratios = first.moduli / first.E_inf
        for n, m in enumerate(moduli):
            same = isinstance(m, Prony) and m.taus.shape == first.taus.shape and \
                np.allclose(m.taus, first.taus, rtol=SHAPE_RTOL, atol=0) and \
                np.allclose(m.moduli / m.E_inf, ratios, rtol=SHAPE_RTOL, atol=0)
            if not same:
                where = f"layers[{n}]" if n < len(self.layers) else "base"
                raise ValueError(f"{where}: a time history under prescribed tractions needs every material to "
                                 f"relax with one shape (E_j(t) = c_j E(t): the same relaxation times and the same "
                                 f"E_i / E_inf), but {m!r} differs from {first!r}; give proportional Prony series, "
                                 "or use the harmonic steady states (steady_sliding, moving_load, transfer), which "
                                 "take any layers")
        return first

    def at(self, time: float) -> LayeredHalfSpace:
        """The elastic layers that give the stress and strain of a traction applied at t = 0 and held until
        ``time`` (s).

        ``0`` is :attr:`instantaneous` and ``inf`` :attr:`relaxed`, for any layers (the response at
        t = 0+ is glassy, and a held load relaxes to the relaxed elastic state). In between the
        materials must relax with one shape ``E_j(t) = c_j E(t)`` (:meth:`relaxation_shape`): then
        the layers of moduli ``E_j(0) / (E(0) J(time))`` (J the shape's creep compliance) have the
        held load's strain, and the stress, which depends on the ratios ``c_j`` only, is unchanged.

        Raises
        ------
        ValueError
            For a negative or NaN ``time``, or a finite ``time > 0`` on materials that relax differently.
        """
        t = float(Prony._times(time, "time"))
        if t == 0.0:
            return self.instantaneous
        if t == np.inf:
            return self.relaxed
        shape = self.relaxation_shape()
        if shape is None:  # every material elastic
            return self.instantaneous
        scale = 1.0 / (shape.E_0 * float(shape.creep_compliance(t)))  # E(t)-like: 1 at t = 0, E_inf / E_0 at inf
        glassy = self.instantaneous
        layers = [Layer(layer.thickness, layer.E * scale, layer.nu) for layer in glassy.layers]
        base = glassy.base if isinstance(glassy.base, str) else HalfSpace(glassy.base.E * scale, glassy.base.nu)
        return LayeredHalfSpace(layers, base=base)

    def stress(self, load, depth, times, history=None, points=None, components=None):
        """Stress (Pa) at depth under prescribed tractions: the elastic stress of the layers at each time.

        Arguments as :meth:`ViscoelasticHalfSpace.stress`; needs one relaxation shape
        (:meth:`relaxation_shape`). Returns a :class:`TimeFieldResult`.
        """
        return self._traction_field(load, depth, times, history, points, components, "stress")

    def strain(self, load, depth, times, history=None, points=None, components=None):
        """TENSOR strain at depth under prescribed tractions: the instantaneous elastic strain convolved with
        ``E(0) J(t)`` of the shared relaxation shape; under a step, the instantaneous strain times ``J(t) / J(0)``."""
        return self._traction_field(load, depth, times, history, points, components, "strain")

    def operator(self, shape, spacing, times, sensors=None, depth: float = 1e-3, components=("zz",), loads=("p",),
                 quantity: str = "stress", periodic: bool = False):
        """The map from a traction history to a sensor history (``scipy.sparse.linalg.LinearOperator``), as
        :meth:`ViscoelasticHalfSpace.operator`: the instantaneous layers' map on every frame, then for strain
        the creep convolution of the shared relaxation shape (:meth:`relaxation_shape`)."""
        from .viscoelastic_operator import HistoryOperator

        return HistoryOperator(self, shape, spacing, times, sensors=sensors, depth=depth, components=components,
                               loads=loads, quantity=quantity, periodic=periodic)

    def _traction_field(self, load, depth, times, history, points, components, quantity):
        shape = self.relaxation_shape()
        times = check_times(times)
        loads, amplitude = _loads_and_history(load, times, history)
        solve = self.instantaneous.stress if quantity == "stress" else self.instantaneous.strain
        results = [solve(one, depth, points=points, components=components) for one in loads]
        fields = np.stack([r.data[quantity].values for r in results])
        if quantity == "strain" and shape is not None:
            fields = shape.E_0 * _convolve(shape.kernel("creep"), times, fields, amplitude)
            how = "creep convolution"
        else:
            if amplitude is not None:
                fields = fields * amplitude.reshape((-1,) + (1,) * (fields.ndim - 1))
            how = "elastic at each time"
        err = max(r.error_estimate for r in results)
        return TimeFieldResult(fields, times, quantity, f"{results[0].method} + {how}", err, results[0])


class _ComplexLayers(LayeredHalfSpace):
    """The layered skin's surface compliance with the complex moduli of one frequency (no validation of E)."""

    def __init__(self, skin: ViscoelasticLayeredHalfSpace, omega: float):
        self.layers, self.base = skin.layers, skin.base
        self._amplitude_cache = collections.OrderedDict()
        self._stack = skin.stack_at(omega)

    def __repr__(self) -> str:
        return f"_ComplexLayers({self.layers!r}, {self.base!r}, G={self._stack.G!r})"


def _quantity(quantity: str) -> str:
    if quantity not in ("stress", "strain"):
        raise ValueError(f"quantity: must be 'stress' or 'strain', got {quantity!r}")
    return quantity


__all__ = ["ViscoelasticLayeredHalfSpace"]

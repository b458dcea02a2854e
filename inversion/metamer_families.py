"""Stimulus families for tactile metameres: parametrised surface stimuli and their strain readouts.

A family maps a parameter vector (SI units, see ``param_units``) to the strain at receptor
depth; with a linear :class:`~tactilab.forward.ReceptorHypothesis` the map to the readout vector
is a matrix (``matrix``) or an operator with an exact adjoint (``operator``). Readouts are
ordered (depth, component, receptor) in C order (docs/theory.md section 4a for the plane
problem). ``receptors=None`` means the family's grid nodes, ``x_j = (j - n // 2) dx`` as
``LoadToSensor`` places them; families without a grid need receptor positions.

- :class:`SinusoidFamily`: ``H = A sin(2 pi x / p + phase)``, the frictionless indentation of a
  sliding sinusoid (params ``[A]``, m), strain of ``sliding_sinusoid_strain``.
- :class:`IndentationFamily`: periodic frictionless indentation heights at grid nodes (m).
- :class:`GridLoadFamily`: surface tractions at grid nodes (Pa), load-major ``(n_load, *shape)``.
- :class:`TractorFamily`: tangential line loads of a tractor row (N/m, +x), ``|q| <= limit``.

Periodic grid families are block-diagonal per Fourier mode: :meth:`GridLoadFamily.modes` gives
the small per-mode matrices from ``n_load`` impulse responses and one FFT (O(n log n)).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import scipy.fft as sfft
from scipy.sparse.linalg import LinearOperator, aslinearoperator

from tactilab.forward import ReceptorHypothesis, sliding_sinusoid_strain, tractor_row_strain
from tactilab.forward.halfspace import HalfSpace, LoadToSensor

VOIGT = ("xx", "yy", "zz", "yz", "zx", "xy")


def _positive(value, name: str, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number in {unit}, got {value!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise ValueError(f"{name}: must be finite and > 0 {unit}, got {value!r}")
    return v


def _check_hypothesis(hypothesis) -> ReceptorHypothesis:
    if isinstance(hypothesis, str):
        return ReceptorHypothesis.parse(hypothesis)
    if not isinstance(hypothesis, ReceptorHypothesis):
        raise ValueError(f"hypothesis: expected a ReceptorHypothesis or a string like 'xx,zx@1.25mm', "
                         f"got {type(hypothesis).__name__}")
    return hypothesis


def _x_receptors(receptors, name: str) -> np.ndarray:
    """Receptor x positions (m) of a plane (1-D) family, shape (n,)."""
    if receptors is None:
        raise ValueError(f"receptors: the {name} family has no grid; give receptor x positions in m, "
                         "e.g. np.linspace(-5e-3, 5e-3, 201)")
    r = np.asarray(receptors, dtype=float)
    if r.ndim == 2 and r.shape[1] == 1:
        r = r[:, 0]
    if r.ndim != 1 or r.size == 0 or not np.isfinite(r).all():
        raise ValueError(f"receptors: the {name} family is a plane (1-D) problem; give finite x positions of "
                         f"shape (n,) in m, got shape {np.shape(receptors)}")
    return r


def require_linear(hypothesis: ReceptorHypothesis, what: str = "matrices and operators") -> None:
    """Raise unless every readout of ``hypothesis`` is linear in strain."""
    if not hypothesis.linear:
        raise ValueError(f"hypothesis: {str(hypothesis)!r} holds nonlinear invariants, which have no matrix; "
                         f"{what} need linear components (xx, yy, zz, yz, zx, xy, volumetric)")


def _linear_readout_matrix(strain_of_unit, hypothesis: ReceptorHypothesis, n_params: int) -> np.ndarray:
    """(n_readouts, n_params) from unit-parameter strains (n_depths, n_params, n_rec, 6)."""
    require_linear(hypothesis)
    return hypothesis.readout(strain_of_unit).reshape(n_params, -1).T


def resolve_receptors(receptors, *families):
    """``receptors`` if given, else the grid nodes of the first family that has a grid."""
    if receptors is not None:
        return receptors
    for fam in families:
        r = fam.default_receptors() if hasattr(fam, "default_receptors") else None
        if r is not None:
            return r
    raise ValueError("receptors: none of the families has a grid; give receptor x positions in m, "
                     "e.g. np.linspace(-5e-3, 5e-3, 201)")


@dataclass(frozen=True)
class FamilyStimulus:
    """One stimulus of a family: ``family`` with parameters ``params`` (units: ``family.param_units``).

    Named FamilyStimulus because ``tactilab.data_schemas.Stimulus`` records a presented interval.
    """

    family: object
    params: np.ndarray

    def __post_init__(self) -> None:
        p = np.asarray(self.params, dtype=float).reshape(-1)
        if p.size != self.family.n_params:
            raise ValueError(f"params: the {self.family.name} family takes {self.family.n_params} parameters "
                             f"({', '.join(sorted(set(self.family.param_units)))}), got {p.size}")
        if not np.isfinite(p).all():
            raise ValueError("params: must be finite (no NaN or inf)")
        object.__setattr__(self, "params", p)

    def strain(self, depths, receptors=None) -> np.ndarray:
        """TENSOR Voigt strain, shape (n_depths, n_receptors, 6), at depths (m)."""
        depths = np.atleast_1d(np.asarray(depths, dtype=float))
        for d in depths:
            _positive(d, "depths", "m")
        return self.family.strain(self.params, depths, receptors)

    def readout(self, hypothesis, receptors=None) -> np.ndarray:
        """Readout vector, shape (n_readouts,), ordered (depth, component, receptor)."""
        h = _check_hypothesis(hypothesis)
        if h.linear:
            return np.asarray(self.family.operator(h, receptors).matvec(self.params))
        return h.readout(self.strain(h.depths, receptors))


@runtime_checkable
class StimulusFamily(Protocol):
    """What metamer analysis needs of a family of stimuli (attributes and methods below)."""

    name: str
    param_units: tuple[str, ...]
    n_params: int
    bounds: tuple[np.ndarray, np.ndarray] | None

    def matrix(self, hypothesis, receptors=None) -> np.ndarray: ...

    def operator(self, hypothesis, receptors=None) -> LinearOperator: ...

    def stimulus(self, params) -> FamilyStimulus: ...


class _DenseFamily:
    """Shared machinery of the small plane families (matrix first, operator from it)."""

    bounds = None
    periodic = False

    def stimulus(self, params) -> FamilyStimulus:
        """The stimulus with these parameters."""
        return FamilyStimulus(self, params)

    def operator(self, hypothesis, receptors=None) -> LinearOperator:
        """The matrix as a LinearOperator (adjoint = transpose)."""
        return aslinearoperator(self.matrix(hypothesis, receptors))

    def default_receptors(self):
        return None


class SinusoidFamily(_DenseFamily):
    """Frictionless sinusoidal indentation ``H = A sin(2 pi x / p + phase)`` (m); params ``[A]``.

    The strain is docs/theory.md 4a's sliding-sinusoid solution (``sliding_sinusoid_strain``),
    independent of E. ``pitch`` in m, ``phase`` in rad, ``nu`` Poisson's ratio.
    """

    name = "sinusoid"
    n_params = 1
    param_units = ("m",)

    def __init__(self, pitch: float, phase: float = 0.0, nu: float = 0.5):
        self.pitch = _positive(pitch, "pitch", "m")
        self.phase = float(phase)
        if not np.isfinite(self.phase):
            raise ValueError(f"phase: must be finite (rad), got {phase!r}")
        self.nu = float(nu)

    def with_phase(self, phase: float) -> SinusoidFamily:
        """The same grating at another spatial phase (rad): one frame of a travelling scan."""
        return SinusoidFamily(self.pitch, phase, self.nu)

    def strain(self, params, depths, receptors) -> np.ndarray:
        x = _x_receptors(receptors, self.name)
        shift = self.phase * self.pitch / (2 * np.pi)  # H(x + shift) = A sin(2 pi x / p + phase)
        return np.stack([sliding_sinusoid_strain(x, z, float(params[0]), self.pitch, 1.0, shift, self.nu)
                         for z in depths])

    def matrix(self, hypothesis, receptors=None) -> np.ndarray:
        """(n_readouts, 1): readouts per metre of amplitude."""
        h = _check_hypothesis(hypothesis)
        return _linear_readout_matrix(self.strain([1.0], h.depths, receptors)[:, None], h, 1)


class TractorFamily(_DenseFamily):
    """A row of tractors: tangential line loads ``q`` (N/m, +x) at ``tractor_x`` (m); ``|q| <= limit``.

    Strain from ``tractor_row_strain`` (plane strain, Flamant's tangential load; a finite
    ``footprint`` (m) spreads each load uniformly over the tractor's contact width).
    """

    name = "tractors"

    def __init__(self, tractor_x, young_modulus: float, nu: float = 0.5, footprint: float = 0.0,
                 limit: float | None = None):
        tx = np.asarray(tractor_x, dtype=float).reshape(-1)
        if tx.size == 0 or not np.isfinite(tx).all():
            raise ValueError(f"tractor_x: give finite tractor centres in m (at least one), got {tractor_x!r}")
        self.tractor_x = tx
        self.young_modulus = _positive(young_modulus, "young_modulus", "Pa")
        self.nu = float(nu)
        self.footprint = float(footprint)
        if not np.isfinite(self.footprint) or self.footprint < 0:
            raise ValueError(f"footprint: must be finite and >= 0 m, got {footprint!r}")
        self.limit = None if limit is None else _positive(limit, "limit", "N/m")
        self.n_params = tx.size
        self.param_units = ("N/m",) * tx.size
        self.bounds = None if self.limit is None else (np.full(tx.size, -self.limit), np.full(tx.size, self.limit))

    @classmethod
    def from_display(cls, description, young_modulus: float, row: int = 0) -> TractorFamily:
        """One row of a ``DisplayDescription``: footprint = tractor width, limit = traction x width (N/m)."""
        if isinstance(row, bool) or not isinstance(row, (int, np.integer)) or not 0 <= row < description.rows:
            raise ValueError(f"row: must be an integer in [0, {description.rows - 1}] for display "
                             f"{description.display_id!r}, got {row!r}")
        limit = None
        if description.max_traction_pa is not None:
            limit = description.max_traction_pa * description.tractor_width_m
        return cls(description.tractor_x_m, young_modulus, footprint=description.tractor_width_m, limit=limit)

    def strain(self, params, depths, receptors) -> np.ndarray:
        x = _x_receptors(receptors, self.name)
        return np.stack([tractor_row_strain(x, z, self.tractor_x, params, self.young_modulus, self.nu,
                                            self.footprint) for z in depths])

    def matrix(self, hypothesis, receptors=None) -> np.ndarray:
        """(n_readouts, n_tractors): readouts per N/m of each tractor's load."""
        h = _check_hypothesis(hypothesis)
        require_linear(h)
        x = _x_receptors(receptors, self.name)
        # unit load of each tractor: one kernel evaluation at every receptor-tractor offset
        offsets = (x[None, :] - self.tractor_x[:, None]).ravel()
        strain = np.stack([tractor_row_strain(offsets, z, [0.0], [1.0], self.young_modulus, self.nu, self.footprint)
                           for z in h.depths])
        return _linear_readout_matrix(strain.reshape(h.n_depths, self.n_params, x.size, 6), h, self.n_params)


class GridLoadFamily:
    """Surface tractions (Pa) at the nodes of a regular grid; params load-major ``(n_load, *shape)``.

    Parameters
    ----------
    shape : (nx,) or (ny, nx)
        Grid shape (1-D: plane strain).
    spacing : float or (dx, dy)
        Grid spacing, m.
    loads : sequence of {"p", "qx", "qy"}
        Load components (normal pressure into the skin, tangential tractions along +x, +y).
    young_modulus : float
        E, Pa (required).
    nu : float
        Poisson's ratio.
    periodic : bool
        True: the grid is one period (exact spectral operator, per-mode analysis).
    """

    name = "grid load"
    bounds = None

    def __init__(self, shape, spacing, loads=("p",), young_modulus: float | None = None, nu: float = 0.5,
                 periodic: bool = True):
        if young_modulus is None:
            raise ValueError("young_modulus: required, in Pa (skin is ~1e5-4e6 Pa), e.g. young_modulus=1.54e6")
        self.halfspace = HalfSpace(E=_positive(young_modulus, "young_modulus", "Pa"), nu=nu)
        self.young_modulus, self.nu = self.halfspace.E, self.halfspace.nu
        self.periodic = bool(periodic)
        probe = LoadToSensor(self.halfspace, shape, spacing, depth=1.0, components=("xx",), loads=loads,
                             quantity="strain", periodic=self.periodic)
        self.shape = tuple(probe.grid_shape)
        self.loads = tuple(probe.loads)
        self.spacing = spacing
        self._nodes = probe.sensor_xy  # (n_nodes, ndim), m
        self._template = probe.template
        self.n_params = len(self.loads) * int(np.prod(self.shape))
        self.param_units = ("Pa",) * self.n_params

    # ----- receptors ------------------------------------------------------------------------
    def default_receptors(self) -> np.ndarray:
        """The grid nodes, (n_nodes,) in 1-D or (n_nodes, 2) (x, y) in 2-D, m."""
        return self._nodes[:, 0].copy() if len(self.shape) == 1 else self._nodes.copy()

    def _sensors(self, receptors):
        """None (all nodes) or validated positions (n, ndim) in m."""
        if receptors is None:
            return None
        r = np.asarray(receptors, dtype=float)
        ndim = len(self.shape)
        if ndim == 1 and r.ndim == 1:
            r = r[:, None]
        if r.ndim != 2 or r.shape[1] != ndim or len(r) == 0 or not np.isfinite(r).all():
            raise ValueError(f"receptors: the {ndim}-D {self.name} family needs finite positions of shape "
                             f"(n,{' 2' if ndim == 2 else ''}) in m, got shape {np.shape(receptors)}")
        if self.periodic:
            t = self._template
            idx = [r[:, 0] / t.dx + self.shape[-1] // 2] + ([r[:, 1] / t.dy + self.shape[0] // 2] if ndim == 2 else [])
            idx = np.array(idx)
            if np.any(np.abs(idx - np.rint(idx)) > 1e-9) or np.any(idx < -1e-9) or \
                    np.any(np.rint(idx) > np.array(self.shape[::-1])[:, None] - 1):
                raise ValueError("receptors: off the grid of a periodic family (its per-mode analysis needs "
                                 "receptors at grid nodes x_j = (j - n//2) dx); give node positions or "
                                 "receptors=None for all nodes")
        return r

    def all_nodes(self, receptors) -> bool:
        """True when ``receptors`` are every grid node in grid order (the block-diagonal case)."""
        if receptors is None:
            return True
        r = self._sensors(receptors)
        return r.shape == self._nodes.shape and np.allclose(r, self._nodes, rtol=0, atol=1e-12)

    # ----- maps -----------------------------------------------------------------------------
    def _loads_to_pressure(self, params: np.ndarray) -> np.ndarray:
        return params  # GridLoadFamily: the parameters are the tractions

    def _maps(self, h: ReceptorHypothesis, receptors):
        """Per depth: (LoadToSensor over the needed Voigt components, weight rows on them)."""
        w = h.weights()  # (n_components, 6) on tensor strain
        needed = [j for j in range(6) if np.any(w[:, j])] or [0]
        sensors = self._sensors(receptors)
        ops = [LoadToSensor(self.halfspace, self.shape, self.spacing, sensors=sensors, depth=z,
                            components=[VOIGT[j] for j in needed], loads=self.loads, quantity="strain",
                            periodic=self.periodic) for z in h.depths]
        return ops, w[:, needed]

    def operator(self, hypothesis, receptors=None) -> LinearOperator:
        """Params (Pa, load-major) -> readouts, as a LinearOperator with an exact adjoint."""
        h = _check_hypothesis(hypothesis)
        require_linear(h)
        ops, w = self._maps(h, receptors)
        n_rec = ops[0].shape[0] // w.shape[1]
        pre, post = self._pre(), self._pre()

        def matmat(m):
            m = pre(np.asarray(m, dtype=float).reshape(self.n_params, -1))
            out = [np.einsum("ck,krf->crf", w, op.matmat(m).reshape(w.shape[1], n_rec, -1)) for op in ops]
            return np.concatenate(out, axis=0).reshape(-1, m.shape[1])

        def rmatmat(d):
            d = np.asarray(d, dtype=float).reshape(len(ops), w.shape[0], n_rec, -1)
            total = sum(op.rmatmat(np.einsum("ck,crf->krf", w, d[i]).reshape(-1, d.shape[-1]))
                        for i, op in enumerate(ops))
            return post(total)

        shape = (len(ops) * w.shape[0] * n_rec, self.n_params)
        return LinearOperator(shape, matvec=lambda v: matmat(v).ravel(), rmatvec=lambda v: rmatmat(v).ravel(),
                              matmat=matmat, rmatmat=rmatmat, dtype=np.float64)

    def _pre(self):
        return lambda m: m

    def matrix(self, hypothesis, receptors=None) -> np.ndarray:
        """Dense (n_readouts, n_params); for small grids (use ``operator`` or ``modes`` otherwise)."""
        op = self.operator(hypothesis, receptors)
        if op.shape[0] * op.shape[1] > 5e7:
            raise ValueError(f"matrix: {op.shape[0]} x {op.shape[1]} is too large to build densely; use "
                             "operator(...) or the per-mode analysis of a periodic family")
        return op.matmat(np.eye(self.n_params))

    def strain(self, params, depths, receptors) -> np.ndarray:
        h = ReceptorHypothesis(VOIGT, tuple(depths))
        r = self.operator(h, receptors).matvec(params)
        return r.reshape(len(depths), 6, -1).transpose(0, 2, 1)

    def stimulus(self, params) -> FamilyStimulus:
        """The stimulus with these (load-major) parameters."""
        return FamilyStimulus(self, params)

    def modes(self, hypothesis):
        """Per-mode matrices of a periodic family read at every grid node.

        Returns
        -------
        m : ndarray, complex, shape (n_modes, n_depths * n_components, n_load)
            Readout spectrum per parameter spectrum on the rfft half grid (flattened).
        weight : ndarray, shape (n_modes,)
            Real dimensions each half-grid mode stands for (2, 1, or 0 for the conjugate
            partner of a mode already counted); the weights sum to ``prod(shape)``.
        rho : ndarray, shape (n_modes,)
            Wavenumber magnitude, rad/m.
        """
        if not self.periodic:
            raise ValueError(f"modes: the {self.name} family is not periodic; per-mode analysis needs periodic=True")
        h = _check_hypothesis(hypothesis)
        n_nodes, n_load = int(np.prod(self.shape)), len(self.loads)
        probes = np.zeros((self.n_params, n_load))
        probes[np.arange(n_load) * n_nodes, np.arange(n_load)] = 1.0  # impulse at FFT index 0
        resp = self.operator(h).matmat(probes).T.reshape(n_load, -1, *self.shape)
        axes = tuple(range(2, 2 + len(self.shape)))
        spec = sfft.rfftn(resp, axes=axes)  # (n_load, n_dc, *half)
        m = np.moveaxis(spec.reshape(n_load, spec.shape[1], -1), -1, 0).transpose(0, 2, 1)
        return m, mode_weights(self.shape), mode_rho(self.shape, self._template.spacing)


class IndentationFamily(GridLoadFamily):
    """Periodic frictionless indentation: heights H (m, into the skin) at grid nodes.

    The pressure is ``P~ = E rho H~ / (2 (1 - nu^2))`` (docs/theory.md section 2); the mean height
    needs no pressure (a uniform indentation of an infinite half-space), so it is a null direction.
    """

    name = "indentation"

    def __init__(self, shape, spacing, young_modulus: float, nu: float = 0.5, periodic: bool = True):
        if not periodic:
            raise ValueError("periodic: IndentationFamily needs periodic=True (an isolated indentation is a "
                             "contact problem); use GridLoadFamily(loads=('p',), periodic=False) instead")
        super().__init__(shape, spacing, ("p",), young_modulus, nu, True)
        self.param_units = ("m",) * self.n_params
        t = self._template
        self._dtn = self.young_modulus * mode_rho(self.shape, t.spacing).reshape(
            *self.shape[:-1], self.shape[-1] // 2 + 1) / (2 * (1 - self.nu ** 2))

    def _pre(self):
        axes = tuple(range(-len(self.shape), 0))

        def dtn(m):  # heights (n, frames) -> pressures; real even multiplier: self-adjoint
            g = m.T.reshape(-1, *self.shape)
            p = sfft.irfftn(sfft.rfftn(g, axes=axes) * self._dtn, s=self.shape, axes=axes)
            return p.reshape(m.shape[1], -1).T
        return dtn


def mode_weights(shape) -> np.ndarray:
    """Real dimensions per rfft half-grid mode (flattened): 2, 1 (self-conjugate) or 0 (counted partner)."""
    nx = shape[-1]
    half = nx // 2 + 1
    self_col = np.zeros(half, bool)
    self_col[0] = True
    if nx % 2 == 0:
        self_col[-1] = True
    if len(shape) == 1:
        return np.where(self_col, 1.0, 2.0)
    ny = shape[0]
    ky = np.arange(ny)
    col_w = np.where((ky == 0) | ((ny % 2 == 0) & (ky == ny // 2)), 1.0, np.where(ky < (ny + 1) // 2, 2.0, 0.0))
    w = np.where(self_col[None, :], col_w[:, None], 2.0)
    return w.reshape(-1)


def mode_rho(shape, spacing) -> np.ndarray:
    """|k| (rad/m) of each rfft half-grid mode (flattened); spacing (dx,) or (dx, dy)."""
    kx = 2 * np.pi * sfft.rfftfreq(shape[-1], spacing[0])
    if len(shape) == 1:
        return np.abs(kx)
    ky = 2 * np.pi * sfft.fftfreq(shape[0], spacing[1])
    return np.hypot(kx[None, :], ky[:, None]).reshape(-1)

"""Grid families for tactile metameres: tractions or periodic indentations at the nodes of a grid.

Parameters are load-major ``(n_load, *shape)`` (Pa) for :class:`GridLoadFamily` and heights (m)
for :class:`IndentationFamily`; receptors default to the grid nodes ``x_j = (j - n // 2) dx`` as
``LoadToSensor`` places them. The maps use the solver's ``LoadToSensor`` (exact spectral
multipliers on a periodic grid, docs/theory.md section 2) with an exact adjoint.

Periodic grid families read at every node are block-diagonal per Fourier mode:
:meth:`GridLoadFamily.modes` gives the small per-mode matrices from ``n_load`` impulse responses
and one FFT (O(n log n)).
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft
from scipy.sparse.linalg import LinearOperator

from tactilab.forward import ReceptorHypothesis
from tactilab.forward.halfspace import HalfSpace, LoadToSensor, SurfaceLoad
from tactilab.core import rules

from .metamer_families import VOIGT, FamilyStimulus, _check_hypothesis, require_linear


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
        self.halfspace = HalfSpace(E=rules.young_modulus(young_modulus), nu=rules.poisson_ratio(nu))
        self.young_modulus, self.nu = self.halfspace.E, self.halfspace.nu
        self.periodic = bool(periodic)
        probe = LoadToSensor(self.halfspace, shape, spacing, depth=1.0, components=("xx",), loads=loads,
                             quantity="strain", periodic=self.periodic)  # validates shape, spacing, loads
        self.loads = tuple(probe.loads)
        self._template = SurfaceLoad(p=np.zeros(tuple(int(v) for v in np.atleast_1d(shape))), spacing=spacing,
                                     periodic=self.periodic)
        self.shape = tuple(self._template.shape)
        self.spacing = spacing
        t = self._template
        if t.ndim == 1:
            self._nodes = t.x[:, None]  # (n_nodes, ndim), m
        else:
            yy, xx = np.meshgrid(t.y, t.x, indexing="ij")
            self._nodes = np.column_stack([xx.ravel(), yy.ravel()])
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

"""The load-to-grid map of a layered skin at one depth, as a ``scipy.sparse.linalg.LinearOperator``.

The conventions of :class:`tactilab.forward.halfspace.LoadToSensor`: the model is load-major
(``(len(loads), *dims)`` flattened), the data component-major (``(n_comp, n_nodes)`` flattened),
sensors at every node of the grid. Periodic: the exact multipliers of :mod:`.layered_multipliers`;
isolated: the same on a grid zero-padded ``padding`` times per axis, cropped (the adjoint pads,
multiplies by the conjugate multiplier and crops), with :attr:`error_estimate` the truncation
estimate of :func:`.layered_fields.truncation_error` for a uniform unit traction of each load
over the whole grid (the load whose images weigh most against its own field).
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft
from scipy.sparse.linalg import LinearOperator

from tactilab.core import rules as check
from tactilab.forward.halfspace import LOAD_COMPONENTS, SurfaceLoad

from .layered_fields import output_weights, padded_load, periodic_outputs, truncation_error
from .layered_multipliers import output_multipliers


class LayeredOperator(LinearOperator):
    """Surface tractions (Pa) on a grid to stress (Pa) or TENSOR strain at every node at one depth.

    Parameters
    ----------
    skin : LayeredHalfSpace
    shape : (nx,) or (ny, nx)
        Load grid shape.
    spacing : float or (dx, dy)
        Grid spacing in m.
    depth : float
        Depth in m (within the layers on a rigid base).
    components : sequence of str
        Voigt components.
    loads : sequence of {"p", "qx", "qy"}
        Load components of the model.
    quantity : {"stress", "strain"}
    periodic : bool
        True: the grid is one period.
    padding : int
        Isolated grids: the padded grid per axis over the load grid (>= 2).
    """

    def __init__(self, skin, shape, spacing, depth: float = 1e-3, components=("zz",), loads=("p",),
                 quantity: str = "stress", periodic: bool = False, padding: int = 4):
        shape = tuple(int(s) for s in np.atleast_1d(shape))
        if len(shape) not in (1, 2) or min(shape) < 1:
            raise ValueError(f"shape: expected (nx,) or (ny, nx) with positive sizes, got {shape}")
        loads = (loads,) if isinstance(loads, str) else tuple(loads)
        if not loads or len(set(loads)) != len(loads) or any(n not in LOAD_COMPONENTS for n in loads):
            raise ValueError(f"loads: give distinct names from {LOAD_COMPONENTS}, got {loads!r}")
        if not isinstance(periodic, (bool, np.bool_)):
            raise ValueError(f"periodic: must be True or False, got {periodic!r}")
        if isinstance(padding, bool) or not isinstance(padding, (int, np.integer)) or padding < 2:
            raise ValueError(f"padding: must be an integer >= 2 (padded grid over load grid per axis), got {padding!r}")
        self.skin = skin
        self.dims = shape
        self.spacing = check.spacing(spacing, len(shape))
        self.depth = check.depth(depth)
        skin.material_at(self.depth)
        self.components = check.components(components)
        self.loads = loads
        self.quantity = quantity
        self.periodic = bool(periodic)
        self.padding = 1 if self.periodic else int(padding)
        self.fft_shape = tuple(self.padding * n for n in shape)
        self._where = tuple(slice(m // 2 - n // 2, m // 2 - n // 2 + n) for n, m in zip(shape, self.fft_shape))
        weights = output_weights(skin, quantity, self.components, self.depth)
        self._table = output_multipliers(skin, self.fft_shape, self.spacing, self.depth, weights, loads)
        self._axes = tuple(range(-len(shape), 0))
        self.dimsd = (len(self.components), int(np.prod(shape)))
        super().__init__(dtype=np.float64, shape=(int(np.prod(self.dimsd)), len(loads) * int(np.prod(shape))))

    @property
    def model_shape(self) -> tuple[int, ...]:
        """Shape of the load-major model array, ``(len(loads), *dims)``."""
        return (len(self.loads), *self.dims)

    @property
    def error_estimate(self) -> float:
        """Truncation error estimate of an isolated grid (0 for a periodic one), relative to the field's peak."""
        if self.periodic:
            return 0.0
        worst = 0.0
        for name in self.loads:
            load = SurfaceLoad(**{name: np.ones(self.dims)}, spacing=self.spacing)
            big, where = padded_load(load, self.padding)
            field = periodic_outputs(self.skin, big, [self.depth], self.components, self.quantity)
            peak = float(np.abs(field[(slice(None), slice(None), *where)]).max())
            worst = max(worst, truncation_error(self.skin, load, [self.depth], self.components, self.quantity,
                                                self.padding, peak))
        return worst

    def _spread(self, grid: np.ndarray) -> np.ndarray:
        if self.periodic:
            return grid
        big = np.zeros(self.fft_shape)
        big[self._where] = grid
        return big

    def _apply(self, x: np.ndarray, adjoint: bool) -> np.ndarray:
        n_in = len(self.components) if adjoint else len(self.loads)
        grids = np.asarray(x, dtype=float).reshape((n_in, *self.dims))
        spectra = [sfft.rfftn(self._spread(g), axes=self._axes) for g in grids]
        outs = []
        for o in range(len(self.loads) if adjoint else len(self.components)):
            acc = None
            for i, spec in enumerate(spectra):
                m = self._table[self.loads[o]][i] if adjoint else self._table[self.loads[i]][o]
                term = (np.conj(m) if adjoint else m) * spec
                acc = term if acc is None else acc + term
            field = sfft.irfftn(acc, s=self.fft_shape, axes=self._axes)
            outs.append(field if self.periodic else field[self._where])
        return np.concatenate([f.ravel() for f in outs])

    def _matvec(self, x: np.ndarray) -> np.ndarray:
        return self._apply(x, adjoint=False)

    def _rmatvec(self, y: np.ndarray) -> np.ndarray:
        return self._apply(y, adjoint=True)

"""The load-to-sensor map of a layered skin at one depth, as a ``scipy.sparse.linalg.LinearOperator``.

The conventions of :class:`tactilab.forward.halfspace.LoadToSensor`: the model is load-major
(``(len(loads), *dims)`` flattened), the data component-major (``(n_comp, n_sensors)`` flattened);
sensors at every node of the grid (default), at some of them, or anywhere (the exact trigonometric
interpolant, whose adjoint is the transpose of the rfft). Periodic: the exact multipliers of
:mod:`.layered_multipliers`; isolated: the same on a grid zero-padded ``padding`` times per axis,
cropped (the adjoint pads, multiplies by the conjugate multiplier and crops), with
:attr:`error_estimate` the truncation estimate of :func:`.layered_fields.truncation_error` for a
uniform unit traction of each load over the whole grid (the load whose images weigh most against
its own field).
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft
from scipy.sparse.linalg import LinearOperator

from tactilab.core import rules as check
from tactilab.forward.halfspace import LOAD_COMPONENTS, SurfaceLoad

from .layered_fields import (check_points, evaluate_at_points, output_weights, padded_load, periodic_outputs,
                             point_phases, rfft_transpose, truncation_error)
from .layered_multipliers import output_multipliers


class LayeredOperator(LinearOperator):
    """Surface tractions (Pa) on a grid to stress (Pa) or TENSOR strain at sensors at one depth.

    Parameters
    ----------
    skin : LayeredHalfSpace
    shape : (nx,) or (ny, nx)
        Load grid shape.
    spacing : float or (dx, dy)
        Grid spacing in m.
    sensors : ndarray, shape (n, 2) or (n,), optional
        Sensor (x, y) positions in m (x only in 1-D); default every grid node (in node order). On
        nodes they are read from the inverse FFT; off the nodes the exact trigonometric interpolant is
        summed at them (cost sensors x modes per output). An isolated grid's sensors lie within it.
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

    def __init__(self, skin, shape, spacing, sensors=None, depth: float = 1e-3, components=("zz",), loads=("p",),
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
        self._select, self._phases = None, None
        if sensors is None:
            n_sensors = int(np.prod(shape))
        else:
            template = SurfaceLoad(p=np.zeros(shape), spacing=self.spacing, periodic=self.periodic)
            pts, index = check_points(sensors, template)
            n_sensors = len(pts)
            if index is not None:
                self._select = index
            else:  # node coordinates of the (padded) periodic grid: the load grid's own
                self._phases = point_phases(self.fft_shape, self.spacing, pts)
        self.dimsd = (len(self.components), n_sensors)
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

    def _read(self, spectrum: np.ndarray) -> np.ndarray:
        """Output spectrum (padded grid) -> values at the sensors."""
        if self._phases is not None:
            return evaluate_at_points(spectrum, self._phases, self.fft_shape)
        field = sfft.irfftn(spectrum, s=self.fft_shape, axes=self._axes)
        field = field if self.periodic else field[self._where]
        return field.ravel() if self._select is None else field[self._select]

    def _read_adjoint(self, values: np.ndarray) -> np.ndarray:
        """The transpose of :meth:`_read` as a (half) spectrum to be multiplied by the multiplier: for grid
        sensors the rfft of the values placed on the grid (with :meth:`_spread_adjoint` it makes the exact
        adjoint with the conjugate multiplier); for off-grid sensors the phases summed over the sensors."""
        if self._phases is not None:
            ex, ey = self._phases
            return (ex @ values) if ey is None else (ey * values) @ ex.T
        grid = np.zeros(self.dims)
        if self._select is None:
            grid = values.reshape(self.dims)
        else:
            np.add.at(grid, self._select, values)
        return sfft.rfftn(self._spread(grid), axes=self._axes)

    def _apply(self, x: np.ndarray) -> np.ndarray:
        grids = np.asarray(x, dtype=float).reshape((len(self.loads), *self.dims))
        spectra = [sfft.rfftn(self._spread(g), axes=self._axes) for g in grids]
        outs = []
        for o in range(len(self.components)):
            acc = self._table[self.loads[0]][o] * spectra[0]
            for i in range(1, len(self.loads)):
                acc += self._table[self.loads[i]][o] * spectra[i]
            outs.append(self._read(acc))
        return np.concatenate(outs)

    def _apply_adjoint(self, y: np.ndarray) -> np.ndarray:
        values = np.asarray(y, dtype=float).reshape(self.dimsd)
        sums = [self._read_adjoint(v) for v in values]
        outs = []
        for name in self.loads:
            if self._phases is None:  # the grid path: irfft of the conjugate multiplier times the rfft
                acc = sum(np.conj(self._table[name][o]) * sums[o] for o in range(len(self.components)))
                field = sfft.irfftn(acc, s=self.fft_shape, axes=self._axes)
            else:  # off-grid sensors: the transpose of the rfft, Re(sum over half k of v_k exp(-i k x_j))
                acc = sum(self._table[name][o] * sums[o] for o in range(len(self.components)))
                field = rfft_transpose(acc, self.fft_shape)
            outs.append(field if self.periodic else field[self._where])
        return np.concatenate([f.ravel() for f in outs])

    def _matvec(self, x: np.ndarray) -> np.ndarray:
        return self._apply(x)

    def _rmatvec(self, y: np.ndarray) -> np.ndarray:
        return self._apply_adjoint(y)

"""Sensor readout of solved tractions: one matrix product per batch of frames.

A sensor array at depth reads the half-space field of the tractions on the skin. The map from
the nodal tractions (p, qx[, qy]) of a grid to the sensors' outputs is linear and does not change
from frame to frame (the sensors move with the finger, and so does the grid), so it is built once
as a weight matrix ``W`` (:class:`tactilab.forward.halfspace.LoadToSensor`: the periodic Green's
function for a periodic cell, the Boussinesq-Cerruti point kernels for an isolated contact; for a
layered skin its own load-to-sensor operator, :class:`tactilab.forward.skin.LayeredHalfSpace`) and
every frame is ``outputs = tractions @ W``: no per-frame FFT. The matrix covers a window of the
grid (the nodes a contact can reach), which keeps it small for a fingertip on a wide grid.

Conventions (docs/theory.md section 1): tractions act on the skin, in Pa; sensor positions are in
the finger frame, in m, with the grid's node ``j`` at ``x_j = (j - nx // 2) dx``; outputs in Pa
(stress) or tensor strain.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence

import numpy as np

from tactilab.core import rules as check
from tactilab.data_schemas.sensors import SensorArray

from .halfspace import COMPONENTS, AccuracyWarning, HalfSpace, LoadToSensor, output_weights, point_geometry, point_unit

#: the most weight values a readout may hold (2 GiB of float64)
MAX_WEIGHT_VALUES = 2**28
#: the largest zero padding (per axis) of a layered skin's isolated readout grid
MAX_LAYERED_PADDING = 16
#: below this fraction of loaded nodes the product is sparse
SPARSE_BELOW = 0.3


class SensorReadout:
    """Sensor arrays reading the tractions of a grid, as a weight matrix over a window of it.

    Parameters
    ----------
    skin : HalfSpace or LayeredHalfSpace
        E in Pa and nu; or a layered skin, read through its transfer (:meth:`LayeredHalfSpace.operator`,
        exact per wavenumber; an isolated window on its zero-padded grid, widened to hold the sensors).
    shape : (nx,) or (ny, nx)
        The traction grid (1-D: plane strain, sensors read at their x).
    spacing : float or (dx, dy)
        Grid spacing in m, x first.
    sensors : SensorArray or sequence of SensorArray
        Arrays in the finger frame (each at its own depth).
    periodic : bool
        True: the grid is one period (the periodic Green's function; the window is the grid).
    window : tuple of slice, optional
        The nodes the tractions may occupy (``(cols,)`` or ``(rows, cols)``); default the whole
        grid. Tractions outside it are refused by :meth:`read`.
    loads : sequence of {"p", "qx", "qy"}
        The traction components read.
    sliding : (float, (float, float)), optional
        ``(mu, (dx, dy))``: every frame slides fully, ``q = mu p`` along ``(dx, dy)``; the tangential
        blocks of the weights are folded into the normal one (``W_p + mu dx W_qx + mu dy W_qy``), so a
        frame is read from its pressure alone (one third of the products and of the memory).
    tol : float
        A layered skin's isolated window: the truncation estimate its padded grid must meet
        (:attr:`tactilab.forward.skin.LayeredOperator.error_estimate`, relative to the field of a uniform
        traction over the grid: a bound; the error of a finger contact's field was found 10 to 20 times
        smaller, about 3e-4 at the default).

    Attributes
    ----------
    weights : ndarray, shape (len(loads) * n_window_nodes, n_outputs)
        Load-major rows (all window nodes of ``loads[0]``, C order, then the next); outputs are the
        arrays' ``n_sensors * n_components`` values one array after the other. With ``sliding``:
        shape (n_window_nodes, n_outputs), rows of the pressure (``loads`` is then ``("p",)``).
    error_estimate : float
        A layered skin's truncation estimate (the largest over the arrays; 0 on a half-space).
    """

    def __init__(self, skin, shape, spacing, sensors, *, periodic: bool = False, window=None,
                 loads: Sequence[str] = ("p", "qx"), sliding=None, tol: float = 1e-2):
        self.arrays = (sensors,) if isinstance(sensors, SensorArray) else tuple(sensors)
        if not self.arrays or not all(isinstance(s, SensorArray) for s in self.arrays):
            raise ValueError(f"sensors: expected a data_schemas SensorArray or a non-empty sequence of them, got "
                             f"{type(sensors).__name__}; build one with SensorArray.grid(...)")
        self.shape = tuple(int(n) for n in shape)
        self.tol = check.positive(tol, "tol", "", "e.g. 1e-3")
        self.error_estimate = 0.0
        self.spacing = check.spacing(spacing, len(self.shape))
        self.periodic = bool(periodic)
        self.loads = tuple(loads)
        full = tuple(slice(0, n) for n in self.shape)
        self.window = full if (window is None or periodic) else tuple(window)
        if len(self.window) != len(self.shape) or any(
                not isinstance(w, slice) or w.step not in (None, 1) or not 0 <= (w.start or 0) < (w.stop or 0) <= n
                for w, n in zip(self.window, self.shape)):
            raise ValueError(f"window: expected {len(self.shape)} slices start:stop inside the grid {self.shape} "
                             f"(rows first), got {window!r}; or None for the whole grid")
        win_shape = tuple(s.stop - s.start for s in self.window)
        n_out = sum(a.n_sensors * a.n_components for a in self.arrays)
        if len(self.loads) * math.prod(win_shape) * n_out > MAX_WEIGHT_VALUES:
            raise ValueError(
                f"sensors: {n_out} outputs over a window of {win_shape} nodes and {len(self.loads)} loads need "
                f"{len(self.loads) * math.prod(win_shape) * n_out * 8 / 2**30:.3g} GiB of weights, above the limit "
                f"{MAX_WEIGHT_VALUES * 8 / 2**30:.3g} GiB; use fewer sensors or components, or a coarser grid")
        # the window's own centre node sits at (start + n_win // 2 - n // 2) nodes from the grid's
        offset = [(s.start + (s.stop - s.start) // 2 - n // 2) * h
                  for s, n, h in zip(self.window[::-1], self.shape[::-1], self.spacing)]
        coef = {name: 1.0 for name in self.loads}
        self.sliding = None
        if sliding is not None:  # q = mu p along (dx, dy): one block, its rows sum the loads' (zero ones skipped)
            mu, (dx, dy) = float(sliding[0]), (float(v) for v in sliding[1])
            coef = {name: c for name, c in {"p": 1.0, "qx": mu * dx, "qy": mu * dy}.items()
                    if name in self.loads and c != 0}
            self.sliding = (mu, (dx, dy))
        blocks = []
        for arr in self.arrays:
            pts = np.asarray(arr.positions_m, dtype=float)[:, :len(self.shape)] - np.array(offset)
            layered = not isinstance(skin, HalfSpace)
            if self.periodic or len(win_shape) == 1 or layered:  # periodic / line kernels; a layered skin's transfer
                grid, crop = win_shape, (slice(None),) * len(win_shape)
                if layered and not self.periodic:  # its operator's sensors lie within its grid: widen the window
                    grid, crop = _widened(win_shape, self.spacing, pts)
                kwargs = dict(sensors=pts, depth=arr.depth_m, components=arr.components, loads=tuple(coef),
                              quantity=arr.quantity, periodic=self.periodic)
                op = self._layered_operator(skin, grid, kwargs) if layered else \
                    LoadToSensor(skin, grid, self.spacing, **kwargs)
                # rows of the operator are (component, sensor); order them (sensor, component) as recordings are
                w = op.rmatmat(np.eye(op.shape[0])).reshape(len(coef), *grid, arr.n_components * arr.n_sensors)
                w = w[(slice(None), *crop)]
                w = w.reshape(len(coef), -1, arr.n_components, arr.n_sensors).transpose(0, 1, 3, 2)
                w = w.reshape(len(coef), -1, arr.n_sensors * arr.n_components)
                if self.sliding is not None:
                    w = sum(c * w[k] for k, c in enumerate(coef.values()))[None]
            else:
                w = self._point_weights(skin, win_shape, offset, pts, arr, coef)
            blocks.append(w.reshape(-1, arr.n_sensors * arr.n_components))
        if self.sliding is not None:
            self.loads = ("p",)
        self.weights = np.ascontiguousarray(np.concatenate(blocks, axis=1))
        self.n_outputs = n_out

    def _layered_operator(self, skin, grid, kwargs: dict):
        """A layered skin's load-to-sensor operator on ``grid``: an isolated grid zero-padded 4, 8 or 16 times
        per axis, the first whose truncation estimate meets :attr:`tol` (a warning when none does)."""
        padding = 1 if self.periodic else 4
        while True:
            op = skin.operator(grid, self.spacing, padding=max(padding, 2), **kwargs)
            estimate = op.error_estimate
            if estimate <= self.tol or padding == 1 or padding >= MAX_LAYERED_PADDING:
                break
            padding *= 2
        if estimate > self.tol:
            warnings.warn(f"tol: the layered skin's readout on a grid padded {padding}x per axis keeps an estimated "
                          f"truncation error {estimate:.1e} above tol={self.tol:g}; widen the window or loosen tol",
                          AccuracyWarning, stacklevel=3)
        self.error_estimate = max(self.error_estimate, estimate)
        return op

    def _point_weights(self, skin, win_shape, offset, pts, arr, coef: dict) -> np.ndarray:
        """Point-load weights of an isolated window, shape (n_blocks, n_nodes, n_sensors, n_components):
        the Boussinesq (p) and Cerruti (qx, qy) stress per unit force at each sensor, times the cell
        area, through Hooke's law for strain (the kernel the finger's node weights use). One block per
        load, or one block of the loads summed with ``coef`` when the readout is sliding."""
        cell = math.prod(self.spacing)
        axes = [(np.arange(n) - n // 2) * h for n, h in zip(win_shape[::-1], self.spacing)]  # x, then y
        X, Y = np.meshgrid(axes[0], axes[1])
        dx = pts[None, :, 0] - X.reshape(-1, 1)
        dy = pts[None, :, 1] - Y.reshape(-1, 1)
        # the sensors' positions and depth were checked by SensorArray: the unchecked kernels, geometry once
        geometry = point_geometry(dx, dy, np.full_like(dx, float(arr.depth_m)))
        rows = output_weights(arr.quantity, arr.components, skin.E, skin.nu)  # (n_components, 6)
        used = [v for v in range(len(COMPONENTS)) if np.any(rows[:, v])]
        direction = {"p": "z", "qx": "x", "qy": "y"}
        groups = [coef] if self.sliding is not None else [{name: 1.0} for name in coef]
        out = np.empty((len(groups), dx.shape[0], arr.n_sensors, arr.n_components))
        for k, group in enumerate(groups):
            green = np.stack([sum(c * point_unit(COMPONENTS[v], direction[name], *geometry, skin.nu)
                                  for name, c in group.items()) for v in used])
            out[k] = np.einsum("vns,ov->nso", green, rows[:, used] * cell, optimize=True)
        return out

    def stack(self, pressure, qx=None, qy=None) -> np.ndarray:
        """The window's tractions of a batch of frames as model rows.

        Parameters
        ----------
        pressure, qx, qy : ndarray, shape (n_frames, *shape), Pa
            Tractions on the skin (``qx``, ``qy`` may be None: zero; ignored with ``sliding``).

        Returns
        -------
        ndarray, shape (n_frames, len(loads) * n_window_nodes)
        """
        p = np.asarray(pressure, dtype=float)
        parts = {"p": p, "qx": qx, "qy": qy}
        rows = []
        sl = (slice(None),) + self.window
        for name in self.loads:
            value = parts[name]
            if value is None:
                rows.append(np.zeros((p.shape[0], math.prod(p[sl].shape[1:]))))
                continue
            value = np.asarray(value, dtype=float)
            inside = value[sl]
            if not self.periodic and np.count_nonzero(value) != np.count_nonzero(inside):
                raise ValueError(f"{name}: tractions lie outside the readout's window {self.window} of the grid "
                                 f"{self.shape}; build the SensorReadout with a larger window (or None: the grid)")
            rows.append(inside.reshape(p.shape[0], -1))
        return np.concatenate(rows, axis=1)

    def apply(self, rows: np.ndarray) -> np.ndarray:
        """``rows @ weights`` for stacked frames (:meth:`stack`), through a sparse product when few
        nodes carry load (a rough contact touches a fraction of its window)."""
        if rows.size and np.count_nonzero(rows) < SPARSE_BELOW * rows.size:
            from scipy import sparse

            return np.asarray(sparse.csr_matrix(rows) @ self.weights)
        return rows @ self.weights

    def read(self, pressure, qx=None, qy=None) -> list[np.ndarray]:
        """Sensor outputs of a batch of frames: one matrix product.

        Parameters
        ----------
        pressure, qx, qy : ndarray, shape (n_frames, *shape), Pa

        Returns
        -------
        list of ndarray, one per sensor array, shape (n_frames, n_sensors, n_components):
            Pa (stress) or tensor strain.
        """
        return self.split(self.apply(self.stack(pressure, qx, qy)))

    def split(self, outputs: np.ndarray) -> list[np.ndarray]:
        """Outputs of shape (n_frames, n_outputs) cut into one (n_frames, n_sensors, n_components) per array."""
        out, start = [], 0
        for arr in self.arrays:
            n = arr.n_sensors * arr.n_components
            out.append(outputs[:, start:start + n].reshape(-1, arr.n_sensors, arr.n_components))
            start += n
        return out


def _widened(win_shape, spacing, pts: np.ndarray) -> tuple[tuple[int, ...], tuple[slice, ...]]:
    """A grid with the window's centre node that also holds the sensors (a layered operator's sensors
    lie within its isolated grid), and where the window sits in it (rows first)."""
    grid, crop = [], []
    for axis, n in enumerate(win_shape[::-1]):  # x, then y
        reach = int(math.ceil(float(np.abs(pts[:, axis]).max()) / spacing[axis])) + 1
        m = max(n, 2 * reach + 1)
        grid.append(m)
        crop.append(slice(m // 2 - n // 2, m // 2 - n // 2 + n))
    return tuple(grid[::-1]), tuple(crop[::-1])

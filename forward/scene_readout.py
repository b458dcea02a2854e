"""Sensor readout of solved tractions: one matrix product per batch of frames.

A sensor array at depth reads the half-space field of the tractions on the skin. The map from
the nodal tractions (p, qx[, qy]) of a grid to the sensors' outputs is linear and does not change
from frame to frame (the sensors move with the finger, and so does the grid), so it is built once
as a weight matrix ``W`` (:class:`tactilab.forward.halfspace.LoadToSensor`: the periodic Green's
function for a periodic cell, the Boussinesq-Cerruti point kernels for an isolated contact) and
every frame is ``outputs = tractions @ W``: no per-frame FFT. The matrix covers a window of the
grid (the nodes a contact can reach), which keeps it small for a fingertip on a wide grid.

Conventions (docs/theory.md section 1): tractions act on the skin, in Pa; sensor positions are in
the finger frame, in m, with the grid's node ``j`` at ``x_j = (j - nx // 2) dx``; outputs in Pa
(stress) or tensor strain.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from tactilab.core import rules as check
from tactilab.data_schemas.sensors import SensorArray

from .halfspace import LoadToSensor

#: the most weight values a readout may hold (2 GiB of float64)
MAX_WEIGHT_VALUES = 2**28


class SensorReadout:
    """Sensor arrays reading the tractions of a grid, as a weight matrix over a window of it.

    Parameters
    ----------
    skin : HalfSpace
        E in Pa and nu.
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

    Attributes
    ----------
    weights : ndarray, shape (len(loads) * n_window_nodes, n_outputs)
        Load-major rows (all window nodes of ``loads[0]``, C order, then the next); outputs are the
        arrays' ``n_sensors * n_components`` values one array after the other.
    """

    def __init__(self, skin, shape, spacing, sensors, *, periodic: bool = False, window=None,
                 loads: Sequence[str] = ("p", "qx")):
        self.arrays = (sensors,) if isinstance(sensors, SensorArray) else tuple(sensors)
        if not self.arrays or not all(isinstance(s, SensorArray) for s in self.arrays):
            raise ValueError(f"sensors: expected a data_schemas SensorArray or a non-empty sequence of them, got "
                             f"{type(sensors).__name__}; build one with SensorArray.grid(...)")
        self.shape = tuple(int(n) for n in shape)
        self.spacing = check.spacing(spacing, len(self.shape))
        self.periodic = bool(periodic)
        self.loads = tuple(loads)
        full = tuple(slice(0, n) for n in self.shape)
        self.window = full if (window is None or periodic) else tuple(window)
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
        blocks = []
        for arr in self.arrays:
            pts = np.asarray(arr.positions_m, dtype=float)[:, :len(self.shape)] - np.array(offset)
            op = LoadToSensor(skin, win_shape, self.spacing, sensors=pts, depth=arr.depth_m,
                              components=arr.components, loads=self.loads, quantity=arr.quantity,
                              periodic=self.periodic)
            # rows of the operator are (component, sensor); order them (sensor, component) as recordings are
            w = op.rmatmat(np.eye(op.shape[0]))
            w = w.reshape(-1, arr.n_components, arr.n_sensors).transpose(0, 2, 1).reshape(w.shape[0], -1)
            blocks.append(w)
        self.weights = np.ascontiguousarray(np.concatenate(blocks, axis=1))
        self.n_outputs = n_out

    def stack(self, pressure, qx=None, qy=None) -> np.ndarray:
        """The window's tractions of a batch of frames as model rows.

        Parameters
        ----------
        pressure, qx, qy : ndarray, shape (n_frames, *shape), Pa
            Tractions on the skin (``qx``, ``qy`` may be None: zero).

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
        return self.split(self.stack(pressure, qx, qy) @ self.weights)

    def split(self, outputs: np.ndarray) -> list[np.ndarray]:
        """Outputs of shape (n_frames, n_outputs) cut into one (n_frames, n_sensors, n_components) per array."""
        out, start = [], 0
        for arr in self.arrays:
            n = arr.n_sensors * arr.n_components
            out.append(outputs[:, start:start + n].reshape(-1, arr.n_sensors, arr.n_components))
            start += n
        return out

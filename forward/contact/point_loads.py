"""A few point loads' displacements summed directly from float32 influence coefficients, compiled or in NumPy.

The contact solver (:mod:`.preconditioned`) brings the few nodes a step clipped back to zero
pressure and adds their displacement ``u += sum_k v_k G(x - x_k)``. By direct summation of the
float64 coefficients (:meth:`ContactCompliance.add_normal_point_loads`: a scaled window of the
kernel per node) a node cost about 0.07 FFT floors at 256^2 to 1024^2, whatever the loop (the
kernel's window is read from memory once per node: the sum is memory-bound). Here the kernel is
kept in float32, half the bytes to read, and the nodes are added row by row by a compiled loop
(a row of ``u`` stays in the L1 cache while each node's kernel row streams past it). Its error is
the coefficients' rounding, at most ``2^-24 max|G| sum(v)`` (:meth:`PointLoads.bound`), which the
solver adds to the drift bound of its other float32 steps.

Periodic grids keep the kernel on one period (``(ny, nx)``, read with wrap-around), isolated ones
on the offsets ``-n .. n - 1`` per axis (``(2 ny, 2 nx)``, node ``j``'s window ``[n - j, 2 n - j)``).
The NumPy twin adds the same products in the same order of nodes: bitwise the same sums
(tests/test_contact_single_correction.py).
"""

from __future__ import annotations

import numpy as np
from scipy import fft as sfft

from tactilab.core import jit

#: the coefficients' rounding to float32, relative to max |G| (2^-24, doubled for the sums' float64 rounding)
RELATIVE_ERROR = 2.0**-23


class PointLoads:
    """Direct summation of point loads on a 2-D grid from the float32 normal influence coefficients.

    Parameters
    ----------
    compliance : ContactCompliance
        A 2-D grid's operator; its ``spectrum("uz", "p")`` gives the coefficients (m/Pa).
    """

    def __init__(self, compliance):
        self.shape, self.periodic = tuple(compliance.shape), bool(compliance.periodic)
        axes = (-2, -1)
        g = sfft.irfftn(compliance.spectrum("uz", "p"), s=compliance.fft_shape, axes=axes, workers=1)
        if not self.periodic:  # offsets beyond the grid wrap in the padding: centre them
            g = np.roll(g, self.shape, axis=axes)
        self.kernel = np.ascontiguousarray(g, dtype=np.float32)
        self._peak = float(np.abs(self.kernel).max())

    def bound(self, values: np.ndarray) -> float:
        """A bound on max |error| of :meth:`add` (m) for the loads ``values`` (Pa)."""
        return RELATIVE_ERROR * self._peak * float(np.abs(values).sum())

    def add(self, u: np.ndarray, nodes: np.ndarray, values: np.ndarray) -> None:
        """``u += sum_k values[k] G(x - x_nodes[k])`` in place (``u``: m, float64, the grid's shape,
        C-contiguous; ``nodes``: flat grid indices; ``values``: Pa)."""
        rows, cols = np.divmod(np.asarray(nodes, dtype=np.int64), self.shape[1])
        values = np.asarray(values, dtype=float)
        if jit.enabled():
            (_add_periodic if self.periodic else _add_isolated)(u, self.kernel, rows, cols, values)
            return
        ny, nx = self.shape
        for r, c, v in zip(rows, cols, values):
            window = np.roll(self.kernel, (r, c), axis=(0, 1)) if self.periodic else \
                self.kernel[ny - r:2 * ny - r, nx - c:2 * nx - c]
            u += np.float64(v) * window


# the loops index slices from 0 (a computed index such as ``start + j`` could be negative to the compiler,
# whose wrap-around check then keeps the loop out of SIMD lanes)
@jit.njit
def _add_periodic(u, kernel, rows, cols, values):  # pragma: no cover - compiled; its twin is PointLoads.add's loop
    ny, nx = u.shape
    for i in range(ny):
        out = u[i]
        for k in range(values.size):
            row = kernel[(i - rows[k]) % ny]
            c, v = cols[k], values[k]
            wrapped = row[nx - c:]  # offsets j - c < 0 wrap to the period's end
            for j in range(c):
                out[j] += v * np.float64(wrapped[j])
            ahead = out[c:]
            for j in range(nx - c):
                ahead[j] += v * np.float64(row[j])


@jit.njit
def _add_isolated(u, kernel, rows, cols, values):  # pragma: no cover - compiled; its twin is PointLoads.add's loop
    ny, nx = u.shape
    for i in range(ny):
        out = u[i]
        for k in range(values.size):
            window = kernel[ny - rows[k] + i][nx - cols[k]:]
            v = values[k]
            for j in range(nx):
                out[j] += v * np.float64(window[j])

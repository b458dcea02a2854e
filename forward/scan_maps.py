"""Full stress/strain maps at the sensor depth for every frame of a scan (batched DC-FFT).

The finger's grid of N x N nodes (spacing h) carries the modulated interfacial tractions
(:mod:`.scanning`). The field at depth Z on the same nodes is the aperiodic convolution with
the point-load kernel sampled at the node offsets (DC-FFT, docs/theory.md section 5), computed
by the solver's one DC-FFT engine (:func:`~tactilab.forward.halfspace.dcfft_kernel_spectrum`,
:func:`~tactilab.forward.halfspace.dcfft_convolve`): the kernel spectra are computed ONCE;
each batch of frames costs one forward and one inverse real FFT per load direction and
output on the padded grid. The result is exact for the sampled load (it equals the direct sum
over nodes to rounding), and its cost does not depend on how many sensors read the maps.
"""

from __future__ import annotations

import numpy as np

from .finger import BiomimeticFinger
from .halfspace import dcfft_convolve, dcfft_correlate, dcfft_kernel_spectrum, output_weights
from .surfaces import Surface


class ScanMaps:
    """Batched DC-FFT maps of the finger's sensor quantity (stress in Pa or tensor strain).

    Parameters
    ----------
    finger : BiomimeticFinger
        Contact, friction, sensors (depth, quantity, components: the maps' components).
    """

    def __init__(self, finger: BiomimeticFinger):
        if not isinstance(finger, BiomimeticFinger):
            raise ValueError(f"finger: expected a BiomimeticFinger, got {type(finger).__name__}")
        self.finger = finger
        x, y = finger.grid()
        self.x, self.y = x, y
        h = finger.spacing
        self.n = x.size
        X, Y = np.meshgrid(x, y)
        p, q = finger.traction(X, Y, cell=(h, h))
        self.tractions = np.stack([p, q])  # (2, ny, nx): p (into the skin) and qx, Pa, before modulation
        W = output_weights(finger.sensors.quantity, finger.sensors.components,
                           finger.contact.young_modulus, finger.contact.poisson_ratio)
        # computed once: (n_comp, 2 directions, padded spectrum)
        self.kernel = dcfft_kernel_spectrum((self.n, self.n), (h, h), finger.depth, finger.contact.poisson_ratio,
                                            W, ("z", "x"))

    def maps(self, surface: Surface, positions, *, y_offset: float = 0.0, reference_height_m: float = 1.0,
             batch: int = 16) -> np.ndarray:
        """Field maps for each frame, shape (n_frames, n_components, ny, nx), on the finger grid."""
        u = np.atleast_1d(np.asarray(positions, dtype=float))
        if u.ndim != 1 or not np.all(np.isfinite(u)):
            raise ValueError(f"positions: need a finite 1-D array of finger positions in m, got shape {u.shape}")
        if int(batch) < 1:
            raise ValueError(f"batch: frames per FFT must be >= 1, got {batch!r}")
        X, Y = np.meshgrid(self.x, self.y)
        n = self.n
        out = np.empty((u.size, self.kernel.shape[0], n, n))
        for i0 in range(0, u.size, int(batch)):
            uu = u[i0:i0 + int(batch), None, None]
            mod = surface.modulation(X + uu, Y + y_offset, reference_height=reference_height_m)
            out[i0:i0 + uu.shape[0]] = dcfft_convolve(self.kernel, mod[:, None] * self.tractions)
        return out

    def apply(self, modulation: np.ndarray) -> np.ndarray:
        """Maps (n_components, ny, nx) for one modulation field (ny, nx) on the finger grid."""
        return dcfft_convolve(self.kernel, modulation * self.tractions)

    def adjoint(self, maps: np.ndarray) -> np.ndarray:
        """Adjoint of :meth:`apply`: (n_components, ny, nx) -> (ny, nx) (correlation with the kernels)."""
        return np.sum(self.tractions * dcfft_correlate(self.kernel, maps), axis=0)

    def operator(self):
        """:meth:`apply` as a ``scipy.sparse.linalg.LinearOperator`` (flattened), with its adjoint."""
        from scipy.sparse.linalg import LinearOperator

        n, nc = self.n, self.kernel.shape[0]
        return LinearOperator(shape=(nc * n * n, n * n), dtype=float,
                              matvec=lambda m: self.apply(np.reshape(m, (n, n))).ravel(),
                              rmatvec=lambda y: self.adjoint(np.reshape(y, (nc, n, n))).ravel())

    def sensor_values(self, maps: np.ndarray) -> np.ndarray:
        """Bilinear read-out of maps at the sensor positions: (n_frames, n_sensors, n_components)."""
        from scipy.ndimage import map_coordinates

        pos = self.finger.sensors.positions_m
        h = self.finger.spacing
        col = (pos[:, 0] - self.x[0]) / h
        row = (pos[:, 1] - self.y[0]) / h
        if col.min() < 0 or row.min() < 0 or col.max() > self.n - 1 or row.max() > self.n - 1:
            raise ValueError("sensors: some sensors lie outside the contact grid the maps cover "
                             f"(|x|, |y| <= {self.x[-1]:.4g} m); use the matrix scan (scan_outputs) for them")
        nt, nc = maps.shape[:2]
        out = np.empty((nt, pos.shape[0], nc))
        for t in range(nt):
            for c in range(nc):
                out[t, :, c] = map_coordinates(maps[t, c], [row, col], order=1)
        return out

"""Full stress/strain maps at the sensor depth for every frame of a scan (batched DC-FFT).

The finger's grid of N x N nodes (spacing h) carries the modulated interfacial tractions
(:mod:`.scanning`). The field at depth Z on the same nodes is the aperiodic convolution with
the point-load kernel sampled at the node offsets (DC-FFT, docs/theory.md section 5): the kernel is
sampled on a (2N) x (2N) circular grid and transformed ONCE; each batch of frames costs one
forward and one inverse real FFT of shape (batch, 2N, 2N). The result is exact for the sampled
load (it equals the direct sum over nodes to rounding), and its cost does not depend on how
many sensors read the maps.
"""

from __future__ import annotations

import numpy as np

from .halfspace import output_weights
from .finger import BiomimeticFinger
from .halfspace import COMPONENTS, point_green
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
        n = x.size
        self.n, self.size = n, 2 * n
        X, Y = np.meshgrid(x, y)
        p, q = finger.traction(X, Y, cell=(h, h))
        self.force_z, self.force_x = p * h * h, q * h * h  # N per node before modulation
        # offsets m h for m in -(n-1)..(n-1), stored circularly (index m mod 2n); index n is unused
        m = np.arange(self.size)
        m = np.where(m < n, m, m - self.size)
        DX, DY = np.meshgrid(m * h, m * h)
        W = output_weights(finger.sensors.quantity, finger.sensors.components,
                           finger.contact.young_modulus, finger.contact.poisson_ratio)
        nu, z = finger.contact.poisson_ratio, finger.depth
        kz = np.zeros((W.shape[0], self.size, self.size))
        kx = np.zeros_like(kz)
        for v, comp in enumerate(COMPONENTS):
            if not np.any(W[:, v]):
                continue
            gz = point_green(comp, "z", DX, DY, z, nu)
            gx = point_green(comp, "x", DX, DY, z, nu)
            kz += W[:, v, None, None] * gz
            kx += W[:, v, None, None] * gx
        self.kernel_z = np.fft.rfft2(kz)  # (n_comp, 2n, n + 1): computed once
        self.kernel_x = np.fft.rfft2(kx)

    def maps(self, surface: Surface, positions, *, y_offset: float = 0.0, reference_height_m: float = 1.0,
             batch: int = 16) -> np.ndarray:
        """Field maps for each frame, shape (n_frames, n_components, ny, nx), on the finger grid."""
        u = np.atleast_1d(np.asarray(positions, dtype=float))
        if u.ndim != 1 or not np.all(np.isfinite(u)):
            raise ValueError(f"positions: need a finite 1-D array of finger positions in m, got shape {u.shape}")
        if int(batch) < 1:
            raise ValueError(f"batch: frames per FFT must be >= 1, got {batch!r}")
        X, Y = np.meshgrid(self.x, self.y)
        n, s = self.n, self.size
        out = np.empty((u.size, self.kernel_z.shape[0], n, n))
        for i0 in range(0, u.size, int(batch)):
            uu = u[i0:i0 + int(batch), None, None]
            mod = surface.modulation(X + uu, Y + y_offset, reference_height=reference_height_m)
            fz = np.fft.rfft2(mod * self.force_z, s=(s, s))
            fx = np.fft.rfft2(mod * self.force_x, s=(s, s))
            spec = fz[:, None] * self.kernel_z + fx[:, None] * self.kernel_x
            out[i0:i0 + uu.shape[0]] = np.fft.irfft2(spec, s=(s, s))[..., :n, :n]
        return out

    def apply(self, modulation: np.ndarray) -> np.ndarray:
        """Maps (n_components, ny, nx) for one modulation field (ny, nx) on the finger grid."""
        s, n = self.size, self.n
        fz = np.fft.rfft2(modulation * self.force_z, s=(s, s))
        fx = np.fft.rfft2(modulation * self.force_x, s=(s, s))
        return np.fft.irfft2(fz * self.kernel_z + fx * self.kernel_x, s=(s, s))[..., :n, :n]

    def adjoint(self, maps: np.ndarray) -> np.ndarray:
        """Adjoint of :meth:`apply`: (n_components, ny, nx) -> (ny, nx) (correlation with the kernels)."""
        s, n = self.size, self.n
        spec = np.fft.rfft2(maps, s=(s, s))
        back_z = np.fft.irfft2((spec * np.conj(self.kernel_z)).sum(axis=0), s=(s, s))[:n, :n]
        back_x = np.fft.irfft2((spec * np.conj(self.kernel_x)).sum(axis=0), s=(s, s))[:n, :n]
        return self.force_z * back_z + self.force_x * back_x

    def operator(self):
        """:meth:`apply` as a ``scipy.sparse.linalg.LinearOperator`` (flattened), with its adjoint."""
        from scipy.sparse.linalg import LinearOperator

        n, nc = self.n, self.kernel_z.shape[0]
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

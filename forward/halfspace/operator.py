"""The load-to-sensor map of a half-space as a ``scipy.sparse.linalg.LinearOperator``.

Model: tractions ``loads`` (a subset of p, qx, qy; Pa) on a regular grid. The operators of
the solver and the inversion share one convention: ``dims`` is the grid shape, the attribute
``loads`` names the load components, and the model vector is load-major (all nodes of the
first load, C order, then all nodes of the next), i.e. the flattening of an array of shape
``(len(loads), *dims)``. Data: ``components`` of stress (Pa) or tensor strain at the
sensors and one depth, flattened from ``dimsd = (n_comp, n_sensors)``. Batched over time
frames through ``matmat`` (columns are frames).

Paths (chosen from the sensors; the attribute ``path`` says which):
- ``"fft-periodic"``: the grid is one period; exact spectral multipliers (docs/theory.md s2).
- ``"fft-padded"``: isolated load; zero-padded convolution with the point (line) kernel
  sampled at depth (DC-FFT, the one engine of :mod:`.dcfft`: :func:`dcfft_kernel_spectrum`,
  :func:`dcfft_convolve`, :func:`dcfft_correlate`). Used when the sensors are the grid nodes
  or a subset of them.
- ``"dense"``: sensors off the grid; the kernel matrix from the closed forms (isolated), or
  from the periodic Green's function evaluated per sensor (periodic).
The adjoint (``rmatvec``/``rmatmat``) is exact for every path and passes a dot test.
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft
from scipy.sparse.linalg import LinearOperator

from .dcfft import dcfft_convolve, dcfft_correlate, dcfft_kernel_spectrum
from tactilab.core import rules as check
from .fields import output_weights
from .kernels import line_green, point_green
from .loads import LOAD_COMPONENTS, SurfaceLoad
from .spectral import VOIGT, _Geometry, multiplier, _half_wavenumbers

_DIRECTION = {"p": "z", "qx": "x", "qy": "y"}


def _check_loads(loads) -> tuple[str, ...]:
    loads = (loads,) if isinstance(loads, str) else tuple(loads)
    bad = [name for name in loads if name not in LOAD_COMPONENTS]
    if bad or not loads or len(set(loads)) != len(loads):
        raise ValueError(f"loads: give distinct names from {LOAD_COMPONENTS}, got {loads!r}")
    return loads


class LoadToSensor(LinearOperator):
    """Linear map from surface tractions to stress or strain at sensors at one depth.

    Parameters
    ----------
    halfspace : HalfSpace
        Material (E in Pa, nu).
    shape : (nx,) or (ny, nx)
        Load grid shape (1-D: plane strain).
    spacing : float or (dx, dy)
        Grid spacing in m.
    sensors : ndarray, shape (n, 2) or (n,), optional
        Sensor (x, y) positions in m (x only in 1-D); default: every grid node.
    depth : float
        Sensor depth in m (> 0).
    components : sequence of str
        Voigt components measured.
    loads : sequence of {"p", "qx", "qy"}
        Load components in the model.
    quantity : {"stress", "strain"}
        Stress in Pa, or TENSOR strain.
    periodic : bool
        True when the grid is one period of a repeating load.
    """

    def __init__(self, halfspace, shape, spacing, sensors=None, depth: float = 1e-3, components=("zz",),
                 loads=("p",), quantity: str = "stress", periodic: bool = False):
        shape = tuple(int(s) for s in np.atleast_1d(shape))
        if len(shape) not in (1, 2) or min(shape) < 1:
            raise ValueError(f"shape: expected (nx,) or (ny, nx) with positive sizes, got {shape}")
        template = SurfaceLoad(p=np.zeros(shape), spacing=spacing, periodic=periodic)
        self.template = template
        self.depth = check.depth(depth)
        self.components = check.components(components)
        self.loads = _check_loads(loads)
        self.quantity = quantity
        self.weights = output_weights(quantity, self.components, halfspace.E, halfspace.nu)
        self.nu = halfspace.nu
        self.grid_shape = shape
        if sensors is None:
            self.sensor_xy = self._grid_points()
            self._select = None
        else:
            pts = np.asarray(sensors, dtype=float)
            pts = pts[:, None] if pts.ndim == 1 else pts
            if pts.ndim != 2 or pts.shape[1] != len(shape) or len(pts) == 0 or not np.all(np.isfinite(pts)):
                raise ValueError(
                    f"sensors: expected finite positions of shape (n, {len(shape)}) in m for a "
                    f"{len(shape)}-D grid, got {np.shape(sensors)}")
            self.sensor_xy = pts
            self._select = self._on_grid(pts)
        self.dims = shape
        self.spacing = template.spacing
        self.dimsd = (len(self.components), len(self.sensor_xy))
        if self._select is not None or sensors is None:
            self.path = "fft-periodic" if periodic else "fft-padded"
            self._spectra = self._periodic_multipliers() if periodic else self._padded_multipliers()
        else:
            self.path = "dense"
            self._matrix = self._dense_matrix()
        super().__init__(dtype=np.float64,
                         shape=(int(np.prod(self.dimsd)), len(self.loads) * int(np.prod(self.dims))))

    @property
    def model_shape(self) -> tuple[int, ...]:
        """Shape of the load-major model array, ``(len(loads), *dims)``."""
        return (len(self.loads), *self.dims)

    @property
    def circulant(self) -> bool:
        """True when the map is a periodic convolution with a sensor at every node (in node
        order): then each (component, load) block is diagonal in Fourier space."""
        return self.path == "fft-periodic" and self._select is None

    def fourier_multiplier(self) -> np.ndarray:
        """The exact Fourier multipliers of a circulant operator on the full grid.

        Returns
        -------
        ndarray, complex, shape ``(n_comp, n_load, *dims)``
            ``H[c, l]`` in ``fftfreq`` order (wavenumbers from :func:`angular_wavenumbers`),
            Hermitian, so that ``data_c = ifft(sum_l H[c, l] fft(load_l))``. Data units per Pa.

        Raises
        ------
        ValueError
            When the operator is not circulant (see :attr:`circulant`).
        """
        if not self.circulant:
            raise ValueError(f"fourier_multiplier: the operator is not a periodic convolution (path {self.path!r}, "
                             "sensors not the grid nodes); build it with periodic=True and sensors=None")
        half = self._spectra
        nx = self.dims[-1]
        neg = np.arange(nx // 2 + 1, nx)
        mirror = half[..., nx - neg]
        if len(self.dims) == 2:
            mirror = mirror[..., (-np.arange(self.dims[0])) % self.dims[0], :]
        return np.concatenate([half, np.conj(mirror)], axis=-1)

    # -- geometry ----------------------------------------------------------------------------
    def _grid_points(self) -> np.ndarray:
        t = self.template
        if t.ndim == 1:
            return t.x[:, None]
        yy, xx = np.meshgrid(t.y, t.x, indexing="ij")
        return np.column_stack([xx.ravel(), yy.ravel()])

    def _on_grid(self, pts: np.ndarray):
        t = self.template
        idx = [pts[:, 0] / t.dx + t.shape[-1] // 2]
        if t.ndim == 2:
            idx.insert(0, pts[:, 1] / t.dy + t.shape[0] // 2)
        idx = np.array(idx)
        r = np.rint(idx)
        upper = np.array(t.shape)[:, None] - 1
        if np.all(np.abs(idx - r) < 1e-9) and np.all(r >= 0) and np.all(r <= upper):
            return np.ravel_multi_index(tuple(r.astype(int)), t.shape)
        return None

    # -- precomputation -----------------------------------------------------------------------
    def _periodic_multipliers(self) -> np.ndarray:
        t = self.template
        xi, eta = _half_wavenumbers(t.shape, t.spacing)
        g = _Geometry(xi, eta, nyquist_x=t.shape[-1] % 2 == 0, nyquist_y=t.ndim == 2 and t.shape[0] % 2 == 0)
        return np.array([[multiplier(g, self.nu, name, row, self.depth) for name in self.loads]
                         for row in self.weights])

    def _padded_multipliers(self) -> np.ndarray:
        t = self.template
        return dcfft_kernel_spectrum(t.shape, t.spacing, self.depth, self.nu, self.weights,
                               [_DIRECTION[name] for name in self.loads])

    def _dense_matrix(self) -> np.ndarray:
        t = self.template
        n_nodes = int(np.prod(t.shape))
        mat = np.zeros((len(self.components), len(self.sensor_xy), len(self.loads), n_nodes))
        nodes = self._grid_points()
        if t.periodic:
            # periodic Green's function: column for a unit load at each sensor via one FFT per sensor
            for l in range(len(self.loads)):
                for s, xy in enumerate(self.sensor_xy):
                    mat[:, s, l] = self._periodic_row(l, xy)
            return mat.reshape(int(np.prod(self.dimsd)), -1)
        # sensors in chunks of ~2^20 pairs, so the kernels' temporaries stay small beside the matrix
        step = max(1, 2**20 // len(nodes))
        for start in range(0, len(self.sensor_xy), step):
            chunk = slice(start, start + step)
            dx = self.sensor_xy[chunk, 0][:, None] - nodes[:, 0][None, :]
            dy = None if t.ndim == 1 else self.sensor_xy[chunk, 1][:, None] - nodes[:, 1][None, :]
            for l, name in enumerate(self.loads):
                for j, comp in enumerate(VOIGT):
                    col = self.weights[:, j]
                    if not np.any(col):
                        continue
                    if t.ndim == 1:
                        g = line_green(comp, _DIRECTION[name], dx, self.depth, self.nu)
                    else:
                        g = point_green(comp, _DIRECTION[name], dx, dy, self.depth, self.nu)
                    for o in np.flatnonzero(col):
                        mat[o, chunk, l] += (col[o] * t.cell_area) * g
        return mat.reshape(int(np.prod(self.dimsd)), -1)

    def _periodic_row(self, l: int, xy: np.ndarray) -> np.ndarray:
        t = self.template
        mult = self._periodic_multipliers_cached()[:, l]
        xi, eta = _half_wavenumbers(t.shape, t.spacing)
        phase = np.exp(1j * xi * xy[0]) if t.ndim == 1 else np.exp(1j * (xi * xy[0] + eta * xy[1]))
        # response at xy to a unit traction at node m = (1/N) sum_k M(k) e^{ik (xy - x_m)}
        axes = tuple(range(1, t.ndim + 1))
        origin = np.exp(-1j * xi * t.x[0]) if t.ndim == 1 else np.exp(-1j * (xi * t.x[0] + eta * t.y[0]))
        spec = np.conj(mult * phase * origin)
        rows = sfft.irfftn(spec, s=t.shape, axes=axes)
        return rows.reshape(len(self.components), -1)

    def _periodic_multipliers_cached(self):
        if not hasattr(self, "_pm"):
            self._pm = self._periodic_multipliers()
        return self._pm

    # -- LinearOperator ------------------------------------------------------------------------
    # Non-finite input would spread NaN over every output through the FFTs: refuse it, naming
    # the first bad index (flat for matvec, (row, column) for matmat).
    _MODEL = ("x (model: tractions)", "Pa")
    _DATA = ("x (data: sensor values)", "data units (Pa or tensor strain)")

    def _matvec(self, v):
        return self._forward(check.finite_array(np.ravel(v), *self._MODEL).reshape(-1, 1)).ravel()

    def _rmatvec(self, v):
        return self._backward(check.finite_array(np.ravel(v), *self._DATA).reshape(-1, 1)).ravel()

    def _matmat(self, m):
        return self._forward(check.finite_array(m, *self._MODEL))

    def _rmatmat(self, d):
        return self._backward(check.finite_array(d, *self._DATA))

    def _forward(self, m: np.ndarray) -> np.ndarray:
        if self.path == "dense":
            return self._matrix @ m
        frames = m.shape[1]
        t = self.template
        model = m.T.reshape(frames, *self.model_shape)
        axes = tuple(range(-t.ndim, 0))
        if self.path == "fft-periodic":
            spec = sfft.rfftn(model, axes=axes)  # (frames, n_load, ...)
            data = sfft.irfftn(np.einsum("cl...,fl...->fc...", self._spectra, spec), s=t.shape, axes=axes)
        else:
            data = dcfft_convolve(self._spectra, model)
        data = data.reshape(frames, len(self.components), -1)
        if self._select is not None:
            data = data[:, :, self._select]
        return data.reshape(frames, -1).T

    def _backward(self, d: np.ndarray) -> np.ndarray:
        if self.path == "dense":
            return self._matrix.T @ d
        frames = d.shape[1]
        t = self.template
        data = d.T.reshape(frames, len(self.components), -1)
        if self._select is not None:
            grid = np.zeros((frames, len(self.components), int(np.prod(t.shape))))
            np.add.at(grid, (slice(None), slice(None), self._select), data)
            data = grid
        data = data.reshape(frames, len(self.components), *t.shape)
        axes = tuple(range(-t.ndim, 0))
        if self.path == "fft-periodic":
            spec = sfft.rfftn(data, axes=axes)
            model = sfft.irfftn(np.einsum("cl...,fc...->fl...", np.conj(self._spectra), spec), s=t.shape, axes=axes)
        else:
            model = dcfft_correlate(self._spectra, data)
        return model.reshape(frames, -1).T

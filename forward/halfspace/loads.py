"""Surface loads on a regular grid: the tractions applied TO the skin surface.

Conventions (docs/theory.md section 1): ``p`` is the normal pressure, positive when it pushes into
the skin; ``qx`` and ``qy`` are the tangential tractions along +x and +y. All in Pa.
A 1-D load (arrays of shape ``(nx,)``) is a plane-strain load, independent of y.
Grid nodes sit at ``x_j = (j - nx // 2) * dx`` (and likewise in y), so index ``nx // 2``
is the origin; this makes the grid centred and FFT-friendly.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tactilab.core import rules as check

#: Surface traction components: normal pressure p (pushes in) and tangential qx, qy (Pa)
LOAD_COMPONENTS = ("p", "qx", "qy")


@dataclass(frozen=True)
class SurfaceLoad:
    """Tractions on the skin surface, sampled on a regular grid.

    Parameters
    ----------
    p, qx, qy : array_like or None
        Normal pressure (into the skin) and tangential tractions along +x, +y, in Pa.
        Shape ``(nx,)`` for a plane-strain (1-D) load or ``(ny, nx)`` for a 2-D one; all
        given arrays share one shape. ``None`` means zero.
    spacing : float or (float, float)
        Grid spacing ``dx`` (1-D) or ``(dx, dy)`` (2-D), in m. One value means dx = dy.
    periodic : bool
        True when the grid is one period of an infinitely repeating load (a grating);
        False (default) when the load is zero outside the grid (an isolated contact).
    error_estimate : float
        Known error of the tractions themselves, relative to their peak (default 0: the values
        are exact). A solved contact sets it (``ContactSolution.load()``); every field computed
        from the load adds it, scaled to the field's peak, to its own error estimate.

    Raises
    ------
    ValueError
        If no component is given, shapes differ, values are not finite, or the spacing
        is not a positive length.
    """

    p: np.ndarray | None = None
    qx: np.ndarray | None = None
    qy: np.ndarray | None = None
    spacing: float | tuple[float, float] = 1e-4
    periodic: bool = False
    error_estimate: float = 0.0
    _arrays: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        arrays = {}
        for name in LOAD_COMPONENTS:
            value = getattr(self, name)
            if value is None:
                continue
            arr = np.asarray(value)
            if arr.dtype.kind not in "biuf":
                raise ValueError(f"{name}: traction must be a real array in Pa, got dtype {arr.dtype}")
            arr = arr.astype(float)
            if arr.ndim not in (1, 2):
                raise ValueError(
                    f"{name}: expected shape (nx,) for a 1-D load or (ny, nx) for a 2-D load, got {arr.shape}"
                )
            bad = ~np.isfinite(arr)
            if bad.any():
                idx = tuple(int(i) for i in np.argwhere(bad)[0])
                raise ValueError(
                    f"{name}: traction must be finite (no NaN or inf), got {arr[idx]} at index {idx}; "
                    "fill gaps before building the load"
                )
            arr.setflags(write=False)
            arrays[name] = arr
            object.__setattr__(self, name, arr)
        if not arrays:
            raise ValueError("SurfaceLoad: give at least one of p, qx, qy (arrays in Pa)")
        shapes = {name: a.shape for name, a in arrays.items()}
        if len(set(shapes.values())) > 1:
            raise ValueError(f"SurfaceLoad: p, qx, qy must share one shape, got {shapes}")
        shape = next(iter(shapes.values()))
        if min(shape) < 1:
            raise ValueError(f"SurfaceLoad: grid is empty, shape {shape}; give at least one node per axis")
        object.__setattr__(self, "spacing", check.spacing(self.spacing, len(shape)))
        if not isinstance(self.periodic, (bool, np.bool_)):
            raise ValueError(f"periodic: must be True or False, got {self.periodic!r}")
        err = self.error_estimate
        if isinstance(err, (bool, np.bool_)) or not isinstance(err, (int, float, np.floating, np.integer)) \
                or not np.isfinite(err) or err < 0:
            raise ValueError(f"error_estimate: must be a finite relative error >= 0, got {err!r}; use 0 for exact tractions")
        object.__setattr__(self, "error_estimate", float(err))
        object.__setattr__(self, "_arrays", arrays)

    @property
    def shape(self) -> tuple[int, ...]:
        """Grid shape: ``(nx,)`` or ``(ny, nx)``."""
        return next(iter(self._arrays.values())).shape

    @property
    def ndim(self) -> int:
        """1 for a plane-strain load, 2 for a surface load."""
        return len(self.shape)

    @property
    def dx(self) -> float:
        """Node spacing along x in m."""
        return self.spacing[0]

    @property
    def dy(self) -> float | None:
        """Node spacing along y in m; None for a plane-strain (1-D) load."""
        return self.spacing[1] if self.ndim == 2 else None

    @property
    def x(self) -> np.ndarray:
        """Node x coordinates in m, shape (nx,)."""
        nx = self.shape[-1]
        return (np.arange(nx) - nx // 2) * self.dx

    @property
    def y(self) -> np.ndarray | None:
        """Node y coordinates in m, shape (ny,), or None for a 1-D load."""
        if self.ndim == 1:
            return None
        ny = self.shape[0]
        return (np.arange(ny) - ny // 2) * self.dy

    @property
    def cell_area(self) -> float:
        """Area per node in m^2 (2-D) or length per node in m (1-D)."""
        return float(np.prod(self.spacing))

    @property
    def components(self) -> dict[str, np.ndarray]:
        """The non-zero-by-declaration components, name -> array in Pa."""
        return dict(self._arrays)

    def is_zero(self) -> bool:
        """True when every given component is identically zero."""
        return all(not a.any() for a in self._arrays.values())

    def varies_in_y(self) -> bool:
        """True for a 2-D load whose rows differ (a 1-D model would not be exact)."""
        if self.ndim == 1:
            return False
        if self.shape[0] > 1 and any(not np.array_equal(a[1], a[0]) for a in self._arrays.values()):
            return True  # rows 0 and 1 differ: the common case, decided without reading the grid
        return any(not np.array_equal(a, np.broadcast_to(a[:1], a.shape)) for a in self._arrays.values())

    def row(self) -> "SurfaceLoad":
        """The 1-D plane-strain load of a 2-D load that does not vary in y."""
        if self.varies_in_y():
            raise ValueError("load: varies in y, so it has no exact plane-strain (1-D) form; keep the 2-D load")
        if self.ndim == 1:
            return self
        return SurfaceLoad(**{k: v[0] for k, v in self._arrays.items()}, spacing=self.dx, periodic=self.periodic,
                           error_estimate=self.error_estimate)

    def scaled(self, factor: float) -> "SurfaceLoad":
        """The same load multiplied by ``factor``."""
        return SurfaceLoad(**{k: v * factor for k, v in self._arrays.items()}, spacing=self.spacing,
                           periodic=self.periodic, error_estimate=self.error_estimate)

    @property
    def total_force(self) -> np.ndarray:
        """Resultant (Fx, Fy, Fz) in N (2-D) or N/m (1-D): tractions times cell area."""
        a = self._arrays
        return np.array([a[k].sum() * self.cell_area if k in a else 0.0 for k in ("qx", "qy", "p")])

    @property
    def extent(self) -> float:
        """RMS radius of the load about its centroid, in m (weighted by |traction|)."""
        w = sum(np.abs(v) for v in self._arrays.values())
        total = w.sum()
        if total == 0:
            return 0.0
        if self.ndim == 1:
            x = self.x
            xc = (w * x).sum() / total
            return float(np.sqrt((w * (x - xc) ** 2).sum() / total))
        yy, xx = np.meshgrid(self.y, self.x, indexing="ij")
        xc, yc = (w * xx).sum() / total, (w * yy).sum() / total
        return float(np.sqrt((w * ((xx - xc) ** 2 + (yy - yc) ** 2)).sum() / total))

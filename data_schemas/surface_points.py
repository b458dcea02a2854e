"""Surface points (x, y) in m: the one check every surface record's ``height_at`` applies."""

from __future__ import annotations

import numpy as np


def surface_points(x, y) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) as float arrays of one shape, in m; y=None is a profile along x (y = 0). Refuses NaN or inf."""
    x = np.asarray(x, dtype=float)
    y = np.zeros_like(x) if y is None else np.asarray(y, dtype=float)
    try:
        x, y = np.broadcast_arrays(x, y)
    except ValueError:
        raise ValueError(
            f"x and y must broadcast together, got shapes {np.shape(x)} and {np.shape(y)}; "
            "give arrays of the same shape (or y=None for a profile along x)"
        ) from None
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("x, y: surface points must be finite (no NaN or inf), in m")
    return x, y

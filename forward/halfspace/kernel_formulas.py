"""The closed-form Green's functions themselves: Boussinesq, Cerruti, Flamant, antiplane.

Formulas only, per unit force and without input checks; the validated public functions
are in :mod:`tactilab.forward.halfspace.kernels` (conventions and limits are documented there).
Geometry is passed in as direction cosines ``l, m, n = x/R, y/R, z/R`` and ``g = 1/(2 pi R^2)``
(point) or ``l, n = x/r, z/r`` and ``g = 1/(pi r)`` (line), so that every stress is ``F g``
times a bounded polynomial-like function of the direction: stable at any distance, exact at
nu = 0.5 (no division by 1 - 2 nu).
"""

from __future__ import annotations

import numpy as np

__all__ = ["radius", "point_geometry", "point_unit", "line_geometry", "line_unit",
           "boussinesq", "cerruti_x"]


def radius(*coords):
    """Euclidean norm; sqrt of squares (fast) unless they under- or overflow, then hypot."""
    with np.errstate(over="ignore", under="ignore"):
        r = np.sqrt(sum(c * c for c in coords))
    if not np.all((r > 1e-150) & (r < 1e150)):
        r = coords[0]
        for c in coords[1:]:
            r = np.hypot(r, c)
    return r


def point_geometry(x, y, z):
    """Direction cosines and 1/(2 pi R^2); R = 0 must be excluded by the caller."""
    inv = 1.0 / radius(x, y, z)
    return x * inv, y * inv, z * inv, (0.5 / np.pi) * inv * inv


def boussinesq(comp: str, l, m, n, g, nu: float):
    """Stress per unit normal force (N) pushing into the skin; Johnson eq. 3.18."""
    if comp == "zz":
        return -3.0 * n**3 * g
    if comp == "zx":
        return -3.0 * l * n * n * g
    if comp == "yz":
        return -3.0 * m * n * n * g
    # In-plane: sigma_r and sigma_theta of docs/theory.md section 3 with the removable r -> 0
    # singularity resolved: (1 - z/R)/r^2 = 1/(R (R + z)) and (sigma_r - sigma_theta)/r^2 =
    # [(1 - 2 nu)(2R + z)/(R^3 (R + z)^2) - 3 z/R^5] / (2 pi) per unit force.
    one_n = 1.0 + n
    dev = (1.0 - 2.0 * nu) * (2.0 + n) / (one_n * one_n) - 3.0 * n
    if comp == "xy":
        return l * m * dev * g
    mean = (1.0 - 2.0 * nu) * n - 3.0 * n * (1.0 - n * n)
    sign = 1.0 if comp == "xx" else -1.0  # yy
    return 0.5 * g * (mean + sign * (l * l - m * m) * dev)


def cerruti_x(comp: str, l, m, n, g, nu: float):
    """Stress per unit tangential force (N) along +x; Johnson eq. 3.19."""
    if comp == "zz":
        return -3.0 * l * n * n * g
    if comp == "zx":
        return -3.0 * l * l * n * g
    if comp == "yz":
        return -3.0 * l * m * n * g
    a = 1.0 / (1.0 + n)
    a2 = a * a
    a3 = a2 * a
    c = 1.0 - 2.0 * nu
    if comp == "xx":
        return g * (-3.0 * l**3 + c * (l - 3.0 * l * a2 + l**3 * a2 + 2.0 * l**3 * a3))
    if comp == "yy":
        return g * (-3.0 * l * m * m + c * (l - l * a2 + l * m * m * a2 + 2.0 * l * m * m * a3))
    # xy
    return g * (-3.0 * l * l * m + c * (-m * a2 + l * l * m * a2 + 2.0 * l * l * m * a3))


_SWAP_XY = {"xx": "yy", "yy": "xx", "zz": "zz", "yz": "zx", "zx": "yz", "xy": "xy"}


def point_unit(comp: str, direction: str, l, m, n, g, nu: float):
    """Stress per unit point force (N) along ``direction`` from the direction cosines and 1/(2 pi R^2)."""
    if direction == "z":
        return boussinesq(comp, l, m, n, g, nu)
    if direction == "x":
        return cerruti_x(comp, l, m, n, g, nu)
    # A force along +y is the +x solution with the roles of x and y exchanged.
    return cerruti_x(_SWAP_XY[comp], m, l, n, g, nu)


def line_geometry(x, z):
    """Direction cosines (x/r, z/r) and 1/(pi r) of points (m) from a line force at the origin."""
    inv = 1.0 / radius(x, z)
    return x * inv, z * inv, inv / np.pi


def line_unit(comp: str, direction: str, l, n, g, nu: float):
    """Stress per unit line force (N/m) along y at x = 0; Flamant and antiplane shear."""
    zero = np.zeros(np.broadcast_shapes(np.shape(l), np.shape(g)))
    if direction == "y":  # antiplane: u_y = -(F / (pi mu)) ln r
        if comp == "yz":
            return -n * g
        if comp == "xy":
            return -l * g
        return zero
    if comp in ("yz", "xy"):
        return zero
    if direction == "z":  # Flamant, normal force pushing in
        table = {"xx": l * l * n, "zz": n**3, "zx": l * n * n, "yy": nu * n}
    else:  # Flamant, tangential force along +x
        table = {"xx": l**3, "zz": l * n * n, "zx": l * l * n, "yy": nu * l}
    # sigma_yy = nu (sigma_xx + sigma_zz) uses l^2 + n^2 = 1 (plane strain).
    return -2.0 * table[comp] * g

"""Hamilton's explicit closed form for the stresses beneath a sliding Hertz contact.

An analytic reference for the forward solver, written apart from it (nothing here imports
``tactilab``): a circular Hertz contact of radius ``a`` with the pressure

    p(x, y)  = p0 sqrt(1 - r^2/a^2)       (r < a, pushing into the skin),
    qx(x, y) = mu p(x, y)                 (tangential traction along +x, sliding friction),

on the surface of an isotropic elastic half-space. The stress at a point (x, y, z) in the
half-space is the sum of Hamilton's normal and tangential parts,

    G. M. Hamilton (1983), "Explicit equations for the stresses beneath a sliding spherical
    contact", Proc. Instn Mech. Engrs 197C, 53-59,

evaluated here in the coordinates of docs/theory.md section 1: z is the depth into the skin
(z >= 0), stress is tension-positive, and the surface boundary conditions read
sigma_zz = -p, sigma_zx = -qx at z = 0. Components come in the Voigt order
(xx, yy, zz, yz, zx, xy).

Hamilton's auxiliary quantities, with all lengths in units of a (x, y, z -> x/a, y/a, z/a),
r^2 = x^2 + y^2:

    A = r^2 + z^2 - 1,   S = sqrt(A^2 + 4 z^2),   M = sqrt((S + A)/2),   N = sqrt((S - A)/2),
    phi = arctan(1/M),   G = M^2 - N^2 + z M - N,   H = 2 M N + M + z N.

The normal part is scaled by p0 (Hamilton's 3 P/(2 pi a^3) with P = 2 pi a^2 p0/3), the
tangential part by mu p0. On the z axis (r = 0) the off-axis formulas are 0/0; there the
limits are used (Huber's closed form for the normal part). Close to the axis the tangential
formulas lose digits like eps (a/r)^3 (about 3e-11 p0 at r = a/64); for 0 < r < 1e-3 a the
stress is therefore taken from its first-order expansion about the axis, with the gradient
from central differences at +-1e-2 a (error below 1e-7 p0). The formulas hold for every
Poisson's ratio 0 <= nu <= 1/2 (no factor divides by 1 - 2 nu).
"""

from __future__ import annotations

import numpy as np

__all__ = ["hamilton_stress"]

_R_NEAR_AXIS = 1e-3  # in units of a: below it the first-order expansion about the axis is used
_DELTA_AXIS = 1e-2  # in units of a: central-difference step for that expansion


def _aux(x, y, z):
    r2 = x * x + y * y
    big_a = r2 + z * z - 1.0
    s = np.sqrt(big_a * big_a + 4.0 * z * z)
    m = np.sqrt(np.maximum((s + big_a) / 2.0, 0.0))
    n = np.sqrt(np.maximum((s - big_a) / 2.0, 0.0))
    phi = np.arctan2(1.0, m)
    g = m * m - n * n + z * m - n
    h = 2.0 * m * n + m + z * n
    return r2, big_a, s, m, n, phi, g, h


def _normal_off_axis(x, y, z, nu):
    """Hamilton's normal-load stresses (units of p0, lengths in units of a), r > 0."""
    r2, big_a, s, m, n, phi, g, h = _aux(x, y, z)
    x2, y2 = x * x, y * y
    common = (1 - nu) * n * z * z - (1 - 2 * nu) / 3 * (n * s + 2 * big_a * n + 1) - nu * m * z
    sxx = (1 + nu) * z * phi + ((y2 - x2) / r2 * common - n * (x2 + 2 * nu * y2) - m * x2 * z / s) / r2
    syy = (1 + nu) * z * phi + ((x2 - y2) / r2 * common - n * (y2 + 2 * nu * x2) - m * y2 * z / s) / r2
    szz = -n + z * m / s
    sxy = (x * y * (1 - 2 * nu) / r2**2 * (-n * r2 + 2.0 / 3.0 * n * (s + 2 * big_a)
                                           - z * (z * n + m) + 2.0 / 3.0)
           + x * y * z / r2**2 * (-m * r2 / s - z * n + m))
    ratio = z * h / (g * g + h * h)
    syz = -z * y * (n / s - ratio)
    szx = -z * x * (n / s - ratio)
    return np.stack([sxx, syy, szz, syz, szx, sxy])


def _tangential_off_axis(x, y, z, nu):
    """Hamilton's tangential-load stresses (units of mu p0, lengths in units of a), r > 0."""
    r2, big_a, s, m, n, phi, g, h = _aux(x, y, z)
    x2, y2, z2 = x * x, y * y, z * z
    fx = 1.5 - 2 * x2 / r2  # (3/2 - 2 x^2/r^2)
    hx = 0.5 - 2 * x2 / r2  # (1/2 - 2 x^2/r^2)
    hy = 0.5 - 2 * y2 / r2  # (1/2 - 2 y^2/r^2)
    c = 1 - 2 * nu
    sxx = (-x * (nu / 4 + 1) * phi
           + x * m / r2**2 * (fx * (s * nu - 2 * big_a * nu + z2) + x2 * z2 / s
                              + 7 * nu * r2 / 4 - 2 * nu * x2 + r2)
           + x * z * n / r2**2 * (fx * (-s / 6 * c - big_a / 3 * c - (z2 + 3) / 2)
                                  + x2 / s - nu * r2 / 4 - 7 * r2 / 4)
           + 4 * x * z / (3 * r2**2) * fx * c)
    syy = (-3 * nu * x * phi / 4
           + x * m / r2**2 * (hy * (nu * (s - 2 * big_a + r2) + z2) + y2 * z2 / s + 0.75 * nu * r2)
           + z * x * n / r2**2 * (hy * (-s / 6 * c - big_a / 3 * c - z2 / 2 - 1.5)
                                  + y2 / s - 0.75 * nu * r2 - r2 / 4)
           + 4 * z * x / (3 * r2**2) * hy * c)
    szz = z * x * n / (2 * r2) * (1 - (r2 + z2 + 1) / s)
    sxy = (y / 2 * (nu / 2 - 1) * phi
           + y * m / r2**2 * (x2 * z2 / s + nu * ((s - 2 * big_a) * hx - 2 * x2 + r2 / 4)
                              + r2 / 2 + z2 * hx)
           + y * z * n / r2**2 * (hx * (-c * (s / 6 + big_a / 3) - z2 / 2 - 1.5 - r2 / 2)
                                  + r2 * nu / 4 + x2 / s - y2 / 2 - 1.5 * x2)
           + 4 * y * z / (3 * r2**2) * hx * c)
    syz = x * y * z / (2 * r2**2) * (m * (0.5 + (z2 / 2 - 1.5 - r2 / 2) / s)
                                     + z * n / 2 * (-3 + (5 + z2 + r2) / s))
    szx = (1.5 * z * phi + z * m / r2 * (1 + x2 / r2 - x2 / s)
           + n / r2 * (-0.75 * (s + 2 * big_a) + z2 - 0.75 - r2 / 4 + z2 / 2 * hx))
    return np.stack([sxx, syy, szz, syz, szx, sxy])


def _on_axis(z, nu, mu):
    """Limits on the z axis (units of p0): Huber's normal part and the tangential zx part."""
    out = np.zeros((6,) + z.shape)
    atan = np.arctan2(1.0, z)
    radial = (1 + nu) * (z * atan - 1) + 1 / (2 * (1 + z * z))
    out[0] = radial
    out[1] = radial
    out[2] = -1 / (1 + z * z)
    out[4] = mu * (-1 + 1.5 * z * atan - z * z / (2 * (1 + z * z)))
    return out


def _off_axis(x, y, z, nu, mu):
    out = _normal_off_axis(x, y, z, nu)
    if mu != 0.0:
        out = out + mu * _tangential_off_axis(x, y, z, nu)
    return out


def hamilton_stress(x, y, z, *, a: float, p0: float, mu: float, nu: float) -> np.ndarray:
    """Stress beneath a Hertz contact sliding with friction (Hamilton 1983).

    Parameters
    ----------
    x, y, z : array_like
        Coordinates (m), broadcast together; z >= 0 is the depth into the skin.
    a : float
        Contact radius (m), > 0.
    p0 : float
        Peak pressure (Pa) at the centre; p = p0 sqrt(1 - r^2/a^2) pushes into the skin.
    mu : float
        Friction coefficient: the tangential traction is qx = mu p along +x.
    nu : float
        Poisson's ratio, 0 <= nu <= 0.5.

    Returns
    -------
    numpy.ndarray, shape (6, *broadcast shape)
        Stress (Pa, tension positive) in the Voigt order (xx, yy, zz, yz, zx, xy).

    Raises
    ------
    ValueError
        If ``a`` is not positive, ``nu`` is outside [0, 0.5], a coordinate is not finite, or a
        depth is negative.
    """
    if not (np.isfinite(a) and a > 0):
        raise ValueError(f"a must be a positive finite contact radius in m, got {a!r}")
    if not (0.0 <= nu <= 0.5):
        raise ValueError(f"nu must lie in [0, 0.5], got {nu!r}")
    xs, ys, zs = np.broadcast_arrays(*(np.asarray(v, dtype=float) / a for v in (x, y, z)))
    for name, v in (("x", xs), ("y", ys), ("z", zs)):
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name} must be finite; first bad index {np.argwhere(~np.isfinite(v))[0]}")
    if np.any(zs < 0):
        raise ValueError(f"z must be >= 0 (depth into the skin), got min {zs.min() * a!r} m")
    # the contact edge on the surface (r = a, z = 0) is 0/0 in the formulas: step just inside
    zs = np.where((zs == 0) & (np.abs(np.hypot(xs, ys) - 1.0) < 1e-12), 1e-12, zs)
    r = np.hypot(xs, ys)
    out = np.zeros((6,) + xs.shape)
    far = r >= _R_NEAR_AXIS
    out[:, far] = _off_axis(xs[far], ys[far], zs[far], nu, mu)
    axis = r == 0
    out[:, axis] = _on_axis(zs[axis], nu, mu)
    near = ~far & ~axis
    if np.any(near):
        xn, yn, zn = xs[near], ys[near], zs[near]
        d = _DELTA_AXIS
        ddx = (_off_axis(d + 0 * zn, 0 * zn, zn, nu, mu) - _off_axis(-d + 0 * zn, 0 * zn, zn, nu, mu)) / (2 * d)
        ddy = (_off_axis(0 * zn, d + 0 * zn, zn, nu, mu) - _off_axis(0 * zn, -d + 0 * zn, zn, nu, mu)) / (2 * d)
        out[:, near] = _on_axis(zn, nu, mu) + xn * ddx + yn * ddy
    return p0 * out

"""Surface compliance of the half-space: surface tractions to surface displacements.

Conventions (docs/theory.md section 1): tractions act on the skin, ``p`` pushes into it, ``qx``
and ``qy`` act along +x and +y; displacements ``uz`` (positive INTO the skin, z > 0), ``ux``,
``uy``. Rows of every matrix here are ``(uz, ux, uy)``, columns ``(p, qx, qy)``; plane strain
(a load independent of y) keeps ``(uz, ux)`` and ``(p, qx)``.

Per wavenumber (Fourier sign of docs/theory.md section 1, ``k = (kx, ky)`` in rad/m, ``G`` the
shear modulus, ``E* = E / (1 - nu^2)``, ``n = k / |k|``)::

    uz~ = 2 / (E* |k|) p~  -  i (1 - 2 nu) / (2 G |k|) (n . q~)
    u~  = (1 / (G |k|)) (I - nu n n^T) q~  +  i (1 - 2 nu) / (2 G |k|) n p~

The normal-normal entry ``(1 - nu) / (G |k|) = 2 / (E* |k|)``; the cross terms (Dundurs' coupling,
``(1 - 2 nu) / (2 G) = beta 2 / E*`` with ``beta = (1 - 2 nu) / (2 (1 - nu))``) vanish at
nu = 1/2. The matrix is Hermitian (Betti's reciprocity). At ``k = 0`` the displacement of a
half-space under a net load is unbounded (3-D: it grows without limit with the period; plane
strain: logarithmically): the ``k = 0`` entries are set to 0, i.e. displacements are defined up to
a rigid-body shift, which a contact solve absorbs in its approach and tangential shift.

In real space, :func:`pixel_influence` integrates the Boussinesq and Cerruti surface
displacements (Johnson, Contact Mechanics, 3.19-3.21 and 3.86) exactly over one pixel of
uniform traction (Love's closed form for the normal entry); in plane strain, the Flamant line-load
displacements over one cell.
"""

from __future__ import annotations

import math

import numpy as np


def _moduli(E: float, nu: float) -> tuple[float, float, float]:
    """``(E*, G, beta)``: plane-strain modulus, shear modulus (Pa), Dundurs' beta (rigid counter-body)."""
    return E / (1.0 - nu * nu), E / (2.0 * (1.0 + nu)), (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu))


def surface_compliance(kx, ky, E: float, nu: float) -> np.ndarray:
    """The surface compliance matrix per wavenumber, in m/Pa per unit Fourier amplitude (m^2/N times m).

    Parameters
    ----------
    kx : array_like
        Angular wavenumbers along x in rad/m.
    ky : array_like or None
        Angular wavenumbers along y in rad/m, broadcast with ``kx``; ``None`` for plane strain.
    E, nu : float
        Young's modulus (Pa) and Poisson's ratio (checked by the caller).

    Returns
    -------
    ndarray, complex, shape ``broadcast(kx, ky).shape + (3, 3)`` or ``kx.shape + (2, 2)``
        Rows ``(uz, ux, uy)``, columns ``(p, qx, qy)`` (see the module docstring); 0 at ``k = 0``.
    """
    Es, G, beta = _moduli(E, nu)
    kx = np.asarray(kx, dtype=float)
    if ky is None:
        k = np.abs(kx)
        with np.errstate(divide="ignore", invalid="ignore"):
            c = np.where(k > 0, 2.0 / (Es * k), 0.0)
        out = np.zeros(kx.shape + (2, 2), dtype=complex)
        out[..., 0, 0] = out[..., 1, 1] = c
        out[..., 0, 1] = -1j * beta * c * np.sign(kx)
        out[..., 1, 0] = 1j * beta * c * np.sign(kx)
        return out
    kx, ky = np.broadcast_arrays(kx, np.asarray(ky, dtype=float))
    k = np.hypot(kx, ky)
    live = k > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.where(live, 1.0 / (G * np.where(live, k, 1.0)), 0.0)
        nx = np.where(live, kx / np.where(live, k, 1.0), 0.0)
        ny = np.where(live, ky / np.where(live, k, 1.0), 0.0)
    cross = 0.5 * (1.0 - 2.0 * nu) * c
    out = np.zeros(kx.shape + (3, 3), dtype=complex)
    out[..., 0, 0] = (1.0 - nu) * c
    out[..., 1, 1] = c * (1.0 - nu * nx * nx)
    out[..., 2, 2] = c * (1.0 - nu * ny * ny)
    out[..., 1, 2] = out[..., 2, 1] = -nu * c * nx * ny
    out[..., 0, 1], out[..., 1, 0] = -1j * cross * nx, 1j * cross * nx
    out[..., 0, 2], out[..., 2, 0] = -1j * cross * ny, 1j * cross * ny
    return out


def _xlogs(u, v):
    """``u asinh(v / |u|)``, 0 at ``u = 0`` (its limit)."""
    au = np.abs(u)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(au > 0, u * np.arcsinh(v / np.where(au > 0, au, 1.0)), 0.0)


def _xatan(u, v):
    """``u arctan(v / u)``, 0 at ``u = 0`` (its limit)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(u != 0, u * np.arctan(v / np.where(u != 0, u, 1.0)), 0.0)


def _half_log(u, v):
    """``v ln(u^2 + v^2) / 2``, 0 at the origin (its limit)."""
    r2 = u * u + v * v
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(r2 > 0, 0.5 * v * np.log(np.where(r2 > 0, r2, 1.0)), 0.0)


#: antiderivatives F(u, v) with d2F/du dv equal to the integrand over the pixel (u, v: field minus source)
_PRIMITIVES = {
    "1/r": lambda u, v: _xlogs(u, v) + _xlogs(v, u),       # Love: u ln(v + r) + v ln(u + r), up to terms that cancel
    "u2/r3": lambda u, v: _xlogs(v, u),                     # v ln(u + r)
    "v2/r3": lambda u, v: _xlogs(u, v),                     # u ln(v + r)
    "uv/r3": lambda u, v: -np.hypot(u, v),
    "u/r2": lambda u, v: _half_log(u, v) + _xatan(u, v),   # v ln r + u atan(v/u), the -v that cancels dropped
    "v/r2": lambda u, v: _half_log(v, u) + _xatan(v, u),
}


def _pixel_integral(name: str, X, Y, a: float, b: float) -> np.ndarray:
    F = _PRIMITIVES[name]
    return F(X + a, Y + b) - F(X - a, Y + b) - F(X + a, Y - b) + F(X - a, Y - b)


#: the pixel integrals each entry of the 3-D matrix needs (rows uz, ux, uy; columns p, qx, qy)
_NEEDS = {(0, 0): ("1/r",), (1, 1): ("1/r", "u2/r3"), (2, 2): ("1/r", "v2/r3"), (1, 2): ("uv/r3",),
          (2, 1): ("uv/r3",), (0, 1): ("u/r2",), (1, 0): ("u/r2",), (0, 2): ("v/r2",), (2, 0): ("v/r2",)}


def pixel_influence(x, y, spacing, E: float, nu: float, reference_length: float | None = None,
                    entry: tuple[int, int] | None = None) -> np.ndarray:
    """Surface displacement at offset ``(x, y)`` from a pixel of unit uniform traction centred at 0.

    Parameters
    ----------
    x : array_like
        Field point minus pixel centre along x, in m.
    y : array_like or None
        The same along y (broadcast with ``x``); ``None`` for plane strain (a strip of cells).
    spacing : tuple of float
        ``(dx, dy)`` in 3-D or ``(dx,)`` in plane strain: the pixel size in m.
    E, nu : float
        Young's modulus (Pa) and Poisson's ratio.
    reference_length : float, optional
        Plane strain only (required there): the distance in m at which a line load's normal and
        tangential displacement is zero (plane-strain displacements are defined up to a constant).
    entry : (int, int), optional
        One ``(row, column)`` entry only (computing just the integrals it needs).

    Returns
    -------
    ndarray, shape ``broadcast(x, y).shape + (3, 3)`` (3-D) or ``x.shape + (2, 2)``, in m/Pa
        Rows ``(uz, ux, uy)``, columns ``(p, qx, qy)``; ``[..., i, j](x) = [..., j, i](-x)``. With
        ``entry``, that entry alone, shape ``broadcast(x, y).shape``.
    """
    Es, G, beta = _moduli(E, nu)
    X = np.asarray(x, dtype=float)
    if y is None:
        a = 0.5 * spacing[0]
        L = float(reference_length)

        def H(u):  # integral of -ln|u / L|
            au = np.abs(u)
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(au > 0, u - u * np.log(np.where(au > 0, au, 1.0) / L), 0.0)

        out = np.zeros(X.shape + (2, 2))
        out[..., 0, 0] = out[..., 1, 1] = 2.0 / (math.pi * Es) * (H(X + a) - H(X - a))
        out[..., 0, 1] = beta / Es * (np.abs(X + a) - np.abs(X - a))
        out[..., 1, 0] = -out[..., 0, 1]
        return out if entry is None else out[..., entry[0], entry[1]]
    X, Y = np.broadcast_arrays(X, np.asarray(y, dtype=float))
    a, b = 0.5 * spacing[0], 0.5 * spacing[1]
    needed = _PRIMITIVES if entry is None else _NEEDS[tuple(entry)]
    I = {name: _pixel_integral(name, X, Y, a, b) for name in needed}
    cross = (1.0 - 2.0 * nu) / (4.0 * math.pi * G)
    formulas = {
        (0, 0): lambda: I["1/r"] / (math.pi * Es),
        (1, 1): lambda: ((1.0 - nu) * I["1/r"] + nu * I["u2/r3"]) / (2.0 * math.pi * G),
        (2, 2): lambda: ((1.0 - nu) * I["1/r"] + nu * I["v2/r3"]) / (2.0 * math.pi * G),
        (1, 2): lambda: nu * I["uv/r3"] / (2.0 * math.pi * G),
        (2, 1): lambda: nu * I["uv/r3"] / (2.0 * math.pi * G),
        (0, 1): lambda: cross * I["u/r2"],
        (1, 0): lambda: -cross * I["u/r2"],
        (0, 2): lambda: cross * I["v/r2"],
        (2, 0): lambda: -cross * I["v/r2"],
    }
    if entry is not None:
        return formulas[tuple(entry)]()
    out = np.zeros(X.shape + (3, 3))
    for (i, j), f in formulas.items():
        out[..., i, j] = f()
    return out

"""Per-wavenumber solution of elastic layers bonded on a rigid base or on a half-space (docs/theory.md 6).

One Fourier mode ``exp(i k x')`` (``x'`` along the wave vector, ``k = |k| > 0``) splits into an
in-plane problem driven by the normal pressure ``P`` and the tangential traction along the wave
``Q_par``, and an antiplane one driven by the traction across it ``Q_perp``. In each layer the
displacement is written in the mixed form ``G lap(u) + grad(Pi) = 0``, ``div(u) = (1 - 2 nu) Pi / G``
with the pressure-like unknown ``Pi = (lambda + G) div(u)``: nothing divides by ``1 - 2 nu``, so
``nu = 1/2`` (``div u = 0``, ``Pi`` the negative pressure) is an ordinary value, not a limit.

Its general solution is a sum of two families, each bounded by 1 inside the layer: one decaying
from the layer's top, ``exp(-k (z - z_top))``, one from its bottom, ``exp(-k (z_bot - z))``, each
with two constants ``(A, B)``. The constants of every layer are found together from the surface
tractions, the continuity of displacement and traction at each interface, and the base (zero
displacement on a rigid base; the decaying family of a half-space). No growing exponential ever
appears, so a layer thousands of wavelengths thick is as accurate as a thin one. Where a layer is
thinner than ``THIN / k`` the two families nearly coincide, and the layer uses instead the
propagator basis, its state at the top carried down by ``exp(A k z)`` (:func:`_propagator`), which
keeps full precision as ``k h -> 0``.

Amplitudes (real; the physical fields carry the factors of docs/theory.md 6): ``Ug = G k U``,
``Wg = G k W`` with ``u_x' = i U``, ``u_z = W``; ``N = sigma_zz``, ``X = sigma_x'x'``,
``Y = sigma_y'y'``, ``sigma_x'z = i S``. Antiplane: ``Vg = G k V`` with ``u_y' = V``,
``T = sigma_y'z``, ``sigma_x'y' = i Vg``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: the in-plane amplitudes each family yields, in this order
QUANTITIES = ("Ug", "Wg", "S", "N", "X", "Y")


@dataclass(frozen=True)
class Stack:
    """Layer arrays of a skin, top first: thickness (m), shear modulus (Pa), Poisson's ratio;
    ``base`` None for a rigid base, else ``(G, nu)`` of the base half-space.

    The shear moduli may be complex (a viscoelastic layer's ``G*(omega)`` in a harmonic steady
    state, docs/theory.md section 7): they enter only the ratios ``G_top / G_layer`` that scale the
    displacement rows and ``G k`` in the displacements, never the families, which depend on ``nu``
    and ``k`` alone; so ``nu = 1/2`` stays exact and ``G -> conj(G)`` conjugates every amplitude."""

    thickness: np.ndarray
    G: np.ndarray
    nu: np.ndarray
    base: tuple[float, float] | None

    @property
    def tops(self) -> np.ndarray:
        """Depth of each layer's top, m."""
        return np.concatenate([[0.0], np.cumsum(self.thickness)[:-1]])

    @property
    def dtype(self) -> np.dtype:
        """float64, or complex128 when a modulus is complex."""
        base = () if self.base is None else (self.base[0],)
        return np.result_type(self.G, *base, float)

    @property
    def total(self) -> float:
        return float(np.sum(self.thickness))

    def locate(self, z: float) -> int:
        """The layer holding depth ``z`` (an interface belongs to the layer above); ``len`` = the base."""
        bottoms = np.cumsum(self.thickness)
        hit = np.flatnonzero(z <= bottoms * (1 + 1e-12))
        return int(hit[0]) if hit.size else len(self.thickness)


def _family(x: np.ndarray, nu: float, up: bool) -> np.ndarray:
    """Amplitudes per unit constant of one family at local distance ``x = k * (distance from its
    origin)``: shape ``(*x.shape, 6, 2)``, quantities as :data:`QUANTITIES`, columns ``(A, B)``."""
    e = np.exp(-x)
    sign = 1.0 if up else -1.0  # the up family is the down one mirrored in z: W, S change sign
    c = 1.5 - 2.0 * nu
    out = np.empty(x.shape + (6, 2))
    out[..., 0, 0], out[..., 0, 1] = e, 0.5 * x * e
    out[..., 1, 0], out[..., 1, 1] = sign * e, sign * (0.5 * x + c) * e
    out[..., 2, 0], out[..., 2, 1] = sign * 2 * e, sign * (x + 1 - 2 * nu) * e
    out[..., 3, 0], out[..., 3, 1] = 2 * e, (2 - 2 * nu + x) * e
    out[..., 4, 0], out[..., 4, 1] = -2 * e, (2 * nu - x) * e
    out[..., 5, 0], out[..., 5, 1] = 0.0, 2 * nu * e
    return out


#: layers thinner than this many inverse wavenumbers (k h below it) use the propagator basis
THIN = 1.0


def _state_matrix(nu: float) -> np.ndarray:
    """``d/ds (Ug, Wg, S, N) = A (Ug, Wg, S, N)`` with ``s = k z`` (docs/theory.md 6); finite at nu = 1/2."""
    return np.array([[0.0, -1.0, 1.0, 0.0],
                     [nu / (1 - nu), 0.0, 0.0, (1 - 2 * nu) / (2 * (1 - nu))],
                     [2.0 / (1 - nu), 0.0, 0.0, -nu / (1 - nu)],
                     [0.0, 0.0, 1.0, 0.0]])


def _propagator(s: np.ndarray, nu: float) -> np.ndarray:
    """Amplitudes at ``s = k z`` (from the layer's top) per unit state ``(Ug, Wg, S, N)`` at the top:
    ``exp(A s) = c0 I + c1 A + c2 A^2 + c3 A^3`` (A's eigenvalues are +-1, each twice), shape
    ``(*s.shape, 6, 4)`` with ``X, Y`` from Hooke's law. For ``s <= 1`` only: bounded, and ``c3``, of
    order ``s^3``, is summed as a series where the closed form would cancel."""
    A = _state_matrix(nu)
    A2 = A @ A
    ch, sh = np.cosh(s), np.sinh(s)
    c0, c1, c2 = ch - 0.5 * s * sh, 0.5 * (3 * sh - s * ch), 0.5 * s * sh
    series = sum(n * s ** (2 * n + 1) / math.factorial(2 * n + 1) for n in range(1, 9))  # (s ch - sh) / 2
    c3 = np.where(s < 0.5, series, 0.5 * (s * ch - sh))
    phi = (c0[..., None, None] * np.eye(4) + c1[..., None, None] * A + c2[..., None, None] * A2
           + c3[..., None, None] * (A2 @ A))
    out = np.empty(s.shape + (6, 4))
    out[..., :4, :] = phi
    out[..., 4, :] = (nu * phi[..., 3, :] - 2 * phi[..., 0, :]) / (1 - nu)  # sigma_x'x'
    out[..., 5, :] = nu * (out[..., 4, :] + phi[..., 3, :])  # sigma_y'y' = nu (sigma_x'x' + sigma_zz)
    return out


def layer_values(k: np.ndarray, stack: Stack, j: int, z_local: float) -> np.ndarray:
    """Amplitudes per unit constant of layer ``j`` at ``z_local`` m below its top (the base: below
    the last interface): shape ``(K, 6, 4)``. Columns ``A_d, B_d, A_u, B_u`` (the base has 2) where
    ``k h >= THIN``; where the layer is thinner, the state ``(Ug, Wg, S, N)`` at its top (the
    propagator basis, whose columns stay independent as ``k h -> 0``)."""
    if j == len(stack.thickness):
        return _family(k * z_local, stack.base[1], up=False)
    h, nu = stack.thickness[j], stack.nu[j]
    down = _family(k * z_local, nu, up=False)
    up = _family(k * max(h - z_local, 0.0), nu, up=True)
    out = np.concatenate([down, up], axis=-1)
    thin = k * h < THIN
    if thin.any():
        out[thin] = _propagator(k[thin] * z_local, nu)
    return out


def _antiplane_values(k: np.ndarray, stack: Stack, j: int, z_local: float) -> np.ndarray:
    """``(Vg, T)`` per unit constant: shape ``(K, 2, 2)`` (columns ``D_d, D_u``; the base has 1)."""
    ed = np.exp(-k * z_local)
    if j == len(stack.thickness):
        return np.stack([ed, -ed], axis=-1)[..., None]
    eu = np.exp(-k * max(stack.thickness[j] - z_local, 0.0))
    return np.stack([np.stack([ed, eu], axis=-1), np.stack([-ed, eu], axis=-1)], axis=-2)


def _moduli(stack: Stack, j: int) -> float:
    return stack.base[0] if j == len(stack.thickness) else stack.G[j]


def solve_inplane(k: np.ndarray, stack: Stack) -> np.ndarray:
    """Constants of every layer for the two in-plane unit loads, shape ``(K, n, 2)``.

    Column 0: ``P = 1`` (``N = -1`` at the surface); column 1: ``Q_par = 1`` solved as ``S = 1``
    at the surface (the physical field is ``i`` times it, see docs/theory.md 6).
    """
    n_layers = len(stack.thickness)
    n = 4 * n_layers + (0 if stack.base is None else 2)
    K = k.shape[0]
    M = np.zeros((K, n, n), dtype=stack.dtype)
    g0 = stack.G[0]
    top = layer_values(k, stack, 0, 0.0)
    M[:, 0:2, 0:4] = top[:, [2, 3], :]
    row = 2
    scale = np.ones(4, dtype=stack.dtype)
    for j in range(n_layers):
        below = j + 1
        bottom = layer_values(k, stack, j, stack.thickness[j])
        if below == n_layers and stack.base is None:  # rigid base: no displacement
            M[:, row:row + 2, 4 * j:4 * j + 4] = bottom[:, [0, 1], :] * (g0 / stack.G[j])
            row += 2
            continue
        nxt = layer_values(k, stack, below, 0.0)
        scale[:2] = g0 / stack.G[j]
        M[:, row:row + 4, 4 * j:4 * j + 4] = bottom[:, :4, :] * scale[:, None]
        scale[:2] = g0 / _moduli(stack, below)
        width = nxt.shape[-1]
        M[:, row:row + 4, 4 * below:4 * below + width] = -nxt[:, :4, :] * scale[:, None]
        row += 4
    rhs = np.zeros((K, n, 2))
    rhs[:, 1, 0] = -1.0  # N = -P
    rhs[:, 0, 1] = 1.0   # S = 1 for Q_par (sigma_x'z = i S: the physical i Q_par is applied by the caller)
    return np.linalg.solve(M, rhs)


def solve_antiplane(k: np.ndarray, stack: Stack) -> np.ndarray:
    """Constants for a unit ``Q_perp`` (``T = -1`` at the surface), shape ``(K, n)``."""
    n_layers = len(stack.thickness)
    n = 2 * n_layers + (0 if stack.base is None else 1)
    K = k.shape[0]
    M = np.zeros((K, n, n), dtype=stack.dtype)
    g0 = stack.G[0]
    M[:, 0, 0:2] = _antiplane_values(k, stack, 0, 0.0)[:, 1, :]
    row = 1
    for j in range(n_layers):
        below = j + 1
        bottom = _antiplane_values(k, stack, j, stack.thickness[j])
        if below == n_layers and stack.base is None:
            M[:, row, 2 * j:2 * j + 2] = bottom[:, 0, :]
            row += 1
            continue
        nxt = _antiplane_values(k, stack, below, 0.0)
        M[:, row, 2 * j:2 * j + 2] = bottom[:, 0, :] * (g0 / stack.G[j])
        M[:, row, 2 * below:2 * below + nxt.shape[-1]] = -nxt[:, 0, :] * (g0 / _moduli(stack, below))
        M[:, row + 1, 2 * j:2 * j + 2] = bottom[:, 1, :]
        M[:, row + 1, 2 * below:2 * below + nxt.shape[-1]] = -nxt[:, 1, :]
        row += 2
    rhs = np.zeros((K, n))
    rhs[:, 0] = -1.0
    return np.linalg.solve(M, rhs[..., None])[..., 0]


def radial_stress(k: np.ndarray, stack: Stack, z: float, inplane=None, antiplane=None) -> dict[str, np.ndarray]:
    """The rotated-frame stress amplitudes at depth ``z`` (m) per unit load, for ``k > 0`` (rad/m).

    Returns ``{"Np", "Xp", "Yp", "Sp", "Nq", "Xq", "Yq", "Sq", "T", "R"}``, each shape ``(K,)``:
    suffix ``p`` for ``P = 1``, ``q`` for ``Q_par`` (the field is ``i`` times the amplitude for
    N, X, Y and ``-1`` times it for S), ``T = sigma_y'z`` and ``R`` (``sigma_x'y' = i R``) for
    ``Q_perp = 1``.
    """
    inplane = solve_inplane(k, stack) if inplane is None else inplane
    antiplane = solve_antiplane(k, stack) if antiplane is None else antiplane
    j = stack.locate(z)
    top = stack.total if j == len(stack.thickness) else stack.tops[j]
    vals = layer_values(k, stack, j, z - top)
    ap = _antiplane_values(k, stack, j, z - top)
    cols = slice(4 * j, 4 * j + vals.shape[-1])
    amp = np.einsum("kqc,kcl->kql", vals, inplane[:, cols, :])
    ap_amp = np.einsum("kqc,kc->kq", ap, antiplane[:, 2 * j:2 * j + ap.shape[-1]])
    out = {}
    for i, name in ((2, "S"), (3, "N"), (4, "X"), (5, "Y")):
        out[name + "p"], out[name + "q"] = amp[:, i, 0], amp[:, i, 1]
    out["T"], out["R"] = ap_amp[:, 1], ap_amp[:, 0]
    return out


def surface_amplitudes(k: np.ndarray, stack: Stack) -> dict[str, np.ndarray]:
    """Surface displacements per unit load, m/Pa, for ``k > 0``: ``Wp, Up`` (``P = 1``: ``u_z = Wp``,
    ``u_par = i Up``), ``Wq, Uq`` (``Q_par = 1``: ``u_z = i Wq``, ``u_par = -Uq``), ``V`` (``Q_perp = 1``:
    ``u_perp = V``)."""
    inplane = solve_inplane(k, stack)
    antiplane = solve_antiplane(k, stack)
    vals = layer_values(k, stack, 0, 0.0)[:, :2, :]  # Ug, Wg only
    amp = np.einsum("kqc,kcl->kql", vals, inplane[:, 0:4, :])
    gk = stack.G[0] * k
    ap = _antiplane_values(k, stack, 0, 0.0)
    vg = np.einsum("kc,kc->k", ap[:, 0, :], antiplane[:, 0:2])
    return {"Up": amp[:, 0, 0] / gk, "Wp": amp[:, 1, 0] / gk, "Uq": amp[:, 0, 1] / gk, "Wq": amp[:, 1, 1] / gk,
            "V": vg / gk}

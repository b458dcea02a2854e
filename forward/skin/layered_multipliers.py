"""Fourier multipliers of a layered skin on a grid: surface tractions to stress at one depth.

For each mode the rotated-frame amplitudes of :mod:`.propagator` (functions of ``|k|`` only, computed
once per distinct ``|k|`` of the grid) are turned back to the (x, y) frame with the mode's direction
``n = (c, s)`` (docs/theory.md section 6). The rules of the half-space's spectral method hold here
too: terms odd in ``c`` (``s``) vanish on the Nyquist column (row) of an even grid, so the map is
exactly real-linear with the conjugate multiplier as its adjoint; the ``k = 0`` mode holds the
uniform solution (laterally constrained layers on a rigid base; on a half-space base the
direction-averaged limit, as the half-space's own).
"""

from __future__ import annotations

import collections
import threading

import numpy as np

from tactilab.core.rules import COMPONENTS as VOIGT
from tactilab.forward.halfspace import angular_wavenumbers

from .propagator import Stack, radial_stress

#: multiplier tables kept (least recently used out first): grids x depths x output sets, within a memory budget
_CACHE_ENTRIES = 16
CACHE_BYTES = 256 * 2**20
_CACHE: collections.OrderedDict = collections.OrderedDict()
_LOCK = threading.Lock()
_NAMES = ("Np", "Xp", "Yp", "Sp", "Nq", "Xq", "Yq", "Sq", "T", "R")


class Directions:
    """Direction monomials of every mode of a half spectrum, with the Nyquist and ``k = 0`` rules."""

    def __init__(self, shape: tuple[int, ...], spacing: tuple[float, ...]):
        ks = angular_wavenumbers(shape, spacing, half=True)
        if len(ks) == 1:  # plane strain: n = sign(xi) e_x
            xi = ks[0]
            self.rho = np.abs(xi)
            self.c = np.sign(xi)
            if shape[-1] % 2 == 0:
                self.c[-1] = 0.0
            self.s = np.zeros_like(self.rho)
            self.c2, self.s2 = np.ones_like(self.rho), np.zeros_like(self.rho)
            self.cs = np.zeros_like(self.rho)
            return
        xi, eta = np.broadcast_arrays(*ks)
        rho = np.hypot(xi, eta)
        live = rho > 0
        safe = np.where(live, rho, 1.0)
        c, s = np.where(live, xi / safe, 0.0), np.where(live, eta / safe, 0.0)
        self.rho = rho
        self.c2, self.s2 = np.where(live, c * c, 0.5), np.where(live, s * s, 0.5)
        if shape[-1] % 2 == 0:
            c[:, -1] = 0.0
        if shape[0] % 2 == 0:
            s[shape[0] // 2, :] = 0.0
        self.c, self.s, self.cs = c, s, c * s

    @classmethod
    def at_points(cls, kx: np.ndarray, ky: np.ndarray) -> "Directions":
        """The monomials at arbitrary wavenumbers (rad/m, same shape), without the Nyquist rule."""
        d = cls.__new__(cls)
        rho = np.hypot(kx, ky)
        live = rho > 0
        safe = np.where(live, rho, 1.0)
        c, s = np.where(live, kx / safe, 0.0), np.where(live, ky / safe, 0.0)
        d.rho, d.c, d.s, d.cs = rho, c, s, c * s
        d.c2, d.s2 = np.where(live, c * c, 0.5), np.where(live, s * s, 0.5)
        return d


def uniform_amplitudes(stack: Stack, z: float) -> dict[str, float]:
    """The ``k = 0`` amplitudes at depth ``z`` (m): the response to uniform tractions.

    Rigid base: the layers are laterally constrained, ``sigma_x'x' = sigma_y'y' = -nu / (1 - nu) P``.
    Half-space base: the layers share the in-plane strain of the base's surface under the
    direction-averaged limit of the half-space (docs/theory.md sections 2 and 6).
    """
    j = stack.locate(z)
    out = dict.fromkeys(_NAMES, 0.0)
    out.update(Np=-1.0, Sq=1.0, T=-1.0)
    if j == len(stack.thickness):  # in the base half-space: its own limit
        out.update(Xp=-1.0, Yp=-2.0 * stack.base[1])
        return out
    nu = float(stack.nu[j])
    if stack.base is None:
        out.update(Xp=-nu / (1 - nu), Yp=-nu / (1 - nu))
        return out
    g_b, nu_b = stack.base
    strain = -(1 - 2 * nu_b) / (2 * g_b)  # the base surface's eps_x'x' under P = 1 (plane strain)
    x = -nu / (1 - nu) + 2 * stack.G[j] / (1 - nu) * strain  # E / (1 - nu^2) = 2 G / (1 - nu)
    out.update(Xp=x, Yp=nu * (x - 1.0))
    return out


def radial_grid(stack: Stack, d: Directions, z: float) -> dict[str, np.ndarray]:
    """The rotated-frame amplitudes at depth ``z`` on every mode of the grid (one solve per distinct |k|)."""
    live = d.rho > 0
    unique, inverse = np.unique(d.rho[live], return_inverse=True)
    radial = radial_stress(unique, stack, z) if unique.size else {}
    zero = uniform_amplitudes(stack, z)
    out = {}
    for name in _NAMES:
        grid = np.full(d.rho.shape, zero[name], dtype=stack.dtype)
        if unique.size:
            grid[live] = radial[name][inverse]
        out[name] = grid
    return out


def voigt_multipliers(r: dict, d: Directions) -> dict[str, np.ndarray]:
    """Per load ``p, qx, qy``: the complex multipliers of the six Voigt stress components, shape ``(6, *grid)``."""
    c, s, c2, s2, cs = d.c, d.s, d.c2, d.s2, d.cs
    i = 1j
    p = [c2 * r["Xp"] + s2 * r["Yp"], s2 * r["Xp"] + c2 * r["Yp"], r["Np"],
         i * s * r["Sp"], i * c * r["Sp"], cs * (r["Xp"] - r["Yp"])]
    along, across = c2 * r["Xq"] + s2 * r["Yq"], s2 * r["Xq"] + c2 * r["Yq"]
    diff = r["Xq"] - r["Yq"]
    qx = [i * (c * along + 2 * c * s2 * r["R"]), i * (c * across - 2 * c * s2 * r["R"]), i * c * r["Nq"],
          -cs * (r["Sq"] + r["T"]), -c2 * r["Sq"] + s2 * r["T"], i * (c2 * s * diff - s * (c2 - s2) * r["R"])]
    qy = [i * (s * along - 2 * s * c2 * r["R"]), i * (s * across + 2 * s * c2 * r["R"]), i * s * r["Nq"],
          -s2 * r["Sq"] + c2 * r["T"], -cs * (r["Sq"] + r["T"]), i * (c * s2 * diff + c * (c2 - s2) * r["R"])]
    return {name: np.asarray(rows, dtype=complex) for name, rows in (("p", p), ("qx", qx), ("qy", qy))}


def output_multipliers(skin, shape: tuple[int, ...], spacing: tuple[float, ...], z: float,
                       weights: np.ndarray, loads: tuple[str, ...]) -> dict[str, np.ndarray]:
    """``{load: multiplier (n_out, *half grid)}``: outputs ``weights @ sigma_voigt`` per unit load spectrum.

    Cached per (skin, grid, depth, weights, loads): a repeated call (frames, scans) only applies them.
    """
    weights = np.atleast_2d(np.asarray(weights, dtype=float))
    key = (repr(skin), tuple(shape), tuple(spacing), float(z), weights.tobytes(), weights.shape, tuple(loads))
    with _LOCK:
        if key in _CACHE:
            _CACHE.move_to_end(key)
            return _CACHE[key]
    d = Directions(tuple(shape), tuple(spacing))
    per_load = voigt_multipliers(radial_grid(skin._stack, d, z), d)
    table = {name: np.tensordot(weights, per_load[name], axes=(1, 0)) for name in loads}
    with _LOCK:
        _CACHE[key] = table
        while len(_CACHE) > 1 and (len(_CACHE) > _CACHE_ENTRIES or _cache_bytes() > CACHE_BYTES):
            _CACHE.popitem(last=False)
    return table


def _cache_bytes() -> int:
    return sum(a.nbytes for table in _CACHE.values() for a in table.values())


def clear_cache() -> None:
    """Forget every cached multiplier table."""
    with _LOCK:
        _CACHE.clear()


def transfer_matrix(skin, kx, ky, z: float) -> np.ndarray:
    """The exact stress multipliers at wavenumbers ``(kx, ky)`` (rad/m, no Nyquist rule), shape
    ``(*broadcast, 6, 3)``: Voigt stress (Pa) per unit load spectrum of ``(p, qx, qy)`` at depth ``z`` (m)."""
    kx, ky = np.broadcast_arrays(np.asarray(kx, float), np.asarray(ky, float))
    d = Directions.at_points(kx, ky)
    per_load = voigt_multipliers(radial_grid(skin._stack, d, z), d)
    return np.stack([np.moveaxis(per_load[n], 0, -1) for n in ("p", "qx", "qy")], axis=-1)


__all__ = ["Directions", "VOIGT", "clear_cache", "output_multipliers", "transfer_matrix", "uniform_amplitudes"]

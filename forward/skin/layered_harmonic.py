"""Harmonic steady states of a viscoelastic layered skin: the layered multipliers at complex moduli.

In a steady state of angular frequency ``omega`` every layer answers with its complex modulus
``E*(omega)`` (docs/theory.md section 7), so one Fourier mode of a layered skin is the elastic
mode of :mod:`.propagator` with complex shear moduli ``G*_j(omega) = E*_j(omega) / (2 (1 + nu_j))``.
A pattern sliding at speed V along +x puts the mode of wavenumber ``kx`` at ``omega = -kx V`` (a
material point sees ``exp(i kx (x - V t))``), so each column of the half spectrum gets its own
complex stack; modes sharing a frequency are solved together (one batched solve per distinct
``|k|`` of the column).

The Nyquist column of an even grid cannot tell a wave travelling along +x from one along -x
(its real mode is their sum): it gets the average of the two, which for amplitudes obeying
``A(-omega) = conj(A(omega))`` is the real part.
"""

from __future__ import annotations

import collections
import threading
from types import SimpleNamespace

import numpy as np

from tactilab.core.rules import COMPONENTS as VOIGT
from tactilab.forward.halfspace import angular_wavenumbers, compliance_matrix

from .layered_multipliers import _NAMES, Directions, radial_grid, voigt_multipliers
from .propagator import surface_amplitudes

_CACHE: collections.OrderedDict = collections.OrderedDict()
_CACHE_ENTRIES = 8
_LOCK = threading.Lock()


def deflection_gain(skin, rho: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Surface pressure per unit normal deflection (Pa/m, complex) of a frictionless full contact,
    ``1 / (uz~ / p~)`` per mode of wavenumber ``rho`` (rad/m) at frequency ``omega`` (rad/s); 0 at ``rho = 0``
    (the mean deflection is an approach and carries no pressure in a periodic steady state)."""
    rho, omega = np.broadcast_arrays(np.asarray(rho, float), np.asarray(omega, float))
    out = np.zeros(rho.shape, dtype=complex)
    live = rho > 0
    for w in np.unique(omega[live]):
        sel = live & (omega == w)
        unique, inverse = np.unique(rho[sel], return_inverse=True)
        out[sel] = 1.0 / surface_amplitudes(unique, skin.stack_at(float(w)))["Wp"][inverse]
    return out


def radial_amplitudes(skin, rho: np.ndarray, omega: np.ndarray, z: float, per_deflection: bool,
                      strain: bool) -> dict[str, np.ndarray]:
    """Rotated-frame amplitudes (docs/theory.md 6) at depth ``z`` (m) per mode, complex, shape ``rho.shape``.

    ``per_deflection``: per unit normal deflection (the pressure of :func:`deflection_gain` applied,
    ``P`` loads only); ``strain``: divided by the modulus ``E*(omega)`` of the layer at ``z`` (the
    strain is ``compliance_matrix(1, nu) @ stress / E*``).
    """
    rho, omega = np.broadcast_arrays(np.asarray(rho, float), np.asarray(omega, float))
    out = {name: np.zeros(rho.shape, dtype=complex) for name in _NAMES}
    for w in np.unique(omega):
        sel = omega == w
        r = radial_grid(skin.stack_at(float(w)), SimpleNamespace(rho=rho[sel]), z)
        for name in _NAMES:
            out[name][sel] = r[name]
    scale = np.ones(rho.shape, dtype=complex)
    if per_deflection:
        scale = deflection_gain(skin, rho, omega)
    if strain:
        scale = scale / skin.complex_modulus_at(z, omega)
    return {name: a * scale for name, a in out.items()}


def sliding_multipliers(skin, shape: tuple[int, ...], spacing: tuple[float, ...], z: float, comps: tuple[str, ...],
                        quantity: str, loads: tuple[str, ...], speed: float, per_deflection: bool) -> dict:
    """``{load: multiplier (n_out, *half grid)}`` of a pattern sliding at ``speed`` (m/s) along +x.

    Per unit load spectrum (``per_deflection`` False: tractions ``p, qx, qy`` in Pa) or per unit
    deflection spectrum (True: m, the load ``"p"`` only), to stress (Pa) or TENSOR strain at depth
    ``z`` (m). Cached per (skin, grid, depth, outputs, speed): a scan at one speed applies them only.
    """
    key = (repr(skin), tuple(shape), tuple(spacing), float(z), tuple(comps), quantity, tuple(loads), float(speed),
           per_deflection)
    with _LOCK:
        if key in _CACHE:
            _CACHE.move_to_end(key)
            return _CACHE[key]
    d = Directions(tuple(shape), tuple(spacing))
    kx = angular_wavenumbers(tuple(shape), tuple(spacing), half=True)[0]
    omega = np.broadcast_to(-kx * speed, d.rho.shape)
    r = radial_amplitudes(skin, d.rho, omega, z, per_deflection, quantity == "strain")
    if shape[-1] % 2 == 0:  # the Nyquist column: the average of the two directions of travel
        for name in _NAMES:
            r[name][..., -1] = r[name][..., -1].real
    per_load = voigt_multipliers(r, d)
    idx = [VOIGT.index(c) for c in comps]
    weights = np.eye(6)[idx] if quantity == "stress" else compliance_matrix(1.0, skin.nu_at(z))[idx]
    table = {name: np.tensordot(weights, per_load[name], axes=(1, 0)) for name in loads}
    with _LOCK:
        _CACHE[key] = table
        while len(_CACHE) > _CACHE_ENTRIES:
            _CACHE.popitem(last=False)
    return table


def point_multipliers(skin, kx, ky, z: float, omega, per_deflection: bool, strain: bool) -> np.ndarray:
    """Exact multipliers at wavenumbers ``(kx, ky)`` (rad/m) and frequencies ``omega`` (rad/s), broadcast;
    no Nyquist rule. Shape ``(..., 6, 3)`` per unit traction, ``(..., 6)`` per unit deflection."""
    kx, ky, omega = np.broadcast_arrays(np.asarray(kx, float), np.asarray(ky, float), np.asarray(omega, float))
    d = Directions.at_points(kx, ky)
    per_load = voigt_multipliers(radial_amplitudes(skin, d.rho, omega, z, per_deflection, strain), d)
    out = np.stack([np.moveaxis(per_load[n], 0, -1) for n in ("p", "qx", "qy")], axis=-1)
    if strain:
        out = np.einsum("ij,...jl->...il", compliance_matrix(1.0, skin.nu_at(z)), out)
    return out[..., 0] if per_deflection else out


def clear_cache() -> None:
    """Forget every cached sliding multiplier table."""
    with _LOCK:
        _CACHE.clear()

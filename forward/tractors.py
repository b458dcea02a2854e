"""Laterotactile tractors: closed-form strain at depth of tractor pairs, arrays and drives.

Plane problem (docs/theory.md section 4a): tractors are tangential line loads along +x on the skin
surface z = 0 (uniform in y), receptors sit at depth ``Z`` (``depth``, m, z > 0 inside the skin).
Loads are the tractions applied TO the skin; a line load ``q`` is a force per unit length in y
(N/m). Strain is returned as a Voigt vector ordered (xx, yy, zz, yz, zx, xy) with TENSOR shear
``eps_zx`` (the symmetric strain tensor); engineering shear ``gamma_zx = 2 eps_zx``, as listed in
docs/theory.md and in the tactile synthesis literature, is obtained with :func:`to_engineering_shear`.

Closed forms used (derived from Flamant's tangential line load, section 3 of docs/theory.md):
with ``w = u + iZ`` (``u`` the horizontal distance from the tractor),

- ``sigma_xx = -(T/pi) Re(a + b)``, ``sigma_zz = -(T/pi) Re(a - b)``, ``sigma_xz = (T/pi) Im b``,
  where ``a = 1/w`` and ``b = u / w**2 = 1/w - iZ/w**2``;
- a finite footprint of width ``c`` (traction ``T/c`` on ``[u - c/2, u + c/2]``) replaces ``a``
  and ``b`` by their averages over the footprint, which integrate in closed form
  (``log w`` and ``iZ/w`` are antiderivatives), written without cancellation;
- a pair ``-q delta(x + d) + q delta(x - d)`` at ``nu = 1/2`` gives ``Phi - i Psi / 2 = C`` with
  ``C = -d/(w^2 - d^2) + 2 i Z w d/(w^2 - d^2)^2`` (``w = x + iZ``): the same as the Phi and Psi
  of docs/theory.md, but free of the cancellation that the difference form suffers as d -> 0.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

# the input rules live on the ground floor, which loads no solver: ``tactilab --help`` loads this
# module (through the display code) and must not load the solver
from tactilab.core import rules as check
from tactilab.core.memory import check_count
from tactilab.core.rules import COMPONENTS

#: Voigt order of the stress components (the one order, tactilab.core.rules.COMPONENTS)
VOIGT = COMPONENTS
SHEAR_INDICES = (3, 4, 5)


# ----- validation helpers --------------------------------------------------------------------
def _non_negative(value, name: str, unit: str = "m") -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number in {unit}, got {check.show(value)}") from None
    if not math.isfinite(v) or v < 0:
        raise ValueError(f"{name}: must be finite and >= 0 {unit}, got {check.show(value)}; give 0 for a line load")
    return v


#: bytes per tractor pair of the arrays a tractor array allocates at once (centres, positions, signs and
#: their sorted and temporary copies: five float64 arrays of 2 values per pair)
PAIR_BYTES = 5 * 2 * 8


def check_pairs(pairs: int, name: str = "pairs") -> int:
    """Validate a number of tractor pairs (an integer >= 1, within the memory rule) and return it as ``int``.

    ``name`` is the argument that set it (``--pairs`` on the command line)."""
    if isinstance(pairs, bool) or not isinstance(pairs, (int, np.integer)) or pairs < 1:
        raise ValueError(f"{name}: the number of tractor pairs must be an integer >= 1, got {pairs!r}")
    return check_count(int(pairs), PAIR_BYTES, name, "tractor pairs (their centres, positions and signs)")


def to_engineering_shear(strain_voigt: np.ndarray) -> np.ndarray:
    """Convert a Voigt strain (..., 6) from tensor shear eps_ij to engineering shear gamma_ij = 2 eps_ij.

    Parameters
    ----------
    strain_voigt : ndarray, shape (..., 6)
        Strain (xx, yy, zz, yz, zx, xy) with TENSOR shear (dimensionless).

    Returns
    -------
    ndarray, shape (..., 6)
        The same strain with the three shear entries doubled.
    """
    s = np.array(strain_voigt, dtype=float, copy=True)
    if s.shape[-1:] != (6,):
        raise ValueError(f"strain_voigt: expected a trailing axis of length 6 (xx, yy, zz, yz, zx, xy), got shape {s.shape}")
    s[..., SHEAR_INDICES] *= 2.0
    return s


# ----- pair and array closed forms (nu = 1/2) -----------------------------------------------
def _pair_complex(x: np.ndarray, half_spacing: float, depth: float) -> np.ndarray:
    w = x + 1j * depth
    den = w * w - half_spacing * half_spacing
    return -half_spacing / den + 2j * depth * w * half_spacing / (den * den)


def pair_phi_psi(x: ArrayLike, half_spacing: float, depth: float) -> tuple[np.ndarray, np.ndarray]:
    """Phi(x) and Psi(x) of a tractor pair (docs/theory.md 4a), in 1/m.

    The pair is ``q [-delta(x + d) + delta(x - d)]`` (tangential line loads, N/m); at depth Z
    with nu = 1/2, ``eps_xx = 3 q Phi / (pi E)``, ``eps_zz = -eps_xx`` and the ENGINEERING shear
    ``gamma_zx = 3 q Psi / (pi E)`` (tensor shear ``eps_zx = 3 q Psi / (2 pi E)``).

    Parameters
    ----------
    x : array_like
        Horizontal positions, m (any shape).
    half_spacing : float
        ``d``, half the distance between the two tractors, m, > 0.
    depth : float
        ``Z``, receptor depth, m, > 0.

    Returns
    -------
    phi, psi : ndarray, same shape as ``x``, 1/m
        Stable for every d > 0, including d << Z (the dipole limit, see :func:`dipole_phi_psi`).
    """
    d = check.positive(half_spacing, "half_spacing", fix="the tractor spacing must be > 0 (give d in m)")
    z = check.depth(depth)
    c = _pair_complex(check.finite_array(x, "x", "m"), d, z)
    return c.real, -2.0 * c.imag


def dipole_phi_psi(x: ArrayLike, depth: float) -> tuple[np.ndarray, np.ndarray]:
    """The d -> 0 limit of ``pair_phi_psi / d`` (a tangential force dipole), in 1/m^2.

    ``Phi(x; d) = d * phi_1(x) + O(d^3)``; with ``w = x + iZ``,
    ``phi_1 - i psi_1 / 2 = -1/w^2 + 2 i Z / w^3``.
    """
    z = check.depth(depth)
    w = check.finite_array(x, "x", "m") + 1j * z
    c = -1.0 / w**2 + 2j * z / w**3
    return c.real, -2.0 * c.imag


def array_centres(half_spacing: float, pairs: int) -> tuple[np.ndarray, int]:
    """Centres ``4 n d`` (m) of the pairs of a symmetric array, and the array's sign.

    ``pairs`` pairs are centred on x = 0. For an odd number, the centres are ``4 n d`` with
    ``n = -(N-1)/2 .. (N-1)/2`` and the sign is +1: the array of docs/theory.md. For an even number
    the centres fall on ``4 (n + 1/2) d`` and the sign is -1, so that in both cases the tractors
    sit at the odd multiples of d and the tractor at x = +d pushes along +x: the array samples
    ``sin(2 pi x / (4 d))`` at its peaks, as the target pattern of the design objective assumes.
    """
    n = check_pairs(pairs)
    d = check.positive(half_spacing, "half_spacing", fix="the tractor spacing must be > 0 (give d in m)")
    centres = (4.0 * np.arange(n) - 2.0 * (n - 1)) * d
    return centres, (1 if n % 2 == 1 else -1)


def array_tractors(half_spacing: float, pairs: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions (m) and unit signs of the ``2 * pairs`` tractors of the array.

    Returns
    -------
    x, sign : ndarray, shape (2 * pairs,)
        Tractors at ``+-d, +-3d, ...``; ``sign = sin(pi x / (2 d))`` (+1 or -1).
    """
    centres, sign = array_centres(half_spacing, pairs)
    d = float(half_spacing)
    x = np.sort(np.concatenate([centres - d, centres + d]))
    signs = np.rint(np.sin(np.pi * x / (2.0 * d)))
    return x, signs


def array_phi_psi(x: ArrayLike, half_spacing: float, depth: float, pairs: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """S_Phi(x) = sum_n Phi(x - 4 n d) and S_Psi(x) for an array of ``pairs`` pairs, in 1/m.

    See :func:`array_centres` for the layout (odd ``pairs``: exactly docs/theory.md's sum).
    """
    z = check.depth(depth)
    centres, sign = array_centres(half_spacing, pairs)
    xs = check.finite_array(x, "x", "m")
    c = np.zeros(xs.shape, dtype=complex)
    for centre in centres:
        c += _pair_complex(xs - centre, float(half_spacing), z)
    c *= sign
    return c.real, -2.0 * c.imag


# ----- single tractors with a footprint, general nu ------------------------------------------
def _complex_log1p(z: np.ndarray) -> np.ndarray:
    # numpy's complex log1p is log(1 + z) and loses the digits of small z
    re, im = z.real, z.imag
    return 0.5 * np.log1p(re * (2.0 + re) + im * im) + 1j * np.arctan2(im, 1.0 + re)


def _ab(u: np.ndarray, depth: float, footprint: float) -> tuple[np.ndarray, np.ndarray]:
    """a = 1/w, b = u/w^2 (w = u + iZ), averaged over the footprint when it is > 0."""
    if footprint == 0.0:
        w = u + 1j * depth
        a = 1.0 / w
        return a, a - 1j * depth / (w * w)
    half = 0.5 * footprint
    w1 = u + half + 1j * depth
    w2 = u - half + 1j * depth
    a = _complex_log1p(footprint / w2) / footprint
    return a, a - 1j * depth / (w1 * w2)


def tractor_stress_kernel(u: ArrayLike, depth: float, footprint: float = 0.0) -> np.ndarray:
    """Plane-strain stress at depth per unit tangential line load, (xx, zz, zx), in 1/m.

    Parameters
    ----------
    u : array_like
        Horizontal distance from the tractor centre, m.
    depth : float
        Z, m, > 0.
    footprint : float
        Contact width of the tractor along x, m (0: a line load). The load is spread
        uniformly over ``[-footprint/2, footprint/2]``.

    Returns
    -------
    ndarray, shape u.shape + (3,)
        ``sigma_xx, sigma_zz, sigma_zx`` for a load of 1 N/m along +x (multiply by q in N/m to
        get Pa). Independent of nu (sigma_yy = nu (sigma_xx + sigma_zz) in plane strain).
    """
    z = check.depth(depth)
    c = _non_negative(footprint, "footprint")
    a, b = _ab(check.finite_array(u, "u", "m"), z, c)
    out = np.empty(a.shape + (3,))
    out[..., 0] = -(a.real + b.real) / np.pi
    out[..., 1] = -(a.real - b.real) / np.pi
    out[..., 2] = b.imag / np.pi
    return out


def plane_strain_from_stress(stress_xz: np.ndarray, young_modulus: float, nu: float) -> np.ndarray:
    """Voigt strain (..., 6), TENSOR shear, from plane-strain stresses (..., 3) = (xx, zz, zx) in Pa."""
    e = check.young_modulus(young_modulus)
    v = check.poisson_ratio(nu)
    sxx, szz, szx = stress_xz[..., 0], stress_xz[..., 1], stress_xz[..., 2]
    out = np.zeros(stress_xz.shape[:-1] + (6,))
    # eps_yy = 0 with sigma_yy = nu (sxx + szz); no division by 1 - 2 nu anywhere
    out[..., 0] = (1 + v) * ((1 - v) * sxx - v * szz) / e
    out[..., 2] = (1 + v) * ((1 - v) * szz - v * sxx) / e
    out[..., 4] = (1 + v) * szx / e
    return out


def tractor_row_strain(x: ArrayLike, depth: float, tractor_x: ArrayLike, line_loads: ArrayLike, young_modulus: float,
                       nu: float = 0.5, footprint: float = 0.0) -> np.ndarray:
    """Strain at depth under a row of tractors driven with tangential line loads (plane strain).

    Parameters
    ----------
    x : array_like, shape (nx,)
        Receptor positions along x, m.
    depth : float
        Receptor depth Z, m.
    tractor_x : array_like, shape (n_tractors,)
        Tractor centres, m.
    line_loads : array_like, shape (..., n_tractors)
        Tangential line load of each tractor along +x, N/m (leading axes: e.g. time frames).
        A traction ``tau`` (Pa) over a footprint of width ``c`` is the line load ``tau * c``.
    young_modulus : float
        E, Pa.
    nu : float
        Poisson's ratio (default 0.5, the incompressible skin of docs/theory.md 4a).
    footprint : float
        Contact width of each tractor along x, m (0: line loads).

    Returns
    -------
    ndarray, shape (..., nx, 6)
        Voigt strain (xx, yy, zz, yz, zx, xy), TENSOR shear (eps_yy = eps_yz = eps_xy = 0).
    """
    xs = check.finite_array(x, "x", "m").reshape(-1)
    tx = check.finite_array(tractor_x, "tractor_x", "m").reshape(-1)
    q = check.finite_array(line_loads, "line_loads", "N/m")
    if q.shape[-1:] != tx.shape:
        raise ValueError(
            f"line_loads: trailing axis must hold one load per tractor ({tx.size}), got shape {q.shape}; "
            "give shape (..., n_tractors) in N/m"
        )
    kernel = tractor_stress_kernel(xs[:, None] - tx[None, :], depth, footprint)  # (nx, ntr, 3)
    stress = np.einsum("...t,xtc->...xc", q, kernel)
    return plane_strain_from_stress(stress, young_modulus, nu)


# ----- the real sliding surface --------------------------------------------------------------
def sliding_sinusoid_strain(x: ArrayLike, depth: float, amplitude: float, pitch: float, speed: float = 0.0,
                            time: ArrayLike = 0.0, nu: float = 0.5) -> np.ndarray:
    """Strain at depth under a frictionless sinusoidal surface ``H = A sin(2 pi (x + V t) / p)``.

    H is the indentation (surface deflection into the skin, m); the surface slides at speed V
    (m/s) along -x, so that the pattern at time t is H(x + V t). The pressure is the spectral
    prescribed-displacement solution ``P = E k H / (2 (1 - nu^2))`` (k = 2 pi / p); strain is
    independent of E. At nu = 1/2 it is docs/theory.md 4a's closed form,
    ``eps_xx = -eps_zz = K sin(k (x + V t))``, ``gamma_zx = 2 K cos(...)``, ``K = k^2 A Z e^{-k Z}``.

    Parameters
    ----------
    x : array_like, shape (nx,)
        Positions, m.
    depth, amplitude, pitch : float
        Z (m, > 0), A (m, any sign), p (m, > 0).
    speed : float
        V, m/s.
    time : float or array_like, shape (nt,)
        Times, s.
    nu : float
        Poisson's ratio.

    Returns
    -------
    ndarray, shape (nx, 6) for scalar time, else (nt, nx, 6)
        Voigt strain with TENSOR shear.
    """
    z = check.depth(depth)
    p = check.positive(pitch, "pitch")
    amp = float(check.finite_array(amplitude, "amplitude", "m"))
    v = float(check.finite_array(speed, "speed", "m/s"))
    nu = check.poisson_ratio(nu)
    xs = check.finite_array(x, "x", "m").reshape(-1)
    t = check.finite_array(time, "time", "s")
    phase = 2 * np.pi * (xs[None, :] + v * t.reshape(-1)[:, None]) / p
    k = 2 * np.pi / p
    kz = k * z
    # pressure amplitude over E: P/E = k A / (2 (1 - nu^2)); the factor E cancels in the strain
    p_over_e = k * amp / (2.0 * (1.0 - nu * nu))
    decay = np.exp(-kz)
    s, c = np.sin(phase), np.cos(phase)
    stress = np.empty(phase.shape + (3,))  # in units of E
    stress[..., 0] = -p_over_e * (1 - kz) * decay * s
    stress[..., 1] = -p_over_e * (1 + kz) * decay * s
    stress[..., 2] = p_over_e * kz * decay * c
    strain = plane_strain_from_stress(stress, 1.0, nu)
    return strain[0] if np.ndim(time) == 0 else strain

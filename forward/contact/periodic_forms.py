"""Closed forms of periodic contacts: Westergaard's sinusoid and the periodic flat punch (plane strain).

Both are rigid, frictionless, periodic surfaces of wavelength ``L`` pressed into an elastic
half-space (``E* = E / (1 - nu^2)``) at mean pressure ``p_bar``; they are the oracles of the
contact engine's periodic cells and of the cheap texture models (Johnson, *Contact Mechanics*,
1985, section 13.3; the punch: Johnson's flat punch made periodic by the same conformal map).
Conventions (docs/theory.md section 1): heights positive towards the skin, ``p`` pushes into it;
a crest sits at x = 0; SI units.

**Westergaard.** The surface ``z = Delta cos(2 pi x / L)``. Full contact holds for
``p_bar >= p* = pi E* Delta / L``, with ``p(x) = p_bar + p* cos(2 pi x / L)``. Below p* the contact
is the band ``|x| < a`` around each crest, ``sin^2(pi a / L) = p_bar / p*``, and::

    p(x) = 2 p_bar cos(pi x / L) sqrt(sin^2(pi a / L) - sin^2(pi x / L)) / sin^2(pi a / L)

**Periodic flat punch** (a deep square grating: plateaus of half-width ``b`` whose grooves the
skin never reaches)::

    p(x) = p_bar cos(pi x / L) / sqrt(sin^2(pi b / L) - sin^2(pi x / L))      (|x| < b)

**Harmonics.** ``p(x) = sum_n c_n cos(2 pi n x / L)`` with ``c_0 = p_bar`` and, for ``n >= 1``,
with ``z = cos(2 pi a / L)`` (``a = b`` for the punch) and Legendre's ``P_n`` (both from the
Mehler--Dirichlet integral; derived for this module and checked by quadrature in the tests)::

    punch:        c_n = p_bar (P_n(z) + P_{n-1}(z))
    Westergaard:  c_n = p_bar (J_n(z) + J_{n-1}(z)) / (1 - z),   J_0 = 1 - z,
                  J_n = (P_{n-1}(z) - P_{n+1}(z)) / (2 n + 1)     (= int_z^1 P_n)

so ``c_1 = p_bar (2 - p_bar / p*)`` below full contact and ``c_1 = p*`` above it. The field at depth
is each harmonic times the half-space transfer (:func:`harmonic_field`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import eval_legendre

from tactilab.core import rules

from ..halfspace import output_weights, transfer

_VOIGT = ("xx", "yy", "zz", "yz", "zx", "xy")


def _x(x) -> np.ndarray:
    return rules.finite_array(x, "x", "m")


def _n_harmonics(n_harmonics) -> int:
    if isinstance(n_harmonics, (bool, np.bool_)) or int(n_harmonics) != n_harmonics or n_harmonics < 0:
        raise ValueError(f"n_harmonics: must be an integer >= 0, got {n_harmonics!r}; give e.g. 16")
    return int(n_harmonics)


def _legendre_harmonics(n_harmonics: int, z: float, westergaard: bool) -> np.ndarray:
    """``c_n / p_bar`` for n = 0..n_harmonics (see the module docstring)."""
    n = np.arange(n_harmonics + 2)
    legendre = eval_legendre(n, z)
    if not westergaard:
        out = np.empty(n_harmonics + 1)
        out[0] = 1.0
        out[1:] = legendre[1:n_harmonics + 1] + legendre[:n_harmonics]
        return out
    integral = np.empty(n_harmonics + 1)  # J_n = int_z^1 P_n(u) du
    integral[0] = 1.0 - z
    m = np.arange(1, n_harmonics + 1)
    integral[1:] = (eval_legendre(m - 1, z) - eval_legendre(m + 1, z)) / (2 * m + 1)
    out = np.empty(n_harmonics + 1)
    out[0] = 1.0
    out[1:] = (integral[1:] + integral[:-1]) / (1.0 - z)
    return out


@dataclass(frozen=True)
class WestergaardContact:
    """A rigid sinusoid ``z = amplitude cos(2 pi x / wavelength)`` pressed at ``mean_pressure`` (plane strain).

    Parameters
    ----------
    amplitude : float
        Delta, the sinusoid's amplitude in m (> 0; peak-to-valley 2 Delta).
    wavelength : float
        L, its period in m (> 0).
    mean_pressure : float
        p_bar, the nominal (mean) pressure in Pa (> 0).
    E : float
        Young's modulus of the skin in Pa.
    nu : float
        Poisson's ratio in (-1, 0.5].

    Raises
    ------
    ValueError
        For a value that is not finite and positive, or ``nu`` outside (-1, 0.5].
    """

    amplitude: float
    wavelength: float
    mean_pressure: float
    E: float
    nu: float = 0.5

    def __post_init__(self) -> None:
        rules.positive(self.amplitude, "amplitude", "m", "give the sinusoid's amplitude in m")
        rules.positive(self.wavelength, "wavelength", "m", "give the sinusoid's period in m")
        rules.positive(self.mean_pressure, "mean_pressure", "Pa", "give the nominal pressure in Pa")
        rules.young_modulus(self.E, "E")
        rules.poisson_ratio(self.nu, "nu")

    @property
    def p_star(self) -> float:
        """p* = pi E* Delta / L (Pa): the mean pressure of full contact."""
        return math.pi * self.E / (1 - self.nu**2) * self.amplitude / self.wavelength

    @property
    def full_contact(self) -> bool:
        """True when ``mean_pressure >= p_star`` (the skin touches everywhere)."""
        return self.mean_pressure >= self.p_star

    @property
    def half_width(self) -> float:
        """a (m): the half-width of the contact band around each crest (L / 2 in full contact)."""
        if self.full_contact:
            return self.wavelength / 2
        return self.wavelength / math.pi * math.asin(math.sqrt(self.mean_pressure / self.p_star))

    @property
    def contact_fraction(self) -> float:
        """2 a / L: the fraction of the surface in contact."""
        return 2 * self.half_width / self.wavelength

    def pressure(self, x) -> np.ndarray:
        """Pressure p(x) in Pa at positions ``x`` (m, any shape; a crest at x = 0)."""
        x = _x(x)
        pm, ps, L = self.mean_pressure, self.p_star, self.wavelength
        if self.full_contact:
            return pm + ps * np.cos(2 * np.pi * x / L)
        s2 = pm / ps
        c = np.cos(np.pi * x / L)
        root = np.sqrt(np.clip(s2 - np.sin(np.pi * x / L) ** 2, 0.0, None))
        return np.where(c > 0, 2 * pm / s2 * c * root, 0.0)  # c <= 0: the band around the next crest's trough

    def harmonics(self, n_harmonics: int) -> np.ndarray:
        """Cosine coefficients c_0..c_n (Pa), shape (n_harmonics + 1,): ``p = sum c_n cos(2 pi n x / L)``.

        Closed form (Legendre polynomials, the module docstring); relative rounding of order
        1e-16 p* / p_bar, so exact to rounding above p_bar / p* ~ 1e-8.
        """
        n = _n_harmonics(n_harmonics)
        if self.full_contact:
            out = np.zeros(n + 1)
            out[0] = self.mean_pressure
            if n >= 1:
                out[1] = self.p_star
            return out
        z = math.cos(2 * math.pi * self.half_width / self.wavelength)
        return self.mean_pressure * _legendre_harmonics(n, z, westergaard=True)


@dataclass(frozen=True)
class PeriodicFlatPunch:
    """Rigid flat punches of half-width ``half_width``, one per ``wavelength``, pressed at ``mean_pressure``.

    The plateau pressure of a deep square grating (plane strain, frictionless; the grooves are
    never touched). The pressure does not depend on the modulus.

    Parameters
    ----------
    half_width : float
        b, the half-width of each plateau in m, 0 < b < wavelength / 2.
    wavelength : float
        L, the period in m (> 0).
    mean_pressure : float
        p_bar, the nominal (mean) pressure in Pa (> 0).

    Raises
    ------
    ValueError
        For a value that is not finite and positive, or ``half_width >= wavelength / 2``.
    """

    half_width: float
    wavelength: float
    mean_pressure: float

    def __post_init__(self) -> None:
        rules.positive(self.half_width, "half_width", "m", "give the plateau's half-width in m")
        rules.positive(self.wavelength, "wavelength", "m", "give the grating's period in m")
        rules.positive(self.mean_pressure, "mean_pressure", "Pa", "give the nominal pressure in Pa")
        if self.half_width >= self.wavelength / 2:
            raise ValueError(f"half_width: must be below wavelength / 2 = {self.wavelength / 2!r} m (plateaus "
                             f"separated by grooves), got {self.half_width!r} m; a flat surface has no punch")

    @property
    def contact_fraction(self) -> float:
        """2 b / L: the plateaus' share of the surface."""
        return 2 * self.half_width / self.wavelength

    def pressure(self, x) -> np.ndarray:
        """Pressure p(x) in Pa at positions ``x`` (m; a plateau centred at x = 0); inf at the edges."""
        x = _x(x)
        L = self.wavelength
        s2 = math.sin(math.pi * self.half_width / L) ** 2
        c = np.cos(np.pi * x / L)
        gap = s2 - np.sin(np.pi * x / L) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            inside = self.mean_pressure * c / np.sqrt(gap)
        return np.where((gap > 0) & (c > 0), inside, np.where((gap == 0) & (c > 0), np.inf, 0.0))

    def harmonics(self, n_harmonics: int) -> np.ndarray:
        """Cosine coefficients c_0..c_n (Pa), shape (n_harmonics + 1,): ``p = sum c_n cos(2 pi n x / L)``.

        ``c_n = p_bar (P_n(z) + P_{n-1}(z))``, z = cos(2 pi b / L); they decay only like n^(-1/2)
        (the inverse-square-root edges), so a field at depth needs many of them.
        """
        n = _n_harmonics(n_harmonics)
        z = math.cos(2 * math.pi * self.half_width / self.wavelength)
        return self.mean_pressure * _legendre_harmonics(n, z, westergaard=False)


def harmonic_field(harmonics, wavelength: float, x, depth: float, E: float, nu: float = 0.5,
                   quantity: str = "strain", components=_VOIGT) -> np.ndarray:
    """Stress or strain at ``depth`` under the periodic pressure ``sum c_n cos(2 pi n x / L)`` (plane strain).

    Each harmonic times the exact half-space transfer (:func:`tactilab.forward.halfspace.transfer`,
    the same multiplier ``HalfSpace`` uses for a periodic load; its ``n = 0`` term is the transfer's
    rho = 0 limit), summed; strain through Hooke's law (tensor shear).

    Parameters
    ----------
    harmonics : array_like, shape (n + 1,)
        c_0..c_n in Pa (from ``WestergaardContact.harmonics`` or ``PeriodicFlatPunch.harmonics``).
    wavelength : float
        L in m.
    x : array_like, shape (nx,)
        Positions in m.
    depth : float
        Depth in m (> 0).
    E : float
        Young's modulus in Pa (used for strain).
    nu : float
        Poisson's ratio in (-1, 0.5].
    quantity : {"strain", "stress"}
    components : sequence of str
        Voigt components (``"xx"``, ``"zz"``, ``"zx"``, ...).

    Returns
    -------
    ndarray, shape (len(components), nx)
        Stress in Pa (tension positive) or tensor strain.
    """
    coeffs = rules.finite_array(harmonics, "harmonics", "Pa")
    if coeffs.ndim != 1 or coeffs.size < 1:
        raise ValueError(f"harmonics: need a 1-D array c_0..c_n in Pa, got shape {coeffs.shape}")
    L = rules.positive(wavelength, "wavelength", "m", "give the period in m")
    depth = rules.depth(depth)
    x = np.atleast_1d(_x(x))
    components = rules.components(components)
    weights = output_weights(quantity, components, E, nu)  # (n_out, 6), checks E and nu
    k = 2 * np.pi * np.arange(coeffs.size) / L
    multipliers = transfer(k, None, depth, nu, "p", _VOIGT)  # (6, n + 1)
    waves = np.exp(1j * np.outer(k, x))  # (n + 1, nx)
    stress = (multipliers * coeffs).dot(waves).real  # the n = 0 term: c_0 T(0), real
    return weights @ stress

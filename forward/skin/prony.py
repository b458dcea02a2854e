"""A linear viscoelastic solid as a Prony series (generalised Maxwell model), in SI units.

Relaxation modulus (tensile, Pa; ``t`` in s)::

    E(t) = E_inf + sum_i E_i exp(-t / tau_i)

with the relaxed modulus ``E_inf > 0``, the spring moduli ``E_i > 0`` and the relaxation times
``tau_i > 0``; the instantaneous (glassy) modulus is ``E(0) = E_inf + sum_i E_i``. A standard
linear solid is one term. In the Laplace domain ``s E~(s) = E_inf + sum_i E_i s tau_i / (1 + s tau_i)``
and the complex modulus is its value on the imaginary axis, ``E*(omega) = s E~(s)`` at
``s = i omega`` (storage modulus its real part, loss modulus its imaginary part).

The creep compliance ``J(t)`` (strain per unit stress held since ``t = 0``, 1/Pa) follows in
closed form from ``s J~(s) = 1 / (s E~(s))``: it is a Prony series too,

    J(t) = J_inf - sum_j J_j exp(-t / lambda_j),   J_inf = 1 / E_inf,   J(0) = 1 / E(0),

whose retardation times ``lambda_j = -1 / r_j`` come from the roots ``r_j`` of ``s E~(s)``.
``s E~(s)`` increases between its poles ``-1 / tau_i`` (its derivative is a sum of positive
terms), so it has exactly one root between consecutive poles and one between the slowest pole
and 0: the retardation times interlace the relaxation times, the slowest one beyond the slowest
relaxation. Each root is bracketed and found to machine precision (``scipy.optimize.brentq``),
and the residue gives ``J_j = lambda_j / (d/ds [s E~(s)])(r_j) > 0``.

At constant Poisson's ratio ``nu`` the shear functions are ``G(t) = E(t) / (2 (1 + nu))`` and
``J_G(t) = 2 (1 + nu) J(t)``; docs/theory.md section 7 states why constant ``nu`` is the model.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import brentq

from tactilab.core import rules as check


#: relative difference of relaxation times below which two terms are merged into one
MERGE = 1e-9


def _modulus(value, name: str, fix: str) -> float:
    return check.positive(value, name, "Pa", fix)


class Prony:
    """A Prony series: relaxation, creep and complex modulus of a linear viscoelastic solid.

    Parameters
    ----------
    E_inf : float
        Relaxed (long-time) Young's modulus in Pa, > 0.
    terms : sequence of (float, float)
        ``(E_i, tau_i)`` pairs: spring modulus in Pa (> 0) and relaxation time in s (> 0). Terms
        whose relaxation times agree to a relative ``MERGE`` (1e-9) are one term (their moduli add,
        at their modulus-weighted mean time; E(t) moves by less than 1e-9 relative, and float64
        could not place a retardation time between them). An empty sequence is an elastic solid.

    Examples
    --------
    >>> sls = Prony(1e6, [(2e6, 0.07)])       # relaxed 1 MPa, instantaneous 3 MPa, tau = 70 ms
    >>> sls.relaxation_modulus([0.0, 0.07])   # Pa
    >>> sls.creep_compliance(1.0)             # 1/Pa (tensile)
    >>> sls.complex_modulus(2 * np.pi * 100)  # Pa, complex
    """

    def __init__(self, E_inf: float, terms: Sequence[tuple[float, float]] = ()):
        self.E_inf = _modulus(E_inf, "E_inf", "give the relaxed Young's modulus in Pa, e.g. 1e6")
        checked = []
        for n, term in enumerate(terms):
            if np.ndim(term) != 1 or len(term) != 2:
                raise ValueError(f"terms[{n}]: must be a pair (E_i in Pa, tau_i in s), got {term!r}")
            E_i = _modulus(term[0], f"terms[{n}] E_i", "each Prony term needs a spring modulus > 0 Pa "
                           "(drop a term of zero modulus)")
            tau = check.positive(term[1], f"terms[{n}] tau_i", "s", "a relaxation time must be > 0 s "
                                 "(e.g. 0.07 for 70 ms)")
            checked.append((tau, E_i))
        merged: list[list[float]] = []  # [tau, E]: times within MERGE of each other are one term
        for tau, E_i in sorted(checked):
            if merged and tau <= merged[-1][0] * (1.0 + MERGE):
                total = merged[-1][1] + E_i
                merged[-1] = [(merged[-1][0] * merged[-1][1] + tau * E_i) / total, total]
            else:
                merged.append([tau, E_i])
        self.taus = np.array([m[0] for m in merged], dtype=float)  #: relaxation times, s, ascending
        self.moduli = np.array([m[1] for m in merged], dtype=float)  #: their moduli E_i, Pa
        self.E_0 = self.E_inf + float(self.moduli.sum())  #: instantaneous modulus E(0), Pa
        self.retardation_times, self.creep_terms = self._interconvert()

    @classmethod
    def sls(cls, E_relaxed: float, E_instantaneous: float, tau: float) -> "Prony":
        """A standard linear solid: relaxed and instantaneous moduli (Pa) and the relaxation time (s)."""
        E_relaxed = _modulus(E_relaxed, "E_relaxed", "give the relaxed Young's modulus in Pa")
        E_instantaneous = _modulus(E_instantaneous, "E_instantaneous", "give the instantaneous Young's "
                                   "modulus in Pa")
        if not E_instantaneous > E_relaxed:
            raise ValueError(f"E_instantaneous: a standard linear solid must stiffen on fast loading, "
                             f"E_instantaneous > E_relaxed = {E_relaxed!r} Pa, got {E_instantaneous!r}; "
                             "swap them, or use an elastic material")
        return cls(E_relaxed, [(E_instantaneous - E_relaxed, tau)])

    def __repr__(self) -> str:
        terms = ", ".join(f"({e!r}, {t!r})" for e, t in zip(self.moduli.tolist(), self.taus.tolist()))
        return f"Prony(E_inf={self.E_inf!r}, terms=[{terms}])"

    def __eq__(self, other) -> bool:
        return isinstance(other, Prony) and repr(self) == repr(other)

    def __hash__(self) -> int:
        return hash(repr(self))

    # -- interconversion ---------------------------------------------------------------------
    def _laplace(self, s: float) -> float:
        """``s E~(s)`` at a real s (Pa)."""
        return self.E_inf + float(np.sum(self.moduli * s * self.taus / (1.0 + s * self.taus)))

    def _laplace_slope(self, s: float) -> float:
        return float(np.sum(self.moduli * self.taus / (1.0 + s * self.taus) ** 2))

    def _interconvert(self) -> tuple[np.ndarray, np.ndarray]:
        """Retardation times (s, ascending) and creep moduli J_j (1/Pa) from the roots of ``s E~(s)``."""
        poles = np.sort(-1.0 / self.taus)  # ascending: fastest relaxation first
        brackets = [(poles[i], poles[i + 1]) for i in range(len(poles) - 1)]
        if len(poles):
            brackets.append((poles[-1], 0.0))
        lams, weights = [], []
        for lo, hi in brackets:
            root = self._root(lo, hi)
            lam = -1.0 / root
            lams.append(lam)
            weights.append(lam / self._laplace_slope(root))
        order = np.argsort(lams)
        return np.array(lams)[order], np.array(weights)[order]

    def _root(self, lo: float, hi: float) -> float:
        """The root of ``s E~(s)`` between the pole ``lo`` and ``hi`` (the next pole, or 0).

        ``s E~`` rises from -inf just above ``lo`` to +inf just below ``hi`` (to ``E_inf`` at 0); the
        bracket's ends step off the poles by 1e-12 of the interval (at least a few units of round-off),
        halving that step while the sign is wrong (the poles are at least ``MERGE`` apart)."""
        width, eps = hi - lo, np.finfo(float).eps
        a = lo + max(1e-12 * width, 8 * eps * abs(lo))  # never closer to a pole than round-off resolves
        b = hi - max(1e-12 * width, 8 * eps * abs(hi))
        while self._laplace(a) > 0 and a - lo > 4 * eps * abs(lo):
            a = 0.5 * (a + lo)
        while self._laplace(b) < 0 and hi - b > 4 * eps * abs(hi):
            b = 0.5 * (b + hi)
        return brentq(self._laplace, a, b, xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=500)

    # -- time and frequency domain -----------------------------------------------------------
    @staticmethod
    def _times(t, name: str = "t") -> np.ndarray:
        arr = np.asarray(t, dtype=float)
        if np.isnan(arr).any() or (arr < 0).any():
            bad = arr[np.isnan(arr) | (arr < 0)].ravel()[0]
            raise ValueError(f"{name}: times must be >= 0 s (0 is the instant of loading, inf the relaxed "
                             f"state) and not NaN, got {check.show(bad)}")
        return arr

    @property
    def J_0(self) -> float:
        """Instantaneous creep compliance 1 / E(0), 1/Pa."""
        return 1.0 / self.E_0

    @property
    def J_inf(self) -> float:
        """Relaxed creep compliance 1 / E_inf, 1/Pa."""
        return 1.0 / self.E_inf

    def relaxation_modulus(self, t) -> np.ndarray:
        """E(t) in Pa at times ``t`` (s, >= 0, any shape; ``inf`` gives ``E_inf``)."""
        t = self._times(t)
        return self.E_inf + np.sum(self.moduli * np.exp(-t[..., None] / self.taus), axis=-1)

    def creep_compliance(self, t) -> np.ndarray:
        """Tensile creep compliance J(t) in 1/Pa at times ``t`` (s, >= 0, any shape)."""
        t = self._times(t)
        return self.J_inf - np.sum(self.creep_terms * np.exp(-t[..., None] / self.retardation_times), axis=-1)

    def shear_relaxation_modulus(self, t, nu: float = 0.5) -> np.ndarray:
        """G(t) = E(t) / (2 (1 + nu)) in Pa at constant Poisson's ratio ``nu``."""
        return self.relaxation_modulus(t) / (2.0 * (1.0 + check.poisson_ratio(nu)))

    def shear_creep_compliance(self, t, nu: float = 0.5) -> np.ndarray:
        """J_G(t) = 2 (1 + nu) J(t) in 1/Pa at constant Poisson's ratio ``nu``."""
        return 2.0 * (1.0 + check.poisson_ratio(nu)) * self.creep_compliance(t)

    def complex_modulus(self, omega) -> np.ndarray:
        """E*(omega) in Pa (complex) at angular frequencies ``omega`` (rad/s, finite, any sign and shape).

        ``E*(-omega) = conj(E*(omega))``; the phase ``angle(E*)`` is the loss angle by which stress
        leads strain in a sinusoidal steady state.
        """
        w = check.finite_array(omega, "omega", "rad/s")
        iwt = 1j * w[..., None] * self.taus
        return self.E_inf + np.sum(self.moduli * iwt / (1.0 + iwt), axis=-1)

    def complex_compliance(self, omega) -> np.ndarray:
        """J*(omega) = 1 / E*(omega) in 1/Pa, evaluated from the creep series (an independent route)."""
        w = check.finite_array(omega, "omega", "rad/s")
        iwl = 1j * w[..., None] * self.retardation_times
        return self.J_inf - np.sum(self.creep_terms * iwl / (1.0 + iwl), axis=-1)

    def laplace_relaxation(self, s) -> np.ndarray:
        """s E~(s) in Pa at Laplace variables ``s`` (real or complex, away from the poles -1/tau_i)."""
        s = np.asarray(s)
        return self.E_inf + np.sum(self.moduli * s[..., None] * self.taus / (1.0 + s[..., None] * self.taus), axis=-1)

    def laplace_creep(self, s) -> np.ndarray:
        """s J~(s) in 1/Pa from the creep series (its product with :meth:`laplace_relaxation` is 1)."""
        s = np.asarray(s)
        sl = s[..., None] * self.retardation_times
        return self.J_inf - np.sum(self.creep_terms * sl / (1.0 + sl), axis=-1)

    @property
    def is_elastic(self) -> bool:
        """True when the series has no term (E(t) = E_inf at every time)."""
        return len(self.taus) == 0

    def kernel(self, kind: str) -> tuple[float, np.ndarray, np.ndarray]:
        """``(K_inf, K_j, theta_j)`` of ``K(t) = K_inf + sum_j K_j exp(-t / theta_j)``.

        ``kind="relaxation"``: E(t) (Pa); ``kind="creep"``: J(t) (1/Pa, ``K_j = -J_j``).
        The hereditary integrals of :mod:`.hereditary` take this form.
        """
        if kind == "relaxation":
            return self.E_inf, self.moduli.copy(), self.taus.copy()
        if kind == "creep":
            return self.J_inf, -self.creep_terms, self.retardation_times.copy()
        raise ValueError(f"kind: must be 'relaxation' or 'creep', got {kind!r}")


def as_prony(value, name: str = "prony") -> Prony:
    """A :class:`Prony`, or a clear error naming ``name``."""
    if not isinstance(value, Prony):
        raise ValueError(f"{name}: expected a Prony series, got {type(value).__name__}; build one with "
                         "Prony(E_inf, terms=[(E_i, tau_i), ...]) or Prony.sls(E_relaxed, E_instantaneous, tau)")
    return value



"""The Prony series (tactilab.forward.skin.Prony) and its hereditary integrals, against closed forms.

Oracles: the standard linear solid's creep compliance and complex modulus written out by hand
(Findley, Lai and Onaran, Creep and Relaxation of Nonlinear Viscoelastic Materials, ch. 5), the
Laplace-domain identity s E~(s) s J~(s) = 1, the convolution identity E(t) J(0) + int E(t - s) J'(s) ds = 1
integrated numerically by adaptive quadrature, and the ramp's hereditary integral in closed form.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from tactilab.forward.skin import HereditaryIntegral, Prony
from tactilab.forward.skin.hereditary import check_times, convolution_matrix, convolve

#: fingertip skin in compression relaxes at about 4 ms, 70 ms and 1.4 s (Pawluk and Howe 1999)
FINGER = Prony(0.2e6, [(1.0e6, 4e-3), (0.5e6, 0.07), (0.3e6, 1.4)])


def test_sls_creep_compliance_is_the_closed_form():
    E_r, E_g, tau = 1e6, 3e6, 0.07
    sls = Prony.sls(E_r, E_g, tau)
    lam = tau * E_g / E_r  # the retardation time of a standard linear solid
    t = np.array([0.0, 0.01, 0.07, 0.3, 1.0, 10.0])
    expected = 1 / E_r - (1 / E_r - 1 / E_g) * np.exp(-t / lam)
    np.testing.assert_allclose(sls.creep_compliance(t), expected, rtol=1e-13)
    np.testing.assert_allclose(sls.retardation_times, [lam], rtol=1e-14)


def test_sls_complex_modulus_is_the_closed_form():
    E_r, E_1, tau = 1e6, 2e6, 0.01
    sls = Prony(E_r, [(E_1, tau)])
    w = 2 * np.pi * np.array([1.0, 10.0, 100.0, 1000.0])
    wt2 = (w * tau) ** 2
    storage = E_r + E_1 * wt2 / (1 + wt2)
    loss = E_1 * w * tau / (1 + wt2)
    np.testing.assert_allclose(sls.complex_modulus(w), storage + 1j * loss, rtol=1e-14)
    np.testing.assert_allclose(sls.complex_modulus(-w), storage - 1j * loss, rtol=1e-14)


@pytest.mark.parametrize("prony", [FINGER, Prony.sls(1e5, 4e5, 0.02),
                                   Prony(1e6, [(1e3, 1e-4), (5e6, 1e-3), (2e5, 1.0), (1e6, 100.0)])])
def test_interconversion_laplace_and_frequency_identities(prony):
    s = np.concatenate([np.geomspace(1e-3, 1e5, 30), 1j * np.geomspace(1e-3, 1e5, 30), [3.0 + 4.0j]])
    np.testing.assert_allclose(prony.laplace_relaxation(s) * prony.laplace_creep(s), 1.0, rtol=1e-10, atol=0)
    w = np.geomspace(1e-3, 1e6, 40)
    np.testing.assert_allclose(prony.complex_modulus(w) * prony.complex_compliance(w), 1.0, rtol=1e-10, atol=0)
    assert np.all(prony.creep_terms > 0)
    # the retardation times interlace the relaxation times, the slowest beyond the slowest relaxation
    assert np.all(prony.retardation_times > prony.taus)
    assert np.all(prony.retardation_times[:-1] < prony.taus[1:])


@pytest.mark.parametrize("t", [1e-3, 0.05, 1.0, 5.0])
def test_convolution_identity_by_quadrature(t):
    """E(t) J(0) + int_0^t E(t - s) J'(s) ds = 1 (Stieltjes form of int E(t - s) dJ(s) = 1)."""
    p = FINGER
    lam, Jj = p.retardation_times, p.creep_terms
    integrand = lambda s: float(p.relaxation_modulus(t - s)) * float(np.sum(Jj / lam * np.exp(-s / lam)))
    value, _ = quad(integrand, 0.0, t, epsabs=0.0, epsrel=1e-13, limit=200, points=[min(t, x) for x in lam])
    assert abs(float(p.relaxation_modulus(t)) * p.J_0 + value - 1.0) < 1e-10


def test_elastic_limits():
    p = FINGER
    assert p.relaxation_modulus(0.0) == pytest.approx(p.E_0, rel=1e-15) and p.E_0 == pytest.approx(2.0e6)
    assert p.relaxation_modulus(np.inf) == p.E_inf
    assert p.creep_compliance(0.0) == pytest.approx(1 / p.E_0, rel=1e-12)
    assert p.creep_compliance(np.inf) == pytest.approx(1 / p.E_inf, rel=1e-15)
    assert p.creep_compliance(1e4) == pytest.approx(1 / p.E_inf, rel=1e-12)
    assert p.complex_modulus(0.0) == pytest.approx(p.E_inf) and abs(p.complex_modulus(1e9) - p.E_0) < 1e-3 * p.E_0
    t = np.geomspace(1e-5, 10, 50)  # monotone (beyond, both sit at their limits to round-off)
    assert np.all(np.diff(p.relaxation_modulus(t)) < 0) and np.all(np.diff(p.creep_compliance(t)) > 0)


def test_shear_functions_at_constant_nu():
    p, t = FINGER, np.array([0.0, 0.1, np.inf])
    np.testing.assert_allclose(p.shear_relaxation_modulus(t, 0.5), p.relaxation_modulus(t) / 3, rtol=1e-15)
    np.testing.assert_allclose(p.shear_creep_compliance(t, 0.3), 2.6 * p.creep_compliance(t), rtol=1e-15)
    np.testing.assert_allclose(p.shear_relaxation_modulus(0.0) * p.shear_creep_compliance(0.0), 1.0, rtol=1e-12)


def test_equal_relaxation_times_merge_and_an_empty_series_is_elastic():
    assert Prony(1e6, [(1e6, 0.1), (2e6, 0.1)]) == Prony(1e6, [(3e6, 0.1)])
    assert len(Prony(1e6, [(1e6, 1.0), (1e6, 1.0 + 1e-12)]).taus) == 1  # closer than float64 can separate
    close = Prony(1e6, [(1e6, 1.0), (1e9, 1.0 + 3e-9)])  # two terms, 3e-9 apart, moduli 1000x apart
    assert len(close.retardation_times) == 2
    w = np.geomspace(1e-3, 1e3, 30)
    np.testing.assert_allclose(close.complex_modulus(w) * close.complex_compliance(w), 1.0, rtol=1e-10, atol=0)
    elastic = Prony(1e6)
    assert elastic.is_elastic and elastic.creep_compliance(5.0) == 1e-6 and elastic.relaxation_modulus(0.0) == 1e6


@pytest.mark.parametrize("args, match", [
    ((-1e6, [(1e6, 0.1)]), r"E_inf: must be finite and > 0 Pa"),
    ((0.0, [(1e6, 0.1)]), r"E_inf: must be finite and > 0 Pa"),
    ((math.nan, [(1e6, 0.1)]), r"E_inf: must be finite and > 0 Pa, got nan"),
    ((1e6, [(1e6, -0.1)]), r"terms\[0\] tau_i: must be finite and > 0 s.*relaxation time"),
    ((1e6, [(1e6, 0.1), (1e6, math.nan)]), r"terms\[1\] tau_i: must be finite and > 0 s"),
    ((1e6, [(0.0, 0.1)]), r"terms\[0\] E_i: must be finite and > 0 Pa"),
    ((1e6, [(-2e6, 0.1)]), r"terms\[0\] E_i: must be finite and > 0 Pa"),
    ((1e6, [(math.nan, 0.1)]), r"terms\[0\] E_i: must be finite and > 0 Pa, got nan"),
    ((1e6, [(1e6, 0.1, 3.0)]), r"terms\[0\]: must be a pair \(E_i in Pa, tau_i in s\)"),
])
def test_bad_series_are_refused(args, match):
    with pytest.raises(ValueError, match=match):
        Prony(*args)


def test_bad_sls_times_and_kind_are_refused():
    with pytest.raises(ValueError, match=r"E_instantaneous: a standard linear solid must stiffen"):
        Prony.sls(3e6, 1e6, 0.1)
    with pytest.raises(ValueError, match=r"t: times must be >= 0 s .* got -1.0"):
        FINGER.relaxation_modulus([0.0, -1.0])
    with pytest.raises(ValueError, match=r"t: times must be >= 0 s .* got nan"):
        FINGER.creep_compliance(math.nan)
    with pytest.raises(ValueError, match=r"omega: .*finite"):
        FINGER.complex_modulus([1.0, math.nan])
    with pytest.raises(ValueError, match=r"kind: must be 'relaxation' or 'creep'"):
        FINGER.kernel("storage")


def test_hereditary_integral_of_a_ramp_is_exact_on_uneven_steps():
    """a(t) = t from 0: c(t) = K_inf t + sum K_j theta_j (1 - exp(-t / theta_j)), exact for linear input."""
    K_inf, K_j, theta = FINGER.kernel("relaxation")
    t = np.array([0.0, 1e-3, 4e-3, 0.05, 0.06, 0.5, 3.0])
    c = convolve((K_inf, K_j, theta), t, t)
    expected = K_inf * t + np.sum(K_j * theta * (1 - np.exp(-t[:, None] / theta)), axis=1)
    np.testing.assert_allclose(c, expected, rtol=1e-12)


def test_hereditary_step_gives_the_kernel_and_the_split_matches_the_state():
    kernel = FINGER.kernel("creep")
    t = np.array([0.0, 0.003, 0.1, 2.0])
    np.testing.assert_allclose(convolve(kernel, t, np.ones(4)), FINGER.creep_compliance(t), rtol=1e-13)
    state = HereditaryIntegral(kernel, (3,))
    rng_values = np.array([[1.0, 2.0, 0.0], [0.5, 2.5, 1.0], [3.0, -1.0, 2.0]])
    previous = 0.0
    for ti, a in zip([0.0, 0.01, 0.05], rng_values):
        gain, memory = state.split(ti - previous)
        state.advance(ti - previous, a)
        np.testing.assert_allclose(gain * a + memory, state.value(), rtol=1e-13, atol=1e-22)
        previous = ti
    T = convolution_matrix(kernel, t)
    assert np.allclose(np.triu(T, 1), 0.0) and T[0, 0] == pytest.approx(FINGER.J_0)


@pytest.mark.parametrize("times, match", [
    ([0.0, 0.1, 0.1], r"times: times must increase strictly, got 0.1 then 0.1"),
    ([0.0, -0.1], r"times: times must be finite and >= 0 s"),
    ([0.0, math.nan], r"times: times must be finite and >= 0 s"),
    ([], r"times: expected a 1-D sequence of times in s"),
])
def test_bad_times_are_refused(times, match):
    with pytest.raises(ValueError, match=match):
        check_times(times)

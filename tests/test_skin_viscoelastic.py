"""The viscoelastic half-space (tactilab.forward.skin.ViscoelasticHalfSpace) against closed forms.

Oracles: the correspondence principle at constant nu (Lee 1955; Findley, Lai and Onaran ch. 9):
under a step traction the strain creeps as J(t) / J(0) and the stress does not change; under a
step deflection the stress relaxes as E(t) / E(0); a standard linear solid under a sinusoid
sliding in full contact carries the pressure P cos(kx) -> the closed-form stress
sigma_zz = -P (1 + kz) exp(-kz) cos(kx) (docs/theory.md section 3) with the gain and phase of
E*(kV) written out by hand, and its strain equals the elastic one (checked through the creep
series' complex compliance, an independent route).
"""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.forward import HalfSpace, SurfaceLoad, dottest, solve_contact
from tactilab.forward.halfspace import compliance_matrix
from tactilab.forward.skin import Prony, ViscoelasticHalfSpace

SLS = Prony.sls(1e5, 3e5, 0.01)  # relaxed 0.1 MPa, glassy 0.3 MPa, tau = 10 ms
SKIN = ViscoelasticHalfSpace(SLS, nu=0.5)
N, H = 32, 1e-4


def _gaussian_load(n=N, h=H):
    x = (np.arange(n) - n // 2) * h
    r2 = x[None, :] ** 2 + x[:, None] ** 2
    return SurfaceLoad(p=2e3 * np.exp(-r2 / 0.4e-6), qx=5e2 * np.exp(-r2 / 0.3e-6), spacing=h)


def _sls_creep_ratio(t):
    E_r, E_g, tau = 1e5, 3e5, 0.01
    return E_g * (1 / E_r - (1 / E_r - 1 / E_g) * np.exp(-t * E_r / (tau * E_g)))


def test_step_traction_strain_creeps_by_the_creep_ratio_and_stress_stays():
    load, t = _gaussian_load(), np.array([0.0, 0.002, 0.01, 0.03, 0.1, 1.0])
    comps = ("xx", "zz", "zx")
    strain = SKIN.strain(load, [5e-4, 1e-3], t, components=comps).values
    stress = SKIN.stress(load, [5e-4, 1e-3], t, components=comps).values
    e0 = SKIN.instantaneous.strain(load, [5e-4, 1e-3], components=comps).data["strain"].values
    s0 = SKIN.instantaneous.stress(load, [5e-4, 1e-3], components=comps).data["stress"].values
    ratio = _sls_creep_ratio(t).reshape(-1, 1, 1, 1, 1)
    np.testing.assert_allclose(strain, ratio * e0, rtol=1e-12, atol=1e-14 * np.abs(e0).max())
    np.testing.assert_array_equal(stress, np.broadcast_to(s0, stress.shape))
    # the relaxed end: the strain of the relaxed elastic skin
    e_inf = SKIN.relaxed.strain(load, [5e-4, 1e-3], components=comps).data["strain"].values
    late = SKIN.strain(load, [5e-4, 1e-3], [0.0, 10.0], components=comps).values[-1]
    np.testing.assert_allclose(late, e_inf, rtol=1e-10, atol=1e-12 * np.abs(e_inf).max())


def test_a_sinusoidal_traction_makes_the_strain_lag_by_the_complex_compliance():
    """A tractor display drives q(t) = Q sin(omega t): after the transient the strain is the glassy
    elastic strain times E(0) [Re J* sin(omega t) + Im J* cos(omega t)], J* = 1 / E*(omega) of the SLS
    written out by hand: a gain |J*| E(0) and a lag -arg J*; the stress does not lag."""
    load, f = _gaussian_load(8), 10.0
    w = 2 * np.pi * f
    t = np.arange(0.0, 0.5, 1 / (400 * f))
    amplitude = np.sin(w * t)
    strain = SKIN.strain(load, 1e-3, t, history=amplitude, components=("zz",)).values[:, 0, 0, 4, 4]
    stress = SKIN.stress(load, 1e-3, t, history=amplitude, components=("zz",)).values[:, 0, 0, 4, 4]
    e0 = SKIN.instantaneous.strain(load, 1e-3, components=("zz",)).data["strain"].values[0, 0, 4, 4]
    s0 = SKIN.instantaneous.stress(load, 1e-3, components=("zz",)).data["stress"].values[0, 0, 4, 4]
    late = t > 0.4  # 13 retardation times (lambda = tau E(0) / E_inf = 30 ms) after the start
    basis = np.stack([np.sin(w * t[late]), np.cos(w * t[late])], axis=1)
    (a, b), *_ = np.linalg.lstsq(basis, strain[late] / (3e5 * e0), rcond=None)
    J_star = 1 / (1e5 + 2e5 * 1j * w * 0.01 / (1 + 1j * w * 0.01))
    assert abs((a + 1j * b) - J_star) < 1e-4 * abs(J_star)
    assert np.angle(a + 1j * b) < 0  # the strain lags the traction
    np.testing.assert_allclose(stress, s0 * amplitude, rtol=1e-12, atol=1e-12 * abs(s0))


def test_one_load_per_time_equals_a_scaled_pattern():
    """Two routes: the history convolved as a scalar, and every field convolved recursively."""
    load, t = _gaussian_load(16), np.array([0.0, 0.004, 0.01, 0.02, 0.05])
    amp = np.array([0.2, 1.0, 0.5, 0.5, 1.5])
    scaled = SKIN.strain(load, 1e-3, t, history=amp, components=("zz",)).values
    per_time = SKIN.strain([load.scaled(a) for a in amp], 1e-3, t, components=("zz",)).values
    np.testing.assert_allclose(per_time, scaled, rtol=1e-12, atol=1e-15)
    assert SKIN.strain(load, 1e-3, t, history=amp, components=("zz",)).data["strain"].dims[0] == "time"


def test_step_deflection_relaxes_pressure_and_stress_not_strain():
    n, L = 64, 4e-3
    x = (np.arange(n) - n // 2) * L / n
    h = 1e-6 * np.cos(2 * np.pi * x / L)
    t = np.array([0.0, 0.005, 0.02, 0.2])
    E = SLS.relaxation_modulus(t) / SLS.E_0
    p = SKIN.pressure_from_deflection(h, L / n, t)
    p0 = SKIN.instantaneous.pressure_from_deflection(h, L / n).p
    np.testing.assert_allclose(p, E[:, None] * p0, rtol=1e-12, atol=1e-12 * np.abs(p0).max())
    sig = SKIN.stress_from_deflection(h, L / n, 1e-3, t, components=("zz",)).values
    sig0 = SKIN.instantaneous.stress(SKIN.instantaneous.pressure_from_deflection(h, L / n), 1e-3,
                                     components=("zz",)).data["stress"].values
    np.testing.assert_allclose(sig, E.reshape(-1, 1, 1, 1) * sig0, rtol=1e-12, atol=1e-12 * np.abs(sig0).max())
    eps = SKIN.strain_from_deflection(h, L / n, 1e-3, t, components=("zz", "xx")).values
    eps_el = HalfSpace(7e5).strain(HalfSpace(7e5).pressure_from_deflection(h, L / n), 1e-3,
                                   components=("zz", "xx")).data["strain"].values
    np.testing.assert_allclose(eps, np.broadcast_to(eps_el, eps.shape), rtol=1e-12, atol=1e-14)


def _harmonic(values, k_index):
    return 2 * np.fft.rfft(values)[..., k_index] / values.shape[-1]


@pytest.mark.parametrize("frequency", [1.0, 10.0, 100.0, 1000.0])
def test_sls_sliding_sinusoid_gain_and_phase_of_pressure_and_stress(frequency):
    """h = A cos(kx) slides at V = f L: per harmonic the pressure is the relaxed one times
    E*(2 pi f) / E_inf (gain |E*| / E_inf; the pressure leads the deflection by the loss angle,
    i.e. its peak sits delta / k AHEAD of the crest, along the motion)."""
    n, L, A, z = 64, 2e-3, 1e-6, 5e-4
    k = 2 * np.pi / L
    x = (np.arange(n) - n // 2) * L / n
    h = A * np.cos(k * x)
    V = frequency * L
    E_r, E_1, tau, w = 1e5, 2e5, 0.01, 2 * np.pi * frequency
    storage, loss = E_r + E_1 * (w * tau) ** 2 / (1 + (w * tau) ** 2), E_1 * w * tau / (1 + (w * tau) ** 2)
    gain, lead = np.hypot(storage, loss) / E_r, np.arctan2(loss, storage)
    relaxed_amplitude = E_r * k / (2 * (1 - 0.25)) * A  # Pa: P~ = E rho H~ / (2 (1 - nu^2))
    j = 1
    phase_x = np.exp(1j * k * x[0])  # the grid starts at x[0], not 0
    p = SKIN.sliding_pressure(h, L / n, V).p
    P = _harmonic(p, j) / phase_x
    assert abs(P) / relaxed_amplitude == pytest.approx(gain, rel=1e-12)
    assert -np.angle(P) == pytest.approx(lead, rel=1e-12)
    assert np.abs(p - np.real(P * phase_x * np.exp(1j * k * (x - x[0])))).max() < 1e-12 * abs(P)
    stress = SKIN.steady_sliding(h, L / n, V, z, components=("zz", "xx", "zx")).data["stress"].values[0]
    decay = np.exp(-k * z)
    expected = {0: -(1 + k * z) * decay, 1: -(1 - k * z) * decay}  # of P cos(kx) (docs/theory.md section 3)
    for row, factor in expected.items():
        S = _harmonic(stress[row], j) / phase_x
        assert abs(S) / (relaxed_amplitude * abs(factor)) == pytest.approx(gain, rel=1e-10)
        assert -np.angle(S / np.sign(factor)) == pytest.approx(lead, rel=1e-10)
    S_zx = _harmonic(stress[2], j) / phase_x  # -P kz exp(-kz) sin(kx): a quarter period on
    assert abs(S_zx) / (relaxed_amplitude * k * z * decay) == pytest.approx(gain, rel=1e-10)


def test_oblique_sliding_grating_sees_the_frequency_of_its_x_wavenumber():
    """h = A cos(kx x + ky y) moving along x: the frequency is kx V (not |k| V); the pressure's amplitude
    is the relaxed one, E_inf |k| A / (2 (1 - nu^2)), times |E*(kx V)| / E_inf."""
    n, L, A, V = 32, 3.2e-3, 1e-6, 0.02
    x = (np.arange(n) - n // 2) * L / n
    kx, ky = 2 * np.pi / L, 3 * 2 * np.pi / L
    h = A * np.cos(kx * x[None, :] + ky * x[:, None])
    p = SKIN.sliding_pressure(h, L / n, V).p
    w = kx * V
    E_star = 1e5 + 2e5 * 1j * w * 0.01 / (1 + 1j * w * 0.01)
    amplitude = abs(E_star) * np.hypot(kx, ky) * A / (2 * (1 - 0.25))
    lead = np.angle(E_star)  # the peak sits lead / kx ahead along +x
    expected = amplitude * np.cos(kx * x[None, :] + ky * x[:, None] - lead)
    assert np.abs(p - expected).max() < 1e-10 * amplitude


def test_sliding_strain_equals_the_elastic_strain_through_the_complex_compliance():
    """eps~ = S(E = 1) J*(-kx V) sigma~ per mode, from the creep series; equal to the elastic strain to 1e-12."""
    n, L, V, z = 64, 2e-3, 0.05, 4e-4
    x = (np.arange(n) - n // 2) * L / n
    h = 1e-6 * (np.cos(2 * np.pi * x / L) + 0.3 * np.sin(6 * np.pi * x / L + 0.4))
    sigma = SKIN.steady_sliding(h, L / n, V, z).data["stress"].values[0]  # (6, n)
    kx = 2 * np.pi * np.fft.rfftfreq(n, L / n)
    spectrum = np.fft.rfft(sigma, axis=-1) * SLS.complex_compliance(-kx * V)
    strain = compliance_matrix(1.0, 0.5) @ np.fft.irfft(spectrum, n=n, axis=-1)
    elastic = HalfSpace(2e5).strain(HalfSpace(2e5).pressure_from_deflection(h, L / n), z).data["strain"].values[0]
    scale = np.abs(elastic).max()
    assert np.abs(strain - elastic).max() < 1e-12 * scale
    direct = SKIN.steady_sliding(h, L / n, V, z, quantity="strain").data["strain"].values[0]
    assert np.abs(direct - elastic).max() < 1e-12 * scale


def test_sliding_at_a_later_time_is_the_profile_moved_along():
    n, L, V = 32, 2e-3, 0.01
    x = (np.arange(n) - n // 2) * L / n
    h = 1e-6 * np.cos(2 * np.pi * x / L)
    shift = 4 * L / n
    later = SKIN.sliding_pressure(h, L / n, V, time=shift / V).p
    np.testing.assert_allclose(later, np.roll(SKIN.sliding_pressure(h, L / n, V).p, 4), atol=1e-12 * np.abs(later).max())
    # speed 0: the relaxed skin; very fast: the glassy skin
    np.testing.assert_allclose(SKIN.sliding_pressure(h, L / n, 0.0).p, SKIN.relaxed.pressure_from_deflection(h, L / n).p,
                               rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("quantity", ["stress", "strain"])
def test_history_operator_passes_the_dot_test_and_matches_the_fields(quantity, rng):
    t = np.array([0.0, 0.003, 0.01, 0.04])
    op = SKIN.operator((8, 8), H, t, depth=1e-3, components=("zz", "zx"), quantity=quantity, periodic=True)
    assert dottest(op, rng=rng) < 1e-10
    p = rng.standard_normal((len(t), 8, 8))
    loads = [SurfaceLoad(p=pi, spacing=H, periodic=True) for pi in p]
    solve = SKIN.stress if quantity == "stress" else SKIN.strain
    fields = solve(loads, 1e-3, t, components=("zz", "zx")).values[:, 0].reshape(len(t), 2, 64)
    np.testing.assert_allclose(op.matvec(p.ravel()).reshape(len(t), 2, 64), fields, rtol=1e-9,
                               atol=1e-9 * np.abs(fields).max())


def test_surface_compliance_at_a_time_and_solve_contact_takes_the_skin():
    kx, ky = np.array([1e3, 2e3]), np.array([0.0, 5e2])
    np.testing.assert_allclose(SKIN.surface_compliance(kx, ky), SKIN.instantaneous.surface_compliance(kx, ky), rtol=1e-12)
    np.testing.assert_allclose(SKIN.surface_compliance(kx, ky, time=np.inf), SKIN.relaxed.surface_compliance(kx, ky),
                               rtol=1e-12)
    x = (np.arange(32) - 16) * 2e-4
    gap = (x[None, :] ** 2 + x[:, None] ** 2) / 0.02
    a = solve_contact(SKIN, gap, 2e-4, normal_force=0.05)
    b = solve_contact(SKIN.instantaneous, gap, 2e-4, normal_force=0.05)
    np.testing.assert_allclose(a.pressure, b.pressure, rtol=1e-10, atol=1e-10 * b.pressure.max())


def test_bad_inputs_are_refused():
    load = _gaussian_load(8)
    with pytest.raises(ValueError, match=r"prony: expected a Prony series, got float"):
        ViscoelasticHalfSpace(1e6)
    with pytest.raises(ValueError, match=r"nu: Poisson's ratio must lie in \(-1, 0.5\]"):
        ViscoelasticHalfSpace(SLS, nu=0.6)
    with pytest.raises(ValueError, match=r"load: expected a SurfaceLoad or a sequence of SurfaceLoad"):
        SKIN.stress(np.zeros((8, 8)), 1e-3, [0.0])
    with pytest.raises(ValueError, match=r"history: needs one amplitude per time, shape \(2,\), got \(3,\)"):
        SKIN.strain(load, 1e-3, [0.0, 1.0], history=[1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match=r"history: .*finite"):
        SKIN.strain(load, 1e-3, [0.0, 1.0], history=[1.0, np.nan])
    with pytest.raises(ValueError, match=r"history: give it with one SurfaceLoad"):
        SKIN.strain([load, load], 1e-3, [0.0, 1.0], history=[1.0, 2.0])
    with pytest.raises(ValueError, match=r"load: one SurfaceLoad per time needs 2 loads, got 3"):
        SKIN.strain([load] * 3, 1e-3, [0.0, 1.0])
    with pytest.raises(ValueError, match=r"times: times must increase strictly"):
        SKIN.stress(load, 1e-3, [0.0, 0.0])
    with pytest.raises(ValueError, match=r"quantity: must be 'stress' or 'strain', got 'energy'"):
        SKIN.steady_sliding(np.zeros(8), 1e-4, 0.1, 1e-3, quantity="energy")
    with pytest.raises(ValueError, match=r"speed: must be finite"):
        SKIN.sliding_pressure(np.zeros(8), 1e-4, np.nan)
    with pytest.raises(ValueError, match=r"height: expected shape \(nx,\) or \(ny, nx\)"):
        SKIN.sliding_pressure(np.zeros((2, 2, 2)), 1e-4, 0.1)
    with pytest.raises(ValueError, match=r"time: times must be >= 0 s"):
        SKIN.at(-1.0)

"""Time-stepped viscoelastic contact (tactilab.forward.skin.solve_viscoelastic_contact) against closed forms.

Oracles: Lee and Radok (J. Appl. Mech. 27, 1960), a rigid sphere under a step load P on a
viscoelastic half-space at nu = 1/2 while the contact grows: a^3(t) = 3 P R J_G(t) / 16 with the
shear creep compliance J_G (= 9 P R J(t) / 16 with the tensile one); the elastic contact on the
same grid with the modulus 1 / J(t) (the same problem by the correspondence principle); the
instantaneous and relaxed elastic limits; and a rigid sinusoid sliding in full contact, whose
pressure per harmonic and hysteretic drag follow from E*(kV) written out by hand.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tactilab.forward import AccuracyWarning, HalfSpace, solve_contact
from tactilab.forward.skin import Prony, ViscoelasticHalfSpace, solve_viscoelastic_contact

SLS = Prony.sls(1e5, 3e5, 0.05)
SKIN = ViscoelasticHalfSpace(SLS)
N, H, R, P = 64, 1e-4, 0.01, 0.1  # grid, m; sphere radius, m; load, N
X = (np.arange(N) - N // 2) * H
SPHERE = (X[None, :] ** 2 + X[:, None] ** 2) / (2 * R)
TIMES = np.concatenate([[0.0], np.geomspace(1e-3, 0.5, 40)])


@pytest.fixture(scope="module")
def step_load():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        return solve_viscoelastic_contact(SKIN, SPHERE, H, TIMES, normal_force=P, keep_every=None)


def test_lee_radok_contact_radius_under_a_step_load(step_load):
    shear = SLS.shear_creep_compliance(TIMES, nu=0.5)
    a_shear = (3 * P * R * shear / 16) ** (1 / 3)
    a_tensile = (9 * P * R * SLS.creep_compliance(TIMES) / 16) ** (1 / 3)
    np.testing.assert_allclose(a_shear, a_tensile, rtol=1e-13)
    # the approach of a sphere is a^2 / R (Hertz at each instant): the smooth measure of a
    np.testing.assert_allclose(np.sqrt(R * step_load.approach), a_shear, rtol=2e-3)
    # the area's disc radius counts nodes: the grid's resolution (64 nodes over 6.4 mm)
    np.testing.assert_allclose(step_load.contact_radius, a_shear, rtol=2e-2)
    assert np.all(np.diff(step_load.area) >= 0) and step_load.area[-1] > 1.3 * step_load.area[0]


def test_the_same_grid_elastic_contact_of_modulus_one_over_J(step_load):
    for i in (3, 12, 20, 30, 40):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", AccuracyWarning)
            elastic = solve_contact(SKIN.at(TIMES[i]), SPHERE, H, normal_force=P)
        assert step_load.approach[i] == pytest.approx(elastic.approach, rel=1e-3)
        assert step_load.area[i] == pytest.approx(elastic.area, abs=4 * H * H)


def test_strain_at_depth_is_the_elastic_one_of_modulus_one_over_J(step_load):
    """While the contact grows under a held load, the strain field at t is the elastic field of 1 / J(t)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        elastic = solve_contact(SKIN.at(TIMES[-1]), SPHERE, H, normal_force=P)
    expected = SKIN.at(TIMES[-1]).strain(elastic.load(), 1e-3, components=("zz", "zx")).data["strain"].values
    got = step_load.strain(SKIN, 1e-3, components=("zz", "zx")).data["strain"].values
    assert np.abs(got - expected).max() < 2e-3 * np.abs(expected).max()


def test_instantaneous_and_relaxed_limits_and_the_relaxed_bound(step_load):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        glassy = solve_contact(SKIN.instantaneous, SPHERE, H, normal_force=P)
        relaxed = solve_contact(SKIN.relaxed, SPHERE, H, normal_force=P)
        late = solve_viscoelastic_contact(SKIN, SPHERE, H, [0.0, 0.05, 0.2, 0.6, 2.0, 5.0], normal_force=P)
    np.testing.assert_allclose(late.pressures[0], glassy.pressure, rtol=1e-9, atol=1e-9 * glassy.pressure.max())
    assert late.approach[0] == pytest.approx(glassy.approach, rel=1e-9)
    np.testing.assert_allclose(late.pressures[-1], relaxed.pressure, atol=1e-4 * relaxed.pressure.max())
    assert late.approach[-1] == pytest.approx(relaxed.approach, rel=1e-4)
    # never past the relaxed limit under a constant load (the Tamaas scheme overshoots it by 30 %)
    for history in (step_load, late):
        assert history.area.max() <= relaxed.area
        assert history.approach.max() <= relaxed.approach * (1 + 1e-6)
    np.testing.assert_allclose(step_load.normal_force, P, rtol=1e-10)


def test_a_held_indentation_keeps_its_contact_and_the_force_relaxes_as_E():
    """Approach held (Lee and Radok, displacement control): the contact stays that of the glassy solve
    and every pressure, hence the force, relaxes as E(t) / E(0), exactly for this step history."""
    t = np.array([0.0, 0.002, 0.01, 0.05, 0.2, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        hist = solve_viscoelastic_contact(SKIN, SPHERE, H, t, approach=2e-4)
    ratio = SLS.relaxation_modulus(t) / SLS.E_0
    np.testing.assert_allclose(hist.normal_force, hist.normal_force[0] * ratio, rtol=1e-6)
    np.testing.assert_allclose(hist.pressures, hist.pressures[0] * ratio[:, None, None], rtol=1e-6,
                               atol=1e-6 * hist.pressures[0].max())
    assert np.all(hist.area == hist.area[0])


def test_sliding_sinusoid_in_full_contact_pressure_and_drag():
    """A rigid sinusoid h = A cos(k (x - V t)) slides over the skin pressed in full contact (plane
    strain, periodic): after the transient, p = p_mean + P Re[conj(E*) exp(ik(x - Vt))] with
    P = k A / (2 (1 - nu^2)) and E* = E*(kV); the drag on the skin per unit length is L P A k E'' / 2."""
    sls = Prony.sls(1e5, 3e5, 0.01)
    skin = ViscoelasticHalfSpace(sls)
    n, L, A, f = 64, 2e-3, 2e-6, 10.0
    k, V, w = 2 * np.pi / L, f * L, 2 * np.pi * f
    x = (np.arange(n) - n // 2) * L / n
    E_star = 1e5 + 2e5 * 1j * w * 0.01 / (1 + 1j * w * 0.01)
    amplitude = k * A / (2 * (1 - 0.25))
    mean = 3 * np.pi * (3e5 / 0.75) * A / L  # three times what full contact of the glassy skin needs
    t = np.arange(0.0, 0.3, 1 / (100 * f))
    hist = solve_viscoelastic_contact(skin, lambda s: -A * np.cos(k * (x - V * s)), L / n, t, mean_pressure=mean,
                                      periodic=True)
    for i in (len(t) - 1, len(t) - 37):
        expected = mean + amplitude * np.real(np.conj(E_star) * np.exp(1j * k * (x - V * t[i])))
        assert np.abs(hist.pressures[i] - expected).max() < 1e-3 * amplitude * abs(E_star)
        steady = mean + skin.sliding_pressure(A * np.cos(k * x), L / n, V, t[i]).p
        assert np.abs(hist.pressures[i] - steady).max() < 1e-3 * amplitude * abs(E_star)
    drag = hist.tangential_force[-100:, 0].mean()
    # central differences of the gap: the factor sin(k h) / (k h)
    factor = np.sin(k * L / n) / (k * L / n)
    assert drag == pytest.approx(0.5 * L * amplitude * A * k * E_star.imag * factor, rel=1e-3)
    assert drag > 0  # the skin is dragged along the motion


def test_a_sphere_pressed_held_then_slid_grows_relaxes_and_drags():
    sls = Prony.sls(1e5, 3e5, 0.02)
    skin = ViscoelasticHalfSpace(sls)
    n, h = 48, 1.5e-4
    x = (np.arange(n) - n // 2) * h
    t = np.linspace(0.0, 0.12, 61)
    centre = np.where(t < 0.06, 0.0, 0.02 * (t - 0.06))  # m: held, then slid at 2 cm/s along +x

    def gap(s):
        c = float(np.interp(s, t, centre))
        return ((x[None, :] - c) ** 2 + x[:, None] ** 2) / (2 * R)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        hist = solve_viscoelastic_contact(skin, gap, h, t, normal_force=0.05, keep_every=10)
    held = t < 0.06
    assert np.all(np.diff(hist.approach[held]) > 0)  # the contact grows while the load is held
    peaks = hist.pressures[:3].max(axis=(1, 2))  # kept at 0, 20 and 40 ms: the peak pressure relaxes
    assert np.all(np.diff(peaks) < 0)
    assert abs(hist.tangential_force[held, 0]).max() < 1e-6 * abs(hist.tangential_force[-1, 0])
    assert hist.tangential_force[-1, 0] > 0  # the sliding sphere drags the skin along +x
    p = hist.pressures[-1]
    centroid = float((p.sum(axis=0) * x).sum() / p.sum())
    assert centroid > centre[-1]  # the pressure leads the sphere


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match=r"skin: expected a ViscoelasticHalfSpace, got HalfSpace"):
        solve_viscoelastic_contact(HalfSpace(1e6), SPHERE, H, [0.0], normal_force=P)
    with pytest.raises(ValueError, match=r"normal_force: give one value \(held\) or one per time, shape \(2,\)"):
        solve_viscoelastic_contact(SKIN, SPHERE, H, [0.0, 1.0], normal_force=[P, P, P])
    with pytest.raises(ValueError, match=r"keep_every: must be a positive integer or None, got 0"):
        solve_viscoelastic_contact(SKIN, SPHERE, H, [0.0], normal_force=P, keep_every=0)
    with pytest.raises(ValueError, match=r"times: times must increase strictly"):
        solve_viscoelastic_contact(SKIN, SPHERE, H, [0.0, 0.0], normal_force=P)
    with pytest.raises(ValueError, match=r"gap: gap\(t\) must keep one grid, shape \(64, 64\) at t = 0 s, got \(32, 32\)"):
        solve_viscoelastic_contact(SKIN, lambda t: SPHERE if t == 0 else SPHERE[:32, :32], H, [0.0, 0.1],
                                   normal_force=P)
    with pytest.raises(ValueError, match=r"normal_force, mean_pressure, approach: give exactly one"):
        solve_viscoelastic_contact(SKIN, SPHERE, H, [0.0], normal_force=P, approach=1e-4)

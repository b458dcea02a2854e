"""The periodic closed forms (forward/contact/periodic_forms.py) against independent checks and the engine.

Independent checks: the harmonics against quadrature of the pressure formula (scipy.integrate.quad),
force balance (the mean pressure), the full-contact limit p_bar -> p*, the light-load limit
(Hertz cylinders of radius L^2 / (4 pi^2 Delta) at the crests, Johnson 4.43), the single-punch
limit b << L (Johnson 2.64: p = P / (pi sqrt(b^2 - x^2))), and the field at depth against
``HalfSpace.strain`` of the finely sampled pressure. Then the engine: ``solve_contact(periodic=True)``
against each closed form to its own error estimate.
"""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from tactilab.forward import (HalfSpace, PeriodicFlatPunch, SurfaceLoad, WestergaardContact, harmonic_field,
                              solve_contact)

E, NU = 1.0e6, 0.5
ES = E / (1 - NU**2)
L, DELTA = 1e-3, 2e-6
P_STAR = math.pi * ES * DELTA / L
SKIN = HalfSpace(E, NU)


def grid(n):
    return (np.arange(n) - n // 2) * (L / n)


def quad_harmonic(pressure, n, half_width):
    """c_n = (2 / L) int p cos(2 pi n x / L) dx over the contact band (c_0 with 1 / L)."""
    weight = 1.0 if n == 0 else 2.0
    value = quad(lambda x: float(pressure(np.array(x))) * math.cos(2 * math.pi * n * x / L), -half_width,
                 half_width, limit=400, epsabs=0, epsrel=1e-9)[0]
    return weight / L * value


@pytest.mark.parametrize("ratio", [0.02, 0.3, 0.8, 0.999])
def test_westergaard_harmonics_equal_quadrature_and_balance_the_force(ratio):
    w = WestergaardContact(DELTA, L, ratio * P_STAR, E, NU)
    assert w.p_star == pytest.approx(P_STAR, rel=1e-15)
    assert math.sin(math.pi * w.half_width / L) ** 2 == pytest.approx(ratio, rel=1e-12)
    c = w.harmonics(8)
    ref = [quad_harmonic(w.pressure, n, w.half_width) for n in range(9)]
    assert np.allclose(c, ref, rtol=0, atol=1e-8 * w.mean_pressure)
    assert ref[0] == pytest.approx(w.mean_pressure, rel=1e-9)  # force balance: the formula carries p_bar
    assert c[1] == pytest.approx(w.mean_pressure * (2 - ratio), rel=1e-12)


@pytest.mark.parametrize("ratio", [0.05, 0.4, 0.9])
def test_punch_harmonics_equal_quadrature_and_balance_the_force(ratio):
    b = ratio * L / 2
    punch = PeriodicFlatPunch(b, L, 3e3)
    c = punch.harmonics(6)
    # the edge singularity: substitute sin(pi x / L) = sin(pi b / L) sin(phi), which makes the integrand smooth
    s = math.sin(math.pi * b / L)
    ref = [(1 if n == 0 else 2) / math.pi * quad(
        lambda phi: 3e3 * math.cos(2 * n * math.asin(s * math.sin(phi))), -math.pi / 2, math.pi / 2,
        epsabs=0, epsrel=1e-10)[0] for n in range(7)]
    assert np.allclose(c, ref, rtol=0, atol=1e-10 * 3e3)
    assert ref[0] == pytest.approx(3e3, rel=1e-12)
    x = np.linspace(-b * 0.999, b * 0.999, 7)
    assert np.all(punch.pressure(x) > 0) and punch.pressure(np.array([b + 1e-9, L / 2])).max() == 0


def test_westergaard_tends_to_full_contact_at_p_star():
    x = grid(64)
    below = WestergaardContact(DELTA, L, P_STAR * (1 - 1e-10), E, NU)
    at = WestergaardContact(DELTA, L, P_STAR, E, NU)
    assert at.full_contact and not below.full_contact
    assert below.half_width == pytest.approx(L / 2, rel=1e-4)
    assert np.allclose(below.pressure(x), at.pressure(x), rtol=0, atol=1e-4 * P_STAR)
    assert np.allclose(below.harmonics(6), at.harmonics(6), rtol=0, atol=1e-8 * P_STAR)
    assert at.harmonics(3).tolist() == [P_STAR, P_STAR, 0.0, 0.0]


def test_westergaard_light_load_is_a_hertz_cylinder_at_each_crest():
    pm = 1e-4 * P_STAR
    w = WestergaardContact(DELTA, L, pm, E, NU)
    radius = L**2 / (4 * math.pi**2 * DELTA)  # curvature of the crest
    a = math.sqrt(4 * pm * L * radius / (math.pi * ES))  # Johnson 4.43, load p_bar L per period
    assert w.half_width == pytest.approx(a, rel=1e-4)
    x = np.linspace(-0.9 * a, 0.9 * a, 9)
    hertz = 2 * pm * L / (math.pi * a) * np.sqrt(1 - (x / a) ** 2)
    assert np.allclose(w.pressure(x), hertz, rtol=1e-3)


def test_narrow_punch_is_a_single_flat_punch():
    b, pm = 1e-3 * L, 2e3
    punch = PeriodicFlatPunch(b, L, pm)
    x = np.linspace(-0.95 * b, 0.95 * b, 11)
    single = pm * L / (math.pi * np.sqrt(b * b - x * x))  # Johnson 2.64
    assert np.allclose(punch.pressure(x), single, rtol=1e-5)


def test_harmonic_field_equals_the_halfspace_strain_of_the_sampled_pressure():
    n = 4096
    x = grid(n)
    w = WestergaardContact(DELTA, L, 0.3 * P_STAR, E, NU)
    field = harmonic_field(w.harmonics(800), L, x[::128], 0.3e-3, E, NU, components=("zz", "xx", "zx"))
    sampled = SKIN.strain(SurfaceLoad(p=w.pressure(x), spacing=L / n, periodic=True), [0.3e-3],
                          components=("zz", "xx", "zx")).data["strain"].transpose("component", "depth", "x")
    ref = sampled.values[:, 0, ::128]
    assert np.abs(field - ref).max() <= 1e-5 * np.abs(ref).max()
    stress = harmonic_field(w.harmonics(800), L, x[::128], 0.3e-3, E, NU, quantity="stress", components=("zz",))
    assert stress.shape == (1, 32) and stress.max() < 0  # compression under the contact everywhere at this depth


@pytest.mark.parametrize("ratio", [0.05, 0.3, 0.9, 1.5])
def test_solve_contact_equals_westergaard_to_its_error_estimate(ratio):
    n = 256
    x = grid(n)
    w = WestergaardContact(DELTA, L, ratio * P_STAR, E, NU)
    gap = DELTA * (1 - np.cos(2 * np.pi * x / L))
    sol = solve_contact(SKIN, gap, L / n, mean_pressure=w.mean_pressure, periodic=True)
    exact = w.pressure(x)
    assert np.abs(sol.pressure - exact).max() <= sol.error_estimate * sol.pressure.max()
    assert abs(sol.contact_fraction - w.contact_fraction) <= 1.0 / n + 1e-12
    got = np.fft.rfft(np.fft.ifftshift(sol.pressure))[:6].real * np.r_[1, 2 * np.ones(5)] / n  # cosine coefficients
    assert np.abs(got - w.harmonics(5)).max() <= max(2e-3 * w.mean_pressure, 1e-6 * P_STAR)
    depth = 0.2e-3
    solved = SKIN.strain(sol.load(), [depth], components=("zz", "zx")).data["strain"]
    solved = solved.transpose("component", "depth", "x").values[:, 0]
    closed = harmonic_field(w.harmonics(400), L, x, depth, E, NU, components=("zz", "zx"))
    assert np.abs(solved - closed).max() <= max(sol.error_estimate, 1e-6) * np.abs(closed).max()


def test_solve_contact_on_a_deep_square_grating_equals_the_periodic_punch():
    n, b = 512, 0.25e-3
    h = L / n
    x = grid(n)
    gap = np.where(np.abs(x) < b - h / 2, 0.0, 50e-6)  # plateaus of half-width b; grooves never touched
    punch = PeriodicFlatPunch(b - h / 2, L, 1e3)  # the plateau's nodes cover |x| < b - h/2 with their cells
    sol = solve_contact(SKIN, gap, h, mean_pressure=1e3, periodic=True)
    middle = np.abs(x) < b / 2
    assert np.allclose(sol.pressure[middle], punch.pressure(x[middle]), rtol=0.01)
    got = np.fft.rfft(np.fft.ifftshift(sol.pressure))[:4].real * np.r_[1, 2, 2, 2] / n
    assert np.allclose(got, punch.harmonics(3), rtol=0, atol=0.02 * 1e3)  # the low harmonics, edges and all


@pytest.mark.parametrize("kwargs, match", [
    (dict(amplitude=0.0), r"amplitude: must be finite and > 0 m"),
    (dict(wavelength=math.nan), r"wavelength: must be finite and > 0 m"),
    (dict(mean_pressure=-1.0), r"mean_pressure: must be finite and > 0 Pa"),
    (dict(E=0.0), r"E: Young's modulus must be finite and > 0 Pa"),
    (dict(nu=0.6), r"nu: Poisson's ratio must lie in"),
])
def test_westergaard_refuses_bad_values(kwargs, match):
    args = dict(amplitude=DELTA, wavelength=L, mean_pressure=1e3, E=E, nu=NU) | kwargs
    with pytest.raises(ValueError, match=match):
        WestergaardContact(**args)


def test_bad_punch_and_harmonic_inputs_are_refused():
    with pytest.raises(ValueError, match=r"half_width: must be below wavelength / 2"):
        PeriodicFlatPunch(L / 2, L, 1e3)
    with pytest.raises(ValueError, match=r"half_width: must be finite and > 0 m"):
        PeriodicFlatPunch(-1e-4, L, 1e3)
    with pytest.raises(ValueError, match=r"n_harmonics: must be an integer >= 0, got 2.5"):
        PeriodicFlatPunch(1e-4, L, 1e3).harmonics(2.5)
    with pytest.raises(ValueError, match=r"harmonics: need a 1-D array"):
        harmonic_field(np.ones((2, 2)), L, [0.0], 1e-3, E)
    with pytest.raises(ValueError, match=r"x: .*finite"):
        WestergaardContact(DELTA, L, 1e3, E).pressure([math.nan])

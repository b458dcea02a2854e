"""Layered skin (forward/skin/layered.py): each check against an independent closed form.

Oracles: the half-space's own spectral solution (docs/theory.md section 2) for deep layers and for
a layer on a half-space of the same material; the closed-form surface compliance of an elastic layer
bonded to a rigid base (docs/theory.md section 6, the form used by Carbone and Mangialardi 2008) and its
nu -> 1/2 limit; the thin-layer limits (uniaxial strain of a compressible layer, lubrication of an
incompressible one, h^3 k^2 / (3 G)); the laterally constrained uniform mode; Betti's reciprocity;
a linear extrapolation to nu = 1/2; the lubrication solution of a sphere on a thin bonded layer.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from tactilab.forward import HalfSpace, SurfaceLoad, dottest, solve_contact, transfer
from tactilab.forward.skin import Layer, LayeredHalfSpace
from tactilab.forward.skin.layered_multipliers import transfer_matrix

E = 1e5  # Pa


def _halfspace_transfer(kx, ky, z, nu):
    """The half-space's multipliers, shape (K, 6, 3) as transfer_matrix."""
    return np.moveaxis(np.stack([transfer(kx, ky, z, nu, name) for name in ("p", "qx", "qy")], -1), 0, 1)


def _closed_form_compliance(k, h, E, nu):
    """Normal surface compliance (m/Pa) of a layer bonded to a rigid base, frictionless on top.

    2 (1 - nu^2) / (E k) * (kappa sinh 2x - 2x) / (kappa cosh 2x + 2 x^2 + (1 + kappa^2) / 2), x = k h,
    kappa = 3 - 4 nu (docs/theory.md section 6); at nu = 1/2: (sinh 2x - 2x) / (cosh 2x + 2 x^2 + 1).
    """
    x = k * h
    kappa = 3 - 4 * nu
    numerator = kappa * np.sinh(2 * x) - 2 * x
    if nu == 0.5:  # sinh 2x - 2x as its series where the difference would cancel
        series = sum((2 * x) ** (2 * n + 1) / math.factorial(2 * n + 1) for n in range(1, 12))
        numerator = np.where(x < 0.1, series, numerator)
    return 2 * (1 - nu**2) / (E * k) * numerator / (kappa * np.cosh(2 * x) + 2 * x**2 + (1 + kappa**2) / 2)


@pytest.mark.parametrize("nu", [0.5, 0.3, 0.0, -0.5])
def test_deep_layer_on_rigid_base_is_the_halfspace_for_every_nonzero_mode(nu, rng):
    h = 5e-3
    k = 2 * np.pi / (h / 5.0) * (1 + 3 * rng.random(40))  # the layer is deeper than 5 wavelengths
    theta = 2 * np.pi * rng.random(40)
    kx, ky = k * np.cos(theta), k * np.sin(theta)
    skin = LayeredHalfSpace([Layer(h, E, nu)])
    ref = HalfSpace(E, nu).surface_compliance(kx, ky)
    assert np.abs(skin.surface_compliance(kx, ky) - ref).max() <= 1e-10 * np.abs(ref).max()
    for z in (0.2e-3, 1e-3):
        T, T_ref = transfer_matrix(skin, kx, ky, z), _halfspace_transfer(kx, ky, z, nu)
        assert np.abs(T - T_ref).max() <= 1e-10
    # no growing exponential: a layer 1e5 wavelengths deep is as exact (cosh(k h) would overflow at 710)
    far = np.array([2e3, 2e5]) / h * 2 * np.pi
    assert np.abs(skin.surface_compliance(far, 0 * far) - HalfSpace(E, nu).surface_compliance(far, 0 * far)).max() \
        <= 1e-15 * np.abs(HalfSpace(E, nu).surface_compliance(far, 0 * far)).max()
    assert np.abs(transfer_matrix(skin, far, 0 * far, 1e-6) - _halfspace_transfer(far, 0 * far, 1e-6, nu)).max() \
        <= 1e-14  # k z = 2.5 and 250
    # the uniform mode differs by physics: bonded to bone, the layer is laterally constrained
    T0 = transfer_matrix(skin, 0.0, 0.0, 1e-3)
    assert np.allclose(T0[:3, 0].real, [-nu / (1 - nu), -nu / (1 - nu), -1.0], atol=1e-15)
    assert T0[4, 1] == -1.0 and T0[3, 2] == -1.0  # sigma_zx = -qx, sigma_yz = -qy


@pytest.mark.parametrize("nu", [0.5, 0.3, 0.0, -0.5])
def test_normal_compliance_of_a_bonded_layer_matches_its_closed_form(nu):
    h = 1e-3
    k = np.logspace(-5, 2.5, 40) / h  # thin layers in the propagator basis, thick ones in decaying exponentials
    skin = LayeredHalfSpace([Layer(h, E, nu)])
    got = skin.surface_compliance(k, np.zeros_like(k))[:, 0, 0].real
    ref = _closed_form_compliance(k, h, E, nu)
    assert np.all(np.abs(got / ref - 1) <= 1e-13)


def test_the_closed_form_at_nu_one_half_is_the_incompressible_one():
    x = np.logspace(-1, 1, 9)
    ref = (np.sinh(2 * x) - 2 * x) / (np.cosh(2 * x) + 2 * x**2 + 1)
    assert np.allclose(_closed_form_compliance(x, 1.0, 1.0, 0.5) * 1.0 * x / (2 * 0.75), ref, rtol=1e-13)


def test_thin_layer_limits():
    """Compressible: uniaxial strain, h (1 + nu)(1 - 2 nu) / (E (1 - nu)); incompressible: lubrication,
    w = h^3 k^2 p / (3 G) with G = E / 3 (a layer squeezed out sideways)."""
    h = 1e-3
    for x in (1e-2, 2e-2):
        k = np.array([x / h])
        c = LayeredHalfSpace([Layer(h, E, 0.3)]).surface_compliance(k, 0 * k)[0, 0, 0].real
        assert c == pytest.approx(h * 1.3 * 0.4 / (E * 0.7), rel=3 * x)
        c = LayeredHalfSpace([Layer(h, E, 0.5)]).surface_compliance(k, 0 * k)[0, 0, 0].real
        assert c == pytest.approx(h**3 * k[0] ** 2 / E, rel=3 * x**2)  # 3 G = E at nu = 1/2
    # and k = 0 itself: the constrained compression and shear of the layers, summed
    skin = LayeredHalfSpace([Layer(h, E, 0.3), Layer(2 * h, 2 * E, 0.5)])
    C0 = skin.surface_compliance(0.0, 0.0)
    assert np.allclose(np.diag(C0).real, [h * 1.3 * 0.4 / (E * 0.7), h * 2.6 / E + 2 * h * 3 / (2 * E)] + [
        h * 2.6 / E + 2 * h * 3 / (2 * E)], rtol=1e-14)


def test_reciprocity_and_positive_energy_of_a_stack(rng):
    skin = LayeredHalfSpace([Layer(0.3e-3, 3 * E, 0.45), Layer(2e-3, E, 0.5), Layer(1e-3, 0.2 * E, 0.3)],
                            base=HalfSpace(5 * E, 0.4))
    kx, ky = rng.standard_normal((2, 60)) * 3e3
    M = skin.surface_compliance(kx, ky)
    assert np.abs(M - np.conj(np.swapaxes(M, -1, -2))).max() <= 1e-14 * np.abs(M).max()
    assert np.all(np.linalg.eigvalsh(M) > 0)
    M1 = skin.surface_compliance(kx, None)
    assert np.abs(M1 - np.conj(np.swapaxes(M1, -1, -2))).max() <= 1e-14 * np.abs(M1).max()
    assert np.array_equal(M1, skin.surface_compliance(kx, np.zeros_like(kx))[:, :2, :2])  # plane strain


def test_nu_one_half_is_exact_not_a_limit(rng):
    """nu = 1/2 against the linear extrapolation from nu = 0.5 - 1e-7 and 0.5 - 2e-7."""
    kx, ky = rng.standard_normal((2, 20)) * 2e3
    layers = lambda nu: LayeredHalfSpace([Layer(1e-3, E, nu), Layer(1e-3, 3 * E, nu)], base=HalfSpace(E, nu))
    for f in (lambda s: s.surface_compliance(kx, ky), lambda s: transfer_matrix(s, kx, ky, 1.5e-3)):
        exact, a, b = f(layers(0.5)), f(layers(0.5 - 1e-7)), f(layers(0.5 - 2e-7))
        assert np.abs(exact - (2 * a - b)).max() <= 1e-8 * np.abs(exact).max()


def test_two_equal_layers_are_one_layer(rng):
    kx, ky = rng.standard_normal((2, 30)) * 2e3
    kx[0] = ky[0] = 0.0
    for base in ("rigid", HalfSpace(2 * E, 0.3)):
        one = LayeredHalfSpace([Layer(3e-3, E, 0.45)], base=base)
        two = LayeredHalfSpace([Layer(1e-3, E, 0.45), Layer(2e-3, E, 0.45)], base=base)
        assert np.abs(one.surface_compliance(kx, ky) - two.surface_compliance(kx, ky)).max() <= \
            1e-12 * np.abs(one.surface_compliance(kx, ky)).max()
        for z in (0.5e-3, 1e-3, 2.5e-3):
            assert np.abs(transfer_matrix(one, kx, ky, z) - transfer_matrix(two, kx, ky, z)).max() <= 1e-12


@pytest.mark.parametrize("nu", [0.5, 0.3])
def test_layers_on_a_halfspace_of_their_material_are_the_halfspace(nu, rng):
    kx, ky = rng.standard_normal((2, 30)) * 2e3
    kx[0] = ky[0] = 0.0  # including the direction-averaged k = 0 mode
    skin = LayeredHalfSpace([Layer(1e-3, E, nu), Layer(0.5e-3, E, nu)], base=HalfSpace(E, nu))
    for z in (0.4e-3, 1.2e-3, 3e-3):
        assert np.abs(transfer_matrix(skin, kx, ky, z) - _halfspace_transfer(kx, ky, z, nu)).max() <= 1e-13
    ref = HalfSpace(E, nu).surface_compliance(kx, ky)
    assert np.abs(skin.surface_compliance(kx, ky) - ref).max() <= 1e-13 * np.abs(ref).max()


def test_the_uniform_mode_is_the_limit_of_small_wavenumbers():
    """The k = 0 entries (laterally constrained on a rigid base, the base's direction-averaged limit
    otherwise) are the limits of the k > 0 solution, averaged over directions, with an O(k h) gap."""
    theta = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    for base in ("rigid", HalfSpace(3 * E, 0.45)):
        skin = LayeredHalfSpace([Layer(1e-3, E, 0.5), Layer(2e-3, 2 * E, 0.3)], base=base)
        for z in (0.5e-3, 2e-3):
            T0 = transfer_matrix(skin, 0.0, 0.0, z)
            gaps = [np.abs(T0 - np.mean(transfer_matrix(skin, k * np.cos(theta), k * np.sin(theta), z), axis=0)).max()
                    for k in (1.0, 0.1)]
            assert gaps[1] <= 0.15 * gaps[0] and gaps[1] <= 1e-3


def test_periodic_fields_of_a_same_material_stack_are_the_halfspace_fields(rng):
    n, h = 32, 1e-4
    x = (np.arange(n) - n // 2) * h
    X, Y = np.meshgrid(x, x)
    g = np.exp(-(X**2 + Y**2) / (2 * (3 * h) ** 2))
    load = SurfaceLoad(p=1e3 * g, qx=300 * g * X / h, qy=rng.standard_normal((n, n)), spacing=h, periodic=True)
    skin = LayeredHalfSpace([Layer(1e-3, E, 0.4), Layer(2e-3, E, 0.4)], base=HalfSpace(E, 0.4))
    for quantity in ("stress", "strain"):
        got = getattr(skin, quantity)(load, [0.5e-3, 1e-3, 4e-3])
        ref = getattr(HalfSpace(E, 0.4), quantity)(load, [0.5e-3, 1e-3, 4e-3], method="spectral")
        a, b = got.data[quantity].values, ref.data[quantity].values
        assert np.abs(a - b).max() <= 1e-13 * np.abs(b).max()
        assert got.method == "layered-periodic" and got.error_estimate < 1e-12
    line = SurfaceLoad(p=1e3 * g[n // 2], qx=rng.standard_normal(n), qy=rng.standard_normal(n), spacing=h,
                       periodic=True)
    a = skin.stress(line, 0.7e-3).data["stress"].values
    b = HalfSpace(E, 0.4).stress(line, 0.7e-3, method="spectral").data["stress"].values
    assert np.abs(a - b).max() <= 1e-13 * np.abs(b).max()
    pts = np.array([[x[3], x[5]], [x[10], x[20]]])
    at = skin.stress(load, 1e-3, points=pts, components=("zz",)).data["stress"].values[0, 0]
    full = skin.stress(load, 1e-3, components=("zz",)).data["stress"].values[0, 0]
    assert np.array_equal(at, full[[5, 20], [3, 10]])


def test_public_transfer_is_the_multiplier_and_its_strain_the_layer_hooke_law(rng):
    skin = LayeredHalfSpace([Layer(1e-3, E, 0.5), Layer(1e-3, 4 * E, 0.3)])
    kx, ky = rng.standard_normal((2, 5)) * 3e3
    stress = skin.transfer(kx, ky, 1.5e-3)
    assert stress.shape == (5, 6, 3) and np.array_equal(stress, transfer_matrix(skin, kx, ky, 1.5e-3))
    strain = skin.transfer(kx, ky, 1.5e-3, quantity="strain")
    trace = stress[:, 0] + stress[:, 1] + stress[:, 2]
    assert np.allclose(strain[:, 2], (1.3 * stress[:, 2] - 0.3 * trace) / (4 * E), rtol=0, atol=1e-20)
    with pytest.raises(ValueError, match="quantity: must be 'stress' or 'strain'"):
        skin.transfer(kx, ky, 1e-3, quantity="energy")
    with pytest.raises(ValueError, match="ky: "):
        skin.transfer(kx, np.full(5, math.inf), 1e-3)


def test_strain_uses_the_hooke_law_of_the_layer_at_the_depth():
    n, h = 16, 2e-4
    load = SurfaceLoad(p=1e3 * np.cos(2 * np.pi * np.arange(n) / n)[None, :].repeat(n, 0), spacing=h, periodic=True)
    skin = LayeredHalfSpace([Layer(1e-3, E, 0.5), Layer(1e-3, 4 * E, 0.3)])
    for z, (Ez, nuz) in ((0.5e-3, (E, 0.5)), (1.5e-3, (4 * E, 0.3))):
        s = skin.stress(load, z).data["stress"].values[0]
        e = skin.strain(load, z).data["strain"].values[0]
        trace = s[0] + s[1] + s[2]
        assert np.allclose(e[2], ((1 + nuz) * s[2] - nuz * trace) / Ez, atol=1e-15)
        assert np.allclose(e[4], (1 + nuz) * s[4] / Ez, atol=1e-15)
    assert np.abs(skin.strain(load, 0.5e-3).data["strain"].values[0, :3].sum(axis=0)).max() < 1e-15  # tr = 0


def test_isolated_truncation_estimate_covers_the_true_error():
    """Half-space base of the same material: truth from the half-space's spectral method on a grid padded
    400x (1-D; its own image error ~1e-3 of the one tested); rigid base: truth at padding 16 (its
    images fall off exponentially: ~1e-15)."""
    n, h = 32, 1e-4
    x = (np.arange(n) - n // 2) * h
    g = np.exp(-x**2 / (2 * (3 * h) ** 2))
    line = SurfaceLoad(p=1e3 * g, qx=200 * g, spacing=h)
    skin = LayeredHalfSpace([Layer(1e-3, E, 0.5)], base=HalfSpace(E, 0.5))
    m = 400 * n
    big = SurfaceLoad(p=np.pad(line.p, (m // 2 - n // 2, m // 2 - n // 2)),
                      qx=np.pad(line.qx, (m // 2 - n // 2, m // 2 - n // 2)), spacing=h, periodic=True)
    truth = HalfSpace(E, 0.5).stress(big, 1e-3, method="spectral").data["stress"].values[..., m // 2 - n // 2:][..., :n]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for padding in (2, 8):
            r = skin.stress(line, 1e-3, padding=padding)
            v = r.data["stress"].values
            true_error = np.abs(v - truth).max() / np.abs(v).max()
            assert true_error <= r.error_estimate <= 5 * true_error
    X, Y = np.meshgrid(x, x)
    patch = SurfaceLoad(p=1e3 * np.exp(-(X**2 + Y**2) / (2 * (3 * h) ** 2)), spacing=h)
    rigid = LayeredHalfSpace([Layer(1e-3, E, 0.5)])
    truth = rigid.stress(patch, 0.5e-3, padding=16).data["stress"].values
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for padding in (1, 2, 4):
            r = rigid.stress(patch, 0.5e-3, padding=padding)
            true_error = np.abs(r.data["stress"].values - truth).max() / np.abs(truth).max()
            assert true_error <= r.error_estimate <= 5 * true_error
    auto = rigid.stress(patch, 0.5e-3, tol=1e-6)
    assert auto.error_estimate <= 1e-6 and auto.data.attrs["padding"] == 8


@pytest.mark.parametrize("periodic", [True, False])
def test_operator_passes_the_dot_test_and_equals_the_field(periodic, rng):
    skin = LayeredHalfSpace([Layer(0.5e-3, 2 * E, 0.45), Layer(1e-3, E, 0.5)])
    shape, h = (12, 16), 1e-4
    op = skin.operator(shape, h, depth=0.8e-3, components=("zz", "zx", "xy"), loads=("p", "qx", "qy"),
                       quantity="strain", periodic=periodic, padding=4)
    assert dottest(op, rng=rng) <= 1e-10
    model = rng.standard_normal(op.model_shape)
    load = SurfaceLoad(p=model[0], qx=model[1], qy=model[2], spacing=h, periodic=periodic)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a random load fills its grid: its images are near (the estimate says so)
        field = skin.strain(load, 0.8e-3, components=("zz", "zx", "xy"), padding=4).data["strain"].values[0]
    assert np.allclose(op @ model.ravel(), field.ravel(), rtol=0, atol=1e-12 * np.abs(field).max())
    assert (op.error_estimate == 0.0) if periodic else (0 < op.error_estimate < 1.0)


def test_contact_on_a_thick_layer_is_the_halfspace_contact():
    """Periodic: the same solve to round-off; isolated (the padded-periodic influence of a skin without
    surface_influence): within the two discretisations' gap, and Hertz's radius within a node."""
    E_, R, n, h = 1e6, 0.01, 64, 4e-5
    x = (np.arange(n) - n // 2) * h
    X, Y = np.meshgrid(x, x)
    gap = (X**2 + Y**2) / (2 * R)
    hs, thick = HalfSpace(E_, 0.5), LayeredHalfSpace([Layer(0.5, E_, 0.5)])
    a = solve_contact(hs, gap, h, periodic=True, mean_pressure=2e3)
    b = solve_contact(thick, gap, h, periodic=True, mean_pressure=2e3)
    assert np.abs(a.pressure - b.pressure).max() <= 1e-9 * a.pressure.max()
    F = 0.005
    a = solve_contact(hs, gap, h, normal_force=F)
    on_itself = LayeredHalfSpace([Layer(1e-3, E_, 0.5)], base=hs)  # k = 0 entry 0: a constant shift, absorbed
    for skin in (thick, on_itself):
        b = solve_contact(skin, gap, h, normal_force=F)
        assert np.abs(a.pressure - b.pressure).max() <= 0.02 * a.pressure.max()
        radius = (3 * F * R / (4 * E_ / 0.75)) ** (1 / 3)  # Hertz
        area = np.count_nonzero(b.pressure) * h * h
        assert math.sqrt(area / math.pi) == pytest.approx(radius, abs=h)


def test_a_thin_layer_stiffens_the_contact_as_lubrication_predicts():
    """A sphere on a thin incompressible layer bonded to bone: p = 3 G (a^2 - r^2)^2 / (32 R H^3),
    F = pi G a^6 / (32 R H^3) (the thin-layer equation w = -H^3 lap(p) / (3 G)); the gap to it falls
    with H / a, and the same force on the half-space gives a lower, wider pressure."""
    E_, R, a_ref, n, h = 1e6, 0.01, 2e-3, 64, 6e-3 / 64
    G = E_ / 3
    x = (np.arange(n) - n // 2) * h
    X, Y = np.meshgrid(x, x)
    gap, r = (X**2 + Y**2) / (2 * R), np.hypot(X, Y)
    gaps = []
    for H in (1e-4, 5e-5):
        F = math.pi * G * a_ref**6 / (32 * R * H**3)
        sol = solve_contact(LayeredHalfSpace([Layer(H, E_, 0.5)]), gap, h, periodic=True,
                            mean_pressure=F / (n * h) ** 2, tol=1e-10)
        p0 = 3 * G * a_ref**4 / (32 * R * H**3)
        ref = np.where(r < a_ref, 3 * G * (a_ref**2 - r**2) ** 2 / (32 * R * H**3), 0.0)
        gaps.append(np.abs(sol.pressure - ref).max() / p0)
    assert gaps[1] <= 0.01 and gaps[1] <= 0.5 * gaps[0]
    F = 0.05
    thin = solve_contact(LayeredHalfSpace([Layer(3e-4, E_, 0.5)]), gap, h, normal_force=F)
    half = solve_contact(HalfSpace(E_, 0.5), gap, h, normal_force=F)
    assert thin.pressure.max() > 1.2 * half.pressure.max()
    assert np.count_nonzero(thin.pressure) < np.count_nonzero(half.pressure)


def test_bad_inputs_are_refused_with_the_rule():
    with pytest.raises(ValueError, match=r"thickness: must be finite and > 0 m, got 0.0"):
        Layer(0.0, E, 0.5)
    with pytest.raises(ValueError, match=r"thickness: must be finite and > 0 m, got nan"):
        Layer(math.nan, E, 0.5)
    with pytest.raises(ValueError, match=r"E: Young's modulus must be finite and > 0 Pa, got nan"):
        Layer(1e-3, math.nan, 0.5)
    with pytest.raises(ValueError, match=r"nu: Poisson's ratio must lie in \(-1, 0.5\]"):
        Layer(1e-3, E, 0.6)
    with pytest.raises(ValueError, match=r"nu: Poisson's ratio must lie in \(-1, 0.5\]"):
        Layer(1e-3, E, math.nan)
    with pytest.raises(ValueError, match="layers: expected a non-empty list of Layer"):
        LayeredHalfSpace([])
    with pytest.raises(ValueError, match="layers: expected a list of Layer"):
        LayeredHalfSpace(3)
    with pytest.raises(ValueError, match="base: must be 'rigid' or a HalfSpace"):
        LayeredHalfSpace([Layer(1e-3, E)], base="bone")
    skin = LayeredHalfSpace([Layer(1e-3, E)])
    periodic = SurfaceLoad(p=np.ones((4, 4)), spacing=1e-4, periodic=True)
    with pytest.raises(ValueError, match="depth: 0.002 m lies in the rigid base"):
        skin.stress(periodic, 2e-3)
    with pytest.raises(ValueError, match="depth: every depth must be finite and > 0 m"):
        skin.stress(periodic, math.nan)
    with pytest.raises(ValueError, match="points: an isolated load's sensors must lie within its grid"):
        skin.stress(SurfaceLoad(p=np.ones((4, 4)), spacing=1e-4), 5e-4, points=[[3e-4, 0.0]])
    with pytest.raises(ValueError, match=r"points: expected finite positions of shape \(n, 2\)"):
        skin.stress(periodic, 5e-4, points=[[math.nan, 0.0]])
    with pytest.raises(ValueError, match="padding: must be 'auto' or an integer >= 1"):
        skin.stress(periodic, 5e-4, padding=0)
    with pytest.raises(ValueError, match="tol: must be a finite relative tolerance > 0"):
        skin.stress(periodic, 5e-4, tol=math.nan)
    with pytest.raises(ValueError, match="load: a layered skin takes a SurfaceLoad"):
        skin.stress(np.ones(4), 5e-4)
    with pytest.raises(ValueError, match="components: unknown component"):
        skin.strain(periodic, 5e-4, components=("qq",))
    with pytest.raises(ValueError, match="kx: "):
        skin.surface_compliance(np.array([math.nan]), None)
    with pytest.raises(ValueError, match="padding: must be an integer >= 2"):
        skin.operator((4,), 1e-4, depth=5e-4, padding=1)
    with pytest.raises(ValueError, match="loads: give distinct names"):
        skin.operator((4,), 1e-4, depth=5e-4, loads=("p", "p"))
    with pytest.raises(ValueError, match=r"shape: expected \(nx,\) or \(ny, nx\)"):
        skin.operator((4, 4, 4), 1e-4, depth=5e-4)
    with pytest.raises(ValueError, match="periodic: must be True or False"):
        skin.operator((4,), 1e-4, depth=5e-4, periodic="yes")
    with pytest.raises(ValueError, match="quantity: must be 'stress' or 'strain'"):
        skin.operator((4,), 1e-4, depth=5e-4, quantity="energy")


def test_receptive_field_of_the_halfspace_is_boussinesq_and_bone_concentrates_it():
    """sigma_zz = -3 F Z^3 / (2 pi R^5): peak 3 F / (2 pi Z^2), half at x = Z sqrt(2^(2/5) - 1), a tenth
    at x = Z sqrt(10^(2/5) - 1); layers of the half-space's material on it read the same; on bone the
    pulp concentrates the stress under the force (docs/layered_skin.md)."""
    from tactilab.forward.skin import receptive_field

    Z = 3e-3
    same = LayeredHalfSpace([Layer(4e-3, E, 0.5)], base=HalfSpace(E, 0.5))
    for skin, tol in ((HalfSpace(E, 0.5), 1e-4), (same, 1e-2)):
        r = receptive_field(skin, Z, "zz", "stress", spacing=2e-4, half_extent=12e-3, tol=tol)
        assert r.peak == pytest.approx(3 / (2 * math.pi * Z**2), rel=2e-3)
        assert r.half_width == pytest.approx(Z * math.sqrt(2**0.4 - 1), rel=1e-2)
        assert r.tenth_width == pytest.approx(Z * math.sqrt(10**0.4 - 1), rel=2e-2)
    pulp = receptive_field(LayeredHalfSpace([Layer(4e-3, E, 0.5)]), Z, "zz", "stress", spacing=2e-4, half_extent=12e-3)
    assert pulp.peak > 1.2 * 3 / (2 * math.pi * Z**2) and pulp.error_estimate < 1e-4
    with pytest.raises(ValueError, match="reading: must be one of"):
        receptive_field(HalfSpace(E, 0.5), Z, "pressure")
    with pytest.raises(ValueError, match="quantity: must be 'strain' or 'stress'"):
        receptive_field(HalfSpace(E, 0.5), Z, "von_mises", "stress")


def _array(d, n=5):
    from tactilab.forward.tractors import array_centres

    centres, sign = array_centres(d, n)
    return np.concatenate([centres - d, centres + d]), np.concatenate([-sign * np.ones(n), sign * np.ones(n)])


def test_tractor_shapes_on_the_halfspace_match_the_closed_form_and_converge_with_the_period():
    """S_Phi, S_Psi of a tractor array (docs/theory.md 4a, closed form at nu = 1/2) from the layered
    Fourier series of a half-space: the images of the period L leave an error falling like 1/L^2."""
    from tactilab.forward.skin import tangential_line_strain
    from tactilab.forward.tractors import array_phi_psi

    z, d = 1e-3, 0.8e-3
    xs = np.linspace(-5e-3, 5e-3, 101)
    src, w = _array(d)
    phi, psi = array_phi_psi(xs, d, z, 5)
    errors = []
    for period in (0.1, 0.4):
        eps, gamma = tangential_line_strain(HalfSpace(E, 0.5), xs, src, w, z, period=period)
        errors.append(max(np.abs(math.pi * E / 3 * eps - phi).max() / np.abs(phi).max(),
                          np.abs(math.pi * E / 3 * gamma - psi).max() / np.abs(psi).max()))
    assert errors[1] < 5e-4 and errors[0] / errors[1] > 12


def test_tractor_shapes_on_a_grid_and_spline_equal_the_direct_sum():
    from tactilab.forward.skin import tangential_line_strain

    skin = LayeredHalfSpace([Layer(4e-3, E, 0.5)])
    src, w = _array(1e-3)
    xs = np.linspace(-6e-3, 6e-3, 200)  # more than 32 points: the FFT grid and the spline
    eps, gamma = tangential_line_strain(skin, xs, src, w, 2e-3)
    direct = [tangential_line_strain(skin, xs[i:i + 20], src, w, 2e-3) for i in range(0, 200, 20)]
    assert np.abs(eps - np.concatenate([e for e, _ in direct])).max() <= 1e-8 * np.abs(eps).max()
    assert np.abs(gamma - np.concatenate([g for _, g in direct])).max() <= 1e-8 * np.abs(gamma).max()


def test_synthesis_optimum_takes_a_skin():
    """The half-space's optimum through the layered series (layers of its material on it) is the closed
    form's; a pulp on bone moves it (docs/layered_skin.md tabulates by how much)."""
    from tactilab.forward import optimal_half_spacing

    z = 1e-3
    closed = optimal_half_spacing(z, grid_points=20)
    assert optimal_half_spacing(z, grid_points=20, skin=HalfSpace(E, 0.5)).d == closed.d
    same = optimal_half_spacing(z, grid_points=20, skin=LayeredHalfSpace([Layer(0.5e-3, E, 0.5)],
                                                                         base=HalfSpace(E, 0.5)))
    assert same.d == pytest.approx(closed.d, rel=2e-3) and same.skin.startswith("LayeredHalfSpace")
    with pytest.raises(ValueError, match="skin: the design takes None or HalfSpace"):
        optimal_half_spacing(z, grid_points=20, skin=HalfSpace(E, 0.3))


def test_a_large_strain_and_a_depth_meant_in_mm_warn():
    from tactilab.data_schemas.plausibility import PlausibilityWarning

    skin = LayeredHalfSpace([Layer(5.0, E, 0.5)])
    load = SurfaceLoad(p=np.full((4, 4), 1e5) * np.cos(np.arange(4) * np.pi / 2), spacing=1e-4, periodic=True)
    with pytest.warns(PlausibilityWarning, match="LayeredHalfSpace.strain"):
        skin.strain(load, 1e-5)
    with pytest.warns(PlausibilityWarning, match="depth"):
        skin.stress(load.scaled(1e-6), 1.25)


def test_a_loads_own_error_is_carried_into_the_estimate():
    n = 16
    p = 1e3 * np.cos(2 * np.pi * np.arange(n) / n)[None, :].repeat(n, 0)
    skin = LayeredHalfSpace([Layer(1e-3, E, 0.5)])
    exact = skin.stress(SurfaceLoad(p=p, spacing=1e-4, periodic=True), 5e-4)
    loose = skin.stress(SurfaceLoad(p=p, spacing=1e-4, periodic=True, error_estimate=1e-3), 5e-4)
    peak = np.abs(exact.data["stress"].values).max()
    assert loose.error_estimate == pytest.approx(exact.error_estimate + 1e-3 * 1e3 / peak, rel=1e-12)
    assert loose.data.attrs["error_covers"] == "method+load"


def test_sensors_off_the_nodes_read_the_exact_field_of_a_plane_wave(rng):
    """A single Fourier mode p = cos(k . x) gives sigma(x) = Re(T(k) exp(i k . x)) at every point, on or
    off the nodes (T from transfer, an independent evaluation of the same multiplier)."""
    n, h = 16, 1e-4
    x = (np.arange(n) - n // 2) * h
    X, Y = np.meshgrid(x, x)
    kx, ky = 2 * np.pi * 3 / (n * h), 2 * np.pi * -2 / (n * h)
    load = SurfaceLoad(p=np.cos(kx * X + ky * Y), qx=np.sin(kx * X + ky * Y), spacing=h, periodic=True)
    skin = LayeredHalfSpace([Layer(0.6e-3, E, 0.5), Layer(1e-3, 2 * E, 0.3)])
    pts = rng.uniform(-1e-3, 1e-3, (7, 2))
    got = skin.strain(load, 0.8e-3, points=pts).data["strain"].values[0]  # (6, 7)
    T = skin.transfer(np.array(kx), np.array(ky), 0.8e-3, quantity="strain")  # (6, 3)
    phase = np.exp(1j * (kx * pts[:, 0] + ky * pts[:, 1]))
    ref = (T[:, 0, None] * phase).real + (T[:, 1, None] * -1j * phase).real  # sin = Re(-i e^{i theta})
    assert np.allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    line = SurfaceLoad(p=np.cos(kx * x), spacing=h, periodic=True)
    got = skin.stress(line, 0.8e-3, points=pts[:, 0], components=("zz",)).data["stress"].values[0, 0]
    T = skin.transfer(np.array(kx), np.array(0.0), 0.8e-3)
    assert np.allclose(got, (T[2, 0] * np.exp(1j * kx * pts[:, 0])).real, rtol=0, atol=1e-12)
    iso = SurfaceLoad(p=np.exp(-(X**2 + Y**2) / (2 * (2 * h) ** 2)), spacing=h)
    inside = np.array([[0.25 * h, -0.5 * h], [3 * h, 2 * h]])  # the second on a node: the interpolant is exact there
    at = skin.stress(iso, 0.5e-3, points=inside, components=("zz",), tol=1e-3, padding=4).data["stress"].values[0, 0]
    grid = skin.stress(iso, 0.5e-3, components=("zz",), tol=1e-3, padding=4).data["stress"].values[0, 0]
    assert at[1] == pytest.approx(grid[n // 2 + 2, n // 2 + 3], rel=1e-12)
    assert abs(at[0]) <= np.abs(grid).max()


@pytest.mark.parametrize("periodic", [True, False])
@pytest.mark.parametrize("shape", [(10, 12), (12,)])
def test_operator_at_sensors_on_and_off_the_nodes(periodic, shape, rng):
    """Off the nodes: the exact interpolant with its exact adjoint (the transpose of the rfft); on nodes:
    a selection of the grid. Both equal the field at those points and pass the dot test."""
    skin = LayeredHalfSpace([Layer(0.5e-3, 2 * E, 0.45), Layer(1e-3, E, 0.5)])
    h = 1e-4
    x = (np.arange(shape[-1]) - shape[-1] // 2) * h
    off = rng.uniform(x[0], x[-1], (5, len(shape)))
    on = np.column_stack([x[[1, 4, 7]], ((np.arange(shape[0]) - shape[0] // 2) * h)[[2, 0, 5]]])[:, :len(shape)]
    for sensors in (off, on):
        op = skin.operator(shape, h, sensors=sensors, depth=0.8e-3, components=("zz", "xx"), loads=("p", "qx"),
                           quantity="strain", periodic=periodic, padding=4)
        assert dottest(op, rng=rng) <= 1e-10
        model = rng.standard_normal(op.model_shape)
        load = SurfaceLoad(p=model[0], qx=model[1], spacing=h, periodic=periodic)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a random load fills its grid: the estimate says the images are near
            field = skin.strain(load, 0.8e-3, points=sensors, components=("zz", "xx"), padding=4)
        ref = field.data["strain"].values[0]
        assert np.allclose(op @ model.ravel(), ref.ravel(), rtol=0, atol=1e-12 * np.abs(ref).max())

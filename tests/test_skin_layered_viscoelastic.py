"""Viscoelastic layers (forward/skin/layered_viscoelastic.py, layered_harmonic.py): independent closed forms.

Oracles: the viscoelastic half-space's steady sliding (``ViscoelasticHalfSpace``, docs/theory.md
section 7) and the half-space's closed form per harmonic, ``p = E*(omega) k H / (2 (1 - nu^2))``
with ``sigma_zz = -(1 + k z) exp(-k z) p``, for a deep layer; the elastic layered skin of the relaxed
and of the instantaneous moduli at omega = 0 and omega -> inf; the closed-form surface compliance of a
layer bonded to a rigid base (Carbone and Mangialardi 2008 form, docs/theory.md section 6) evaluated at
the complex modulus; the correspondence principle for layers that relax with one shape (stress
independent of time, strain times ``E(0) J(t)``); conjugate symmetry and the linear extrapolation
to nu = 1/2 of the propagator with complex moduli.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactilab.cli.main import main
from tactilab.data_schemas import SkinMaterial, read_material
from tactilab.forward import HalfSpace, SurfaceLoad, ViscoelasticHalfSpace, angular_wavenumbers, skin_from_material
from tactilab.forward.skin import Layer, LayeredHalfSpace, Prony, ViscoelasticLayeredHalfSpace
from tactilab.forward.skin.layered_multipliers import transfer_matrix

SLS = Prony.sls(1e5, 3e5, 0.05)  # Pa, Pa, s
DERMIS = Prony(4e5, [(8e5, 0.01)])
PULP = Prony(2e5, [(1e6, 4e-3), (5e5, 0.07), (3e5, 1.4)])
HERTZ = (1.0, 10.0, 100.0, 1000.0)  # temporal frequencies of the checks


def _closed_form_compliance(k, h, E, nu):
    """Normal compliance (m/Pa) of a layer bonded to a rigid base, frictionless on top, at any (complex) E:
    2 (1 - nu^2) / (E k) (kappa sinh 2x - 2x) / (kappa cosh 2x + 2 x^2 + (1 + kappa^2) / 2), x = k h."""
    x, kappa = k * h, 3 - 4 * nu
    return 2 * (1 - nu**2) / (E * k) * (kappa * np.sinh(2 * x) - 2 * x) / (
        kappa * np.cosh(2 * x) + 2 * x**2 + (1 + kappa**2) / 2)


def _two_layers(base="rigid"):
    return ViscoelasticLayeredHalfSpace([Layer(1e-3, DERMIS, 0.5), Layer(3e-3, PULP, 0.45)], base=base)


@pytest.mark.parametrize("ndim", [1, 2])
def test_a_deep_stack_of_one_material_is_the_viscoelastic_halfspace_in_steady_sliding(ndim, rng):
    """Two equal SLS layers 40 wavelengths deep: pressure, stress and strain as ViscoelasticHalfSpace, to 1e-10."""
    n, h = 32, 1e-4
    height = 1e-6 * rng.standard_normal((n,) * ndim)
    skin = ViscoelasticLayeredHalfSpace([Layer(0.05, SLS, 0.5), Layer(0.08, SLS, 0.5)])
    half = ViscoelasticHalfSpace(SLS, 0.5)
    for speed in (0.0, 1e-3, 0.03, 2.0):
        p, q = skin.sliding_pressure(height, h, speed).p, half.sliding_pressure(height, h, speed).p
        assert np.abs(p - q).max() <= 1e-10 * np.abs(q).max()
        for quantity in ("stress", "strain"):
            a = skin.steady_sliding(height, h, speed, [3e-4, 1e-3], quantity, time=0.01).data[quantity].values
            b = half.steady_sliding(height, h, speed, [3e-4, 1e-3], quantity, time=0.01).data[quantity].values
            assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max()


@pytest.mark.parametrize("hertz", HERTZ)
def test_gain_and_phase_per_harmonic_of_a_deep_layer_are_the_halfspace_closed_form(hertz):
    """Per unit deflection: p = E*(omega) k / (2 (1 - nu^2)), sigma_zz = -(1 + k z) exp(-k z) p, strain elastic."""
    wavelength, z, nu = 2e-3, 1e-3, 0.5
    k = 2 * np.pi / wavelength
    omega = -2 * np.pi * hertz
    skin = ViscoelasticLayeredHalfSpace([Layer(50 * wavelength, SLS, nu)])
    pressure = SLS.complex_modulus(omega) * k / (2 * (1 - nu**2))
    stress = skin.deflection_transfer(k, 0.0, z, omega)
    assert abs(stress[2] - (-(1 + k * z) * math.exp(-k * z) * pressure)) <= 1e-10 * abs(stress[2])
    strain = skin.deflection_transfer(k, 0.0, z, omega, quantity="strain")
    assert np.abs(strain - skin.deflection_transfer(k, 0.0, z, 0.0, quantity="strain")).max() <= \
        1e-12 * np.abs(strain).max()


def test_zero_and_infinite_frequency_are_the_relaxed_and_instantaneous_elastic_layers(rng):
    """omega = 0: every E_inf; omega = 1e16 rad/s: every E(0) (relative error 1/(omega tau) < 1e-12)."""
    kx, ky = rng.standard_normal((2, 12)) * 3e3
    for base in ("rigid", HalfSpace(1e5, 0.5), ViscoelasticHalfSpace(SLS, 0.5)):
        skin = _two_layers(base)
        for omega, elastic in ((0.0, skin.relaxed), (1e16, skin.instantaneous)):
            for z in (5e-4, 2.5e-3):
                for quantity in ("stress", "strain"):
                    a, b = skin.transfer(kx, ky, z, omega, quantity), elastic.transfer(kx, ky, z, quantity)
                    assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max()
            a, b = skin.surface_compliance(kx, ky, omega=omega), elastic.surface_compliance(kx, ky)
            assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max()
            g = skin.deflection_transfer(kx, ky, 1e-3, omega)
            t = elastic.transfer(kx, ky, 1e-3)[..., 0] / elastic.surface_compliance(kx, ky)[..., 0, 0][:, None]
            assert np.abs(g - t).max() <= 1e-10 * np.abs(t).max()
    assert np.array_equal(skin.surface_compliance(kx, ky), skin.instantaneous.surface_compliance(kx, ky))


@pytest.mark.parametrize("nu", [0.5, 0.3])
def test_a_single_sls_layer_per_harmonic_is_the_bonded_layer_closed_form_at_the_complex_modulus(nu):
    """A grating sliding over one SLS layer on bone: each harmonic's pressure is its deflection over the
    closed-form compliance evaluated at E*(-kx V), at 1, 10, 100 and 1000 Hz of temporal frequency."""
    thickness, wavelength, n = 2e-3, 4e-3, 64
    h = wavelength / n
    x = np.arange(n) * h
    skin = ViscoelasticLayeredHalfSpace([Layer(thickness, SLS, nu)])
    for harmonic in (1, 3):
        k = 2 * np.pi * harmonic / wavelength
        height = 1e-6 * np.cos(k * x)
        for hertz in HERTZ:
            speed = hertz * wavelength / harmonic  # the harmonic passes at `hertz`
            modulus = SLS.complex_modulus(-k * speed)
            expected = 1e-6 * np.real(np.exp(1j * k * x) / _closed_form_compliance(k, thickness, modulus, nu))
            p = skin.sliding_pressure(height, h, speed).p
            assert np.abs(p - expected).max() <= 1e-10 * np.abs(expected).max()
            gain = skin.deflection_transfer(k, 0.0, 1e-3, -k * speed)[2] / skin.deflection_transfer(k, 0.0, 1e-3)[2]
            ratio = _closed_form_compliance(k, thickness, SLS.E_inf, nu) / _closed_form_compliance(
                k, thickness, modulus, nu)
            assert abs(gain - ratio) <= 1e-10 * abs(ratio)


def test_the_propagator_takes_complex_moduli_conjugates_and_stays_exact_at_nu_one_half(rng):
    """G -> conj(G) conjugates every multiplier; nu = 1/2 with complex moduli equals the linear
    extrapolation from nu = 0.5 - 1e-7 and 0.5 - 2e-7; a common complex factor on every modulus leaves
    the stress under tractions unchanged and divides the compliance."""
    kx, ky = rng.standard_normal((2, 15)) * 2e3
    omega = 2 * np.pi * 30

    def skin(nu, scale=1.0):
        return ViscoelasticLayeredHalfSpace([Layer(1e-3, DERMIS, nu), Layer(2e-3, PULP, nu)],
                                            base=ViscoelasticHalfSpace(SLS, nu))

    exact, a, b = (skin(nu).transfer(kx, ky, 1.5e-3, omega) for nu in (0.5, 0.5 - 1e-7, 0.5 - 2e-7))
    assert np.abs(exact - (2 * a - b)).max() <= 1e-8 * np.abs(exact).max()
    s = skin(0.5)
    assert np.abs(s.transfer(kx, ky, 1.5e-3, -omega) - np.conj(s.transfer(kx, ky, 1.5e-3, omega))
                  * np.array([1, 1, 1, -1, -1, 1])[:, None] * np.array([1, -1, -1])).max() <= \
        1e-12 * np.abs(exact).max()
    holder = LayeredHalfSpace([Layer(1e-3, 1e5, 0.5), Layer(2e-3, 3e5, 0.5)], base=HalfSpace(2e5, 0.5))
    ref_t, ref_c = transfer_matrix(holder, kx, ky, 1.5e-3), holder.surface_compliance(kx, ky)
    factor = 2.0 - 1.5j
    stack = holder._stack
    holder._stack = type(stack)(stack.thickness, stack.G * factor, stack.nu, (stack.base[0] * factor, 0.5))
    holder._amplitude_cache.clear()
    assert np.abs(transfer_matrix(holder, kx, ky, 1.5e-3) - ref_t).max() <= 1e-12 * np.abs(ref_t).max()
    assert np.abs(holder.surface_compliance(kx, ky) * factor - ref_c).max() <= 1e-12 * np.abs(ref_c).max()


def test_layers_of_one_relaxation_shape_obey_the_correspondence_principle(rng):
    """E_j(t) = c_j E(t): under tractions the stress is elastic at every time and frequency; the strain is
    the instantaneous one times E(0) J*(omega) (harmonic) and E(0) J(t) under a step (time history)."""
    shape = Prony(1e5, [(2e5, 0.01), (1e5, 0.3)])
    skin = ViscoelasticLayeredHalfSpace([Layer(1e-3, Prony(3e5, [(6e5, 0.01), (3e5, 0.3)]), 0.5),
                                         Layer(3e-3, shape, 0.45)], base=ViscoelasticHalfSpace(
                                             Prony(2e5, [(4e5, 0.01), (2e5, 0.3)]), 0.5))
    assert skin.relaxation_shape() == Prony(3e5, [(6e5, 0.01), (3e5, 0.3)])
    n, h = 16, 2e-4
    load = SurfaceLoad(p=1e3 * rng.standard_normal((n, n)), qx=1e2 * rng.standard_normal((n, n)), spacing=h,
                       periodic=True)
    glassy = skin.instantaneous
    for z in (5e-4, 2e-3, 5e-3):
        elastic_stress = glassy.stress(load, z).data["stress"].values
        elastic_strain = glassy.strain(load, z).data["strain"].values
        moving = skin.moving_load(load, 0.02, z).data["stress"].values
        assert np.abs(moving - elastic_stress).max() <= 1e-10 * np.abs(elastic_stress).max()
        kx = 2 * np.pi / (n * h)
        omega = -kx * 0.02
        factor = skin.relaxation_shape().E_0 / skin.relaxation_shape().complex_modulus(omega)
        a, b = skin.transfer(kx, 0.0, z, omega, "strain"), glassy.transfer(kx, 0.0, z, "strain") * factor
        assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max()
        times = np.array([0.0, 0.005, 0.05, 1.0, 1e3])
        strain = skin.strain(load, z, times).values
        creep = skin.relaxation_shape().creep_compliance(times) / skin.relaxation_shape().J_0
        assert np.abs(strain - creep[:, None, None, None, None] * elastic_strain).max() <= \
            1e-10 * np.abs(strain).max()
        stress = skin.stress(load, z, times, history=[0.0, 0.5, 1.0, 1.0, 2.0]).values
        assert np.abs(stress[-1] - 2 * elastic_stress).max() <= 1e-12 * np.abs(elastic_stress).max()
    relaxed = skin.relaxed.strain(load, 2e-3).data["strain"].values
    assert np.abs(skin.strain(load, 2e-3, [0.0, 1e4]).values[-1] - relaxed).max() <= 1e-10 * np.abs(relaxed).max()


def test_a_held_load_is_the_elastic_layers_of_at(rng):
    """at(t): the elastic layers of a traction held from 0 to t. One shape: the recursive creep convolution of
    strain() (an independent route) and the unchanged stress, and a deep stack's modulus is the half-space's
    1 / J(t); any layers: 0 and inf are the glassy and the relaxed layers, and a time between is refused."""
    skin = ViscoelasticLayeredHalfSpace([Layer(1e-3, Prony(3e5, [(6e5, 0.01), (3e5, 0.3)]), 0.5),
                                         Layer(3e-3, Prony(1e5, [(2e5, 0.01), (1e5, 0.3)]), 0.45)])
    load = SurfaceLoad(p=1e3 * rng.standard_normal((16, 16)), qy=1e2 * rng.standard_normal((16, 16)), spacing=2e-4,
                       periodic=True)
    for t in (0.0, 0.004, 0.07, 2.0):
        held = skin.at(t)
        for quantity in ("stress", "strain"):
            api = getattr(skin, quantity)(load, [5e-4, 2e-3], [0.0] if t == 0 else [0.0, t]).values[-1]
            mine = getattr(held, quantity)(load, [5e-4, 2e-3]).data[quantity].values
            assert np.abs(mine - api).max() <= 1e-12 * np.abs(api).max()
    assert skin.at(0.0) is skin.instantaneous and skin.at(math.inf) is skin.relaxed
    deep = ViscoelasticLayeredHalfSpace([Layer(0.05, DERMIS, 0.5)], base=ViscoelasticHalfSpace(DERMIS, 0.5))
    for t in (0.003, 0.05):
        assert deep.at(t).layers[0].E == pytest.approx(ViscoelasticHalfSpace(DERMIS, 0.5).at(t).E, rel=1e-14)
        assert deep.at(t).base.E == pytest.approx(deep.at(t).layers[0].E, rel=1e-14)
    differ = _two_layers()
    assert differ.at(math.inf) is differ.relaxed and differ.at(0.0) is differ.instantaneous
    with pytest.raises(ValueError, match=r"layers\[1\]: a time history under prescribed tractions needs every "
                                         r"material to relax with one shape"):
        differ.at(0.01)
    with pytest.raises(ValueError, match=r"time: times must be >= 0 s"):
        skin.at(-1.0)


def test_elastic_layers_are_their_layered_skin_at_every_time_and_speed(rng):
    skin = ViscoelasticLayeredHalfSpace([Layer(1e-3, 2e5, 0.5), Layer(2e-3, 1e5, 0.5)])
    height = 1e-6 * rng.standard_normal(32)
    elastic = LayeredHalfSpace([Layer(1e-3, 2e5, 0.5), Layer(2e-3, 1e5, 0.5)])
    assert skin.relaxation_shape() is None
    a = skin.steady_sliding(height, 1e-4, 0.3, 1e-3, "strain").data["strain"].values
    b = skin.steady_sliding(height, 1e-4, 0.0, 1e-3, "strain").data["strain"].values
    assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()
    load = SurfaceLoad(p=1e3 * rng.standard_normal(32), spacing=1e-4, periodic=True)
    c = skin.strain(load, 1e-3, [0.0, 1.0]).values
    d = elastic.strain(load, 1e-3).data["strain"].values
    assert np.abs(c - d).max() <= 1e-12 * np.abs(d).max()


def test_layers_that_relax_differently_make_the_strain_depend_on_speed():
    """The dermis relaxes faster than the pulp: the strain at 1 mm of a sliding grating is no longer
    speed-independent (it is for one relaxation shape, above)."""
    skin = _two_layers()
    k = 2 * np.pi / 2e-3
    slow, fast = (skin.deflection_transfer(k, 0.0, 1e-3, -k * v, "strain")[2] for v in (1e-4, 0.2))
    assert abs(abs(fast) / abs(slow) - 1) > 1e-3


def test_a_material_file_with_layer_terms_builds_the_viscoelastic_layers(tmp_path):
    path = tmp_path / "skin.toml"
    path.write_text('[material]\nlayers = [{thickness = "1mm", young_modulus = "0.4MPa", terms = [["0.8MPa", "10ms"]]},'
                    '\n  {thickness = "3mm", young_modulus = "0.2MPa", poisson_ratio = 0.45}]\n'
                    'base = {young_modulus = "0.1MPa"}\n', encoding="utf-8")
    material = read_material(path)
    assert material.has_viscoelastic_layers and not material.is_viscoelastic
    skin = skin_from_material(material)
    assert isinstance(skin, ViscoelasticLayeredHalfSpace)
    assert skin.layers[0].E == DERMIS and skin.layers[1].E == 2e5 and skin.layers[1].nu == 0.45
    assert skin.base.E == 1e5


def test_bad_inputs_are_refused_with_the_rule(tmp_path, capsys):
    viscous = Layer(1e-3, SLS, 0.5)
    with pytest.raises(ValueError, match=r"layers\[0\]: a LayeredHalfSpace is elastic.*ViscoelasticLayeredHalfSpace"):
        LayeredHalfSpace([viscous])
    with pytest.raises(ValueError, match=r"E: a viscoelastic layer .* has no single shear modulus"):
        viscous.G
    with pytest.raises(ValueError, match=r"limit: must be 'instantaneous' or 'relaxed'"):
        viscous.elastic("glassy")
    with pytest.raises(ValueError, match=r"layers: expected a non-empty list of Layer"):
        ViscoelasticLayeredHalfSpace([])
    with pytest.raises(ValueError, match=r"layers: expected a list of Layer"):
        ViscoelasticLayeredHalfSpace(3)
    with pytest.raises(ValueError, match=r"base: must be 'rigid', a HalfSpace"):
        ViscoelasticLayeredHalfSpace([viscous], base="bone")
    skin = _two_layers()
    load = SurfaceLoad(p=np.ones(8), spacing=1e-4, periodic=True)
    with pytest.raises(ValueError, match=r"layers\[1\]: a time history under prescribed tractions needs every material "
                                         r"to relax with one shape"):
        skin.strain(load, 1e-3, [0.0, 0.1])
    with pytest.raises(ValueError, match=r"base: a time history .* one shape"):
        ViscoelasticLayeredHalfSpace([viscous], base=HalfSpace(1e5, 0.5)).stress(load, 1e-3, [0.0])
    with pytest.raises(ValueError, match=r"load: a moving load is one period of a periodic pattern"):
        skin.moving_load(SurfaceLoad(p=np.ones(8), spacing=1e-4), 0.1, 1e-3)
    with pytest.raises(ValueError, match=r"quantity: must be 'stress' or 'strain'"):
        skin.steady_sliding(np.zeros(8), 1e-4, 0.1, 1e-3, quantity="stretch")
    with pytest.raises(ValueError, match=r"quantity: must be 'stress' or 'strain'"):
        skin.transfer(1e3, 0.0, 1e-3, quantity="stretch")
    with pytest.raises(ValueError, match=r"depth: .* lies in the rigid base"):
        skin.steady_sliding(np.zeros(8), 1e-4, 0.1, 5e-3)
    with pytest.raises(ValueError, match=r"height: expected shape \(nx,\) or \(ny, nx\)"):
        skin.sliding_pressure(np.zeros((2, 2, 2)), 1e-4, 0.1)
    with pytest.raises(ValueError, match=r"speed"):
        skin.steady_sliding(np.zeros(8), 1e-4, math.nan, 1e-3)
    with pytest.raises(ValueError, match=r"omega"):
        skin.surface_compliance(1e3, 0.0, omega=math.inf)
    with pytest.raises(ValueError, match=r"layers: a layered skin takes model 'elastic'.*own Prony terms"):
        SkinMaterial(young_modulus_pa=1e5, model="prony", terms=[dict(modulus_pa=1e5, relaxation_time_s=0.1)],
                     layers=[dict(thickness_m=1e-3, young_modulus_pa=1e5)])
    with pytest.raises(ValueError, match=r"relaxation"):
        SkinMaterial(layers=[dict(thickness_m=1e-3, young_modulus_pa=1e5,
                                  terms=[dict(modulus_pa=1e5, relaxation_time_s=-1.0)])])
    path = tmp_path / "skin.toml"
    path.write_text('[material]\nlayers = [{thickness = "1mm", young_modulus = "0.4MPa", terms = [["0.8MPa", "10ms"]]},'
                    '\n  {thickness = "1mm", young_modulus = "0.2MPa"}]\n', encoding="utf-8")
    assert main(["stress", "examples/fingertip_load.toml", "--depth", "1mm", "--material", str(path), "--time", "5ms",
                 "--out", str(tmp_path / "out")]) == 2
    assert "--time: a held load on viscoelastic layers at a time between 0 and relaxed needs every material to " \
        "relax with one shape" in capsys.readouterr().err


def test_a_depth_meant_in_mm_warns_at_the_users_line():
    from tactilab.data_schemas.plausibility import PlausibilityWarning

    skin = ViscoelasticLayeredHalfSpace([Layer(4.0, SLS, 0.5)])
    with pytest.warns(PlausibilityWarning, match=r"depth = 1.5 m is outside the usual range") as record:
        skin.steady_sliding(np.zeros(8), 1e-4, 0.1, 1.5)
    assert record[0].filename == __file__


@pytest.mark.parametrize("shape", [(15, 17), (17,)])
def test_grid_fields_of_layers_that_relax_differently_are_the_point_multipliers_mode_by_mode(shape, rng):
    """On an odd grid (no Nyquist mode) every Fourier mode of a travelling traction's field, and of a sliding
    grating's, is the per-wavenumber multiplier at omega = -kx V times the load's mode: two routes, one
    column-grouped on the grid, one per point."""
    skin = _two_layers(ViscoelasticHalfSpace(SLS, 0.5))
    h, speed, z = 1e-4, 0.04, 1.5e-3
    axes = tuple(range(-len(shape), 0))
    load = SurfaceLoad(p=rng.standard_normal(shape), qx=rng.standard_normal(shape), qy=rng.standard_normal(shape),
                       spacing=h, periodic=True) if len(shape) == 2 else \
        SurfaceLoad(p=rng.standard_normal(shape), qx=rng.standard_normal(shape), spacing=h, periodic=True)
    waves = angular_wavenumbers(shape, h, half=True)
    kx, ky = (waves[0], np.zeros_like(waves[0])) if len(shape) == 1 else np.broadcast_arrays(*waves)
    for quantity in ("stress", "strain"):
        field = np.fft.rfftn(skin.moving_load(load, speed, z, quantity).data[quantity].values[0], axes=axes)
        T = skin.transfer(kx, ky, z, -kx * speed, quantity)
        names = ("p", "qx", "qy")[:len(load.components)]
        expected = sum(np.moveaxis(T[..., i], -1, 0) * np.fft.rfftn(load.components[n], axes=axes)
                       for i, n in enumerate(names))
        assert np.abs(field - expected).max() <= 1e-10 * np.abs(expected).max()
        height = 1e-6 * rng.standard_normal(shape)
        field = np.fft.rfftn(skin.steady_sliding(height, h, speed, z, quantity).data[quantity].values[0], axes=axes)
        expected = np.moveaxis(skin.deflection_transfer(kx, ky, z, -kx * speed, quantity), -1, 0) * \
            np.fft.rfftn(height, axes=axes)
        assert np.abs(field - expected).max() <= 1e-10 * np.abs(expected).max()


def test_layers_on_a_viscoelastic_halfspace_of_their_own_material_are_that_halfspace(rng):
    half = ViscoelasticHalfSpace(SLS, 0.45)
    skin = ViscoelasticLayeredHalfSpace([Layer(3e-4, SLS, 0.45), Layer(5e-4, SLS, 0.45)], base=half)
    height = 1e-6 * rng.standard_normal((16, 16))
    for speed in (0.0, 0.01, 1.0):
        for depth in (2e-4, 1e-3):
            a = skin.steady_sliding(height, 1e-4, speed, depth).data["stress"].values
            b = half.steady_sliding(height, 1e-4, speed, depth).data["stress"].values
            assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max()


def test_the_nyquist_mode_of_an_even_grid_is_the_average_of_the_two_directions_of_travel():
    """A load on the Nyquist mode alone cannot travel one way: its field is the same at +V and -V, the real
    part of the multiplier (the mean of omega and -omega)."""
    skin = _two_layers()
    n, h, z = 16, 1e-4, 1e-3
    load = SurfaceLoad(p=(-1.0) ** np.arange(n), spacing=h, periodic=True)
    kx = np.pi / h
    plus, minus = (skin.moving_load(load, v, z, components=("zz",)).data["stress"].values[0, 0] for v in (0.05, -0.05))
    expected = np.real(skin.transfer(kx, 0.0, z, -kx * 0.05)[2, 0]) * load.p
    assert np.abs(plus - minus).max() <= 1e-12 * np.abs(plus).max()
    assert np.abs(plus - expected).max() <= 1e-10 * np.abs(expected).max()


@pytest.mark.parametrize("quantity", ["stress", "strain"])
def test_the_history_operator_of_one_shape_passes_the_dot_test_and_equals_the_field(quantity, rng):
    from tactilab.forward import dottest

    law = Prony(1e5, [(2e5, 0.01)])
    skin = ViscoelasticLayeredHalfSpace([Layer(5e-4, Prony(3e5, [(6e5, 0.01)]), 0.5), Layer(1.5e-3, law, 0.5)])
    times, shape, h = np.array([0.0, 0.004, 0.02, 0.1]), (12,), 1e-4
    op = skin.operator(shape, h, times, depth=1e-3, components=("zz", "zx"), loads=("p", "qx"), quantity=quantity,
                       periodic=True)
    assert dottest(op, rng=rng) <= 1e-10  # raises above its rtol; the mismatch itself is returned
    load = SurfaceLoad(p=rng.standard_normal(shape), qx=rng.standard_normal(shape), spacing=h, periodic=True)
    model = np.tile(np.concatenate([load.p, load.qx]), len(times))  # a step, then held
    field = getattr(skin, quantity)(load, 1e-3, times, components=("zz", "zx")).values[:, 0]
    assert np.abs(op @ model - field.ravel()).max() <= 1e-10 * np.abs(field).max()
    with pytest.raises(ValueError, match=r"layers\[1\]: a time history .* one shape"):
        _two_layers().operator(shape, h, times)


def test_the_example_file_is_the_speed_benchmarks_fingertip():
    skin = skin_from_material(read_material("examples/dermis_on_pulp.toml"))
    assert skin.layers == (Layer(1e-3, Prony(0.6e6, [(0.6e6, 2e-3)]), 0.5), Layer(3e-3, PULP, 0.5))
    assert skin.base == "rigid"


def test_contact_solves_a_scenes_viscoelastic_layers_at_their_limits(tmp_path, capsys):
    """A scene's [material] with layer terms, as --material: the instantaneous contact (the scene's friction
    kept), the relaxed one (frictionless), and a time in between refused."""
    import json

    from tactilab.data_schemas import example_path

    text = example_path("fingertip_defect").read_text()
    scene = tmp_path / "scene.toml"
    scene.write_text(text.replace('young_modulus = "1MPa"\npoisson_ratio = 0.5',
                                  'layers = [{thickness = "2mm", young_modulus = "1MPa", terms = [["1MPa", "50ms"]]}]'),
                     encoding="utf-8")
    argv = ["contact", str(scene), "--grid", "32", "--quiet", "--json"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    now = json.loads(capsys.readouterr().out)
    assert now["held_state"] == "instantaneous" and now["condition"] == "sliding"
    assert main([*argv, "--time", "relaxed", "--out", str(tmp_path / "b")]) == 0
    relaxed = json.loads(capsys.readouterr().out)
    assert relaxed["condition"] == "frictionless" and any("solved frictionless" in d for d in relaxed["dropped"])
    assert now["contact_area_mm2"] < relaxed["contact_area_mm2"]
    assert main([*argv, "--time", "10ms", "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--time: the contact of viscoelastic layers is computed at its two exact" in err

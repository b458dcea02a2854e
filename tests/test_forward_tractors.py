"""Tractor pairs, arrays, drives and the sliding sinusoid (docs/theory.md 4a).

Oracles: Flamant's tangential line load (tactilab.forward.halfspace.kernels, an independent
implementation of docs/theory.md section 3) summed over tractors; docs/theory.md's literal Phi, Psi and
sliding-sinusoid formulas written out here; the periodic spectral solver with the
prescribed-displacement pressure P~ = E rho H~ / (2 (1 - nu^2)); fine quadrature of line loads
for footprints; the Cerruti point force integrated over long patches for the 3-D display.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.data_schemas.display import DisplayDescription
from tactilab.forward import tractor_display, tractors
from tactilab.forward.halfspace import spectral
from tactilab.forward.halfspace.kernels import line_load_stress
from tactilab.forward.halfspace.loads import SurfaceLoad

Z = 1.25e-3
E = 200e3


def phi_literal(x, d, z):
    a, b = x + d, x - d
    return (0.5 * (a / (z**2 + a**2) - b / (z**2 + b**2))
            - z**2 * (a / (z**2 + a**2) ** 2 - b / (z**2 + b**2) ** 2))


def psi_literal(x, d, z):
    a, b = x + d, x - d
    return (z * ((z**2 - b**2) / (z**2 + b**2) ** 2 - (z**2 - a**2) / (z**2 + a**2) ** 2)
            - (z / (z**2 + b**2) - z / (z**2 + a**2)))


def flamant_strain(x, z, positions, loads, nu=0.5):
    """Plane-strain strain (tensor shear) of tangential line loads, from H2's Flamant kernel."""
    stress = sum(line_load_stress(x - x0, z, fx=q, nu=nu) for x0, q in zip(positions, loads))
    return tractor_display.hooke_strain(stress, E, nu)


def test_pair_matches_flamant_and_literal_formula():
    x = np.linspace(-8e-3, 8e-3, 161)
    d, q = 0.9e-3, 2.5
    phi, psi = tractors.pair_phi_psi(x, d, Z)
    strain = flamant_strain(x, Z, [-d, d], [-q, q])
    scale = 3 * q / (np.pi * E)
    np.testing.assert_allclose(strain[:, 0], scale * phi, rtol=1e-10, atol=1e-14 * scale * np.abs(phi).max())
    np.testing.assert_allclose(strain[:, 2], -strain[:, 0], atol=1e-18)  # zero volumetric strain at nu = 1/2
    np.testing.assert_allclose(2 * strain[:, 4], scale * psi, rtol=1e-10, atol=1e-14 * scale * np.abs(psi).max())
    np.testing.assert_allclose(phi, phi_literal(x, d, Z), rtol=1e-10, atol=1e-12 * np.abs(phi).max())
    np.testing.assert_allclose(psi, psi_literal(x, d, Z), rtol=1e-10, atol=1e-12 * np.abs(psi).max())


def test_pair_collapses_to_dipole_without_cancellation():
    x = np.linspace(-5e-3, 5e-3, 101)
    dip_phi, dip_psi = tractors.dipole_phi_psi(x, Z)
    for ratio in (1e-2, 1e-4, 1e-8, 1e-12):
        d = ratio * Z
        phi, psi = tractors.pair_phi_psi(x, d, Z)
        assert np.isfinite(phi).all() and np.isfinite(psi).all()
        # Phi(d) = d phi_1 + O(d^3): relative error O((d/Z)^2), never the eps Z/d of the difference form
        tol = 10 * ratio**2 + 1e-12
        np.testing.assert_allclose(phi / d, dip_phi, rtol=0, atol=tol * np.abs(dip_phi).max())
        np.testing.assert_allclose(psi / d, dip_psi, rtol=0, atol=tol * np.abs(dip_psi).max())
    # the dipole is the derivative of a single tractor's pattern: check by finite differences of Flamant
    h = 1e-7
    single = flamant_strain(x, Z, [0.0], [1.0])
    ahead = flamant_strain(x + h, Z, [0.0], [1.0])
    behind = flamant_strain(x - h, Z, [0.0], [1.0])
    derivative = (ahead - behind) / (2 * h)  # d/dx of a +x tractor at 0
    scale = 3 / (np.pi * E)
    # pair q[-delta(x+d) + delta(x-d)] ~ -2 d q d/dx(single): Phi ~ d phi_1
    np.testing.assert_allclose(-2 * derivative[:, 0], scale * dip_phi, atol=1e-6 * scale * np.abs(dip_phi).max())
    assert np.abs(single).max() > 0


@pytest.mark.parametrize("pairs", [1, 2, 4, 5])
def test_array_is_superposition_of_signed_tractors(pairs):
    x = np.linspace(-12e-3, 12e-3, 241)
    d = 0.8e-3
    s_phi, s_psi = tractors.array_phi_psi(x, d, Z, pairs)
    tx, sign = tractors.array_tractors(d, pairs)
    assert tx.size == 2 * pairs
    np.testing.assert_allclose(np.abs(tx / d) % 2, 1.0)  # odd multiples of d
    np.testing.assert_allclose(sign, np.sin(np.pi * tx / (2 * d)))
    strain = flamant_strain(x, Z, tx, sign)
    scale = 3 / (np.pi * E)
    np.testing.assert_allclose(strain[:, 0], scale * s_phi, atol=1e-10 * scale * np.abs(s_phi).max())
    np.testing.assert_allclose(2 * strain[:, 4], scale * s_psi, atol=1e-10 * scale * np.abs(s_psi).max())
    if pairs % 2 == 1:  # docs/theory.md's sum over n of Phi(x - 4 n d)
        n = np.arange(pairs) - (pairs - 1) // 2
        np.testing.assert_allclose(s_phi, sum(phi_literal(x - 4 * k * d, d, Z) for k in n),
                                   atol=1e-10 * np.abs(s_phi).max())
        np.testing.assert_allclose(s_psi, sum(psi_literal(x - 4 * k * d, d, Z) for k in n),
                                   atol=1e-10 * np.abs(s_psi).max())


@pytest.mark.parametrize("nu", [0.5, 0.3])
def test_footprint_strip_matches_quadrature_of_line_loads(nu):
    x = np.linspace(-4e-3, 4e-3, 81)
    width = 0.6e-3
    strip = tractors.tractor_row_strain(x, Z, [0.3e-3], [1.7], E, nu=nu, footprint=width)
    nodes, weights = np.polynomial.legendre.leggauss(40)
    xs = 0.3e-3 + 0.5 * width * nodes
    reference = flamant_strain(x, Z, xs, 1.7 * weights / 2, nu=nu)
    np.testing.assert_allclose(strip, reference, atol=1e-11 * np.abs(reference).max())
    # a vanishing footprint tends to the line load
    thin = tractors.tractor_row_strain(x, Z, [0.3e-3], [1.7], E, nu=nu, footprint=1e-9)
    line = tractors.tractor_row_strain(x, Z, [0.3e-3], [1.7], E, nu=nu)
    np.testing.assert_allclose(thin, line, atol=1e-9 * np.abs(line).max())


def test_sliding_sinusoid_closed_form_and_spectral_solution():
    amplitude, pitch = 50e-6, 4e-3
    n = 256
    x = (np.arange(n) - n // 2) * (2 * pitch / n)  # two periods
    strain = tractors.sliding_sinusoid_strain(x, Z, amplitude, pitch)
    k = 2 * np.pi / pitch
    big_k = k * k * amplitude * Z * np.exp(-k * Z)
    phase = k * x
    # docs/theory.md 4a (engineering shear): eps = K [sin, 0, -sin, 0, 2 cos, 0]
    engineering = tractors.to_engineering_shear(strain)
    expected = big_k * np.stack([np.sin(phase), 0 * phase, -np.sin(phase), 0 * phase, 2 * np.cos(phase),
                                 0 * phase], axis=-1)
    np.testing.assert_allclose(engineering, expected, atol=1e-12 * big_k)
    np.testing.assert_allclose(strain[:, 4], big_k * np.cos(phase), atol=1e-12 * big_k)  # tensor shear
    # second method: spectral pressure for the prescribed deflection, stress at depth, Hooke
    for young in (50e3, 2e6):  # independent of E
        load = spectral.pressure_from_deflection(amplitude * np.sin(phase), 2 * pitch / n, young, 0.5)
        stress = spectral.periodic_stress(load, [Z], 0.5, np.eye(6))[0].T  # (nx, 6)
        spectral_strain = tractor_display.hooke_strain(stress, young, 0.5)
        np.testing.assert_allclose(spectral_strain, strain, atol=1e-9 * big_k)
    # travelling: the pattern at time t is the pattern at x + V t
    later = tractors.sliding_sinusoid_strain(x, Z, amplitude, pitch, speed=0.05, time=[0.0, 0.01])
    shifted = tractors.sliding_sinusoid_strain(x + 0.05 * 0.01, Z, amplitude, pitch)
    np.testing.assert_allclose(later[1], shifted, atol=1e-12 * big_k)


def test_sliding_sinusoid_general_nu_matches_spectral():
    amplitude, pitch, nu = 20e-6, 3e-3, 0.3
    n = 128
    x = (np.arange(n) - n // 2) * (pitch / n)
    strain = tractors.sliding_sinusoid_strain(x, 2e-3, amplitude, pitch, nu=nu)
    load = spectral.pressure_from_deflection(amplitude * np.sin(2 * np.pi * x / pitch), pitch / n, E, nu)
    stress = spectral.periodic_stress(load, [2e-3], nu, np.eye(6))[0].T
    np.testing.assert_allclose(strain, tractor_display.hooke_strain(stress, E, nu), atol=1e-9 * np.abs(strain).max())


def test_travelling_wave_drive_samples_the_virtual_surface():
    tx = np.array([-1.5e-3, -0.5e-3, 0.5e-3, 1.5e-3])
    times = np.linspace(0, 0.02, 5)

    def height(pos):
        return 30e-6 * np.sin(2 * np.pi * pos / 4e-3)

    q = tractor_display.travelling_wave_drive(tx, height, 0.04, times, gain=1e5, lead=1e-3)
    assert q.shape == (5, 4)
    np.testing.assert_allclose(q, 1e5 * height(tx[None, :] + 0.04 * times[:, None] + 1e-3))
    # within the limit: passes; over it: ValueError naming the drive and the limit
    peak = np.abs(q).max() / 0.6e-3
    tractor_display.travelling_wave_drive(tx, height, 0.04, times, 1e5, 1e-3, traction_limit=1.01 * peak,
                                          footprint=0.6e-3)
    with pytest.raises(ValueError, match="exceeds the display's traction_limit"):
        tractor_display.travelling_wave_drive(tx, height, 0.04, times, 1e5, 1e-3, traction_limit=0.5 * peak,
                                              footprint=0.6e-3)


def test_display_row_strain_uses_display_geometry():
    display = DisplayDescription.braille_row(n_tractors=6)
    x = np.linspace(-5e-3, 5e-3, 41)
    loads = np.array([[0.0, 1.0, -1.0, 0.5, 0.0, 2.0]])
    got = tractor_display.display_row_strain(display, x, Z, loads, E)
    want = tractors.tractor_row_strain(x, Z, display.tractor_x_m, loads, E, footprint=display.tractor_width_m)
    assert got.shape == (1, 41, 6)
    np.testing.assert_allclose(got, want)


def test_long_patches_in_3d_tend_to_the_plane_strip():
    width, length = 0.6e-3, 240e-3  # length >> depth: the centre line is in plane strain
    x = np.linspace(-3e-3, 3e-3, 7)
    points = np.column_stack([x, np.zeros_like(x), np.full_like(x, Z)])
    centres = np.array([[-0.6e-3, 0.0], [0.6e-3, 0.0]])
    tau = np.array([-4e3, 4e3])
    strain3d = tractor_display.patch_strain_3d(points, centres, tau, width, length, E, panels_per_depth=1.0)
    plane = tractors.tractor_row_strain(x, Z, centres[:, 0], tau * width, E, footprint=width)
    # end effects of a finite strip decay like (Z / L)^2
    np.testing.assert_allclose(strain3d[:, [0, 2, 4]], plane[:, [0, 2, 4]], atol=5e-4 * np.abs(plane).max())
    np.testing.assert_allclose(strain3d[:, 1], 0.0, atol=5e-4 * np.abs(plane).max())


def test_small_patch_is_a_point_force_and_quadrature_converges():
    from tactilab.forward.halfspace.kernels import point_load_stress

    points = np.array([[1e-3, 0.5e-3, 2e-3], [0.0, 0.0, 1e-3]])
    size = 1e-6  # finite-size correction (size / R)^2 ~ 2e-7
    strain = tractor_display.patch_strain_3d(points[:1], [[0.0, 0.0]], [5e3], size, size, E)
    point = tractor_display.hooke_strain(point_load_stress(*points[0], fx=5e3 * size * size), E, 0.5)
    np.testing.assert_allclose(strain[0], point, atol=1e-6 * np.abs(point).max())
    coarse = tractor_display.patch_strain_3d(points, [[0.2e-3, 0.1e-3]], [5e3], 1e-3, 1.4e-3, E)
    fine = tractor_display.patch_strain_3d(points, [[0.2e-3, 0.1e-3]], [5e3], 1e-3, 1.4e-3, E, panels_per_depth=8)
    np.testing.assert_allclose(coarse, fine, atol=1e-5 * np.abs(fine).max())


def test_display_patch_strain_3d_shapes():
    display = DisplayDescription.stress2()
    tau = np.zeros((2, *display.shape))
    tau[1, 2, 3] = 1e3
    points = np.array([[0.0, 0.0, 1e-3], [1e-3, 1e-3, 2e-3]])
    out = tractor_display.display_patch_strain_3d(display, points, tau, E)
    assert out.shape == (2, 2, 6)
    assert np.all(out[0] == 0) and np.abs(out[1]).max() > 0
    with pytest.raises(ValueError, match="trailing axes must be the display shape"):
        tractor_display.display_patch_strain_3d(display, points, np.zeros((2, 3)), E)


def test_engineering_shear_conversion():
    s = np.arange(12.0).reshape(2, 6)
    g = tractors.to_engineering_shear(s)
    np.testing.assert_array_equal(g[:, :3], s[:, :3])
    np.testing.assert_array_equal(g[:, 3:], 2 * s[:, 3:])
    with pytest.raises(ValueError, match="trailing axis of length 6"):
        tractors.to_engineering_shear(np.zeros((2, 3)))


@pytest.mark.parametrize("call, match", [
    (lambda: tractors.pair_phi_psi(0.0, 0.0, Z), "half_spacing: must be finite and > 0"),
    (lambda: tractors.pair_phi_psi(0.0, -1e-3, Z), "tractor spacing must be > 0"),
    (lambda: tractors.pair_phi_psi(0.0, "wide", Z), "half_spacing: must be finite and > 0 m, got 'wide'"),
    (lambda: tractors.pair_phi_psi(0.0, 1e-3, 0.0), "depth: every depth must be finite and > 0 m"),
    (lambda: tractors.pair_phi_psi(np.nan, 1e-3, Z), "x: must be finite"),
    (lambda: tractors.dipole_phi_psi(0.0, -Z), "depth"),
    (lambda: tractors.array_phi_psi(0.0, 1e-3, Z, 0), "pairs: the number of tractor pairs"),
    (lambda: tractors.array_phi_psi(0.0, 1e-3, Z, 2.5), "integer >= 1"),
    (lambda: tractors.array_tractors(1e-3, True), "pairs"),
    (lambda: tractors.tractor_stress_kernel(0.0, Z, -1e-4), "footprint: must be finite and >= 0"),
    (lambda: tractors.tractor_stress_kernel(0.0, Z, "thin"), "footprint: expected a number"),
    (lambda: tractors.tractor_row_strain([0.0], Z, [0.0, 1e-3], [1.0], E), "one load per tractor"),
    (lambda: tractors.tractor_row_strain([0.0], Z, [0.0], [1.0], -E), "young_modulus"),
    (lambda: tractors.tractor_row_strain([0.0], Z, [0.0], [1.0], E, nu=0.6), "nu: Poisson's ratio"),
    (lambda: tractors.sliding_sinusoid_strain([0.0], Z, 1e-5, 0.0), "pitch"),
    (lambda: tractors.sliding_sinusoid_strain([0.0], Z, np.inf, 1e-3), "amplitude: must be finite"),
])
def test_tractor_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def _flat(pos):
    return np.zeros_like(pos)


@pytest.mark.parametrize("kwargs, match", [
    (dict(height="bump"), "height: expected a callable"),
    (dict(height=lambda pos: np.zeros(3)), "one height per position"),
    (dict(height=lambda pos: np.full_like(pos, np.nan)), "returned NaN or inf"),
    (dict(traction_limit=1e3), "footprint: needed with traction_limit"),
    (dict(traction_limit=-1.0, footprint=1e-3), "traction_limit: must be finite and > 0"),
    (dict(traction_limit=1e3, footprint=0.0), "footprint: must be finite and > 0"),
])
def test_drive_errors(kwargs, match):
    args = dict(tractor_x=[0.0, 1e-3], height=_flat, speed=0.01, times=[0.0, 0.1], gain=1.0)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        tractor_display.travelling_wave_drive(**args)


@pytest.mark.parametrize("args, match", [
    (dict(points=np.zeros((2, 2))), "points: expected shape \\(n_points, 3\\)"),
    (dict(points=np.array([[0.0, 0.0, -1e-3]])), "depth z must be > 0"),
    (dict(tractor_xy=np.zeros(3)), "tractor_xy: expected shape"),
    (dict(tractions=np.zeros(3)), "tractions: trailing axis"),
    (dict(width=0.0), "width: must be finite and > 0"),
])
def test_patch_errors(args, match):
    kw = dict(points=np.array([[0.0, 0.0, 1e-3]]), tractor_xy=np.zeros((2, 2)), tractions=np.zeros(2),
              width=1e-3, length=1e-3, young_modulus=E)
    kw.update(args)
    with pytest.raises(ValueError, match=match):
        tractor_display.patch_strain_3d(**kw)


@pytest.mark.parametrize("method", ["closed_form", "dcfft"])
def test_footprint_row_matches_the_halfspace_solver(method):
    """Second method: the lead's HalfSpace on a 1-D grid of strip tractions (cell edges on the strip edges)."""
    from tactilab.forward.halfspace.facade import HalfSpace

    width, cells = 0.6e-3, 24
    h = width / cells
    nx = 1024
    grid = (np.arange(nx) - nx // 2) * h
    centres = np.array([-36.5 * h, 36.5 * h])
    tau = np.array([-4e3, 4e3])
    qx = np.zeros(nx)
    for x0, t in zip(centres, tau):
        qx[np.abs(grid - x0) < width / 2] = t
    assert np.count_nonzero(qx) == 2 * cells
    points = np.linspace(-4e-3, 4e-3, 17)
    result = HalfSpace(E, 0.5).strain(SurfaceLoad(qx=qx, spacing=h), depth=Z, points=points,
                                      components=("xx", "zz", "zx"), method=method)
    got = result.data["strain"].values[0].T
    want = tractors.tractor_row_strain(points, Z, centres, tau * width, E, footprint=width)[:, [0, 2, 4]]
    # midpoint sampling of the strip: error O((h / Z)^2)
    np.testing.assert_allclose(got, want, atol=5e-4 * np.abs(want).max())


def test_patch_in_3d_matches_the_halfspace_dcfft_solver():
    """Second method for the 3-D patch integral: the lead's HalfSpace (DC-FFT) on a 2-D grid."""
    from tactilab.forward.halfspace.facade import HalfSpace

    depth, h, n = 1e-3, 0.05e-3, 128
    width, length = 0.6e-3, 1.0e-3  # 12 x 20 cells; patch edges on cell boundaries
    grid = (np.arange(n) - n // 2) * h
    gx, gy = np.meshgrid(grid, grid)
    centre = (0.5 * h, 0.5 * h)
    qx = ((np.abs(gx - centre[0]) < width / 2) & (np.abs(gy - centre[1]) < length / 2)) * 3e3
    points = np.array([[1e-3, 0.3e-3], [0.0, 0.0], [-0.7e-3, 0.8e-3]])
    result = HalfSpace(E, 0.5).strain(SurfaceLoad(qx=qx.astype(float), spacing=h), depth=depth, points=points,
                                      method="dcfft")
    got = result.data["strain"].values[0].T
    want = tractor_display.patch_strain_3d(np.column_stack([points, np.full(3, depth)]), [centre], [3e3],
                                           width, length, E)
    np.testing.assert_allclose(got, want, atol=2e-3 * np.abs(want).max())  # grid sampling O((h/Z)^2)


def test_render_virtual_surface_composes_drive_and_strain():
    display = DisplayDescription.braille_row(n_tractors=8, max_traction_pa=20e3)
    times = np.linspace(0, 0.05, 6)
    x = np.linspace(-4e-3, 4e-3, 21)

    def height(pos):
        return 40e-6 * np.sin(2 * np.pi * pos / 2.4e-3)

    q, strain = tractor_display.render_virtual_surface(display, height, 0.02, times, x, Z, 2e5, E)
    want_q = tractor_display.travelling_wave_drive(display.tractor_x_m, height, 0.02, times, 2e5)
    np.testing.assert_allclose(q, want_q)
    np.testing.assert_allclose(strain, tractors.tractor_row_strain(x, Z, display.tractor_x_m, want_q, E,
                                                                   footprint=display.tractor_width_m))
    with pytest.raises(ValueError, match="exceeds the display's traction_limit 2e\\+04 Pa"):
        tractor_display.render_virtual_surface(display, height, 0.02, times, x, Z, 2e7, E)

"""What the mechanics says about tactile metameres, each checked against an independent computation.

Derivations (plane strain, nu = 1/2, one Fourier mode k > 0, E Young's modulus, depth Z,
docs/theory.md section 3): for p = P cos kx and q_x = Q cos kx the tensor strains are

    eps_xx = 3/2 kZ e^{-kZ} P cos kx / E - 3/2 (1 - kZ) e^{-kZ} Q sin kx / E,
    eps_zx = -3/2 kZ e^{-kZ} P sin kx / E - 3/2 (1 - kZ) e^{-kZ} Q cos kx / E,  eps_zz = -eps_xx,

so eps_zx = -Hilbert(eps_xx) for any load (one readout per mode at one depth), and the lateral
traction Q~ = -i sgn(k) kZ / (1 - kZ) P~ reads exactly like the pressure P~ at depth Z. With
the indentation's pressure P~ = 2/3 E |k| H~, the metamer of H = A sin(kx + phi) is
Q(x) = -2/3 E k A kZ / (1 - kZ) cos(kx + phi). At another depth Z2 it misses the indentation's
readouts by the fraction |Z2 - Z| / (Z2 |1 - kZ|), and at kZ = 1 (pitch 2 pi Z) a tangential
traction leaves no strain at all (a blind pitch): the metamer's sign flips across it.
"""

import numpy as np
import pytest

from tactilab.forward import HalfSpace, ReceptorHypothesis, SurfaceLoad, pair_phi_psi
from tactilab.inversion import (
    GridLoadFamily,
    IndentationFamily,
    SinusoidFamily,
    TractorFamily,
    metamer_pair,
    resolvable_subspace,
)

E = 1.54e6
Z = 1.25e-3


def _hilbert(f):
    """Periodic Hilbert transform (H[cos] = sin) by FFT, independent of the solver."""
    k = np.fft.fftfreq(f.size)
    return np.real(np.fft.ifft(-1j * np.sign(k) * np.fft.fft(f)))


def test_xx_and_zx_form_a_hilbert_pair_at_one_depth(rng):
    n, dx = 256, 0.1e-3
    p, q = rng.normal(size=(2, n)) * 1e3
    load = SurfaceLoad(p=p - p.mean(), qx=q - q.mean(), spacing=dx, periodic=True)
    strain = HalfSpace(E, 0.5).strain(load, Z, components=("xx", "zx")).data["strain"].values[0]
    np.testing.assert_allclose(strain[1], -_hilbert(strain[0]), atol=1e-12 * np.abs(strain).max())


def test_second_component_adds_one_rank_but_second_depth_doubles_it():
    n, dx = 32, 0.5e-3
    fam = GridLoadFamily((n,), dx, ("p", "qx"), young_modulus=E)

    def sub(text):
        return resolvable_subspace(fam, text + ";noise=1e-6", 1e3, rtol=1e-12)

    xx, xxzx, two = sub("xx@1mm"), sub("xx,zx@1mm"), sub("xx@1mm,1.5mm")
    rank = {k: fam.n_params - s.null_dimension for k, s in (("xx", xx), ("xxzx", xxzx), ("two", two))}
    # xx at k = 0 sees nothing. zx adds two real dimensions out of 2n: the mean shear traction
    # (k = 0) and the Nyquist mode, where odd (Hilbert) terms vanish on a grid.
    assert rank["xx"] == n - 1
    assert rank["xxzx"] - rank["xx"] == 2
    assert rank["two"] - rank["xx"] == n - 2
    # resolvable (s > 1) at a signal-to-noise of ~1000: zx adds those two, a second depth many
    assert xxzx.dimension - xx.dimension <= 2
    assert two.dimension - xx.dimension >= 5 * (xxzx.dimension - xx.dimension)


def _metamer_q(h_height, dx, depth):
    """Closed-form lateral-traction metamer (Pa) of a periodic indentation (m), nu = 1/2."""
    k = 2 * np.pi * np.fft.fftfreq(h_height.size, dx)
    kz = np.abs(k) * depth
    factor = np.where(k == 0, 0.0, -1j * np.sign(k) * kz / (1 - kz) * (2.0 / 3.0) * E * np.abs(k))
    return np.real(np.fft.ifft(factor * np.fft.fft(h_height)))


def test_every_periodic_indentation_has_an_exact_lateral_traction_metamer(rng):
    n, dx = 128, 0.1e-3  # period 12.8 mm: no mode sits exactly at kZ = 1
    k = 2 * np.pi * np.fft.rfftfreq(n, dx)
    spec = (rng.normal(size=k.size) + 1j * rng.normal(size=k.size)) * (k * Z < 4) * (k > 0)
    height = np.fft.irfft(spec, n) * 1e-4 / np.abs(np.fft.irfft(spec, n)).max()
    q = _metamer_q(height, dx, Z)
    # independent: the solver's strain under the pressure of the indentation and under q
    hs = HalfSpace(E, 0.5)
    pressure = hs.pressure_from_deflection(height, dx)
    for depth, agree in ((Z, True), (2 * Z, False)):
        a = hs.strain(pressure, depth).data["strain"].values[0]
        b = hs.strain(SurfaceLoad(qx=q, spacing=dx, periodic=True), depth).data["strain"].values[0]
        err = np.abs(a - b).max() / np.abs(a).max()
        assert (err < 1e-10) if agree else (err > 0.1)
    # the family solve finds the same traction (minimum norm, per mode)
    target = IndentationFamily((n,), dx, E).stimulus(height)
    pair = metamer_pair(target, GridLoadFamily((n,), dx, ("qx",), young_modulus=E), "xx,zz,zx@1.25mm", rcond=1e-6)
    assert pair.relative_residual < 1e-10
    np.testing.assert_allclose(pair.params, q, atol=1e-8 * np.abs(q).max())


@pytest.mark.parametrize("pitch_mm", [3.2, 4.0, 12.8])
def test_sinusoid_metamer_closed_form_and_its_break_at_a_second_depth(pitch_mm):
    n, dx, amp = 256, 0.05e-3, 0.5e-3
    pitch = n * dx / round(n * dx / (pitch_mm * 1e-3))
    k = 2 * np.pi / pitch
    fam = GridLoadFamily((n,), dx, ("qx",), young_modulus=E)
    target = SinusoidFamily(pitch, phase=0.3).stimulus([amp])
    pair = metamer_pair(target, fam, "xx,zx@1.25mm;noise=1e-3", rcond=1e-6)
    x = fam.default_receptors()
    expected = -(2 / 3) * E * k * amp * (k * Z / (1 - k * Z)) * np.cos(k * x + 0.3)
    assert pair.relative_residual < 1e-10
    np.testing.assert_allclose(pair.params, expected, atol=1e-8 * np.abs(expected).max())
    for z2 in (0.75e-3, 2e-3, 3e-3):
        broken = pair.evaluate(ReceptorHypothesis(("xx", "zx"), (z2,), 1e-3))
        assert broken.relative_residual == pytest.approx(abs(z2 - Z) / (z2 * abs(1 - k * Z)), rel=1e-9)


def test_blind_pitch_and_the_metamer_flips_across_it():
    n = 64
    dx = 2 * np.pi * Z * 4 / n  # mode 4 has k Z = 1 exactly
    x = (np.arange(n) - n // 2) * dx
    for nu in (0.5, 0.3):
        s = HalfSpace(E, nu).strain(SurfaceLoad(qx=1e3 * np.cos(x / Z + 0.7), spacing=dx, periodic=True),
                                    [Z, 1.5 * Z]).data["strain"].values  # (depth, comp, x)
        ref = np.abs(s[1]).max()
        assert np.abs(s[0, 0] - s[0, 2]).max() < 1e-12 * ref and np.abs(s[0, 4]).max() < 1e-12 * ref
        if nu == 0.5:
            assert np.abs(s[0]).max() < 1e-12 * ref  # no strain at all, deviatoric or volumetric
    fam = GridLoadFamily((n,), dx, ("qx",), young_modulus=E)
    sub = resolvable_subspace(fam, "xx,zz,zx@1.25mm;noise=1e-6", 1e3, rtol=1e-10)
    null = sub.basis("null")
    blind = np.stack([np.cos(x / Z), np.sin(x / Z)], axis=1) / np.sqrt(n / 2)
    np.testing.assert_allclose(np.linalg.norm(null.T @ blind, axis=0), 1.0, rtol=1e-9)
    signs = []
    for pitch in (n * dx / 3, n * dx / 5):  # kZ = 0.75 and 1.25, either side of the blind pitch
        pair = metamer_pair(SinusoidFamily(pitch).stimulus([1e-5]), fam, "xx,zx@1.25mm", rcond=1e-8)
        assert pair.relative_residual < 1e-9
        signs.append(np.sign(pair.params @ -np.cos(2 * np.pi * x / pitch)))
    assert signs[0] == 1 and signs[1] == -1  # kZ / (1 - kZ) changes sign at kZ = 1


def test_volumetric_resolves_nothing_and_uniform_pressure_is_null(rng):
    n, dx = 64, 0.2e-3
    load = SurfaceLoad(p=rng.normal(size=n) * 1e3, qx=rng.normal(size=n) * 1e3, spacing=dx, periodic=True)
    s = HalfSpace(E, 0.5).strain(load, [1e-3, 2e-3]).data["strain"].values
    assert np.abs(s[:, 0] + s[:, 1] + s[:, 2]).max() < 1e-12 * np.abs(s).max()
    fam = GridLoadFamily((n,), dx, ("p", "qx"), young_modulus=E)
    vol = resolvable_subspace(fam, "volumetric@1mm,2mm;noise=1e-9", 1e3)
    dev = resolvable_subspace(fam, "xx@1mm,2mm;noise=1e-9", 1e3)
    assert vol.dimension == 0 and vol.singular_values[0] < 1e-12 * dev.singular_values[0]
    assert dev.dimension > 10
    soft = GridLoadFamily((n,), dx, ("p", "qx"), young_modulus=E, nu=0.3)
    assert resolvable_subspace(soft, "volumetric@1mm,2mm;noise=1e-9", 1e3).dimension > 10
    # uniform pressure: hydrostatic at depth, no strain in 1-D and in 3-D (solver, independently)
    for shape in ((n,), (8, 8)):
        flat = SurfaceLoad(p=np.full(shape, 5e3), spacing=dx, periodic=True)
        assert np.abs(HalfSpace(E, 0.5).strain(flat, 1e-3).data["strain"].values).max() < 1e-15
    full = resolvable_subspace(fam, "xx,yy,zz,yz,zx,xy@1mm;noise=1e-9", 1e3, rtol=1e-10)
    uniform_p = np.concatenate([np.ones(n), np.zeros(n)]) / np.sqrt(n)
    assert np.linalg.norm(full.basis("null").T @ uniform_p) == pytest.approx(1.0, rel=1e-10)
    assert np.linalg.norm(full.basis("resolvable").T @ uniform_p) < 1e-10


def test_tractor_family_matches_the_pair_closed_form():
    x = np.linspace(-6e-3, 6e-3, 121)
    d, q = 1e-3, 250.0
    fam = TractorFamily([-d, d], E)
    r = fam.stimulus([-q, q]).readout("xx,zx@1.25mm", x).reshape(2, -1)
    phi, psi = pair_phi_psi(x, d, Z)
    np.testing.assert_allclose(r[0], 3 * q * phi / (np.pi * E), rtol=1e-10, atol=1e-18)
    np.testing.assert_allclose(r[1], 3 * q * psi / (2 * np.pi * E), rtol=1e-10, atol=1e-18)


def _paper_target(x, phase, amp=0.5e-3, pitch=4e-3):
    """docs/theory.md 4a closed form, tensor shear: eps_xx = K sin(kx + phase), eps_zx = K cos(kx + phase)."""
    k = 2 * np.pi / pitch
    big_k = k * k * amp * Z * np.exp(-k * Z)
    return np.concatenate([big_k * np.sin(k * x + phase), big_k * np.cos(k * x + phase)])


def test_the_papers_case_favourable_unfavourable_and_scan():
    x = np.linspace(-5e-3, 5e-3, 201)
    tractor_x = np.array([-9, -7, -5, -3, -1, 1, 3, 5, 7, 9]) * 1e-3
    fam = TractorFamily(tractor_x, E)
    phases = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    good = metamer_pair(SinusoidFamily(4e-3, np.pi / 2).stimulus([0.5e-3]), fam, "xx,zx@1.25mm;noise=1e-3", x,
                        scan_phases=phases)
    bad = metamer_pair(SinusoidFamily(4e-3, 0.0).stimulus([0.5e-3]), fam, "xx,zx@1.25mm;noise=1e-3", x)
    # independent: the paper's target and its 5-pair closed form, solved by plain least squares
    target = _paper_target(x, np.pi / 2)
    np.testing.assert_allclose(good.target_readout, target, rtol=1e-12, atol=1e-15)
    cols = []
    for d in (1e-3, 3e-3, 5e-3, 7e-3, 9e-3):
        phi, psi = pair_phi_psi(x, d, Z)
        cols.append(np.concatenate([3 * phi / (np.pi * E), 3 * psi / (2 * np.pi * E)]))
    a = np.array(cols).T
    q, *_ = np.linalg.lstsq(a, target, rcond=None)
    np.testing.assert_allclose(good.params[5:], q, rtol=1e-8)
    np.testing.assert_allclose(good.params[:5], -q[::-1], rtol=1e-8)  # antisymmetric drive
    assert good.relative_residual == pytest.approx(np.linalg.norm(a @ q - target) / np.linalg.norm(target), rel=1e-8)
    # favourable phase (tractors at the extrema of the ideal traction) beats the unfavourable one
    assert good.relative_residual < 0.15 < 0.8 < bad.relative_residual
    # the scan: rms over independent frames equals the rms of frame-by-frame pairs
    frames = [metamer_pair(SinusoidFamily(4e-3, ph).stimulus([0.5e-3]), fam, "xx,zx@1.25mm", x).relative_residual
              for ph in phases]
    assert good.scan_rms == pytest.approx(np.sqrt(np.mean(np.square(frames))), rel=1e-12)
    np.testing.assert_allclose(good.scan_residuals, frames, rtol=1e-12)
    assert good.relative_residual <= good.scan_rms <= bad.relative_residual
    # loads (N/m) of the order of the paper's matching amplitude Q (docs/theory.md 4a)
    k2p = pair_phi_psi(np.array([1e-3]), 1e-3, Z)[1].sum() + sum(
        pair_phi_psi(np.array([1e-3 - c]), 1e-3, Z)[1].sum() for c in (-8e-3, -4e-3, 4e-3, 8e-3))
    q_paper = 8 * np.sqrt(2) * np.pi ** 3 * 0.5e-3 * Z * E * np.exp(-2 * np.pi * Z / 4e-3) / (3 * k2p * 16e-6)
    assert 0.5 < np.abs(good.params[3:7]).max() / q_paper < 1.0

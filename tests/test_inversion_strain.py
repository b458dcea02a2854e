"""Strain recordings: the defect model in strain, the strain height operator (closed forms, dot test),
and a strain recording of a simulated scene inverts to the defect position of its stress twin."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tactilab.data_schemas import read_recording
from tactilab.data_schemas.files import load_example
from tactilab.data_schemas.scene import Scan
from tactilab.data_schemas.sensors import SensorArray
from tactilab.forward import dottest, simulate_scene
from tactilab.forward.halfspace import compliance_matrix
from tactilab.inversion import (
    DefectScanModel, halfspace_fourier_operator, halfspace_strain_operator, invert_defect_position,
    rigid_surface_height_strain_operator,
)
from tactilab.forward import dottest

VOIGT = ("xx", "yy", "zz", "yz", "zx", "xy")
PARAMS = dict(x0=0.4e-3, y0=-0.2e-3, friction=0.5, depth=2e-3, young_modulus=7e5, normal_force=0.8)


def test_strain_design_is_compliance_times_stress_design():
    u = np.linspace(-4e-3, 4e-3, 9)
    sensors = np.array([[0.0, 0.0], [1e-3, 0.5e-3]])
    stress = DefectScanModel(u, sensors, VOIGT, poisson_ratio=0.3)
    strain = DefectScanModel(u, sensors, VOIGT, poisson_ratio=0.3, quantity="strain")
    sig = stress.design(PARAMS)[0].reshape(stress.data_shape)
    eps = strain.design(PARAMS)[0].reshape(strain.data_shape)
    expected = sig @ compliance_matrix(PARAMS["young_modulus"], 0.3).T
    np.testing.assert_allclose(eps, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    # vectorised over walkers with different E (compliance and Hertz radius): each row as alone
    two = strain.design(dict(PARAMS, young_modulus=np.array([7e5, 1.4e6])))
    np.testing.assert_allclose(two[1], strain.design(dict(PARAMS, young_modulus=1.4e6))[0], rtol=1e-13)
    np.testing.assert_allclose(two[0], eps.ravel(), rtol=1e-13)
    with pytest.raises(ValueError, match="quantity: must be 'stress' .* or 'strain'"):
        DefectScanModel(u, sensors, quantity="displacement")


def test_strain_height_operator_closed_forms():
    """H0 cos kx in full contact: eps_zz = -k H0 e^{-kZ} (1 - 2 nu + kZ) / (2 (1 - nu)) cos kx and
    eps_xx = -k H0 e^{-kZ} (1 - 2 nu - kZ) / (2 (1 - nu)) cos kx (plane strain; docs/theory.md
    sections 2 and 3)."""
    n, dx, depth, h0 = 128, 50e-6, 0.4e-3, 2e-6
    x = np.arange(n) * dx
    for nu in (0.0, 0.3, 0.5):
        for m in (1, 5, 20):
            k = 2 * np.pi * m / (n * dx)
            kz = k * depth
            height = h0 * np.cos(k * x)
            for comp, sign in (("zz", 1.0), ("xx", -1.0)):
                op = rigid_surface_height_strain_operator(n, dx, depth, 1e6, nu, comp)
                expected = -k * h0 * np.exp(-kz) * (1 - 2 * nu + sign * kz) / (2 * (1 - nu)) * np.cos(k * x)
                np.testing.assert_allclose(op.matvec(height), expected, rtol=1e-10, atol=1e-12 * h0 * k)
            # plane strain: no strain along y
            eps_yy = rigid_surface_height_strain_operator(n, dx, depth, 1e6, nu, "yy").matvec(height)
            assert np.abs(eps_yy).max() < 1e-14 * k * h0


def test_strain_height_operator_matches_compliance_of_stresses_and_passes_dot_test(rng):
    n, dx, depth, nu = 64, 40e-6, 0.3e-3, 0.45
    op_zz = rigid_surface_height_strain_operator(n, dx, depth, 1e6, nu, "zz")
    # independent of E: pressure scales with E, strain with 1/E
    np.testing.assert_allclose(rigid_surface_height_strain_operator(n, dx, depth, 3e5, nu, "zz").multiplier,
                               op_zz.multiplier, rtol=1e-12, atol=1e-18)
    # second route: the compliance row applied to the six stress multipliers of the pressure
    s = compliance_matrix(1e6, nu)
    h = rng.standard_normal(n)
    pressure_gain = 1e6 * np.abs(2 * np.pi * np.fft.fftfreq(n, dx)) / (2 * (1 - nu**2))
    stress = {c: halfspace_fourier_operator((n,), dx, depth, nu, "p", c).multiplier for c in VOIGT}
    expected = sum(s[2, j] * stress[c] for j, c in enumerate(VOIGT)) * pressure_gain
    np.testing.assert_allclose(op_zz.multiplier, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    for comp in VOIGT:
        op = rigid_surface_height_strain_operator(n, dx, depth, 1e6, nu, comp)
        assert dottest(op, rng) < 1e-12
    assert abs(op_zz.matvec(np.ones(n))).max() < 1e-15  # a uniform height strains nothing
    assert np.allclose(op_zz.matvec(h), np.fft.ifft(op_zz.multiplier * np.fft.fft(h)).real)


def test_strain_operator_validation():
    with pytest.raises(ValueError, match="component: expected a Voigt strain component"):
        rigid_surface_height_strain_operator(16, 1e-4, 1e-3, 1e6, 0.5, "zzz")
    with pytest.raises(ValueError, match="depth: every depth must be finite and > 0 m"):
        rigid_surface_height_strain_operator(16, 1e-4, 0.0, 1e6)
    with pytest.raises(ValueError, match=r"poisson_ratio: Poisson's ratio must lie in \(-1, 0.5\]"):
        rigid_surface_height_strain_operator(16, 1e-4, 1e-3, 1e6, 0.7)
    with pytest.raises(ValueError, match="young_modulus"):
        halfspace_strain_operator((16,), 1e-4, 1e-3, -1.0)


def _simulated(quantity: str, noise: float, tmp_path):
    base = load_example("fingertip_defect")
    sensors = SensorArray(positions_m=np.array([[0.0, 0.0], [1e-3, 0.0], [-1e-3, 1e-3]]), depth_m=2e-3,
                          components=("zz",), noise_std=noise, quantity=quantity)
    scan = Scan(speed_m_per_s=0.02, duration_s=0.4, sampling_rate_hz=75.0, start_position_m=-4e-3)
    scene = base.model_copy(update={"sensors": sensors, "scan": scan})
    out = tmp_path / quantity
    simulate_scene(scene, out, rng=np.random.default_rng(5), plots=False)
    return scene, read_recording(out / "recording.nc")


@pytest.mark.slow
def test_strain_recording_inverts_to_the_stress_position(tmp_path):
    """The forward model (node weights of the finger, not the point-defect model) writes a stress and
    a strain recording of the same scene (noise 20 Pa and the equivalent 20 Pa / E); both invert to
    the same defect position."""
    fast = dict(n_walkers=12, check_every=150, max_steps=3000, min_ess=100, tau_factor=10, n_start=128)
    found = {}
    for quantity, noise in (("stress", 20.0), ("strain", 2e-5)):
        scene, rec = _simulated(quantity, noise, tmp_path)
        assert rec.quantity == quantity
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            res, info = invert_defect_position(scene, rec, np.random.default_rng(3), **fast)
        assert res.converged, res.message
        assert info["quantity"] == quantity
        post = res.tree["posterior"]
        found[quantity] = {q: (float(post[q].mean()), float(post[q].std())) for q in ("x0", "y0")}
    for q in ("x0", "y0"):
        (m1, s1), (m2, s2) = found["stress"][q], found["strain"][q]
        assert abs(m1 - m2) < 3 * np.hypot(s1, s2), found
        assert abs(m1) < 0.1e-3 and abs(m2) < 0.1e-3  # the bump sits at the origin

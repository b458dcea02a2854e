"""Tactile synthesis design (docs/theory.md 4a): objective, optimiser, matching traction.

Oracles: a brute-force dense scan of J(d); scipy.integrate.quad for the objective's integrals;
exact scale invariance (J(d; Z, w) = J(d/Z; 1, w/Z) / Z, so with w proportional to Z the optimum
d/Z is constant); the strain of the driven array computed from the tractor closed forms
(Flamant) against the sliding grating's closed form, both at the peak and in RMS over space
and time. The matching formula Q = 8 sqrt(2) pi^3 A Z E e^{-2 pi Z/p} / (3 k2' p^2) is the one
of Wang & Hayward's tactile synthesis analysis as restated in docs/theory.md 4a.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from tactilab.forward import synthesis, tractor_display, tractors

E = 200e3


@pytest.fixture(scope="module")
def design_125():
    return synthesis.optimal_half_spacing(1.25e-3)


def test_objective_quadrature_converges():
    z, d = 1.25e-3, 0.9e-3
    coarse = synthesis.spacing_objective(d, z)
    fine = synthesis.spacing_objective(d, z, panel_fraction=0.125)
    assert abs(coarse["objective"] - fine["objective"]) <= 1e-10 * fine["objective"]
    k2 = coarse["k2"]

    def integrand(x):
        s_phi, s_psi = tractors.array_phi_psi(np.array(x), d, z, 5)
        ph = np.pi * x / (2 * d)
        return (s_phi + 0.5 * k2 * np.cos(ph)) ** 2 + (s_psi - k2 * np.sin(ph)) ** 2

    reference, err = quad(integrand, -5e-3, 5e-3, limit=400, epsabs=0, epsrel=1e-12)
    assert abs(coarse["objective"] - reference) <= 1e-9 * reference
    assert 0 < coarse["relative_residual"] < 1


def test_amplitude_factor_is_the_max_over_the_window():
    z, d = 1.25e-3, 0.9e-3
    k2, where = synthesis.amplitude_factor(d, z, 5)
    xs = np.linspace(-4 * d, 4 * d, 200001)
    dense = tractors.array_phi_psi(xs, d, z, 5)[1].max()
    assert dense <= k2 <= dense * (1 + 1e-9)
    assert abs(where) <= 4 * d


def test_optimum_is_a_minimum_of_a_dense_scan(design_125):
    z = design_125.depth
    assert 0.2 * z < design_125.d < 5 * z
    grid = np.linspace(0.2 * z, 2 * z, 400)
    values = np.array([synthesis.spacing_objective(d, z)["objective"] for d in grid])
    assert design_125.objective <= values.min() * (1 + 1e-9)
    assert abs(grid[np.argmin(values)] - design_125.d) <= (grid[1] - grid[0])
    # k2' = S_Psi(d) and k2 (the max) agree when the match is good
    assert 0.9 < design_125.k2_prime / design_125.k2 <= 1.0
    assert design_125.pitch == 4 * design_125.d
    row = design_125.to_dict()
    assert row["d_over_depth"] == pytest.approx(design_125.d / z)


def test_same_optimum_from_different_grids_and_brackets(design_125):
    z = design_125.depth
    for grid_points, bracket in [(60, None), (333, None), (100, (0.3 * z, 3 * z)), (40, (0.5 * z, 1.5 * z))]:
        other = synthesis.optimal_half_spacing(z, grid_points=grid_points, bracket=bracket)
        assert other.d == pytest.approx(design_125.d, rel=1e-5)
        assert other.objective == pytest.approx(design_125.objective, rel=1e-8)


def test_not_fooled_by_spurious_small_spacing_minima():
    """Below 0.2 Z, J has minima lower than the non-trivial one (and J -> 0 as d -> 0)."""
    z = 0.5e-3
    design = synthesis.optimal_half_spacing(z)
    small = np.geomspace(0.02 * z, 0.2 * z, 60)
    values = np.array([synthesis.spacing_objective(d, z)["objective"] for d in small])
    interior = (values[1:-1] < values[:-2]) & (values[1:-1] < values[2:])
    assert interior.any()  # a spurious minimum exists
    assert values[1:-1][interior].min() < design.objective  # ... and it is lower than the optimum
    assert design.d > 0.2 * z
    tiny = synthesis.spacing_objective(1e-4 * z, z)["objective"]
    assert np.isfinite(tiny) and tiny < 1e-3 * design.objective  # the trivial d -> 0 limit
    # every reported minimum sits in the bracket, and the chosen one has the lowest J
    ds = [m[0] for m in design.minima]
    assert all(design.bracket[0] <= d <= design.bracket[1] for d in ds)
    assert design.objective == pytest.approx(min(m[1] for m in design.minima if m[2] < 1), rel=1e-9)
    assert design.relative_residual < 1


def test_trivial_minima_are_skipped():
    """Two pairs at Z = 1.25 mm: the minimum of lowest J near 0.28 Z fits worse than zero strain."""
    design = synthesis.optimal_half_spacing(1.25e-3, pairs=2)
    trivial = [m for m in design.minima if m[2] >= 1]
    assert trivial and min(m[1] for m in trivial) < design.objective
    assert design.relative_residual < 1 and design.d > 0.5 * design.depth


def test_scale_invariance_with_window_proportional_to_depth():
    a = synthesis.optimal_half_spacing(1e-3, width=8e-3)
    b = synthesis.optimal_half_spacing(2.5e-3, width=20e-3)
    assert a.d_over_depth == pytest.approx(b.d_over_depth, rel=1e-5)
    assert a.k2 * a.depth == pytest.approx(b.k2 * b.depth, rel=1e-6)
    assert a.objective * a.depth == pytest.approx(b.objective * b.depth, rel=1e-5)


def test_depth_scaling_fit_recovers_a_proportional_law():
    fit = synthesis.depth_scaling([1e-3, 2e-3], width=None, width_over_depth=8.0)
    assert fit.ratio == pytest.approx(fit.ratios[0], rel=1e-5)
    assert fit.exponent == pytest.approx(1.0, abs=1e-4)
    fixed = synthesis.depth_scaling([1.25e-3, 2e-3, 3e-3], width=10e-3)
    assert len(fixed.designs) == 3 and fixed.exponent > 0
    with pytest.raises(ValueError, match="all made at one depth"):
        synthesis.scaling_from_designs([fixed.designs[0], fixed.designs[0]])


def test_design_table_rows():
    table = synthesis.design_table([1.25e-3], widths=[8e-3, 10e-3], pairs_list=[3, 5])
    assert len(table) == 4
    assert set(table.columns) >= {"depth_m", "width_m", "pairs", "d_m", "d_over_depth", "k2_per_m",
                                  "k2_prime_per_m", "objective_per_m", "relative_residual", "n_minima"}
    assert (table["d_m"] > 0).all()


def test_matching_traction_reproduces_the_grating_strain(design_125):
    """Peak: the drive's engineering shear at x = d is sqrt(2) times the grating's; RMS over a
    period and the central pitch: within 10 % (the sqrt(2) compensates the standing wave)."""
    z, amplitude = design_125.depth, 50e-6
    d, p = design_125.d, design_125.pitch
    q = synthesis.matching_line_load(amplitude, None, None, E, design_125)
    tx, sign = tractors.array_tractors(d, 5)
    at_d = tractors.tractor_row_strain([d], z, tx, q * sign, E)[0]
    grating_peak = 8 * np.pi**2 * amplitude * z * np.exp(-2 * np.pi * z / p) / p**2  # engineering shear
    assert 2 * at_d[4] == pytest.approx(np.sqrt(2) * grating_peak, rel=1e-10)
    speed = 0.02
    times = np.linspace(0, p / speed, 48, endpoint=False)
    drive = tractor_display.travelling_wave_drive(tx, lambda x: amplitude * np.sin(2 * np.pi * x / p), speed,
                                                  times, gain=q / amplitude)
    x = np.linspace(-2 * d, 2 * d, 121)[:-1]
    rendered = tractors.tractor_row_strain(x, z, tx, drive, E)
    real = tractors.sliding_sinusoid_strain(x, z, amplitude, p, speed, times)
    for c in (0, 4):
        ratio = np.sqrt(np.mean(rendered[..., c] ** 2) / np.mean(real[..., c] ** 2))
        assert 0.9 < ratio < 1.1


def test_traction_and_max_amplitude_round_trip(design_125):
    amplitude = 50e-6
    tau = synthesis.matching_traction_amplitude(amplitude, None, None, E, design_125)
    q = synthesis.matching_line_load(amplitude, None, None, E, design_125)
    assert tau == pytest.approx(q / design_125.d)
    assert synthesis.matching_traction_amplitude(amplitude, None, 1.25e-3, E, design_125, footprint=0.5e-3) == \
        pytest.approx(q / 0.5e-3)
    a_max = synthesis.max_virtual_amplitude(tau, None, None, E, design_125)
    assert a_max == pytest.approx(amplitude, rel=1e-12)
    # Q is proportional to E and A, so the renderable amplitude scales as 1/E
    assert synthesis.max_virtual_amplitude(tau, None, None, 2 * E, design_125) == pytest.approx(amplitude / 2)
    # Q follows the grating's strain amplitude k^2 e^{-k Z}, which peaks at k Z = 2
    p, z = design_125.pitch, design_125.depth
    half = synthesis.matching_line_load(amplitude, 0.5 * p, None, E, design_125)
    assert half / q == pytest.approx(4 * np.exp(-2 * np.pi * z / p), rel=1e-12)


@pytest.mark.parametrize("call, match", [
    (lambda: synthesis.optimal_half_spacing(0.0), "depth: must be finite and > 0"),
    (lambda: synthesis.optimal_half_spacing(-1e-3), "receptors sit inside the skin"),
    (lambda: synthesis.optimal_half_spacing(1e-3, width=0.0), "width: must be finite and > 0"),
    (lambda: synthesis.optimal_half_spacing(1e-3, pairs=0), "pairs: the number of tractor pairs"),
    (lambda: synthesis.optimal_half_spacing(1e-3, bracket=(1e-3,)), "bracket: expected two half spacings"),
    (lambda: synthesis.optimal_half_spacing(1e-3, bracket=(2e-3, 1e-3)), "bracket: need finite 0 < low < high"),
    (lambda: synthesis.optimal_half_spacing(1e-3, grid_points=5), "grid_points: need an integer >= 20"),
    (lambda: synthesis.optimal_half_spacing(1e-3, bracket=(2.5e-3, 2.6e-3)), "no non-trivial interior"),
    (lambda: synthesis.optimal_half_spacing(1.25e-3, pairs=2, bracket=(0.25e-3, 0.4e-3)), "relative residual 1.1"),
    (lambda: synthesis.scaling_from_designs([]), "designs: need at least two"),
    (lambda: synthesis.spacing_objective(0.0, 1e-3), "tractor spacing must be > 0"),
    (lambda: synthesis.spacing_objective(1e-3, 1e-3, panel_fraction=0), "panel_fraction"),
    (lambda: synthesis.amplitude_factor(-1e-3, 1e-3), "half_spacing"),
    (lambda: synthesis.depth_scaling([1e-3]), "depths: give at least 2 values"),
    (lambda: synthesis.depth_scaling([1e-3, 2e-3], width=None), "give width or width_over_depth"),
    (lambda: synthesis.depth_scaling([1e-3, 2e-3], width=1e-2, width_over_depth=8.0), "exactly one"),
    (lambda: synthesis.design_table([], [1e-2], [5]), "depths: give at least one"),
    (lambda: synthesis.design_table([1e-3], [1e-2], []), "pairs_list: give at least one"),
    (lambda: synthesis.design_table([1e-3], [-1e-2], [5]), "widths: must be finite and > 0"),
])
def test_design_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.parametrize("kwargs, match", [
    (dict(design="optimal"), "design: expected a SpacingDesign"),
    (dict(pitch=0.0), "pitch: must be finite and > 0"),
    (dict(depth=2e-3), "differs from the depth the design was made for"),
    (dict(amplitude=np.nan), "amplitude: must be finite"),
    (dict(young_modulus=0.0), "young_modulus: must be finite and > 0"),
    (dict(footprint=-1e-3), "footprint: must be finite and > 0"),
])
def test_matching_errors(design_125, kwargs, match):
    args = dict(amplitude=50e-6, pitch=None, depth=None, young_modulus=E, design=design_125)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        synthesis.matching_traction_amplitude(**args)


def test_max_amplitude_rejects_bad_limit(design_125):
    with pytest.raises(ValueError, match="traction_limit: must be finite and > 0"):
        synthesis.max_virtual_amplitude(-5e3, None, None, E, design_125)

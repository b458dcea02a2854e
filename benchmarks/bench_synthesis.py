"""Benchmark the tactile synthesis design (docs/theory.md 4a): speed, accuracy, robustness, results.

Run: ``python benchmarks/bench_synthesis.py`` (about 30 s). Prints, from one run:

1. the optimiser (geometric scan + bounded refinement) against a brute-force baseline (a dense
   uniform scan of J with 2000 points, the same non-trivial filter): time, ratio, d agreement;
2. quadrature error of J against scipy.integrate.quad at the optimum;
3. robustness: the optimum from four different grids and brackets;
4. the design table for depths 0.5-3 mm, and the scaling of d with Z (window fixed at 10 mm,
   and window proportional to Z, where d/Z must be constant);
5. sensitivity of the optimum to the window width and to the number of pairs.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.integrate import quad

from tactilab.forward import synthesis, tractors

DEPTHS_MM = (0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0)


def brute_force(depth: float, width: float = 10e-3, pairs: int = 5, n: int = 2000) -> float:
    grid = np.linspace(0.2 * depth, 5 * depth, n)
    parts = [synthesis.spacing_objective(d, depth, width, pairs) for d in grid]
    j = np.array([p["objective"] for p in parts])
    rel = np.array([p["relative_residual"] for p in parts])
    interior = np.zeros(n, dtype=bool)
    interior[1:-1] = (j[1:-1] <= j[:-2]) & (j[1:-1] < j[2:]) & (rel[1:-1] < 1)
    idx = np.flatnonzero(interior)
    return float(grid[idx[np.argmin(j[idx])]])


def section_speed() -> None:
    print("1. optimiser vs brute-force dense scan (2000 points), w = 10 mm, 5 pairs")
    print(f"{'Z_mm':>6} {'t_opt_s':>8} {'t_brute_s':>9} {'speedup':>8} {'d_opt_mm':>9} {'d_brute_mm':>10} "
          f"{'|diff|/grid_step':>16}")
    for z_mm in (0.5, 1.25, 3.0):
        z = z_mm * 1e-3
        t0 = time.perf_counter()
        design = synthesis.optimal_half_spacing(z)
        t1 = time.perf_counter()
        d_brute = brute_force(z)
        t2 = time.perf_counter()
        step = 4.8 * z / 1999
        print(f"{z_mm:6.2f} {t1 - t0:8.3f} {t2 - t1:9.3f} {(t2 - t1) / (t1 - t0):8.1f} {design.d * 1e3:9.4f} "
              f"{d_brute * 1e3:10.4f} {abs(design.d - d_brute) / step:16.2f}")


def section_quadrature() -> None:
    print("\n2. quadrature of J at the optimum: composite Gauss-Legendre vs scipy.integrate.quad (epsrel 1e-12)")
    print(f"{'Z_mm':>6} {'J_gl':>14} {'J_quad':>14} {'rel_err':>9} {'rel_err_fine_panels':>19}")
    for z_mm in (0.5, 1.25, 3.0):
        z = z_mm * 1e-3
        design = synthesis.optimal_half_spacing(z)
        d, k2 = design.d, design.k2

        def integrand(x):
            s_phi, s_psi = tractors.array_phi_psi(np.array(x), d, z, 5)
            ph = np.pi * x / (2 * d)
            return (s_phi + 0.5 * k2 * np.cos(ph)) ** 2 + (s_psi - k2 * np.sin(ph)) ** 2

        ref = quad(integrand, -5e-3, 5e-3, limit=1000, epsabs=0, epsrel=1e-12)[0]
        fine = synthesis.spacing_objective(d, z, panel_fraction=0.125)["objective"]
        print(f"{z_mm:6.2f} {design.objective:14.8g} {ref:14.8g} {abs(design.objective - ref) / ref:9.1e} "
              f"{abs(design.objective - fine) / fine:19.1e}")


def section_robustness() -> None:
    print("\n3. robustness: optimum from different scan grids and brackets (Z = 1.25 mm)")
    z = 1.25e-3
    print(f"{'grid_points':>11} {'bracket/Z':>14} {'d_mm':>10}")
    ds = []
    for grid_points, bracket in [(200, None), (60, None), (333, None), (100, (0.3, 3.0)), (40, (0.5, 1.5))]:
        br = None if bracket is None else (bracket[0] * z, bracket[1] * z)
        d = synthesis.optimal_half_spacing(z, grid_points=grid_points, bracket=br).d
        ds.append(d)
        label = "(0.2, 5)" if bracket is None else str(bracket)
        print(f"{grid_points:11d} {label:>14} {d * 1e3:10.6f}")
    print(f"max relative spread {(max(ds) - min(ds)) / np.mean(ds):.1e}")


def section_table() -> None:
    print("\n4. design table, w = 10 mm, 5 pairs; A = 50 um, E = 200 kPa, footprint d, traction limit 5 kPa")
    print(f"{'Z_mm':>6} {'d_mm':>8} {'d/Z':>6} {'k2_1/mm':>8} {'k2p_1/mm':>8} {'J_1/m':>10} {'rel_res':>8} "
          f"{'Q_N/m':>8} {'tau_kPa':>8} {'Amax_um':>8}")
    designs = []
    for z_mm in DEPTHS_MM:
        dsg = synthesis.optimal_half_spacing(z_mm * 1e-3)
        designs.append(dsg)
        q = synthesis.matching_line_load(50e-6, None, None, 200e3, dsg)
        tau = synthesis.matching_traction_amplitude(50e-6, None, None, 200e3, dsg)
        a_max = synthesis.max_virtual_amplitude(5e3, None, None, 200e3, dsg)
        print(f"{z_mm:6.2f} {dsg.d * 1e3:8.4f} {dsg.d_over_depth:6.3f} {dsg.k2 * 1e-3:8.4f} "
              f"{dsg.k2_prime * 1e-3:8.4f} {dsg.objective:10.4g} {dsg.relative_residual:8.4f} {q:8.3f} "
              f"{tau * 1e-3:8.3f} {a_max * 1e6:8.3f}")
    fit = synthesis.scaling_from_designs(designs)
    print(f"fixed w = 10 mm: d = {fit.ratio:.4f} Z (max deviation {fit.max_deviation * 100:.1f} %), "
          f"power law d/mm = {fit.prefactor * 1e3 ** (1 - fit.exponent):.4f} (Z/mm)^{fit.exponent:.3f}")
    fit_1_3 = synthesis.scaling_from_designs([d for d in designs if d.depth >= 1e-3])
    print(f"fixed w = 10 mm, Z >= 1 mm only: d = {fit_1_3.ratio:.4f} Z (max deviation "
          f"{fit_1_3.max_deviation * 100:.1f} %), exponent {fit_1_3.exponent:.3f}")
    prop = synthesis.depth_scaling([0.5e-3, 1.25e-3, 3e-3], width=None, width_over_depth=8.0)
    print(f"w = 8 Z: d/Z = {', '.join(f'{r:.5f}' for r in prop.ratios)} (exponent {prop.exponent:.5f}; "
          "scale invariance makes d/Z exactly constant)")


def section_sensitivity() -> None:
    for z_mm in (1.25, 2.0):
        z = z_mm * 1e-3
        print(f"\n5. sensitivity at Z = {z_mm} mm: window width (5 pairs) and number of pairs (w = 10 mm)")
        print(f"{'w_mm':>6} {'d_mm':>8} {'d/Z':>6} {'rel_res':>8}   | {'pairs':>5} {'d_mm':>8} {'d/Z':>6} {'rel_res':>8}")
        widths = (5, 6, 8, 10, 12, 15, 20)
        pairs = (1, 2, 3, 4, 5, 6, 7)
        for w_mm, n in zip(widths, pairs):
            a = synthesis.optimal_half_spacing(z, w_mm * 1e-3, 5)
            b = synthesis.optimal_half_spacing(z, 10e-3, n)
            print(f"{w_mm:6.1f} {a.d * 1e3:8.4f} {a.d_over_depth:6.3f} {a.relative_residual:8.4f}   | "
                  f"{n:5d} {b.d * 1e3:8.4f} {b.d_over_depth:6.3f} {b.relative_residual:8.4f}")


def main() -> None:
    t0 = time.perf_counter()
    section_speed()
    section_quadrature()
    section_robustness()
    section_table()
    section_sensitivity()
    print(f"\ntotal {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()

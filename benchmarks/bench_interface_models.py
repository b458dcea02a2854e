"""The cheap texture models against the solved contact: their sensor error and the estimate's coverage.

Run: ``python benchmarks/bench_interface_models.py`` (about a minute); ``--quick`` for the reduced
sizes the test suite uses; ``--sections a b`` to run part of it.

Skin E = 1 MPa, nu = 1/2. Error = max over the cell of |eps_model - eps_exact| / max |eps_exact|,
per strain component (its scale at least 1e-3 of the largest component's), the largest over them: the sensor error of
issue 27's ``tol``. The cell slides under the sensor, so max over the cell is max over a scan.

- (a) Sinusoid (plane strain): period L = 1 mm, amplitude 2 um (p* = pi E* Delta / L = 8.38 kPa),
  at p_bar / p* and depth / L. The truth is Westergaard's closed form (its harmonics times the
  half-space transfer, ``harmonic_field``); the models' strains come from their pressures sampled
  on 4096 nodes (the sampling error of the truth's own pressure there is 1.5e-6). The estimate is
  ``interface_model_errors`` on a cell of 64 nodes.
- (b) Random rough (3-D, periodic): a self-affine cell (Hurst 0.8, cut-offs 1.28 mm and 80 um,
  2.56 mm square, 256^2 nodes of 10 um), its amplitude scaled to each p_bar / p* at p_bar = 10 kPa,
  two seeds; depth over the long cut-off. The truth is the solved contact on 256^2 nodes; the
  estimate is ``interface_model_errors`` on every other node (128^2).

Each table shows the true errors (linear / modulation; the larger of the seeds); below it, the
number of cases (each seed, depth, ratio and model) where the estimate is at least the true error.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings

import numpy as np

from tactilab.forward import (AccuracyWarning, HalfSpace, SurfaceLoad, WestergaardContact, full_contact_pressure,
                              harmonic_field, interface_model_errors, linear_pressure, modulation_pressure,
                              random_rough_surface, solve_contact)

E_PA, NU = 1e6, 0.5
E_STAR = E_PA / (1 - NU**2)
SKIN = HalfSpace(E=E_PA, nu=NU)
COMPONENTS = ("xx", "yy", "zz", "yz", "zx", "xy")
MODELS = ("linear", "modulation")


def relative_error(model: np.ndarray, exact: np.ndarray) -> float:
    """max over components of max |model - exact| / max |exact| (scales floored at 1e-3 of the largest, as the
    scenes do); arrays (component, ...)."""
    scale = np.abs(exact).reshape(exact.shape[0], -1).max(axis=1)
    diff = np.abs(model - exact).reshape(exact.shape[0], -1).max(axis=1)
    return float((diff / np.maximum(scale, 1e-3 * scale.max())).max()) if scale.max() > 0 else 0.0


def strain(p: np.ndarray, spacing, depth: float) -> np.ndarray:
    field = SKIN.strain(SurfaceLoad(p=p, spacing=spacing, periodic=True), [depth], components=COMPONENTS)
    return field.data["strain"].isel(depth=0).transpose("component", ...).values


def sinusoid_case(ratio: float, depth_ratio: float, n_truth: int, n_cell: int,
                  wavelength: float = 1e-3, amplitude: float = 2e-6) -> dict:
    """True and estimated errors of both models for one sinusoid at p_bar / p* and depth / L."""
    p_star = math.pi * E_STAR * amplitude / wavelength
    contact = WestergaardContact(amplitude, wavelength, ratio * p_star, E_PA, NU)
    depth = depth_ratio * wavelength
    x = (np.arange(n_truth) - n_truth // 2) * wavelength / n_truth
    n_harmonics = int(min(n_truth // 2, math.ceil(40 / (2 * math.pi * depth_ratio))))
    exact = harmonic_field(contact.harmonics(n_harmonics), wavelength, x, depth, E_PA, NU, components=COMPONENTS)
    h = amplitude * np.cos(2 * np.pi * x / wavelength)
    dx = wavelength / n_truth
    true = {"linear": relative_error(strain(linear_pressure(h, dx, contact.mean_pressure, E_PA, NU), dx, depth), exact),
            "modulation": relative_error(strain(modulation_pressure(h, contact.mean_pressure), dx, depth), exact)}
    xc = (np.arange(n_cell) - n_cell // 2) * wavelength / n_cell
    est = interface_model_errors(amplitude * np.cos(2 * np.pi * xc / wavelength), wavelength / n_cell,
                                 contact.mean_pressure, E_PA, NU, depth)
    return {"true": true, "estimate": est}


def rough_case(ratio: float, depth_ratios, n: int, seed: int, mean_pressure: float = 1e4) -> list[dict]:
    """True and estimated errors for one random rough cell at p_bar / p*, for each depth / long cut-off."""
    dx = 2.56e-3 / n
    long_cutoff, short_cutoff = 1.28e-3, 80e-6
    h = random_rough_surface((n, n), dx, rms_height=1e-6, hurst=0.8, long_cutoff=long_cutoff,
                             short_cutoff=short_cutoff, rng=np.random.default_rng(seed))
    h *= mean_pressure / ratio / full_contact_pressure(h, dx, E_PA, NU)  # now p* = p_bar / ratio
    sol = solve_contact(SKIN, h.max() - h, dx, mean_pressure=mean_pressure, periodic=True)  # solved in full contact too
    exact_p = sol.pressure
    rows = []
    for depth_ratio in depth_ratios:
        depth = depth_ratio * long_cutoff
        exact = strain(exact_p, dx, depth)
        true = {"linear": relative_error(strain(linear_pressure(h, dx, mean_pressure, E_PA, NU), dx, depth), exact),
                "modulation": relative_error(strain(modulation_pressure(h, mean_pressure), dx, depth), exact)}
        est = interface_model_errors(h[::2, ::2], 2 * dx, mean_pressure, E_PA, NU, depth)
        rows.append({"true": true, "estimate": est, "depth_ratio": depth_ratio,
                     "contact_fraction": float(sol.contact_fraction)})
    return rows


def _table(title: str, ratios, depth_ratios, results: dict, depth_label: str) -> tuple[int, int]:
    """Print the true errors (the largest over the cases of each cell) and count the estimate's coverage per case."""
    print(f"\n{title}")
    print("| p_bar / p* | " + " | ".join(f"{depth_label} = {d:g}" for d in depth_ratios) + " |")
    print("|---|" + "---|" * len(depth_ratios))
    covered = total = 0
    worst = math.inf
    for ratio in ratios:
        cells = []
        for d in depth_ratios:
            cases = results[(ratio, d)]
            cells.append(" / ".join(f"{max(c['true'][m] for c in cases):.2g}" for m in MODELS))
            for case in cases:
                for m in MODELS:
                    total += 1
                    covered += case["estimate"][m] >= case["true"][m]
                    if case["true"][m] > 1e-9:
                        worst = min(worst, case["estimate"][m] / case["true"][m])
        print(f"| {ratio:g} | " + " | ".join(cells) + " |")
    print(f"(linear / modulation, true errors); the estimate covers {covered} of {total} cases, "
          f"smallest estimate / true error {worst:.3f} (true errors above 1e-9)")
    return covered, total


def section_a(quick: bool) -> tuple[int, int]:
    ratios = (0.05, 0.3, 1.0, 2.0) if quick else (0.05, 0.1, 0.2, 0.5, 0.8, 1.0, 1.5, 2.0, 4.0)
    depth_ratios = (0.1, 0.5) if quick else (0.1, 0.25, 0.5, 1.0, 2.0)
    n_truth, n_cell = (1024, 32) if quick else (4096, 64)
    t0 = time.perf_counter()
    results = {(r, d): [sinusoid_case(r, d, n_truth, n_cell)] for r in ratios for d in depth_ratios}
    covered, total = _table(f"(a) sinusoid, L = 1 mm, plane strain: error of the sensor strain "
                               f"(truth: Westergaard; estimate on {n_cell} nodes)", ratios, depth_ratios, results,
                               "depth / L")
    print(f"({time.perf_counter() - t0:.1f} s)")
    return covered, total


def section_b(quick: bool) -> tuple[int, int]:
    ratios = (0.1, 0.5, 2.0) if quick else (0.05, 0.2, 0.5, 1.0, 2.0)
    depth_ratios = (0.25, 1.0) if quick else (0.1, 0.25, 0.5, 1.0)
    n = 64 if quick else 256
    seeds = (1,) if quick else (1, 2)
    t0 = time.perf_counter()
    results: dict = {}
    fractions = {}
    for ratio in ratios:
        for seed in seeds:
            for row in rough_case(ratio, depth_ratios, n, seed):
                results.setdefault((ratio, row["depth_ratio"]), []).append(row)
                fractions[ratio] = row["contact_fraction"]
    covered, total = _table(f"(b) random rough, Hurst 0.8, cut-offs 1.28 mm and 80 um, {n}^2 nodes, "
                               f"{len(seeds)} seed(s): error of the sensor strain (truth: solved on {n}^2; "
                               f"estimate on {n // 2}^2)", ratios, depth_ratios, results, "depth / 1.28 mm")
    print("contact fraction: " + ", ".join(f"{fractions[r]:.2f} at {r:g}" for r in ratios))
    print(f"({time.perf_counter() - t0:.1f} s)")
    return covered, total


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="reduced sizes (the test suite's)")
    parser.add_argument("--sections", nargs="+", choices=("a", "b"), default=("a", "b"))
    args = parser.parse_args(argv)
    covered = total = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)  # light loads: patches of a few nodes, as intended
        for name in args.sections:
            c, t = {"a": section_a, "b": section_b}[name](args.quick)
            covered, total = covered + c, total + t
    print(f"\nestimate covers the true error in {covered} of {total} cases")
    return 0 if covered == total else 1


if __name__ == "__main__":
    sys.exit(main())

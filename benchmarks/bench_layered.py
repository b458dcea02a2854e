"""Benchmark of the layered skin (forward/skin/layered.py): cost against the half-space, and science.

Run: ``python benchmarks/bench_layered.py [--sizes 256 512] [--repeats 15] [--no-science]``
(about 40 s on an idle 2-core machine). Prints, from one run:

1. Cost of a layered field against the elastic half-space: ``stress`` of a periodic load (p, qx,
   qy) at one depth, six components, float64, one FFT thread, on 256^2 and 512^2 grids. Times are
   medians and minima over interleaved repeats after a warm-up call, so the transfer tables of both
   (the half-space's depth tables, the layered multipliers) are cached: the figure a scan over
   frames sees. ``first`` is the layered call that builds its tables (one small solve per distinct
   |k| of the grid). Goal: layered <= 1.5x elastic with the tables cached.
2. Science (2): the receptive field of a sensor 3 mm deep (and 1 mm) in a 4 mm pulp (E = 0.5 MPa,
   nu = 1/2) bonded to bone, against the half-space of the same material: peak reading per newton
   of normal force, and the radii where it falls to a half and a tenth (docs/layered_skin.md).
3. Science (3): the tactile-synthesis optimum half spacing d_opt (docs/theory.md 4a) for receptors
   1, 2 and 3 mm deep in the 4 mm pulp on bone, against the half-space's, same window (10 mm) and
   number of pairs (5): ``optimal_half_spacing(Z, skin=...)``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.fft as sfft

from tactilab.forward import HalfSpace, Layer, LayeredHalfSpace, SurfaceLoad, optimal_half_spacing
from tactilab.forward.skin import receptive_field

from bench_forward import interleaved  # the timer of bench_forward (this folder is on sys.path when run)

E_PA, DEPTH, SPACING = 0.5e6, 1e-3, 1e-4


def _load(n: int, rng) -> SurfaceLoad:
    return SurfaceLoad(p=rng.standard_normal((n, n)), qx=rng.standard_normal((n, n)),
                       qy=rng.standard_normal((n, n)), spacing=SPACING, periodic=True)


def section_cost(sizes, repeats: int) -> None:
    print("1. layered field vs elastic half-space: stress, p + qx + qy, 1 depth, 6 components, float64")
    print(f"{'n':>5} {'elastic_ms':>11} {'layered_ms':>11} {'ratio_med':>9} {'ratio_min':>9} {'first_ms':>9} "
          f"{'max|diff|/peak':>14}")
    rng = np.random.default_rng(0)
    hs = HalfSpace(E_PA, 0.5)
    pulp = LayeredHalfSpace([Layer(4e-3, E_PA, 0.5)])
    same = LayeredHalfSpace([Layer(4e-3, E_PA, 0.5)], base=hs)  # = the half-space: the agreement column
    for n in sizes:
        load = _load(n, rng)
        with sfft.set_workers(1):
            t0 = time.perf_counter()
            pulp.stress(load, DEPTH).data  # noqa: B018 (builds the tables)
            first = time.perf_counter() - t0
            ref = hs.stress(load, DEPTH, method="spectral").data["stress"].values
            diff = np.abs(same.stress(load, DEPTH).data["stress"].values - ref).max() / np.abs(ref).max()
            t = interleaved({"elastic": lambda: hs.stress(load, DEPTH, method="spectral").data,
                             "layered": lambda: pulp.stress(load, DEPTH).data}, repeats)
        (em, emin), (lm, lmin) = t["elastic"], t["layered"]
        print(f"{n:>5} {em * 1e3:>11.1f} {lm * 1e3:>11.1f} {lm / em:>9.2f} {lmin / emin:>9.2f} {first * 1e3:>9.0f} "
              f"{diff:>14.1e}")


def section_receptive_field() -> None:
    print("2. receptive field: normal point force, sensor in a 4 mm pulp on bone vs the half-space "
          "(E = 0.5 MPa, nu = 1/2)")
    print(f"{'depth_mm':>8} {'reading':>12} {'skin':>10} {'peak_per_N':>11} {'r_half_mm':>9} {'r_tenth_mm':>10}")
    skins = {"half-space": HalfSpace(E_PA, 0.5), "pulp/bone": LayeredHalfSpace([Layer(4e-3, E_PA, 0.5)])}
    for depth in (3e-3, 1e-3):
        for reading, quantity in (("zz", "stress"), ("zz", "strain"), ("xx", "strain"), ("von_mises", "strain")):
            for name, skin in skins.items():
                r = receptive_field(skin, depth, reading, quantity, spacing=1e-4, half_extent=15e-3)
                label = f"{quantity[:6]} {reading}"
                print(f"{depth * 1e3:>8.1f} {label:>12} {name:>10} {r.peak:>11.4g} {r.half_width * 1e3:>9.2f} "
                      f"{r.tenth_width * 1e3:>10.2f}")


def section_synthesis() -> None:
    print("3. tactile-synthesis optimum: half-space vs 4 mm pulp on bone (window 10 mm, 5 pairs)")
    print(f"{'Z_mm':>5} {'d_half_mm':>9} {'d_pulp_mm':>9} {'change_%':>8} {'resid_half':>10} {'resid_pulp':>10} "
          f"{'t_pulp_s':>8}")
    pulp = LayeredHalfSpace([Layer(4e-3, E_PA, 0.5)])
    for z in (1e-3, 2e-3, 3e-3):
        half = optimal_half_spacing(z)
        t0 = time.perf_counter()
        layered = optimal_half_spacing(z, skin=pulp)
        t = time.perf_counter() - t0
        print(f"{z * 1e3:>5.1f} {half.d * 1e3:>9.4f} {layered.d * 1e3:>9.4f} {100 * (layered.d / half.d - 1):>8.2f} "
              f"{half.relative_residual:>10.4f} {layered.relative_residual:>10.4f} {t:>8.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 512])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--no-science", action="store_true")
    args = parser.parse_args()
    section_cost(args.sizes, args.repeats)
    if not args.no_science:
        section_receptive_field()
        section_synthesis()


if __name__ == "__main__":
    main()

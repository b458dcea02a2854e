"""Benchmark of the skin models (forward/skin/): their cost against the elastic half-space.

Run: ``python benchmarks/bench_skin_models.py [--sizes 256 512] [--repeats 15] [--steps 1000]``
(about a minute on an idle 2-core machine). Prints, from one run:

1. Fields: each row of ``FIELD_CASES`` against the elastic half-space on the same load, one depth,
   six stress components, float64, one FFT thread, on 256^2 and 512^2 grids. Times are medians and
   minima over interleaved repeats after a warm-up call (the transfer tables cached: what a scan
   over frames sees), with each row's goal and an agreement column against an independent
   reference. The table is the list ``FIELD_CASES``: a skin model adds a row. Rows: a rigid random
   surface sliding at 10 cm/s over a standard linear solid in full contact (goal 1.2x), and a
   random traction on a 4 mm pulp on bone (goal 1.5x; its first call builds the layered tables,
   ``benchmarks/bench_layered.py`` times that), and a rigid random surface sliding at 10 cm/s over
   viscoelastic layers (a dermis on a pulp on bone; goal 1.5x, its sliding tables cached per speed).
2. A time-stepped viscoelastic contact at 128^2 (isolated; a standard linear solid, tau = 50 ms):
   a sphere pressed with 0.1 N, held, then slid at 1 cm/s, ``--steps`` steps of 0.5 ms; the time
   per step against one elastic ``solve_contact`` of the same grid.
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft

from tactilab.forward import (AccuracyWarning, HalfSpace, Layer, LayeredHalfSpace, Prony, SurfaceLoad,
                              ViscoelasticHalfSpace, ViscoelasticLayeredHalfSpace, angular_wavenumbers, solve_contact,
                              solve_viscoelastic_contact)

DEPTH, SPACING = 1e-3, 1e-4
SLS = Prony.sls(1e5, 3e5, 0.05)  # Pa, Pa, s
SKIN = ViscoelasticHalfSpace(SLS)


@dataclass(frozen=True)
class FieldCase:
    """One row of the field table.

    ``build(n, rng)`` returns ``(model, elastic, check)``: the model's call, the elastic half-space's
    call on the same load (both return a FieldResult), and a function giving max |difference| / peak
    against an independent reference (the agreement column)."""

    name: str
    goal: float  # the largest acceptable median ratio model / elastic
    build: Callable


def _grating(n: int, rng) -> np.ndarray:
    """A random periodic surface of a few um (m), one period on the grid."""
    spectrum = rng.standard_normal((n, n // 2 + 1)) + 1j * rng.standard_normal((n, n // 2 + 1))
    k = np.hypot(*np.meshgrid(np.fft.rfftfreq(n), np.fft.fftfreq(n)))
    spectrum *= np.where(k > 0, k, np.inf) ** -1.8
    h = np.fft.irfft2(spectrum, s=(n, n))
    return 2e-6 * h / np.abs(h).max()


def _viscoelastic_steady(n: int, rng):
    """A rigid random surface sliding at 10 cm/s in full contact, against the elastic skin of E(0)."""
    h = _grating(n, rng)
    glassy = SKIN.instantaneous
    model = lambda: SKIN.steady_sliding(h, SPACING, 0.1, DEPTH, method="spectral")  # noqa: E731
    elastic = lambda: glassy.stress(glassy.pressure_from_deflection(h, SPACING), DEPTH, method="spectral")  # noqa: E731

    def check() -> float:  # at speed 0 the relaxed elastic skin
        ref = SKIN.relaxed.stress(SKIN.relaxed.pressure_from_deflection(h, SPACING), DEPTH, method="spectral")
        got = SKIN.steady_sliding(h, SPACING, 0.0, DEPTH, method="spectral")
        r = ref.data["stress"].values
        return float(np.abs(got.data["stress"].values - r).max() / np.abs(r).max())

    return model, elastic, check


def _layered(n: int, rng):
    """A random periodic traction (p, qx, qy) on a 4 mm pulp (0.5 MPa) on bone, against the half-space of
    the pulp's material; agreement: the pulp on a half-space of its own material is that half-space."""
    load = SurfaceLoad(p=rng.standard_normal((n, n)), qx=rng.standard_normal((n, n)),
                       qy=rng.standard_normal((n, n)), spacing=SPACING, periodic=True)
    hs = HalfSpace(0.5e6, 0.5)
    pulp = LayeredHalfSpace([Layer(4e-3, 0.5e6, 0.5)])
    model = lambda: pulp.stress(load, DEPTH)  # noqa: E731
    elastic = lambda: hs.stress(load, DEPTH, method="spectral")  # noqa: E731

    def check() -> float:
        same = LayeredHalfSpace([Layer(4e-3, 0.5e6, 0.5)], base=hs)
        ref = elastic().data["stress"].values
        return float(np.abs(same.stress(load, DEPTH).data["stress"].values - ref).max() / np.abs(ref).max())

    return model, elastic, check


def _viscoelastic_layers(n: int, rng):
    """A rigid random surface sliding at 10 cm/s over a viscoelastic dermis (1 mm) on a viscoelastic pulp
    (3 mm) on bone, in full contact, against the elastic half-space's field of the same surface;
    agreement: at speed 0 the elastic layered skin of the relaxed moduli."""
    h = _grating(n, rng)
    skin = ViscoelasticLayeredHalfSpace([Layer(1e-3, Prony(0.6e6, [(0.6e6, 2e-3)]), 0.5),
                                         Layer(3e-3, Prony(0.2e6, [(1e6, 4e-3), (0.5e6, 0.07), (0.3e6, 1.4)]), 0.5)])
    hs = HalfSpace(0.6e6, 0.5)
    model = lambda: skin.steady_sliding(h, SPACING, 0.1, DEPTH)  # noqa: E731
    elastic = lambda: hs.stress(hs.pressure_from_deflection(h, SPACING), DEPTH, method="spectral")  # noqa: E731

    def check() -> float:
        relaxed = skin.relaxed
        compliance = relaxed.surface_compliance(*angular_wavenumbers(h.shape, SPACING, half=True))[..., 0, 0]
        compliance[0, 0] = np.inf  # the mean deflection is an approach (0 compliance at nu = 1/2 on bone)
        gain = 1.0 / compliance
        p = sfft.irfft2(sfft.rfft2(h) * gain, s=h.shape)
        ref = relaxed.stress(SurfaceLoad(p=p, spacing=SPACING, periodic=True), DEPTH).data["stress"].values
        got = skin.steady_sliding(h, SPACING, 0.0, DEPTH).data["stress"].values
        return float(np.abs(got - ref).max() / np.abs(ref).max())

    return model, elastic, check


#: the field rows: (name, goal, build)
FIELD_CASES: list[FieldCase] = [
    FieldCase("viscoelastic steady sliding", 1.2, _viscoelastic_steady),
    FieldCase("layered: 4 mm pulp on bone", 1.5, _layered),
    FieldCase("viscoelastic layers sliding", 1.5, _viscoelastic_layers),
]


def interleaved(funcs: dict, repeats: int) -> dict[str, tuple[float, float]]:
    """(median, min) wall time per function, the functions run in turn within each repeat."""
    times = {name: [] for name in funcs}
    for _ in range(repeats):
        for name, f in funcs.items():
            t0 = time.perf_counter()
            f().data  # noqa: B018 (the labelled result, as a user reads it)
            times[name].append(time.perf_counter() - t0)
    return {name: (float(np.median(t)), float(np.min(t))) for name, t in times.items()}


def section_fields(sizes, repeats: int) -> None:
    print("1. skin-model fields vs the elastic half-space: stress, 1 depth, 6 components, float64, 1 FFT thread")
    print(f"{'model':>28} {'n':>5} {'elastic_ms':>11} {'model_ms':>9} {'ratio_med':>9} {'ratio_min':>9} "
          f"{'goal':>5} {'agreement':>10}")
    for case in FIELD_CASES:
        for n in sizes:
            model, elastic, check = case.build(n, np.random.default_rng(0))
            with sfft.set_workers(1):
                model().data, elastic().data  # noqa: B018 (warm-up: tables cached)
                t = interleaved({"elastic": elastic, "model": model}, repeats)
                agreement = check()
            (em, emin), (mm, mmin) = t["elastic"], t["model"]
            print(f"{case.name:>28} {n:>5} {em * 1e3:>11.1f} {mm * 1e3:>9.1f} {mm / em:>9.2f} {mmin / emin:>9.2f} "
                  f"{case.goal:>5.1f} {agreement:>10.1e}")


def section_contact(steps: int, n: int = 128) -> None:
    print(f"2. viscoelastic contact, {n}^2 isolated, SLS (E_inf 0.1 MPa, E(0) 0.3 MPa, tau 50 ms): sphere R = 10 mm, "
          f"0.1 N, held then slid at 1 cm/s, {steps} steps of 0.5 ms")
    h, R = 5e-5, 0.01
    x = (np.arange(n) - n // 2) * h
    t = np.arange(steps) * 5e-4
    slide_from = t[steps // 2]
    centre = np.where(t < slide_from, 0.0, 0.01 * (t - slide_from))

    def gap(s):
        c = float(np.interp(s, t, centre))
        return ((x[None, :] - c) ** 2 + x[:, None] ** 2) / (2 * R)

    with warnings.catch_warnings(), sfft.set_workers(1):
        warnings.simplefilter("ignore", AccuracyWarning)
        t0 = time.perf_counter()
        history = solve_viscoelastic_contact(SKIN, gap, h, t, normal_force=0.1, keep_every=None)
        total = time.perf_counter() - t0
        elastic = HalfSpace(SLS.E_0)
        solve_contact(elastic, gap(0.0), h, normal_force=0.1)
        t0 = time.perf_counter()
        for _ in range(5):
            solve_contact(elastic, gap(0.0), h, normal_force=0.1)
        one = (time.perf_counter() - t0) / 5
    print(f"{'steps':>6} {'total_s':>8} {'ms/step':>8} {'elastic_ms':>10} {'iter/step':>9} {'area0_mm2':>9} "
          f"{'area_held_mm2':>13} {'drag_mN':>8}")
    held = steps // 2 - 1
    print(f"{steps:>6} {total:>8.1f} {total / steps * 1e3:>8.1f} {one * 1e3:>10.1f} "
          f"{history.iterations.mean():>9.1f} {history.area[0] * 1e6:>9.3f} {history.area[held] * 1e6:>13.3f} "
          f"{history.tangential_force[-1, 0] * 1e3:>8.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 512])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--steps", type=int, default=1000)
    args = parser.parse_args()
    section_fields(args.sizes, args.repeats)
    section_contact(args.steps)


if __name__ == "__main__":
    main()

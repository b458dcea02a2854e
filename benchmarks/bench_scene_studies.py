"""The founding papers' studies redone with the solved contact (issue 27): defects, fingerprints, Wiener kernels.

Run: ``python benchmarks/bench_scene_studies.py`` (about 11 minutes: every frame's contact is solved);
``--quick`` for the reduced sizes the test suite uses; ``--sections a b c d`` to run part of it.

Scene: a fingertip (R = 10 mm, E = 1 MPa, nu = 1/2, friction 0.5, full sliding) over raised-cosine
bumps of 0.4 mm base diameter, sensed by one strain sensor (zz and zx) under the contact centre at
1 mm; 40 um nodes, one node per frame (40 mm/s at 1 kHz). A defect's response is the scan over it
minus the scan over a flat plate (the receptive field as a function of the finger position u).
Each study runs the exact model (``scene_signals(..., "exact")``, every frame solved) and the
modulation model of docs/theory.md 4b beside it; the studies themselves are
``tactilab.forward.scene_studies`` (the scene-models demo section runs them at a reduced size).

- (a) Shape invariance: the response to one 20 um bump at 0.5 N against those at 0.3 and 1.0 N and
  of 5 and 50 um bumps at 0.5 N: Pearson correlation over u (position frame) and over u / a
  (contact-scaled frame, a the Hertz radius), and the gain (ratio of peak |response|) per um of
  bump height.
- (b) Fingerprint band-pass: ridged skin (0.5 mm ridges standing 20 um out of the grooves, in the
  gap of the exact model; the modulation's 1 +- 1 factor) against smooth skin, both scanning a
  random +-2 um grating of one-node bars at 0.1 m/s: the sensor's Welch spectrum, its peak above
  40 Hz and the ridged / smooth ratio at v / lambda = 200 Hz.
- (c) First-order Wiener kernel: random +-A gratings of one-node bits scanned one bit per frame,
  the kernel per um of A (``wiener_kernel``) against the linear model's kernel at the smallest A
  (the same input sequence, so the estimation's leakage is common to both): the relative L2 error
  and 1 - correlation, as A (the texture's depth) grows.
- (d) Interaction: two bumps (20 and 50 um) at separation s along the scan; the superposition error
  max |r_pair - r_1 - r_2| / max |r_pair| per component, r_2 being r_1 moved by s (the scan is
  translation invariant: the same bump s later).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings

from tactilab.forward import (AccuracyWarning, defect_response, fingerprint_band_pass, kernel_error,
                              receptive_field_change, superposition_error, wiener_kernels)
from tactilab.forward.scene_studies import bump, contact_radius


def section_a(quick: bool, spacing: float) -> dict:
    reach = 2.4e-3 if quick else 3.2e-3
    forces, heights = ((0.3, 1.0), (5e-6, 50e-6)) if not quick else ((0.3,), (50e-6,))
    rows = {}
    print("\n(a) shape invariance of a bump's receptive field (sensor under the centre at 1 mm)")
    print("| model | change | a (mm) | zz corr (position / contact-scaled) | zx corr (position / contact-scaled) "
          "| gain per um (zz) |")
    print("|---|---|---|---|---|---|")
    for model in ("exact", "modulation"):
        t0 = time.perf_counter()
        reference = defect_response(bump(20e-6), 0.5, model, -reach, reach, spacing)
        cases = [("force", f, 20e-6) for f in forces] + [("height", 0.5, h) for h in heights]
        for kind, force, height in cases:
            corr, gain = receptive_field_change(model, force, height, reach, spacing, reference=reference)
            change = f"{'F = ' + format(force, 'g') + ' N' if kind == 'force' else 'h = ' + format(height * 1e6, 'g') + ' um'}"
            rows[(model, kind, force, height)] = corr, gain
            print(f"| {model} | {change} | {contact_radius(force) * 1e3:.2f} | {corr[0][0]:.4f} / {corr[0][1]:.4f} | "
                  f"{corr[1][0]:.4f} / {corr[1][1]:.4f} | {gain:.2f} |")
        print(f"({model}: {time.perf_counter() - t0:.0f} s)")
    print("reference: F = 0.5 N, h = 20 um; gain = (peak |zz| per um of height) / the reference's")
    return rows


def section_d(quick: bool, spacing: float) -> dict:
    reach = 2.4e-3 if quick else 3.2e-3
    separations = (1.2e-3, 0.4e-3) if quick else (2.4e-3, 1.2e-3, 0.8e-3, 0.4e-3)
    heights = (20e-6,) if quick else (20e-6, 50e-6)
    rows = {}
    print("\n(d) two bumps at separation s: the superposition error of their single responses")
    print("| model | h (um) | s (mm) | zz: max \\|r_pair - r_1 - r_2\\| / max \\|r_pair\\| | zx: the same |")
    print("|---|---|---|---|---|")
    for model in ("exact", "modulation"):
        t0 = time.perf_counter()
        for height in heights:
            for s, err in superposition_error(model, height, separations, reach, spacing).items():
                rows[(model, height, s)] = err
                print(f"| {model} | {height * 1e6:g} | {s * 1e3:g} | {err[0]:.3g} | {err[1]:.3g} |")
        print(f"({model}: {time.perf_counter() - t0:.0f} s)")
    return rows


def section_b(quick: bool) -> dict:
    """Fingerprint ridges (0.5 mm, 20 um) scanning a random fine texture: the sensor spectrum's peak at v / lambda."""
    spacing, rate = (50e-6, 2000.0) if quick else (25e-6, 4000.0)
    frames, force = (256, 0.2) if quick else (1024, 0.5)
    rows = {}
    print(f"\n(b) fingerprint band-pass: ridges 0.5 mm x 20 um, random {spacing * 1e6:g} um bars of +-2 um, v = "
          f"{spacing * rate * 1e3:g} mm/s, {frames} frames at {rate:g} Hz, F = {force:g} N (zz)")
    print("| model | PSD peak above 40 Hz, ridged (Hz) | PSD ridged / smooth at v / lambda | smooth: PSD at v / lambda "
          "/ its peak |")
    print("|---|---|---|---|")
    for model in ("exact", "modulation"):
        t0 = time.perf_counter()
        out = fingerprint_band_pass(model, spacing, rate, frames, force)
        rows[model] = out["peak"], out["ratio"], out["resolution"]
        print(f"| {model} | {out['peak']:.0f} (bin {out['resolution']:.1f} Hz) | {out['ratio']:.3g} | "
              f"{out['smooth']:.3g} |")
        print(f"({model}: {time.perf_counter() - t0:.0f} s)")
    return rows


def section_c(quick: bool) -> dict:
    """The first-order Wiener kernel from random gratings on the solved contact, against the linear kernel."""
    spacing = 80e-6 if quick else 50e-6
    n_bits = 256 if quick else 1024
    amplitudes = (1e-6, 20e-6) if quick else (1e-6, 5e-6, 20e-6, 50e-6)
    rows = {}
    print(f"\n(c) Wiener kernel (zz) from a random +-A grating of {spacing * 1e6:g} um bits, {n_bits} frames, "
          "against the linear model's kernel at the smallest A")
    print("| A (um) | exact: rel. L2 error per um vs linear kernel | exact: 1 - corr | exact: gain per um | "
          "linear model: rel. error | modulation: rel. error |")
    print("|---|---|---|---|---|---|")
    t0 = time.perf_counter()
    kernels = wiener_kernels(amplitudes, spacing, n_bits)
    reference = kernels[("linear", amplitudes[0])]
    modulation = kernels[("modulation", amplitudes[0])]
    best = float(modulation @ reference / (modulation @ modulation))  # the modulation has no modulus: best gain
    for amplitude in amplitudes:
        exact = kernel_error(kernels[("exact", amplitude)], reference)
        lin = kernel_error(kernels[("linear", amplitude)], reference)["error"]
        mod = kernel_error(best * modulation, reference)["error"]
        rows[amplitude] = exact["error"], exact["one_minus_corr"], lin, mod, exact["gain"]
        print(f"| {amplitude * 1e6:g} | {exact['error']:.3g} | {exact['one_minus_corr']:.3g} | {exact['gain']:.3g} | "
              f"{lin:.3g} | {mod:.3g} (best gain) |")
    print(f"({time.perf_counter() - t0:.0f} s)")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="reduced sizes (the test suite's)")
    parser.add_argument("--sections", nargs="+", choices=("a", "b", "c", "d"), default=("a", "b", "c", "d"))
    args = parser.parse_args(argv)
    spacing = 80e-6 if args.quick else 40e-6
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        for name in args.sections:
            if name in "ad":
                {"a": section_a, "d": section_d}[name](args.quick, spacing)
            else:
                {"b": section_b, "c": section_c}[name](args.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())

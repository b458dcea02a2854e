"""Measured figures of the biomimetic-finger studies (docs/scenes.md), all from one run.

- Hertz contact sizes for the ranges of docs/theory.md 4b (0.5-1 N, E 1-4 MPa) and two finger radii.
- Shape invariance tables (sigma_zz and sigma_zx sensors at Z = 3 mm; sigma_zz at Z = 1 mm).
- First-order Wiener kernel: error vs record length (mean of repeats), time per identification.
- Fingerprint band-pass: spectral peak frequency vs v / lambda for several speeds and periods.

Run:  python benchmarks/bench_finger_studies.py [--seed N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from tactilab.data_schemas.sensors import SensorArray
from tactilab.forward.contact import HertzContact
from tactilab.forward.exploration import BASELINE, kernel_identification, shape_invariance, texture_spectrum
from tactilab.forward.finger import BiomimeticFinger, Fingerprint


def table(df, columns, fmt) -> None:
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * len(columns))
    for _, row in df.iterrows():
        print("| " + " | ".join(fmt.get(c, "{}").format(row[c]) for c in columns) + " |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=20261122)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)

    print("## Hertz contact (nu = 0.5)")
    print("| F (N) | E (MPa) | R (mm) | contact diameter (mm) | p0 (kPa) |")
    print("|---|---|---|---|---|")
    for R in (0.01, 0.1):
        for E in (1e6, 2e6, 4e6):
            for F in (0.5, 1.0):
                c = HertzContact(F, R, E, 0.5)
                print(f"| {F:g} | {E / 1e6:g} | {R * 1e3:g} | {2e3 * c.contact_radius:.2f} | {c.peak_pressure / 1e3:.1f} |")

    fmt = {"baseline": "{:.4g}", "value": "{:.4g}", "corr_position": "{:.4f}", "corr_contact_scaled": "{:.4f}",
           "gain": "{:.3f}"}
    cols = ["parameter", "baseline", "value", "corr_position", "corr_contact_scaled", "gain"]
    for comp in ("zz", "zx"):
        print(f"\n## Shape invariance, sigma_{comp} sensor under the contact centre, Z = 3 mm")
        table(shape_invariance(component=comp), cols, fmt)
    print("\n## Shape invariance, sigma_zz sensor, Z = 1 mm (shallow: a = 2.8 mm >> Z)")
    shallow = dict(normal_force=(0.5, 1.0), depth=(0.8e-3, 1.2e-3), y_offset=(0.5e-3, 1.0e-3),
                   finger_radius=(0.07, 0.14), sensor_x=(1.0e-3, 2.0e-3), friction=(0.0, 1.0))
    table(shape_invariance(dict(BASELINE, depth=1e-3), shallow), cols, fmt)

    print("\n## First-order Wiener kernel vs record length (sigma_zz at centre, bits = grid = 0.1 mm, 4 repeats)")
    sensors = SensorArray(positions_m=[[0.0, 0.0]], depth_m=3e-3, components=("zz",))
    finger = BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, grid_spacing=0.1e-3)
    t0 = time.perf_counter()
    wk = kernel_identification(finger, rng, bit_length=0.1e-3, record_lengths=(256, 1024, 4096, 16384, 65536),
                               repeats=4)
    elapsed = time.perf_counter() - t0
    table(wk, ["bits", "record_m", "error_binned", "error_binned_std", "error_continuous"],
          {"bits": "{:.0f}", "record_m": "{:.4g}", "error_binned": "{:.4f}", "error_binned_std": "{:.4f}", "error_continuous": "{:.4f}"})
    print(f"(total {elapsed:.1f} s for {4 * sum(wk['bits'])} scanned frames)")

    print("\n## Fingerprint band-pass: PSD peak of sigma_zz scanning a random 25 um texture")
    print("| lambda (mm) | v (mm/s) | v / lambda (Hz) | peak (Hz) | PSD ratio ridged / smooth at v / lambda |")
    print("|---|---|---|---|---|")
    for lam, v in ((0.5e-3, 0.1), (0.5e-3, 0.05), (0.4e-3, 0.1)):
        spectra = []
        seed = int(rng.integers(1 << 30))
        for fp in (Fingerprint(lam), None):
            f = BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, fingerprint=fp, grid_spacing=0.025e-3)
            spectra.append(texture_spectrum(f, np.random.default_rng(seed), speed=v, sampling_rate=4000.0,
                                            duration=0.5, bit_length=0.025e-3))
        fr, ridged = spectra[0]
        band = fr > 30
        at = np.argmin(np.abs(fr - v / lam))
        print(f"| {lam * 1e3:g} | {v * 1e3:g} | {v / lam:g} | {fr[band][np.argmax(ridged[band])]:g} | "
              f"{ridged[at] / spectra[1][1][at]:.3g} |")


if __name__ == "__main__":
    main()

"""Demo section: a biomimetic finger scanning a surface with one small defect (docs/theory.md 4b).

The scene: an elastomer fingertip (E = 2 MPa, nu = 0.5, radius 100 mm) pressed at 0.8 N
(Hertz contact 5.6 mm across) slides with mu = 0.5 at 20 mm/s over a 0.3 mm, 30 µm bump;
a 5 x 5 array of stress sensors 3 mm deep records sigma_zz and sigma_zx at 1 kHz. The demo
writes the recording, the field maps, the receptive fields and the time series, checks the
point-defect receptive field against a full forward solve, prints the shape-invariance
table (which exploration parameters change the SHAPE of a sensor's defect response), plots the
fingerprint band-pass (ridged vs smooth skin) and identifies the first-order Wiener kernel.
"""

from __future__ import annotations

import pathlib
from collections.abc import Iterator

import numpy as np

from tactilab.data_schemas import Contact, IsolatedDefect, Scan, Scene, SensorArray, SkinMaterial
from tactilab.forward import (BiomimeticFinger, Fingerprint, HalfSpace, HertzContact, RecordFeature, SurfaceLoad,
                              kernel_identification, plot_fingerprint_spectra, plot_wiener_kernels, scene_finger,
                              shape_invariance, simulate_scene, texture_spectrum)


def demo_scene() -> Scene:
    """The demo's finger scene (SI)."""
    return Scene(
        name="finger_defect_demo",
        description="biomimetic finger sliding over one 0.3 mm, 30 µm bump",
        material=SkinMaterial(young_modulus_pa=2e6, poisson_ratio=0.5, name="elastomer fingertip"),
        surface=IsolatedDefect(shape="bump", size_m=0.3e-3, height_m=30e-6, position_m=(0.0, 0.0)),
        contact=Contact(normal_force_n=0.8, finger_radius_m=0.1, friction_coefficient=0.5, model="modulation"),
        sensors=SensorArray.grid(5, 5, 1.0e-3, 3e-3, components=("zz", "zx"), noise_std=5.0),
        scan=Scan(speed_m_per_s=0.02, duration_s=0.5, sampling_rate_hz=1000.0, start_position_m=-5e-3),
    )


def receptive_field_check(scene: Scene, positions=(-1.5e-3, 0.0, 1.0e-3)) -> float:
    """Largest difference (relative to the RF peak) between the point-defect receptive field and a
    brute-force forward solve (HalfSpace.stress of the full contact load with and without the bump)."""
    finger = scene_finger(scene)
    x, y = finger.grid()
    X, Y = np.meshgrid(x, y)
    h = finger.spacing
    p, q = finger.traction(X, Y, cell=(h, h))
    d = scene.surface
    bump = RecordFeature(d.replace(height_m=1.0))  # unit height: the modulation is h / h_ref
    hs = HalfSpace(finger.contact.young_modulus, finger.contact.poisson_ratio)
    pts, comps = finger.sensors.positions_m, finger.sensors.components
    base = hs.stress(SurfaceLoad(p=p, qx=q, spacing=h), finger.depth, points=pts, components=comps).data["stress"]
    worst, peak = 0.0, 0.0
    for u in positions:
        m = 1 + bump.height(X + u, Y)
        full = hs.stress(SurfaceLoad(p=p * m, qx=q * m, spacing=h), finger.depth, points=pts, components=comps)
        brute = (full.data["stress"] - base).values[0].T
        rf = finger.receptive_field([u], d.position_m[0], d.position_m[1], strength=bump.integral())[0]
        worst, peak = max(worst, float(np.abs(brute - rf).max())), max(peak, float(np.abs(rf).max()))
    return worst / peak


def run_demo(report_dir: pathlib.Path, progress: bool = True) -> Iterator[str]:
    """Run the finger-scan demo, writing into ``report_dir / "finger_scan"``; yield report lines."""
    out = pathlib.Path(report_dir) / "finger_scan"
    scene = demo_scene()
    yield "== biomimetic finger scanning a small defect (docs/theory.md 4b) =="
    yield from simulate_scene(scene, out, rng=np.random.default_rng(20261122), progress=progress)
    err = receptive_field_check(scene)
    yield (f"receptive field (interfacial stress x point-load response) vs full forward solve with the "
           f"bump: max difference {100 * err:.2f} % of the peak")
    table = shape_invariance()
    table.to_csv(out / "shape_invariance.csv", index=False)
    best = table.assign(best=table[["corr_position", "corr_contact_scaled"]].max(axis=1))
    worst = best.groupby("parameter")["best"].min()
    keep = ", ".join(f"{k} {v:.4f}" for k, v in worst.items() if k not in ("sensor_x", "friction"))
    yield ("shape invariance of a sigma_zz sensor's defect response (min normalised correlation, "
           f"best of position / contact-scaled frame): scale-only {keep}")
    yield (f"  shape changers: sensor position {worst['sensor_x']:.3f}, friction {worst['friction']:.4f} "
           f"(weak at this depth); table: {out / 'shape_invariance.csv'}")
    yield from _fingerprint_and_kernel(out)


def _fingerprint_and_kernel(out: pathlib.Path) -> Iterator[str]:
    """Fingerprint band-pass and first-order Wiener kernel identification, one sensor at 3 mm."""
    sensor = SensorArray(positions_m=[[0.0, 0.0]], depth_m=3e-3, components=("zz",))
    speed, period = 0.1, 0.5e-3
    spectra = {}
    for label, fp in (("ridged", Fingerprint(period)), ("smooth", None)):
        finger = BiomimeticFinger(HertzContact(0.8), sensor, friction=0.5, fingerprint=fp, grid_spacing=0.05e-3)
        spectra[label] = texture_spectrum(finger, np.random.default_rng(7), speed=speed, sampling_rate=2000.0,
                                          duration=0.5, bit_length=0.05e-3)
    freqs, ridged = spectra["ridged"]
    band = freqs > 30
    peak = float(freqs[band][np.argmax(ridged[band])])
    fig = plot_fingerprint_spectra(freqs, ridged, spectra["smooth"][1], speed / period, out / "fingerprint_spectrum.png")
    yield (f"fingerprint (lambda = {period * 1e3:g} mm, v = {speed * 1e3:g} mm/s over a random 50 µm texture): "
           f"spectral peak at {peak:g} Hz, v / lambda = {speed / period:g} Hz; plot {fig}")
    finger = BiomimeticFinger(HertzContact(0.8), sensor, friction=0.5, grid_spacing=0.1e-3)
    table = kernel_identification(finger, np.random.default_rng(8), bit_length=0.1e-3,
                                  record_lengths=(1024, 16384), repeats=4)
    est = {f"estimate, {n} bits ({n * 0.1:g} mm)": k for n, k in table.attrs["estimates"].items()}
    fig = plot_wiener_kernels(table.attrs["lags_m"], table.attrs["true_kernel"], est, out / "wiener_kernel.png")
    errs = ", ".join(f"{int(r.bits)} bits {100 * r.error_binned:.1f} +- {100 * r.error_binned_std:.1f} %"
                     for r in table.itertuples())
    yield (f"first-order Wiener kernel from random square-wave gratings: relative error (mean +- sd of 4 "
           f"gratings) {errs}; plot {fig}")

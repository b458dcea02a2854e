"""The founding papers' studies redone with the solved contact (issue 27): defects, fingerprints, Wiener kernels.

Run: ``python benchmarks/bench_scene_studies.py`` (about 11 minutes: every frame's contact is solved);
``--quick`` for the reduced sizes the test suite uses; ``--sections a b c d`` to run part of it.

Scene: a fingertip (R = 10 mm, E = 1 MPa, nu = 1/2, friction 0.5, full sliding) over raised-cosine
bumps of 0.4 mm base diameter, sensed by one strain sensor (zz and zx) under the contact centre at
1 mm; 40 um nodes, one node per frame (40 mm/s at 1 kHz). A defect's response is the scan over it
minus the scan over a flat plate (the receptive field as a function of the finger position u).
Each study runs the exact model (``scene_signals(..., "exact")``, every frame solved) and the
modulation model of docs/theory.md 4b beside it.

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

import numpy as np

from scipy.signal import welch

from tactilab.data_schemas import (FlatSurface, HeightMap, IsolatedDefect, Scene, SensorArray, SkinMaterial,
                                   SquareWaveGrating)
from tactilab.data_schemas.scene import Contact, Scan
from tactilab.forward import AccuracyWarning, HertzContact, wiener_kernel
from tactilab.forward.scene_models import scene_signals

E_PA, NU, RADIUS, MU = 1e6, 0.5, 0.01, 0.5
SPEED, RATE = 0.04, 1000.0  # one 40 um node per frame
BUMP = 0.4e-3
COMPONENTS = ("zz", "zx")


def scene(surface, force: float, model: str, start: float, stop: float, *, speed: float = SPEED,
          rate: float = RATE, ridges: tuple[float, float] | None = None) -> Scene:
    """A finger scan from ``start`` to ``stop`` (m, contact centre) over ``surface``; ``ridges`` (period, height) in m."""
    duration = max((stop - start) / speed, 1 / rate)
    period, height = (None, None) if ridges is None else ridges
    return Scene(material=SkinMaterial(young_modulus_pa=E_PA, poisson_ratio=NU), surface=surface,
                 contact=Contact(normal_force_n=force, finger_radius_m=RADIUS, friction_coefficient=MU, model=model,
                                 fingerprint_period_m=period, fingerprint_height_m=height),
                 sensors=SensorArray(positions_m=[[0.0, 0.0]], depth_m=1e-3, quantity="strain", components=COMPONENTS),
                 scan=Scan(speed_m_per_s=speed, duration_s=duration, sampling_rate_hz=rate, start_position_m=start))


def response(surface, force: float, model: str, start: float, stop: float, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """(u, defect response (n_frames, component)): the scan over ``surface`` minus the scan over a flat plate."""
    values, info = scene_signals(scene(surface, force, model, start, stop), model, grid_spacing=spacing)
    flat, _ = scene_signals(scene(FlatSurface(), force, model, 0.0, 0.0), model, grid_spacing=spacing)
    u = info["frames"].positions
    return u, values[:, 0, :] - flat[0, 0, :]


def bump(height: float, x0: float = 0.0) -> IsolatedDefect:
    return IsolatedDefect(shape="bump", size_m=BUMP, height_m=height, position_m=(x0, 0.0))


def two_bumps(height: float, separation: float, spacing: float) -> HeightMap:
    """Two bumps at x = 0 and x = separation, sampled on a map of ``spacing`` / 4 (exact at the finger's nodes)."""
    step = spacing / 4
    x = np.arange(-BUMP, separation + BUMP + step, step)
    y = np.arange(-BUMP, BUMP + step, step)
    X, Y = np.meshgrid(x, y)
    h = bump(height).height_at(X, Y) + bump(height, separation).height_at(X, Y)
    return HeightMap(heights_m=h, spacing_x_m=step, spacing_y_m=step, origin_m=(float(x[0]), float(y[0])))


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    return float(a @ b / np.sqrt((a @ a) * (b @ b)))


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
        u, ref = response(bump(20e-6), 0.5, model, -reach, reach, spacing)
        a_ref = HertzContact(0.5, finger_radius=RADIUS, young_modulus=E_PA, poisson_ratio=NU).contact_radius
        cases = [("force", f, 20e-6) for f in forces] + [("height", 0.5, h) for h in heights]
        for kind, force, height in cases:
            _, r = response(bump(height), force, model, -reach, reach, spacing)
            a = HertzContact(force, finger_radius=RADIUS, young_modulus=E_PA, poisson_ratio=NU).contact_radius
            scaled = np.linspace(-reach / a_ref, reach / a_ref, 400) * min(1.0, a_ref / a)  # inside both scans
            corr = []
            for c in range(len(COMPONENTS)):
                pos = correlation(r[:, c], ref[:, c])
                con = correlation(np.interp(scaled, u / a, r[:, c]), np.interp(scaled, u / a_ref, ref[:, c]))
                corr.append((pos, con))
            gain = (np.abs(r[:, 0]).max() / (height * 1e6)) / (np.abs(ref[:, 0]).max() / 20)
            change = f"{'F = ' + format(force, 'g') + ' N' if kind == 'force' else 'h = ' + format(height * 1e6, 'g') + ' um'}"
            rows[(model, kind, force, height)] = corr, gain
            print(f"| {model} | {change} | {a * 1e3:.2f} | {corr[0][0]:.4f} / {corr[0][1]:.4f} | "
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
        top = max(separations)
        for height in heights:
            u, single = response(bump(height), 0.5, model, -reach, reach + top, spacing)
            for s in separations:
                _, pair = response(two_bumps(height, s, spacing), 0.5, model, -reach, reach + top, spacing)
                shift = int(round(s / (SPEED / RATE)))
                moved = np.zeros_like(single)
                moved[shift:] = single[:single.shape[0] - shift]  # the second bump, s later
                err = np.abs(pair - single - moved).max(axis=0) / np.abs(pair).max(axis=0)
                rows[(model, height, s)] = err
                print(f"| {model} | {height * 1e6:g} | {s * 1e3:g} | {err[0]:.3g} | {err[1]:.3g} |")
        print(f"({model}: {time.perf_counter() - t0:.0f} s)")
    return rows


def random_grating(bit: float, amplitude: float, n_bits: int, start: float, seed: int) -> SquareWaveGrating:
    return SquareWaveGrating(pattern="random", element_width_m=bit, amplitude_m=amplitude, length_m=n_bits * bit,
                             start_m=start, seed=seed)


def section_b(quick: bool) -> dict:
    """Fingerprint ridges (0.5 mm, 20 um) scanning a random fine texture: the sensor spectrum's peak at v / lambda."""
    spacing, rate = (50e-6, 2000.0) if quick else (25e-6, 4000.0)
    speed, period = spacing * rate, 0.5e-3  # 0.1 m/s, one node per frame: v / lambda = 200 Hz
    frames, force = (256, 0.2) if quick else (1024, 0.5)
    reach = 1.6 * HertzContact(force, finger_radius=RADIUS, young_modulus=E_PA).contact_radius
    length = frames * spacing
    texture = random_grating(spacing, 2e-6, int(np.ceil((length + 2 * reach) / spacing)) + 2, -reach - spacing, 5)
    rows = {}
    print(f"\n(b) fingerprint band-pass: ridges 0.5 mm x 20 um, random {spacing * 1e6:g} um bars of +-2 um, v = "
          f"{speed * 1e3:g} mm/s, {frames} frames at {rate:g} Hz, F = {force:g} N (zz)")
    print("| model | PSD peak above 40 Hz, ridged (Hz) | PSD ridged / smooth at v / lambda | smooth: PSD at v / lambda "
          "/ its peak |")
    print("|---|---|---|---|")
    for model in ("exact", "modulation"):
        t0 = time.perf_counter()
        psd = {}
        for ridged in (True, False):
            values, info = scene_signals(scene(texture, force, model, 0.0, length, speed=speed, rate=rate,
                                               ridges=(period, 20e-6) if ridged else None), model,
                                         grid_spacing=spacing)
            f, psd[ridged] = welch(values[:, 0, 0], fs=rate, nperseg=frames // 4)
        band = f > 40.0  # above the contact's own low-pass envelope
        peak = float(f[band][np.argmax(psd[True][band])])
        at = int(np.argmin(np.abs(f - speed / period)))
        ratio = float(psd[True][at] / psd[False][at])
        smooth = float(psd[False][at] / psd[False][band].max())
        rows[model] = peak, ratio, f[1] - f[0]
        print(f"| {model} | {peak:.0f} (bin {f[1] - f[0]:.1f} Hz) | {ratio:.3g} | {smooth:.3g} |")
        print(f"({model}: {time.perf_counter() - t0:.0f} s)")
    return rows


def section_c(quick: bool) -> dict:
    """The first-order Wiener kernel from random gratings on the solved contact, against the linear kernel."""
    spacing = 80e-6 if quick else 50e-6
    n_bits = 256 if quick else 1024
    amplitudes = (1e-6, 20e-6) if quick else (1e-6, 5e-6, 20e-6, 50e-6)
    speed, max_lag = spacing * RATE, int(round(3.5e-3 / spacing))
    reach = 1.6 * HertzContact(0.5, finger_radius=RADIUS, young_modulus=E_PA).contact_radius
    pad = int(np.ceil(reach / spacing)) + 2
    rows = {}
    print(f"\n(c) Wiener kernel (zz) from a random +-A grating of {spacing * 1e6:g} um bits, {n_bits} frames, "
          "against the linear model's kernel at the smallest A")
    print("| A (um) | exact: rel. L2 error per um vs linear kernel | exact: 1 - corr | exact: gain per um | "
          "linear model: rel. error | modulation: rel. error |")
    print("|---|---|---|---|---|---|")
    kernels = {}
    t0 = time.perf_counter()
    for amplitude in amplitudes:
        texture = random_grating(spacing, amplitude, n_bits + 2 * pad, -pad * spacing, 7)
        bits = texture.signs()[pad:pad + n_bits]  # the bit under the contact centre at each frame
        for model in ("exact", "linear", "modulation"):
            if model == "modulation" and amplitude != amplitudes[0]:
                continue  # h / h_ref: the same record at every amplitude
            values, _ = scene_signals(scene(texture, 0.5, model, 0.5 * spacing, (n_bits + 0.5) * spacing, speed=speed),
                                      model, grid_spacing=spacing)
            kernels[(model, amplitude)] = wiener_kernel(bits, values[:, 0, 0], max_lag) / (amplitude * 1e6)
    reference = kernels[("linear", amplitudes[0])]
    scale = float(np.linalg.norm(reference))
    modulation = kernels[("modulation", amplitudes[0])]
    best = float(modulation @ reference / (modulation @ modulation))  # the modulation has no modulus: best gain
    for amplitude in amplitudes:
        k = kernels[("exact", amplitude)]
        err = float(np.linalg.norm(k - reference)) / scale
        corr = correlation(k, reference)
        lin = float(np.linalg.norm(kernels[("linear", amplitude)] - reference)) / scale
        mod = float(np.linalg.norm(best * modulation - reference)) / scale
        gain = float(k @ reference) / scale**2  # the least-squares factor k ~ gain * reference
        rows[amplitude] = err, 1 - corr, lin, mod, gain
        print(f"| {amplitude * 1e6:g} | {err:.3g} | {1 - corr:.3g} | {gain:.3g} | {lin:.3g} | {mod:.3g} (best gain) |")
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

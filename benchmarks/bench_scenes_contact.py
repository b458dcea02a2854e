"""Benchmark of a scene scanned through the solved contact: the exact model's time, the linear model's.

Run: ``python benchmarks/bench_scenes_contact.py [--frames 1000] [--cold-frames 100] [--quick] [--auto-table]``
(``--quick``: 128^2 nodes of 40 um, 40 frames, to check the harness in seconds). One thread (OMP/BLAS 1,
``scipy.fft`` workers 1), float64, SI.

The scene (docs/scenes.md, "Benchmark"): a fingertip (R = 10 mm, 0.5 N, E = 1 MPa, nu = 1/2,
mu = 0.5) sliding towards +x over a fixed random rough plate (self-affine, rms height 5 um, Hurst
0.8, cut-offs 2 mm and 40 um, seed 1, periodic over the strip the scan crosses) on a 256^2 grid of
20 um nodes, one node per frame, full sliding (the plate drags the skin towards -x); six strain
components at 25 sensors (5 x 5, 0.5 mm pitch) at each of 0.5, 1 and 2 mm depth, read every frame.

- exact: :func:`tactilab.forward.solve_scan`, warm-started (the previous frame moved one node with
  the plate), sensors by one weight matrix (built once, inside the timing);
- cold: the same solves without warm start on the first ``--cold-frames`` frames (iterations);
- linear: the Hertz pressure plus the plate's full-contact pressure ``E* |k| H~ / 2`` inside the
  Hertz disc, clipped at 0 (the plate's pressure by one FFT of the strip), the same readout;
- the linear model's error against the exact one, the scene's measure (max over the scan of |error|
  / max |signal| per sensor and component), per depth.

``--auto-table`` instead prints what ``"auto"`` estimates on Westergaard's sinusoid (a periodic cell,
A = 2 um, L = 1 mm, E = 1 MPa, nu = 1/2, mu = 0.3, strain zz, zx, xx at three sensors 0.3 mm deep, 20
frames, tol 1e-2) against the cheap models' true errors (the exact scan), for p_bar / p* 0.05 to 2.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from tactilab.data_schemas import SensorArray, random_rough_surface  # noqa: E402
from tactilab.forward import (HalfSpace, HertzContact, SensorReadout, finger_gap,  # noqa: E402
                              pressure_from_deflection, signal_error, solve_scan)

E_PA, NU, FORCE, RADIUS, MU = 1e6, 0.5, 0.5, 10e-3, 0.5
E_STAR = E_PA / (1 - NU**2)
DEPTHS = (0.5e-3, 1e-3, 2e-3)
DIRECTION = (-1.0, 0.0)  # the traction on the skin of a finger sliding towards +x over a fixed plate


def _scene(n: int, frames: int, spacing: float):
    plate = random_rough_surface((n, n + frames), spacing, rms_height=5e-6, hurst=0.8, long_cutoff=2e-3,
                                 short_cutoff=max(40e-6, 2 * spacing), rng=np.random.default_rng(1))
    g0 = finger_gap((n, n), spacing, RADIUS)
    arrays = [SensorArray.grid(5, 5, 0.5e-3, z, quantity="strain",
                               components=("xx", "yy", "zz", "yz", "zx", "xy")) for z in DEPTHS]
    return plate, g0, arrays


def _linear(skin, plate, g0, arrays, n, frames, spacing, batch=64):
    t0 = time.perf_counter()
    x = (np.arange(n) - n // 2) * spacing
    X, Y = np.meshgrid(x, x)
    p_hertz = HertzContact(FORCE, RADIUS, E_PA, NU).pressure(X, Y)
    inside = p_hertz > 0
    p_plate = pressure_from_deflection(plate, spacing, E_PA, NU).p  # E* |k| H~ / 2: the strip is one period
    half = int(np.count_nonzero(inside[n // 2]) // 2) + 8
    window = (slice(max(0, n // 2 - half), min(n, n // 2 + half)),) * 2
    readout = SensorReadout(skin, (n, n), spacing, arrays, window=window, loads=("p", "qx", "qy"),
                            sliding=(MU, DIRECTION))
    out = np.empty((frames, readout.n_outputs))
    for i0 in range(0, frames, batch):
        idx = range(i0, min(frames, i0 + batch))
        p = np.stack([np.where(inside, np.maximum(p_hertz + p_plate[:, i:i + n], 0.0), 0.0) for i in idx])
        out[i0:i0 + len(idx)] = readout.apply(readout.stack(p))
    return readout.split(out), time.perf_counter() - t0


def auto_table() -> None:
    """What auto estimates against the true errors on a periodic sinusoid (docs/scenes.md)."""
    import math

    from tactilab.data_schemas import Contact, Scan, Scene, SinusoidalGrating, SkinMaterial
    from tactilab.forward import SceneFrames, choose_model, run_model

    length, amplitude = 1e-3, 2e-6
    p_star = math.pi * E_STAR * amplitude / length
    sensors = SensorArray(positions_m=[[0, 0], [0.25e-3, 0], [-0.1e-3, 0]], depth_m=0.3e-3, quantity="strain",
                          components=("zz", "zx", "xx"))
    print("| p_bar/p* | chosen | linear: a priori | measured (3 frames) | reported | true "
          "| modulation: a priori | measured | reported | true |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for ratio in (0.05, 0.1, 0.3, 0.5, 0.9, 1.0, 1.5, 2.0):
        scene = Scene(material=SkinMaterial(young_modulus_pa=E_PA, poisson_ratio=NU),
                      surface=SinusoidalGrating(period_m=length, amplitude_m=amplitude, phase_rad=0.3),
                      contact=Contact(mean_pressure_pa=ratio * p_star, friction_coefficient=0.3), sensors=sensors,
                      scan=Scan(speed_m_per_s=0.01, duration_s=0.01, sampling_rate_hz=2000))
        frames = SceneFrames.from_scene(scene)
        choice = choose_model(frames, 1e-2)
        exact = run_model(frames, "exact").values
        true = {m: signal_error(run_model(frames, m).values, exact) for m in ("linear", "modulation")}
        print(f"| {ratio:g} | {choice.model} | " + " | ".join(
            f"{choice.apriori[m]:.2g} | {choice.aposteriori[m]:.2g} | {choice.errors[m]:.2g} | {true[m]:.2g}"
            for m in ("linear", "modulation")) + " |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000, help="frames of the scan (count)")
    parser.add_argument("--cold-frames", type=int, default=100, help="frames solved cold for the iteration count")
    parser.add_argument("--n", type=int, default=256, help="nodes per axis")
    parser.add_argument("--quick", action="store_true", help="128^2 nodes, 40 frames")
    parser.add_argument("--contact-tol", type=float, default=1e-6,
                        help="solve_contact's relative gap residual (default 1e-6: what a scene at tol 1e-2 uses)")
    parser.add_argument("--auto-table", action="store_true", help="what auto estimates on a periodic sinusoid")
    args = parser.parse_args(argv)
    if args.auto_table:
        auto_table()
        return 0
    n, frames, cold_frames = (128, 40, 10) if args.quick else (args.n, args.frames, args.cold_frames)
    spacing = 40e-6 if args.quick else 20e-6  # the grid spans 5.12 mm either way
    skin = HalfSpace(E=E_PA, nu=NU)
    load0 = os.getloadavg()
    print(f"bench_scenes_contact: {os.cpu_count()} CPUs, load average {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}, "
          f"numpy {np.__version__}, one thread; {n}^2 nodes of {spacing * 1e6:g} um, {frames} frames, contact tol "
          f"{args.contact_tol:g}")
    plate, g0, arrays = _scene(n, frames, spacing)
    gap = lambda i: g0 - plate[:, i:i + n]  # noqa: E731  (frame i: the plate moved i nodes towards -x)
    cpu0, t0 = time.process_time(), time.perf_counter()
    warm = solve_scan(skin, gap, spacing, n_frames=frames, normal_force=FORCE, friction=MU, slide_direction=DIRECTION,
                      shifts=-1, sensors=arrays, keep_tractions=False, tol=args.contact_tol)
    t_exact, cpu_exact = time.perf_counter() - t0, time.process_time() - cpu0
    t0 = time.perf_counter()
    cold = solve_scan(skin, gap, spacing, n_frames=cold_frames, normal_force=FORCE, friction=MU,
                      slide_direction=DIRECTION, warm_start=False, keep_tractions=False, tol=args.contact_tol)
    t_cold = time.perf_counter() - t0
    linear, t_linear = _linear(skin, plate, g0, arrays, n, frames, spacing)
    errors = [signal_error(lin, ex) for lin, ex in zip(linear, warm.outputs)]
    load1 = os.getloadavg()
    print()
    print("| model | total (s) | per frame (ms) | contact solves (s) | readout (s) | iterations per frame (median, mean) |")
    print("|---|---|---|---|---|---|")
    print(f"| exact, warm-started | **{t_exact:.1f}** | {1e3 * t_exact / frames:.1f} | {warm.seconds['contact']:.1f} | "
          f"{warm.seconds['readout']:.2f} | {np.median(warm.iterations):.0f}, {warm.iterations.mean():.1f} |")
    print(f"| exact, cold ({cold_frames} frames) | {t_cold:.1f} | {1e3 * t_cold / cold_frames:.1f} | "
          f"{cold.seconds['contact']:.1f} | - | {np.median(cold.iterations):.0f}, {cold.iterations.mean():.1f} |")
    print(f"| linear | {t_linear:.2f} | {1e3 * t_linear / frames:.2f} | - | (inside) | - |")
    print()
    print(f"exact: CPU time {cpu_exact:.1f} s of {t_exact:.1f} s wall; contact fraction {warm.contact_fraction.mean():.3f} "
          f"(mean); all converged: {bool(warm.converged.all())}; error estimate (median) "
          f"{np.median(warm.error_estimate):.2g}")
    print("linear model's error against the exact model (max |error| / max |signal| per sensor and component): "
          + ", ".join(f"{z * 1e3:g} mm: {e:.3g}" for z, e in zip(DEPTHS, errors)))
    print(f"load average after: {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Benchmark: DC-FFT (method 3) time, FFT floor, peak memory and error, 128^2 to 1024^2.

Run: ``python benchmarks/bench_forward_dcfft.py [--sizes 128 256 512 1024] [--repeats 2] [--estimate]``

Scene: a fingertip-like Gaussian contact (p, qx, qy all non-zero) on an n x n grid with
0.1 mm spacing; six stress components at one depth (1 mm) or three (0.5, 1, 2 mm); nu = 0.5.

Columns
- time: best wall time of ``dcfft_stress`` over the repeats (float64).
- floor: the transforms the method cannot avoid, timed raw in the same run on the same
  shapes: one real FFT per load component, one DCT-I/DST-I pair per (depth, component, load
  direction) kernel (the kernel's reflection symmetry makes its spectrum real), one inverse
  real FFT per (depth, component).
- io floor: load transforms and inverses only (what a method with free kernel spectra needs,
  e.g. the periodic spectral method with closed-form transfer functions).
- peak: tracemalloc peak during one call (numpy buffers, output included), MiB.
- err: max |DC-FFT - direct node sum| / max |stress| at 16 random nodes (method 1 oracle).
- f32 err: the same for ``dtype=float32`` against float64.

``--direct`` adds a table for method 1 (closed forms summed directly): time against the
number of sensors (10 to 10^4) for 10 point forces and for a 32 x 32 loaded patch, with the
DC-FFT time of the same patch (on its grid nodes) for comparison.

``--estimate`` adds a second table: the sampling error of DC-FFT against a 3x refined grid
(a converged reference: its own error is about the cube of the coarse one) on isolated
Gaussian loads, for h/Z from 0.05 to 2, next to ``dcfft_error_estimate``.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np
import scipy.fft as sfft

from tactilab.forward.halfspace.dcfft import dcfft_error_estimate, dcfft_stress, padded_shape
from tactilab.forward.halfspace.kernels import COMPONENTS, active_pairs, direct_stress
from tactilab.forward.halfspace.loads import SurfaceLoad

SPACING = 1e-4  # m


def contact_load(n: int) -> SurfaceLoad:
    x = (np.arange(n) - n // 2) * SPACING
    xx, yy = np.meshgrid(x, x)
    width = n * SPACING / 10
    g = np.exp(-(xx**2 + yy**2) / (2 * width**2))
    return SurfaceLoad(p=20e3 * g, qx=8e3 * g, qy=-3e3 * g, spacing=SPACING)


def best_time(fun, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fun()
        best = min(best, time.perf_counter() - t0)
    return best


def fft_floor(load: SurfaceLoad, n_depth: int, repeats: int) -> tuple[float, float]:
    """Time of the raw transforms DC-FFT performs, on the same shapes, summed with their counts.

    Per load component: rfft of the loaded rows (x, zero-padded) + fft of the columns (y).
    Per (depth, component, load direction) kernel: a DCT-I/DST-I along x of the quadrant rows
    and along y of the zero-padded quadrant (timed as DCT-I; DST-I costs the same).
    Per (depth, component): in-place ifft of the columns + irfft of the rows kept.
    Returns (floor, io floor) where io floor omits the kernel transforms.
    """
    ny, nx = load.shape
    my, mx = padded_shape(load.shape)
    rng = np.random.default_rng(0)
    rows = rng.normal(size=(ny, mx // 2 + 1))
    half = rng.normal(size=(my // 2 + 1, mx // 2 + 1))
    spectrum = sfft.fft(sfft.rfft(load.p, n=mx, axis=1), n=my, axis=0)
    t_load = best_time(lambda: sfft.fft(sfft.rfft(load.p, n=mx, axis=1), n=my, axis=0, overwrite_x=True), repeats)
    t_kernel = best_time(lambda: (sfft.dct(rows, type=1, axis=1), sfft.dct(half, type=1, axis=0)), repeats)

    def inverse():
        columns = sfft.ifft(spectrum.copy(), axis=0, overwrite_x=True)
        return sfft.irfft(columns[:ny], n=mx, axis=1)

    t_copy = best_time(lambda: spectrum.copy(), repeats)  # the copy only protects `spectrum`
    t_inv = max(best_time(inverse, repeats) - t_copy, 0.0)
    n_kernels = len(active_pairs(COMPONENTS, ("x", "y", "z"), 2))
    io = 3 * t_load + n_depth * len(COMPONENTS) * t_inv
    return io + n_depth * n_kernels * t_kernel, io


def accuracy(load: SurfaceLoad, depths, rng) -> tuple[float, float]:
    field = dcfft_stress(load, depths)
    field32 = dcfft_stress(load, depths, dtype=np.float32)
    n = load.shape[0]
    idx = rng.integers(0, n, size=(16, 2))
    pts = np.column_stack([load.x[idx[:, 1]], load.y[idx[:, 0]], np.full(16, depths[0])])
    ref = direct_stress(load, pts)  # (16, 6)
    got = field[0][:, idx[:, 0], idx[:, 1]].T
    err = np.abs(got - ref).max() / np.abs(field[0]).max()
    err32 = np.abs(field32 - field).max() / np.abs(field).max()
    return err, err32


def gaussian_load(ndim: int, h: float, width: float, amps: dict, refine: int = 1) -> SurfaceLoad:
    n = 2 * int(round(8 * width / h)) * refine + 1
    x = (np.arange(n) - n // 2) * h / refine
    if ndim == 1:
        r2 = (x - 0.13 * width) ** 2
    else:
        xx, yy = np.meshgrid(x, x)
        r2 = (xx - 0.13 * width) ** 2 + (yy + 0.21 * width) ** 2
    g = np.exp(-r2 / (2 * width**2))
    return SurfaceLoad(**{k: a * g for k, a in amps.items()}, spacing=(h / refine,) * ndim)


def estimate_table() -> None:
    depth = 1e-3
    cases = [(1, {"p": 1.0, "qx": 0.6}, 1.0), (1, {"p": 1.0}, 0.3), (1, {"qy": 1.0}, 1.0),
             (2, {"p": 1.0, "qx": 0.6, "qy": -0.4}, 1.0), (2, {"p": 1.0}, 0.3), (2, {"qx": 1.0}, 1.0),
             (2, {"p": 1.0, "qx": 0.5}, 3.0)]
    print("\nSampling error vs dcfft_error_estimate (Gaussian load of width w, Z = 1 mm, nu = 0.4);")
    print("measured = max|coarse - 3x refined| / peak(|p| + |qx| + |qy|); rel. stress = same / max|stress|")
    header = f"{'dim':>3} {'load':>10} {'w/Z':>4} {'h/Z':>5} {'measured':>9} {'rel.stress':>10} {'estimate':>9} {'est/meas':>8}"
    print(header)
    print("-" * len(header))
    for ndim, amps, wf in cases:
        for ratio in (2.0, 1.0, 0.5, 0.35, 0.25, 0.15, 0.1, 0.05):
            h, width = ratio * depth, wf * depth
            if ndim == 2 and 16 * width / h * 3 > 1000:
                continue  # reference grid too large for a quick run
            coarse = gaussian_load(ndim, h, width, amps)
            fine = gaussian_load(ndim, h, width, amps, refine=3)
            a = dcfft_stress(coarse, [depth], nu=0.4)[0]
            b = dcfft_stress(fine, [depth], nu=0.4)[0][(slice(None),) + (slice(None, None, 3),) * ndim]
            measured = np.abs(a - b).max() / sum(abs(v) for v in amps.values())
            rel_stress = np.abs(a - b).max() / np.abs(b).max()
            est = dcfft_error_estimate(coarse.spacing, depth, load_width=width)
            print(f"{ndim:>3} {'+'.join(amps):>10} {wf:4.1f} {ratio:5.2f} {measured:9.1e} {rel_stress:10.1e} "
                  f"{est:9.1e} {est / measured:8.2f}")


def direct_table(repeats: int) -> None:
    from tactilab.forward.halfspace.kernels import direct_stress_from_forces

    rng = np.random.default_rng(1)
    forces = rng.normal(size=(10, 3))
    positions = rng.uniform(-2e-3, 2e-3, (10, 2))
    patch = contact_load(32)
    t_patch_dcfft = best_time(lambda: dcfft_stress(patch, [1e-3]), repeats)
    print("\nMethod 1 (direct sum of closed forms), 6 components, one depth")
    header = f"{'sensors':>8} {'10 forces s':>12} {'32x32 patch s':>14} {'pairs/s':>9} {'DC-FFT patch s':>15}"
    print(header)
    print("-" * len(header))
    for n in (10, 100, 1000, 10000):
        pts = np.column_stack([rng.uniform(-3e-3, 3e-3, (n, 2)), np.full(n, 1e-3)])
        t_forces = best_time(lambda: direct_stress_from_forces(forces, positions, pts), repeats)
        t_patch = best_time(lambda: direct_stress(patch, pts), repeats)
        print(f"{n:>8} {t_forces:12.4f} {t_patch:14.4f} {n * patch.p.size / t_patch:9.1e} {t_patch_dcfft:15.4f}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 256, 512, 1024])
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--estimate", action="store_true", help="also verify dcfft_error_estimate")
    parser.add_argument("--direct", action="store_true", help="also time method 1 against the sensor count")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(20261122)
    print(f"DC-FFT, 6 components, p+qx+qy Gaussian contact, spacing {SPACING * 1e3} mm, nu = 0.5, scipy.fft 1 thread")
    header = f"{'grid':>9} {'depths':>6} {'padded':>10} {'time s':>8} {'floor s':>8} {'ratio':>6} " \
             f"{'io floor':>8} {'peak MiB':>9} {'out MiB':>8} {'err':>9} {'f32 err':>9} {'estimate':>9}"
    print(header)
    print("-" * len(header))
    for n in args.sizes:
        load = contact_load(n)
        err, err32 = accuracy(load, [1e-3], rng)
        for depths in ([1e-3], [0.5e-3, 1e-3, 2e-3]):
            t = best_time(lambda: dcfft_stress(load, depths), args.repeats)
            floor, io = fft_floor(load, len(depths), args.repeats)
            tracemalloc.start()
            out = dcfft_stress(load, depths)
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            estimate = max(dcfft_error_estimate(load.spacing, z) for z in depths)
            pad = "x".join(map(str, padded_shape(load.shape)))
            print(f"{n:>4}x{n:<4} {len(depths):>6} {pad:>10} {t:8.3f} {floor:8.3f} {t / floor:6.2f} {io:8.3f} "
                  f"{peak / 2**20:9.1f} {out.nbytes / 2**20:8.1f} {err:9.1e} {err32:9.1e} {estimate:9.1e}")
            del out
    if args.direct:
        direct_table(args.repeats)
    if args.estimate:
        estimate_table()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

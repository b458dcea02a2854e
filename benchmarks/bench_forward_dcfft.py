"""Benchmark: DC-FFT (method 3) time, FFT floor, peak memory and error, 128^2 to 1024^2.

Run: ``python benchmarks/bench_forward_dcfft.py [--sizes 128 256 512 1024] [--repeats 2]``

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
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np
import scipy.fft as sfft

from tactilab.forward.dcfft import dcfft_error_estimate, dcfft_stress, padded_shape
from tactilab.forward.kernels import COMPONENTS, active_pairs, direct_stress
from tactilab.forward.loads import SurfaceLoad

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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 256, 512, 1024])
    parser.add_argument("--repeats", type=int, default=2)
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

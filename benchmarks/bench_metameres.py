"""Benchmark: tactile metameres, per-mode analysis of periodic families and the tractor metamer pair.

Run:  .venv/bin/python benchmarks/bench_metameres.py [--quick] [--threads N]

Cases (best of ``--repeats`` wall-clock runs, the family built beforehand):

- ``resolvable_subspace`` of a periodic 1-D ``GridLoadFamily`` with two load components
  (p, qx), hypothesis ``xx,zx@1.25mm``, n = 2^12 .. 2^20 nodes; beside it, in the same run, the
  FFTs that analysis must do: ``n_load`` impulse responses through the operator (one rfft of
  n_load x n_load rows, one irfft of n_load x n_components rows) and one rfft of the
  n_load x n_readout-rows responses, i.e. 12 real FFTs of length n, timed alone;
  ``ratio`` = subspace time / FFT time;
- ``metamer_pair`` of a sliding sinusoid (A = 0.5 mm, p = 4 mm) against a 60-tractor row
  (1 mm pitch, 0.5 mm footprint) read by 1000 receptors on [-30, 30] mm (xx, zx at 1.25 mm), unbounded and
  bounded (|q| <= 2 N/mm, ``lsq_linear`` on the triangular factor).

OpenBLAS threads default to 1 (``--threads``): on a shared 2-core machine more threads make
small dense solves slower by orders of magnitude. The table is printed in markdown.
"""

from __future__ import annotations

import argparse
import os
import sys
import time


def _best(fn, repeats: int) -> float:
    fn()  # warm-up: caches, imports, first-touch pages
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def bench_subspace(n: int, repeats: int) -> dict:
    """Time resolvable_subspace (periodic, 2 loads) and the 12 length-n FFTs it needs."""
    import numpy as np
    import scipy.fft as sfft

    from tactilab.forward import ReceptorHypothesis
    from tactilab.inversion import GridLoadFamily, resolvable_subspace

    fam = GridLoadFamily((n,), 10e-6, ("p", "qx"), young_modulus=1.54e6)
    h = ReceptorHypothesis(("xx", "zx"), (1.25e-3,), 1e-4)
    sub = resolvable_subspace(fam, h, 1e3)
    rows = np.random.default_rng(0).normal(size=(4, n))

    def ffts():
        spec = sfft.rfft(rows, axis=-1)  # loads in: 2 probes x 2 loads
        back = sfft.irfft(spec, n, axis=-1)  # readouts out: 2 probes x 2 components
        sfft.rfft(back, axis=-1)  # responses to spectra: 2 loads x 2 readout rows

    t_sub = _best(lambda: resolvable_subspace(fam, h, 1e3), repeats)
    t_fft = _best(ffts, repeats)
    return dict(n=n, time=t_sub, fft=t_fft, ratio=t_sub / t_fft, dimension=sub.dimension, params=fam.n_params)


def bench_pair(repeats: int, n_receptors: int = 1000, n_tractors: int = 60) -> list[dict]:
    """1000 receptors x 60 tractors (1 mm pitch): metamer_pair, unbounded and bounded."""
    import numpy as np

    from tactilab.inversion import SinusoidFamily, TractorFamily, metamer_pair

    fam = TractorFamily((np.arange(n_tractors) - (n_tractors - 1) / 2) * 1e-3, 1.54e6, footprint=0.5e-3, limit=2000.0)
    x = np.linspace(-n_tractors / 2 * 1e-3, n_tractors / 2 * 1e-3, n_receptors)  # receptors under the whole row
    target = SinusoidFamily(4e-3, np.pi / 2).stimulus([0.5e-3])
    rows = []
    for label, bounds in (("unbounded", None), ("bounded |q| <= 2 N/mm", "family")):
        pair = metamer_pair(target, fam, "xx,zx@1.25mm;noise=1e-3", x, bounds=bounds)
        t = _best(lambda b=bounds: metamer_pair(target, fam, "xx,zx@1.25mm;noise=1e-3", x, bounds=b), repeats)
        rows.append(dict(case=label, time=t, residual=pair.relative_residual,
                         max_load=float(np.abs(pair.params).max())))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="n up to 2^16 only, 3 repeats")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--threads", default="1", help="OpenBLAS/MKL threads (default 1)")
    args = parser.parse_args(argv)
    if "numpy" in sys.modules:
        print("note: numpy already imported; --threads may not apply", file=sys.stderr)
    for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
        os.environ[var] = args.threads
    repeats = 3 if args.quick else args.repeats
    sizes = [2 ** k for k in ((12, 14, 16) if args.quick else (12, 14, 16, 18, 20))]
    print(f"threads {args.threads}; best of {repeats}; cpu count {os.cpu_count()}")
    print()
    print("| n (nodes) | params | resolvable_subspace (ms) | its 12 FFTs alone (ms) | ratio | resolved dims |")
    print("|---:|---:|---:|---:|---:|---:|")
    for n in sizes:
        r = bench_subspace(n, repeats if n <= 2 ** 18 else max(1, repeats // 3))
        print(f"| 2^{n.bit_length() - 1} | {r['params']} | {r['time'] * 1e3:.2f} | {r['fft'] * 1e3:.2f} | "
              f"{r['ratio']:.1f} | {r['dimension']} |")
    print()
    print("| metamer_pair, 1000 receptors x 60 tractors | time (ms) | relative residual | max load (N/mm) |")
    print("|---|---:|---:|---:|")
    for r in bench_pair(repeats):
        print(f"| {r['case']} | {r['time'] * 1e3:.1f} | {r['residual']:.4f} | {r['max_load'] * 1e-3:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())

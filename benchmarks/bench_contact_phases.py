"""Where the contact solver's fine loop spends an iteration, in FFT floors (docs/contact.md, Cost).

Run: ``python benchmarks/bench_contact_phases.py [--sizes 256 512 1024] [--repeats 3] [--clock cpu]
[--preconditioner auto]`` (``TACTILAB_JIT=0``: the loop's NumPy passes instead of the compiled kernels; the
header says which).

The scenes of ``bench_contact.py``: section a's periodic self-affine surface (floor: one rfft2 +
one irfft2 of the grid) and section d's isolated fingertip (floor: the same of the grid zero-padded
to twice each side). Each solve's fine loop (``preconditioned_cg`` on the finest grid) is split
into its compliance products (``ContactCompliance.normal``: per iteration, and each one's cost),
the preconditioner (``ContactCompliance.preconditioner(kind)``'s operator: the exact ``stiffness``, in
float32 beside float32 direction products, or the two-level one, whichever the kind gives on the grid), the direct summation of a few clipped nodes
(``add_normal_point_loads``, or ``PointLoads.add`` in float32 beside float32 corrections), the float32 corrections after steps that clip many nodes
(``SingleCorrection.correction``, or ``add`` in plane strain), the float32 direction products
(``SingleCorrection.transform_direction``, columns ``f32A`` and ``f32A/it``), the elementwise passes
(``forward/contact/kernels.py`` and ``step_kernels.py``, compiled or NumPy) and the rest (Python between them). The fastest of ``--repeats`` solves is kept, and the
fastest of as many floors; the wrappers that time the parts add two clock reads per call.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_contact as bench  # noqa: E402  (the scenes, the floor, the clock, the method table)

from tactilab.forward.contact import ContactCompliance, kernels, step_kernels  # noqa: E402
from tactilab.forward.contact.coarse_stiffness import TwoLevelStiffness  # noqa: E402
from tactilab.forward.contact.point_loads import PointLoads  # noqa: E402
from tactilab.forward.contact.single_correction import SingleCorrection  # noqa: E402

PRODUCTS = ("normal", "add_normal_point_loads")
PASSES = {"gap": kernels, "residual": kernels, "project": kernels, "direction": kernels, "dot": step_kernels,
          "descend": step_kernels}


class Phases:
    """Times the parts of the fine loop on ``shape`` while in its ``with`` block (the patches undone after)."""

    def __init__(self, shape, kind: str = "auto"):
        self.shape, self.kind = tuple(shape), kind
        self.time: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self.loop = [0.0, 0, 0]  # seconds, iterations, products of the fine loop
        self._undo = []

    def _count(self, name, t, shape):
        if tuple(shape) == self.shape:
            self.time[name] = self.time.get(name, 0.0) + t
            self.calls[name] = self.calls.get(name, 0) + 1

    def _patch(self, owner, name, wrapper):
        self._undo.append((owner, name, getattr(owner, name)))
        setattr(owner, name, wrapper(getattr(owner, name)))

    def __enter__(self):
        def method(f, name):
            def timed(comp, *args, **kwargs):
                t0 = bench.clock()
                out = f(comp, *args, **kwargs)
                self._count(name, bench.clock() - t0, comp.shape)
                return out
            return timed

        def function(f, name):
            def timed(first, *args, **kwargs):
                t0 = bench.clock()
                out = f(first, *args, **kwargs)
                self._count(name, bench.clock() - t0, first.shape)
                return out
            return timed

        def solver(f):
            def timed(comp, g0, **kwargs):
                t0 = bench.clock()
                out = f(comp, g0, **kwargs, preconditioner=self.kind)
                if tuple(g0.shape) == self.shape:
                    self.loop = [self.loop[0] + bench.clock() - t0, self.loop[1] + out.iterations,
                                 self.loop[2] + out.products]
                return out
            return timed

        for name in PRODUCTS:
            self._patch(ContactCompliance, name, lambda f, name=name: method(f, name))
        self._patch(SingleCorrection, "add", lambda f: method(f, "single"))
        self._patch(SingleCorrection, "correction", lambda f: method(f, "single"))
        self._patch(PointLoads, "add", lambda f: method(f, "add_normal_point_loads"))
        self._patch(SingleCorrection, "transform_direction", lambda f: method(f, "single_product"))
        # the preconditioner: the exact stiffness (float64, or float32 beside float32 products) or the two-level one
        self._patch(ContactCompliance, "stiffness", lambda f: method(f, "stiffness"))
        self._patch(SingleCorrection, "stiffness", lambda f: method(f, "stiffness"))
        self._patch(TwoLevelStiffness, "__call__", lambda f: method(f, "stiffness"))
        for name, module in PASSES.items():
            self._patch(module, name, lambda f, name=name: function(f, name))
        self._patch_method_table(solver)
        return self

    def _patch_method_table(self, solver):
        table = bench.contact_solve.METHODS
        self._undo.append((table, "preconditioned_cg", table["preconditioned_cg"]))
        table["preconditioned_cg"] = solver(table["preconditioned_cg"])

    def __exit__(self, *exc):
        for owner, name, original in reversed(self._undo):
            if isinstance(owner, dict):
                owner[name] = original
            else:
                setattr(owner, name, original)


def measure(n: int, periodic: bool, tol: float, kind: str = "auto") -> dict:
    """The fastest of ``--repeats`` solves of the scene on n^2, split into parts (floors per iteration)."""
    skin = bench.HalfSpace(E=bench.E_PA, nu=bench.NU)
    if periodic:
        h, pbar = bench.rough_cell(n)
        args, kwargs = (skin, -h, 1e-6), dict(mean_pressure=pbar, periodic=True, tol=tol)
    else:
        plate, finger, dx = bench.fingertip(n)
        args, kwargs = (skin, finger - plate, dx), dict(normal_force=0.5, tol=tol)
    best = None
    for _ in range(bench.REPEATS["n"]):
        with Phases((n, n), kind) as phases:
            bench.solve_contact(*args, **kwargs)
        if best is None or phases.loop[0] < best.loop[0]:
            best = phases
    floor = bench.floor_of((n, n), periodic)
    seconds, iterations, products = best.loop
    per = {name: best.time.get(name, 0.0) / iterations / floor
           for name in PRODUCTS + ("stiffness", "single", "single_product") + tuple(PASSES)}
    passes = sum(per[name] for name in PASSES)
    loop = seconds / iterations / floor
    calls = best.calls.get("normal", 0)
    return dict(iterations=iterations, products=products / iterations, loop=loop,
                normal_per_iteration=calls / iterations,
                normal_each=best.time.get("normal", 0.0) / max(calls, 1) / floor, normal=per["normal"],
                stiffness=per["stiffness"], point_loads=per["add_normal_point_loads"], single=per["single"],
                single_per_iteration=best.calls.get("single", 0) / iterations, single_product=per["single_product"],
                single_product_per_iteration=best.calls.get("single_product", 0) / iterations, passes=passes,
                rest=loop - passes - per["normal"] - per["stiffness"] - per["add_normal_point_loads"] - per["single"]
                - per["single_product"])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
    parser.add_argument("--tol", type=float, default=1e-8)
    parser.add_argument("--repeats", type=int, default=3, help="solves and floors per size, the fastest kept")
    parser.add_argument("--clock", choices=sorted(bench.CLOCKS), default="cpu")
    parser.add_argument("--preconditioner", choices=("auto", "fft"), default="auto",
                        help="the fine loop's (auto: the two-level stiffness on periodic grids, compiled)")
    args = parser.parse_args(argv)
    bench.REPEATS["n"], bench.CLOCK["name"] = max(1, args.repeats), args.clock
    print(f"bench_contact_phases: elementwise passes {bench.passes()}, preconditioner {args.preconditioner}, "
          f"fastest of {bench.REPEATS['n']}, {args.clock} clock, tol {args.tol:g}, one thread")
    bench.warm_up([args.preconditioner])
    print(f"{'n':>6} {'grid':<9}{'iter':>5}{'prod/it':>8}{'loop':>7}{'A':>7}{'A/it':>6}{'A each':>7}{'K':>6}"
          f"{'points':>7}{'f32':>6}{'f32/it':>7}{'f32A':>6}{'f32A/it':>8}{'passes':>7}{'rest':>6}   (FFT floors per iteration)")
    for n in args.sizes:
        for periodic in (True, False):
            r = measure(n, periodic, args.tol, args.preconditioner)
            print(f"{n:6d} {'periodic' if periodic else 'isolated':<9}{r['iterations']:5d}{r['products']:8.2f}"
                  f"{r['loop']:7.2f}{r['normal']:7.2f}{r['normal_per_iteration']:6.2f}{r['normal_each']:7.2f}"
                  f"{r['stiffness']:6.2f}{r['point_loads']:7.2f}{r['single']:6.2f}{r['single_per_iteration']:7.2f}"
                  f"{r['single_product']:6.2f}{r['single_product_per_iteration']:8.2f}{r['passes']:7.2f}{r['rest']:6.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

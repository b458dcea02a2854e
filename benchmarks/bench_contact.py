"""Benchmark of the contact engine: time, iterations and error, against Tamaas and the FFT floor.

Run: ``python benchmarks/bench_contact.py [--sections a b c d] [--sizes 256 512 1024] [--frames 10] [--method auto]
[--preconditioner auto fft] [--no-peer] [--repeats 3] [--clock cpu]`` (``TACTILAB_JIT=0``: the solvers' NumPy passes
instead of the compiled kernels; the header says which ran)
(the full run takes tens of minutes; ``--quick`` uses small grids and checks the harness in about
a minute). Everything runs on one core (OMP/BLAS threads 1, ``scipy.fft`` workers=1), float64, SI.

Sections (all tables from one run):

a. Normal contact, periodic: one self-affine surface per size (Hurst 0.8, rms slope 0.1 with the
   spectral derivative, cut-offs: the grid and 2 nodes; seed 1), pressed to about 10 % contact at the
   mean pressure 0.05 E* h'_rms, tolerance ``--tol``, cold start. Tamaas's ``PolonskyKeerRey``
   solves the same discrete problem (same surface, grid, mean pressure and tolerance; its own
   criterion) in its own venv (``$TACTILAB_TAMAAS_VENV`` or ``.bench-venv`` at the repository root,
   as for ``bench_forward.py``). Columns: our time and iterations, contact fraction, the FFT floor
   (one rfft2 + one irfft2 of the grid, timed in the same run), our time per iteration over the
   floor (the whole solve's time over its fine-grid iterations, so the coarse-grid solve and the error
   estimate are counted in), the fine grid's loop alone per iteration over the floor, Tamaas's time, the speed ratio (Tamaas / ours) and
   max |p - p_Tamaas| / max p. Then the
   peak memory of one solve at the largest size (max RSS of a child process minus its RSS before
   the solve).
b. Partial slip: a Hertz sphere on a 128^2 isolated grid (contact radius a quarter of the grid) at
   Q / (mu P) = 0.5; the stick radius (disc of equal area) against Cattaneo-Mindlin's
   c = a (1 - Q / (mu P))^(1/3), in grid spacings, and the time; Tamaas ``Condat`` on the same grid
   (periodic, its own associated friction law) beside it when it answers within ``--peer-cap`` s.
c. A warm-started sliding sequence: a fingertip (R = 10 mm, 0.5 N, E = 1 MPa, nu = 1/2) sliding one
   node per frame over a rough plate (rms 5 um, Hurst 0.8, 20 um nodes), 256^2, mu = 0.5, full
   sliding: time and iterations per frame, cold, warm (``initial=`` the previous frame as is) and warm
   shifted (the previous pressure moved one node with the plate).
d. Time and iterations against the grid size (up to 2048^2): the periodic surface of (a), and an
   isolated fingertip (section c's finger and plate, the grid spanning 5.12 mm at every size), each
   with its cost per iteration over its floor (the padded grid's for the isolated one), whole solve
   and fine loop.

``--preconditioner`` (the preconditioned CG's, :meth:`ContactCompliance.preconditioner`) takes several kinds:
(a) and (d) then solve each size with each kind in turn, in the same run, one row each (its last column).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.fft as sfft  # noqa: E402

from tactilab.core import jit  # noqa: E402
from tactilab.data_schemas import random_rough_surface  # noqa: E402
from tactilab.forward import HalfSpace  # noqa: E402
from tactilab.forward import solve_contact as _solve_contact  # noqa: E402
from tactilab.forward.contact import solve as contact_solve  # noqa: E402  (the method table, to time the loop)
from tactilab.forward.halfspace import inverse_into, rfftn_into  # noqa: E402

E_PA, NU = 1e6, 0.5
E_STAR = E_PA / (1 - NU**2)
SLOPE = 0.1  # rms slope of section a's surface
TAMAAS_VENV = Path(os.environ.get("TACTILAB_TAMAAS_VENV", Path(__file__).resolve().parents[1] / ".bench-venv"))

PKR_SCRIPT = r'''
import sys, time, numpy as np
import tamaas as tm
tm.set_log_level(tm.LogLevel.error)
d = np.load(sys.argv[1])
h, size, pbar, tol = d["h"], float(d["size"]), float(d["pbar"]), float(d["tol"])
model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [size, size], list(h.shape))
model.E, model.nu = float(d["E"]), float(d["nu"])
solver = tm.PolonskyKeerRey(model, h, tol)
t0 = time.perf_counter(); solver.solve(pbar); t = time.perf_counter() - t0
np.savez(sys.argv[2], p=np.array(model.traction), time=t, version=tm.__version__)
'''

CONDAT_SCRIPT = r'''
import sys, time, numpy as np
import tamaas as tm
tm.set_log_level(tm.LogLevel.error)
d = np.load(sys.argv[1])
h, size, tol, mu = d["h"], float(d["size"]), float(d["tol"]), float(d["mu"])
model = tm.ModelFactory.createModel(tm.model_type.surface_2d, [size, size], list(h.shape))
model.E, model.nu = float(d["E"]), float(d["nu"])
solver = tm.Condat(model, h, tol, mu)
solver.max_iter = int(d["max_iter"])
t0 = time.perf_counter(); solver.solve([float(d["qmean"]), 0.0, float(d["pmean"])], 0.9)
t = time.perf_counter() - t0
np.savez(sys.argv[2], t=np.array(model.traction), time=t, version=tm.__version__)
'''


def tamaas_python() -> Path | None:
    """The benchmark venv's python if it imports tamaas, else None."""
    exe = TAMAAS_VENV / "bin" / "python"
    if not exe.exists():
        return None
    ok = subprocess.run([str(exe), "-c", "import tamaas"], capture_output=True)
    return exe if ok.returncode == 0 else None


def run_peer(script: str, arrays: dict, cap: float) -> dict | str:
    """Run a Tamaas script in its venv (one thread) on ``arrays``; its outputs, or why there are none."""
    exe = tamaas_python()
    if exe is None:
        return (f"Tamaas skipped: no importable tamaas in {TAMAAS_VENV} (create it with 'python3.12 -m venv "
                ".bench-venv && .bench-venv/bin/pip install tamaas', or set TACTILAB_TAMAAS_VENV)")
    with tempfile.TemporaryDirectory() as tmp:
        src, dst, path = Path(tmp, "in.npz"), Path(tmp, "out.npz"), Path(tmp, "peer.py")
        np.savez(src, **arrays)
        path.write_text(script)
        env = dict(os.environ, OMP_NUM_THREADS="1")
        try:
            proc = subprocess.run([str(exe), str(path), str(src), str(dst)], capture_output=True, text=True,
                                  env=env, timeout=cap)
        except subprocess.TimeoutExpired:
            return f"Tamaas gave no answer within {cap:g} s"
        if proc.returncode != 0:
            return f"Tamaas failed: {proc.stderr.strip().splitlines()[-1:]}"
        return dict(np.load(dst))


def fft_floor(shape: tuple[int, ...], periodic: bool, repeats: int = 5) -> float:
    """Median time (s) of one rfft2 + one irfft2 of the grid (zero-padded to twice each side if isolated).

    The faster of two ways, each timed: ``scipy.fft`` (fresh arrays) and the transforms into kept
    arrays that the solver itself uses (``rfftn_into`` / ``inverse_into``: no page faults), so the
    floor is the cheapest FFT pair this machine does, not a slow one."""
    full = shape if periodic else tuple(2 * n for n in shape)
    x = np.random.default_rng(0).standard_normal(full)
    spec = np.empty(full[:-1] + (full[-1] // 2 + 1,), complex)
    out = np.empty(full)

    def fresh():
        sfft.irfftn(sfft.rfftn(x, workers=1), s=full, workers=1)

    def kept():
        inverse_into(rfftn_into(x, spec, workers=1), out, workers=1)

    medians = []
    for pair in (fresh, kept):
        times = []
        for _ in range(repeats + 1):
            t0 = clock()
            pair()
            times.append(clock() - t0)
        medians.append(float(np.median(times[1:])))
    return min(medians)


class FineLoop:
    """Times the fine grid's solver loop of each solve (the normal method's call on the finest grid),
    so that the cost per iteration of the loop itself is reported beside the whole solve's."""

    def __init__(self, preconditioner: str = "auto"):
        self.calls: list[tuple[tuple[int, ...], int, float]] = []
        self.preconditioner = preconditioner

    def __enter__(self):
        name = "preconditioned_cg" if METHOD["method"] == "auto" else METHOD["method"]
        self._name, self._inner = name, contact_solve.METHODS[name]
        extra = {"preconditioner": self.preconditioner, "single_corrections": CORRECTIONS["single"],
                 "single_products": CORRECTIONS["products"]} \
            if name == "preconditioned_cg" else {}

        def timed_method(compliance, g0, **kwargs):
            t0 = clock()
            out = self._inner(compliance, g0, **kwargs, **extra)
            self.calls.append((g0.shape, out.iterations, clock() - t0))
            return out

        contact_solve.METHODS[name] = timed_method
        return self

    def __exit__(self, *exc):
        contact_solve.METHODS[self._name] = self._inner

    def per_iteration(self, shape) -> float:
        """Seconds per iteration of the fastest call on ``shape`` (nan if none)."""
        rows = [c[2] / max(c[1], 1) for c in self.calls if tuple(c[0]) == tuple(shape)]
        return min(rows) if rows else float("nan")


def rough_cell(n: int, spacing: float = 1e-6) -> tuple[np.ndarray, float]:
    """Section a's surface on n^2 nodes and its mean pressure (about 10 % contact)."""
    h = random_rough_surface((n, n), spacing, rms_slope=SLOPE, hurst=0.8, rng=np.random.default_rng(1))
    return h, 0.05 * E_STAR * SLOPE


#: the normal-contact method of every solve here (``--method``)
METHOD = {"method": "auto"}
#: float32 clip corrections in the preconditioned CG (``--float64-corrections`` turns them off)
CORRECTIONS = {"single": True, "products": True}


def solve_contact(*args, **kwargs):
    """``tactilab.forward.solve_contact`` with the benchmark's ``--method``."""
    return _solve_contact(*args, **kwargs, **METHOD)


#: the clock of every time here (``--clock``): wall time, or this process's CPU time, which a loaded
#: machine's other jobs leave alone (the solves run on one thread, so the two agree on an idle machine)
CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}
CLOCK = {"name": "wall"}


def clock() -> float:
    return CLOCKS[CLOCK["name"]]()


#: times each solve of (a) and (d) and its floor is repeated, the fastest kept (``--repeats``)
REPEATS = {"n": 1}


def timed(fn):
    t0 = clock()
    out = fn()
    return out, clock() - t0


def fastest(fn):
    """``fn()``'s output and its fastest time over ``--repeats`` calls (a loaded machine's noise is one-sided)."""
    runs = [timed(fn) for _ in range(REPEATS["n"])]
    return runs[0][0], min(t for _, t in runs)


def floor_of(shape, periodic: bool) -> float:
    """The FFT floor, the fastest of ``--repeats`` measurements."""
    return min(fft_floor(shape, periodic) for _ in range(REPEATS["n"]))


def warm_up(kinds) -> None:
    """One small periodic solve per preconditioner and one isolated solve, untimed: compiled kernels load
    from numba's cache on their first call in a process (about 0.2 s, once), which no table should count."""
    skin = HalfSpace(E=E_PA, nu=NU)
    h, pbar = rough_cell(32)
    for kind in kinds:
        with FineLoop(kind):
            solve_contact(skin, -h, 1e-6, mean_pressure=pbar, periodic=True, tol=1e-6)
    plate, finger, dx = fingertip(32)
    solve_contact(skin, finger - plate, dx, normal_force=0.5, tol=1e-6)


def section_a(sizes, tol: float, peer: bool, cap: float, kinds=("auto",)) -> None:
    print("\n(a) normal contact, periodic self-affine surface (H 0.8, rms slope 0.1), cold start, one core")
    print(f"{'n':>6}{'time s':>10}{'iter':>7}{'fraction':>10}{'floor ms':>10}{'iter/floor':>12}{'loop/floor':>12}"
          f"{'precond':>10}{'Tamaas s':>10}{'speed-up':>10}{'max|dp|/pmax':>14}")
    skin = HalfSpace(E=E_PA, nu=NU)
    for n in sizes:
        h, pbar = rough_cell(n)
        res = run_peer(PKR_SCRIPT, {"h": h, "size": n * 1e-6, "pbar": pbar, "tol": tol, "E": E_PA, "nu": NU},
                       cap) if peer else "Tamaas skipped (--no-peer)"
        floor = floor_of((n, n), True)  # once per size: the kinds' rows share one yardstick
        for kind in kinds:
            with FineLoop(kind) as loop:
                sol, t = fastest(lambda: solve_contact(skin, -h, 1e-6, mean_pressure=pbar, periodic=True, tol=tol))
            per_iter = t / max(sol.iterations, 1) / floor
            per_loop = loop.per_iteration((n, n)) / floor
            if isinstance(res, str):
                cols = f"{'-':>10}{'-':>10}{'-':>14}   {res}"
            else:
                dp = float(np.max(np.abs(res["p"] - sol.pressure)) / np.max(sol.pressure))
                cols = f"{float(res['time']):10.3f}{float(res['time']) / t:10.2f}{dp:14.2e}"
            print(f"{n:6d}{t:10.3f}{sol.iterations:7d}{sol.contact_fraction:10.3f}{floor * 1e3:10.2f}"
                  f"{per_iter:12.2f}{per_loop:12.2f}{kind:>10}{cols}", flush=True)


def peak_rss_mib() -> float:
    """This process's peak resident memory (MiB): Linux's VmHWM, which belongs to the process's own memory
    map; ``ru_maxrss`` (the fallback elsewhere) keeps the parent's peak across fork and exec on Linux, so a
    child started by a large parent would report the parent's peak."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def memory_child(n: int, tol: float, kind: str = "auto") -> None:
    """Child process: peak RSS before and after one section-a solve at n^2 (printed in MiB)."""
    h, pbar = rough_cell(n)
    before = peak_rss_mib()
    with FineLoop(kind):
        solve_contact(HalfSpace(E=E_PA, nu=NU), -h, 1e-6, mean_pressure=pbar, periodic=True, tol=tol)
    after = peak_rss_mib()
    print(f"{before:.1f} {after:.1f}")


def section_a_memory(n: int, tol: float, kind: str = "auto") -> None:
    proc = subprocess.run([sys.executable, __file__, "--memory-child", str(n), "--tol", str(tol),
                           "--method", METHOD["method"], "--preconditioner", kind]
                          + ([] if CORRECTIONS["single"] else ["--float64-corrections"])
                          + ([] if CORRECTIONS["products"] else ["--float64-products"]),
                          capture_output=True, text=True)
    if proc.returncode != 0:
        print(f"memory at {n}^2: the child failed: {proc.stderr.strip().splitlines()[-1:]}")
        return
    before, after = (float(v) for v in proc.stdout.split())
    print(f"memory at {n}^2 (periodic, preconditioner {kind}): peak RSS {after:.0f} MiB, of which the solve "
          f"{after - before:.0f} MiB (the rest: Python, numpy, numba where installed, the surface)")


def hertz_grid(n: int):
    """Section b's sphere: gap, spacing, force and Hertz radius (contact radius a quarter of the grid)."""
    radius, force = 10e-3, 0.5
    a = (3 * force * radius / (4 * E_STAR)) ** (1 / 3)
    dx = 4 * a / n
    x = (np.arange(n) - n // 2) * dx
    yy, xx = np.meshgrid(x, x, indexing="ij")
    return (xx**2 + yy**2) / (2 * radius), dx, force, a


def section_b(n: int, tol: float, peer: bool, cap: float, peer_tol: float, peer_iter: int) -> None:
    mu, ratio = 0.5, 0.5
    gap, dx, force, a = hertz_grid(n)
    c_exact = a * (1 - ratio) ** (1 / 3)
    print(f"\n(b) partial slip, Hertz {n}^2, Q/(mu P) = {ratio}, mu = {mu}: stick radius c = {c_exact * 1e3:.4f} mm "
          f"({c_exact / dx:.2f} spacings)")
    print(f"{'solver':<22}{'time s':>10}{'c error (spacings)':>20}  note")
    q = ratio * mu * force
    sol, t = timed(lambda: solve_contact(HalfSpace(E=E_PA, nu=NU), gap, dx, normal_force=force, friction=mu,
                                         condition="partial", tangential_force=(q, 0.0), tol=tol))
    c = np.sqrt(np.count_nonzero(sol.stick) * dx * dx / np.pi)
    print(f"{'tactilab':<22}{t:10.3f}{(c - c_exact) / dx:20.2f}  {sol.iterations} iterations")
    if not peer:
        return
    # Tamaas in units of the grid's size and E (its stopping test is absolute: SI pressures stop it at once)
    size = n * dx
    res = run_peer(CONDAT_SCRIPT, {"h": -gap / size, "size": 1.0, "tol": peer_tol, "mu": mu, "E": 1.0, "nu": NU,
                                   "max_iter": peer_iter, "qmean": q / size**2 / E_PA, "pmean": force / size**2 / E_PA},
                   cap)
    if isinstance(res, str):
        print(f"{'Tamaas Condat':<22}{'-':>10}{'-':>20}  {res}")
        return
    tr = res["t"]
    p, qm = tr[..., 2], np.hypot(tr[..., 0], tr[..., 1])
    stick = (p > 0) & (qm < mu * p * (1 - 1e-3))
    c_peer = np.sqrt(np.count_nonzero(stick) * dx * dx / np.pi)
    print(f"{'Tamaas Condat':<22}{float(res['time']):10.3f}{(c_peer - c_exact) / dx:20.2f}  "
          f"tol {peer_tol:g}, at most {peer_iter} iterations, periodic cell, associated friction law, "
          f"tamaas {res['version']}")


def fingertip(n: int, frames: int = 0, extent: float = 5.12e-3):
    """Section c's finger on its rough plate: the plate (n x (n + frames)) and the finger's r^2 / 2R, spacing."""
    dx = extent / n
    plate = random_rough_surface((n, n + frames), dx, rms_height=5e-6, hurst=0.8, rng=np.random.default_rng(2))
    x = (np.arange(n) - n // 2) * dx
    yy, xx = np.meshgrid(x, x, indexing="ij")
    return plate, (xx**2 + yy**2) / (2 * 10e-3), dx


def section_c(frames: int, tol: float, n: int = 256) -> None:
    plate, finger, dx = fingertip(n, frames)
    print(f"\n(c) sliding fingertip (R 10 mm, 0.5 N, E 1 MPa, nu 1/2, mu 0.5) over a rough plate (rms 5 um, H 0.8, "
          f"{dx * 1e6:g} um nodes), {n}^2, one node per frame, {frames} frames")
    skin = HalfSpace(E=E_PA, nu=NU)
    rows = {"cold": [], "warm": [], "warm shifted": []}
    previous = None
    kw = dict(normal_force=0.5, friction=0.5, condition="sliding", tol=tol)
    for k in range(frames):
        gap = finger - plate[:, k:k + n]  # the plate moves by -dx per frame in the finger's frame
        cold, tc = timed(lambda: solve_contact(skin, gap, dx, **kw))
        rows["cold"].append((tc, cold.iterations))
        if previous is not None:
            warm, tw = timed(lambda: solve_contact(skin, gap, dx, initial=previous, **kw))
            rows["warm"].append((tw, warm.iterations))
            # the previous pressure moved with the plate: its roughness lands where it now is
            shifted = dataclasses.replace(previous, pressure=np.roll(previous.pressure, -1, axis=-1))
            warm_s, ts = timed(lambda: solve_contact(skin, gap, dx, initial=shifted, **kw))
            rows["warm shifted"].append((ts, warm_s.iterations))
        previous = cold
    print(f"{'start':<14}{'time/frame s (median)':>24}{'iterations/frame (median)':>28}")
    for name, vals in rows.items():
        if vals:
            print(f"{name:<14}{np.median([v[0] for v in vals]):24.3f}{np.median([v[1] for v in vals]):28.1f}")
    print("warm: initial = the previous frame's solution as is; warm shifted: its pressure moved one node with "
          "the plate (frame 0 is cold in both)")


def section_d(sizes, tol: float, kinds=("auto",)) -> None:
    print("\n(d) time and iterations against the grid size (cold starts)")
    print(f"{'n':>6}{'periodic s':>12}{'iter':>7}{'iter/floor':>12}{'loop/floor':>12}{'isolated s':>12}{'iter':>7}"
          f"{'iso floor ms':>14}{'iter/floor':>12}{'loop/floor':>12}{'precond':>10}")
    skin = HalfSpace(E=E_PA, nu=NU)
    for n in sizes:
        h, pbar = rough_cell(n)
        fp, fi = floor_of((n, n), True), floor_of((n, n), False)  # once per size: the kinds' rows share them
        plate, finger, dx = fingertip(n)
        for kind in kinds:
            with FineLoop(kind) as loop_p:
                per, tp = fastest(lambda: solve_contact(skin, -h, 1e-6, mean_pressure=pbar, periodic=True, tol=tol))
            with FineLoop(kind) as loop_i:
                iso, ti = fastest(lambda: solve_contact(skin, finger - plate, dx, normal_force=0.5, tol=tol))
            print(f"{n:6d}{tp:12.3f}{per.iterations:7d}{tp / max(per.iterations, 1) / fp:12.2f}"
                  f"{loop_p.per_iteration((n, n)) / fp:12.2f}{ti:12.3f}{iso.iterations:7d}{fi * 1e3:14.2f}"
                  f"{ti / max(iso.iterations, 1) / fi:12.2f}{loop_i.per_iteration((n, n)) / fi:12.2f}{kind:>10}",
                  flush=True)
        del h, plate


def passes() -> str:
    """Which path the solvers' elementwise passes take (tactilab.core.jit)."""
    if jit.enabled():
        import numba

        return f"compiled (numba {numba.__version__})"
    return "NumPy (TACTILAB_JIT=0)" if jit.available() else "NumPy (numba not installed)"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sections", nargs="+", choices=("a", "b", "c", "d"), default=["a", "b", "c", "d"])
    parser.add_argument("--sizes", type=int, nargs="+", help="grid sizes of (a) and (d); default 256 512 1024 "
                                                               "for (a) and up to 2048 for (d)")
    parser.add_argument("--frames", type=int, default=None, help="frames of the sliding sequence (c); default 10")
    parser.add_argument("--sliding-size", type=int, default=256, help="grid of the sliding sequence (c)")
    parser.add_argument("--partial-size", type=int, default=128, help="grid of the partial-slip frame (b)")
    parser.add_argument("--method", default="auto", choices=("auto", "preconditioned_cg", "polonsky_keer"),
                        help="normal-contact method of every solve (default auto = preconditioned_cg)")
    parser.add_argument("--preconditioner", nargs="+", default=["auto"], choices=("auto", "fft"),
                        help="the preconditioned CG's preconditioner in (a) and (d); several: each size is solved "
                             "with each in turn (auto: the two-level stiffness on periodic grids, the exact one, "
                             "fft, on isolated ones)")
    parser.add_argument("--float64-corrections", action="store_true",
                        help="(a), (d): recompute the displacement in float64 after every step that clips many "
                             "nodes, as before the float32 corrections (preconditioned_cg(single_corrections=False))")
    parser.add_argument("--float64-products", action="store_true",
                        help="(a), (d): every direction product of the preconditioned CG in float64, as before the "
                             "mixed-precision ones on 2-D grids (preconditioned_cg(single_products=False))")
    parser.add_argument("--tol", type=float, default=1e-8, help="solver tolerance of every solve (and Tamaas's)")
    parser.add_argument("--condat-tol", type=float, default=1e-4,
                        help="Tamaas Condat's tolerance in (b) (its own cost criterion; 1e-8 gives no answer "
                             "in minutes)")
    parser.add_argument("--condat-max-iter", type=int, default=20000, help="Tamaas Condat's iteration limit in (b)")
    parser.add_argument("--peer-cap", type=float, default=300.0, help="seconds Tamaas may take per solve")
    parser.add_argument("--no-peer", action="store_true", help="skip Tamaas")
    parser.add_argument("--clock", choices=sorted(CLOCKS), default="wall",
                        help="wall time, or the process's CPU time (steadier on a machine shared with other jobs)")
    parser.add_argument("--repeats", type=int, default=1,
                        help="solves of (a) and (d) and their floors repeated, the fastest kept (a loaded machine)")
    parser.add_argument("--quick", action="store_true", help="tiny grids: checks the harness (about a minute)")
    parser.add_argument("--memory-child", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    CORRECTIONS["single"] = not args.float64_corrections
    CORRECTIONS["products"] = not args.float64_products
    if args.memory_child:
        METHOD["method"] = args.method
        memory_child(args.memory_child, args.tol, args.preconditioner[0])
        return 0
    peer = not args.no_peer
    METHOD["method"] = args.method
    REPEATS["n"] = max(1, args.repeats)
    CLOCK["name"] = args.clock
    sizes_a = args.sizes or ([32, 64] if args.quick else [256, 512, 1024])
    sizes_d = args.sizes or ([32, 64] if args.quick else [256, 512, 1024, 2048])
    print(f"bench_contact: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}, numpy {np.__version__}, "
          f"tol {args.tol:g}, method {args.method}, one thread, elementwise passes: {passes()}, "
          f"fastest of {REPEATS['n']}, {CLOCK['name']} clock, clip corrections "
          f"{'float32' if CORRECTIONS['single'] else 'float64'}, direction products "
          f"{'mixed' if CORRECTIONS['products'] else 'float64'}")
    warm_up(args.preconditioner)
    if "a" in args.sections:
        section_a(sizes_a, args.tol, peer, args.peer_cap, args.preconditioner)
        for kind in args.preconditioner:
            section_a_memory(max(sizes_a), args.tol, kind)
    if "b" in args.sections:
        section_b(32 if args.quick else args.partial_size, args.tol, peer, 60 if args.quick else args.peer_cap,
                  args.condat_tol, args.condat_max_iter)
    if "c" in args.sections:
        frames = args.frames or (3 if args.quick else 10)
        section_c(frames, args.tol, 32 if args.quick else args.sliding_size)
    if "d" in args.sections:
        section_d(sizes_d, args.tol, args.preconditioner)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark of the forward model: time, error and memory of each method, against its FFT floor and Tamaas.

Run: ``python benchmarks/bench_forward.py [--quick] [--sizes 128 256 512 1024] [--no-peer]``

Tables (all from one run, single-threaded scipy.fft, float64, SI units):

1. Methods on the grid. Six stress components at one depth (1 mm) or three (0.5, 1, 2 mm).
   - ``spectral``: periodic band-limited load (a sum of oblique plane waves, p, qx, qy, zero mean,
     no Nyquist content), error against the exact plane-wave closed form (docs/theory.md s3,
     rotated to each wave's direction; independent of the spectral code). ``periodic_stress``
     is the core; ``facade`` is ``HalfSpace.stress(method="spectral")`` (validation, labelling).
   - ``dcfft``: isolated Gaussian contact (p, qx, qy), error against the closed-form direct sum
     (Boussinesq/Cerruti over every node) at 16 random nodes per depth, and (small grids) against
     a converged reference: the same continuous load on a grid twice as fine.
   - ``closed_form``: direct sums over nodes x points; on the full grid only where feasible
     (otherwise the time is extrapolated from a measured sensor subset and marked ``~``).
   Times: median and min over interleaved repeats; the FFT floor is timed in the same loop.
2. The FFT floor: what the method cannot avoid. spectral: one rfft2 per load component and one
   irfft2 per (depth, component); dcfft: the same on the zero-padded grid plus one kernel
   transform per (depth, component, load direction), a 2-D DCT-I of the kernel's quadrant
   (the kernels are even or odd in x and y). ``ratio`` = method / floor. DC-FFT's own load
   and inverse transforms are pruned (zero rows skipped, cropped output), so it can dip below.
3. Sensors at arbitrary (off-grid) points, 10 .. 10^4: closed form, spectral exact trigonometric
   sums, the ``LoadToSensor`` operator (dense off-grid path; fft path with sensors snapped to
   nodes). Times and agreement.
4. Peak memory at 1024^2, six components, three depths (tracemalloc; ``/usr/bin/time -v`` max
   RSS of a child process, minus the RSS of a child that only builds the load).
5. Peer: Tamaas ``volume_2d`` + ``boussinesq_gradient`` + ``hooke`` on the same periodic
   problem (512^2, one depth, nu = 0.49 because Tamaas's ``hooke`` refuses 0.5), run in its own
   venv as a subprocess; arrays exchanged via .npz, timed inside the subprocess.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import scipy.fft as sfft

from tactilab.core import jit
from tactilab.forward.halfspace.dcfft import dcfft_stress, padded_shape
from tactilab.forward.halfspace.facade import HalfSpace
from tactilab.forward.halfspace.fields import largest_strain
from tactilab.forward.halfspace.kernels import COMPONENTS, active_pairs, direct_stress
from tactilab.forward.halfspace.loads import SurfaceLoad
from tactilab.forward.halfspace.operator import LoadToSensor
from tactilab.forward.halfspace.spectral import periodic_stress

SPACING = 1e-4  # m, grid spacing of every scene
E_PA = 1e6  # Pa
DEPTHS = {1: (1e-3,), 3: (0.5e-3, 1e-3, 2e-3)}  # m
def _default_tamaas_venv() -> Path:
    """$TACTILAB_TAMAAS_VENV, else .bench-venv at the repository root (see docs/forward_benchmark.md)."""
    if "TACTILAB_TAMAAS_VENV" in os.environ:
        return Path(os.environ["TACTILAB_TAMAAS_VENV"])
    return Path(__file__).resolve().parents[1] / ".bench-venv"


TAMAAS_VENV = _default_tamaas_venv()
IDENTITY = np.eye(6)


# -- scenes and exact references ---------------------------------------------------------------
def plane_wave_modes(n: int, rng: np.random.Generator, count: int = 6) -> list[tuple]:
    """Random oblique plane waves on an n x n periodic grid: (mx, my, (P, Qx, Qy) Pa, phase).

    Wavelengths >= about 2 mm (|m| <= n / 20), never the zero mode or a Nyquist mode, so the
    grid represents each wave exactly and the rho = 0 convention does not enter.
    """
    top = max(2, n // 20)
    modes = []
    while len(modes) < count:
        mx, my = (int(v) for v in rng.integers(-top, top + 1, size=2))
        if mx == 0 and my == 0:
            continue
        modes.append((mx, my, rng.normal(scale=1e4, size=3), float(rng.uniform(0, 2 * np.pi))))
    return modes


def _phase(n: int, mx: int, my: int, phase: float, x, y):
    period = n * SPACING
    kx, ky = 2 * np.pi * mx / period, 2 * np.pi * my / period
    return kx, ky, kx * x + ky * y + phase


def plane_wave_load(n: int, modes) -> SurfaceLoad:
    """The periodic load sum_m (P, Qx, Qy)_m cos(k_m . x + phi_m) on the centred n x n grid."""
    x = (np.arange(n) - n // 2) * SPACING
    xx, yy = np.meshgrid(x, x)
    comps = np.zeros((3, n, n))
    for mx, my, amp, phase in modes:
        theta = _phase(n, mx, my, phase, xx, yy)[2]
        comps += amp[:, None, None] * np.cos(theta)
    return SurfaceLoad(p=comps[0], qx=comps[1], qy=comps[2], spacing=SPACING, periodic=True)


def plane_wave_stress(n: int, modes, depth: float, nu: float, x, y) -> np.ndarray:
    """Exact stress (6, *x.shape), Voigt order, of the plane-wave load at (x, y, depth).

    docs/theory.md s3 sinusoid solutions in the frame of each wave (x' along k, y' across), the
    antiplane part for the traction across the wave, sigma_y'y' = nu (sigma_x'x' + sigma_zz),
    then the tensor rotated back to (x, y). Written in real space, independently of spectral.py.
    """
    out = np.zeros((6,) + np.broadcast_shapes(np.shape(x), np.shape(y)))
    for mx, my, (p, qx, qy), phase in modes:
        kx, ky, theta = _phase(n, mx, my, phase, x, y)
        k = np.hypot(kx, ky)
        c, s = kx / k, ky / k
        q_par, q_perp = c * qx + s * qy, -s * qx + c * qy
        kz = k * depth
        e = np.exp(-kz)
        cos, sin = np.cos(theta), np.sin(theta)
        szz = -p * (1 + kz) * e * cos - q_par * kz * e * sin
        sxx_r = -p * (1 - kz) * e * cos - q_par * (2 - kz) * e * sin
        sxz_r = -p * kz * e * sin - q_par * (1 - kz) * e * cos
        syy_r = nu * (sxx_r + szz)
        syz_r = -q_perp * e * cos
        sxy_r = -q_perp * e * sin
        out[0] += c * c * sxx_r + s * s * syy_r - 2 * c * s * sxy_r
        out[1] += s * s * sxx_r + c * c * syy_r + 2 * c * s * sxy_r
        out[2] += szz
        out[3] += s * sxz_r + c * syz_r
        out[4] += c * sxz_r - s * syz_r
        out[5] += c * s * (sxx_r - syy_r) + (c * c - s * s) * sxy_r
    return out


def plane_wave_grid_stress(n: int, modes, depths, nu: float) -> np.ndarray:
    """Exact stress on the grid, shape (n_depth, 6, n, n)."""
    x = (np.arange(n) - n // 2) * SPACING
    xx, yy = np.meshgrid(x, x)
    return np.stack([plane_wave_stress(n, modes, z, nu, xx, yy) for z in depths])


def gaussian_load(n: int, spacing: float = SPACING, extent: float | None = None) -> SurfaceLoad:
    """Isolated fingertip-like contact: Gaussian p, qx, qy of standard deviation extent / 20 (Pa).

    At the grid edge (10 standard deviations) the load is e^-50 of its peak: the grid holds the
    whole contact, so a finer grid over the same extent sees the same continuous load.
    """
    extent = n * spacing if extent is None else extent
    x = (np.arange(n) - n // 2) * spacing
    xx, yy = np.meshgrid(x, x)
    g = np.exp(-(xx**2 + yy**2) / (2 * (extent / 20) ** 2))
    return SurfaceLoad(p=20e3 * g, qx=8e3 * g, qy=-3e3 * g, spacing=spacing)


def rel_err(got: np.ndarray, ref: np.ndarray) -> float:
    """max |got - ref| / max |ref| (the facade's error_estimate is defined the same way)."""
    return float(np.abs(got - ref).max() / np.abs(ref).max())


# -- timing ------------------------------------------------------------------------------------
def interleaved(funcs: dict, repeats: int, warm_up: bool = True) -> dict[str, tuple[float, float]]:
    """(median, min) wall time per function, the functions run in turn within each repeat.

    Interleaving makes the method and its FFT floor share the same background load of the
    (shared, noisy) machine; one warm-up call each is not timed (FFT plans, caches).
    """
    for f in funcs.values() if warm_up else ():
        f()
    times = {name: [] for name in funcs}
    for _ in range(repeats):
        for name, f in funcs.items():
            t0 = time.perf_counter()
            f()
            times[name].append(time.perf_counter() - t0)
    return {name: (float(np.median(t)), float(np.min(t))) for name, t in times.items()}


def spectral_floor(load: SurfaceLoad, n_depth: int):
    """The FFTs spectral cannot avoid: rfft2 per load component, irfft2 per (depth, component)."""
    arrays = list(load.components.values())
    spectrum = sfft.rfft2(arrays[0])
    shape = load.shape

    def run():
        for a in arrays:
            sfft.rfft2(a)
        for _ in range(n_depth * 6):
            sfft.irfft2(spectrum, s=shape)
    return run


def dcfft_floor(load: SurfaceLoad, n_depth: int):
    """DC-FFT's unavoidable transforms: loads and inverses on the padded grid, one kernel transform
    per (depth, component, load direction).

    Each point kernel is even or odd in x and in y, so its spectrum on the padded grid is a real
    2-D cosine/sine transform (DCT-I) of the quadrant of non-negative offsets, (M/2 + 1)^2 reals:
    that, not a full padded rfft2, is the kernel transform a method must pay.
    """
    padded = padded_shape(load.shape)
    arrays = list(load.components.values())
    quadrant = np.zeros(tuple(m // 2 + 1 for m in padded))
    spectrum = sfft.rfft2(np.zeros(padded))
    n_kernels = len(active_pairs(COMPONENTS, ("x", "y", "z"), 2))

    def run():
        for a in arrays:
            sfft.rfft2(a, s=padded)
        for _ in range(n_depth * n_kernels):
            sfft.dctn(quadrant, type=1)
        for _ in range(n_depth * 6):
            sfft.irfft2(spectrum, s=padded)
    return run, n_kernels


def repeats_for(n: int, quick: bool) -> int:
    if quick:
        return 5
    return {128: 21, 256: 15, 512: 11}.get(n, 5)


# -- table 1 and 2: methods vs FFT floor -------------------------------------------------------
def bench_spectral(n: int, n_depth: int, rng, repeats: int, nu: float = 0.5) -> dict:
    modes = plane_wave_modes(n, rng)
    load = plane_wave_load(n, modes)
    depths = DEPTHS[n_depth]
    hs = HalfSpace(E=E_PA, nu=nu)
    ref = plane_wave_grid_stress(n, modes, depths, nu)
    got = periodic_stress(load, depths, nu, IDENTITY)
    facade = hs.stress(load, list(depths), method="spectral", tol=1e-9)
    err_facade = rel_err(facade.data["stress"].values, ref)
    del facade
    t = interleaved({
        "time": lambda: periodic_stress(load, depths, nu, IDENTITY),
        "floor": spectral_floor(load, n_depth),
        "facade": lambda: hs.stress(load, list(depths), method="spectral", tol=1e-9),
    }, repeats)
    return dict(method="spectral", n=n, depths=n_depth, err=rel_err(got, ref), err_facade=err_facade, **t,
                note="periodic plane waves vs closed form")


def _dcfft_reference_err(n: int, depths) -> float:
    """dcfft on grid h vs dcfft on grid h/2 (same continuous Gaussian), at the common nodes."""
    coarse = dcfft_stress(gaussian_load(n), depths)
    fine = dcfft_stress(gaussian_load(2 * n, SPACING / 2, extent=n * SPACING), depths)
    return rel_err(fine[:, :, ::2, ::2], coarse) if fine.shape[-1] == 2 * n else float("nan")


def bench_dcfft(n: int, n_depth: int, rng, repeats: int, converged: bool) -> dict:
    load = gaussian_load(n)
    depths = DEPTHS[n_depth]
    hs = HalfSpace(E=E_PA, nu=0.5)
    got = dcfft_stress(load, depths)
    idx = rng.integers(0, n, size=(16, 2))
    errs = []
    for d, z in enumerate(depths):
        pts = np.column_stack([load.x[idx[:, 1]], load.y[idx[:, 0]], np.full(16, z)])
        ref = direct_stress(load, pts)  # (16, 6)
        errs.append(np.abs(got[d][:, idx[:, 0], idx[:, 1]].T - ref).max() / np.abs(got[d]).max())
    conv = _dcfft_reference_err(n, depths) if converged else float("nan")
    facade = hs.stress(load, list(depths), method="dcfft", tol=1e-9)
    estimate = facade.error_estimate
    del facade, got
    floor, n_kernels = dcfft_floor(load, n_depth)
    t = interleaved({
        "time": lambda: dcfft_stress(load, depths),
        "floor": floor,
        "facade": lambda: hs.stress(load, list(depths), method="dcfft", tol=1e-9),
    }, repeats)
    return dict(method="dcfft", n=n, depths=n_depth, err=float(max(errs)), err_conv=conv, estimate=estimate,
                **t, note=f"isolated Gaussian; floor has {n_kernels} kernel transforms per depth")


def bench_closed_form(n: int, n_depth: int, rng, repeats: int, full_grid_limit: int = 64) -> dict:
    """Direct sums: on the full grid when n <= full_grid_limit, else timed on 32 nodes and scaled."""
    load = gaussian_load(n)
    depths = DEPTHS[n_depth]
    hs = HalfSpace(E=E_PA, nu=0.5)
    if n <= full_grid_limit:
        t = interleaved({"time": lambda: hs.stress(load, list(depths), method="closed_form", tol=1e-9)},
                        max(3, repeats // 3))
        field = hs.stress(load, list(depths), method="closed_form", tol=1e-9).data["stress"].values
        err = rel_err(field, dcfft_stress(load, depths))
        return dict(method="closed_form", n=n, depths=n_depth, err=err, extrapolated=False, **t,
                    note="full grid; err vs dcfft (same nodal forces)")
    m = 32
    idx = rng.choice(n * n, size=m, replace=False)
    yy, xx = np.meshgrid(load.y, load.x, indexing="ij")
    pts = np.column_stack([xx.ravel()[idx], yy.ravel()[idx]])
    t = interleaved({"time": lambda: hs.stress(load, list(depths), points=pts, method="closed_form", tol=1e-9)},
                    1, warm_up=False)
    scale = n * n / m
    med, lo = t["time"]
    return dict(method="closed_form", n=n, depths=n_depth, err=float("nan"), extrapolated=True,
                time=(med * scale, lo * scale), note=f"~ scaled from {m} nodes (cost ~ n^4)")


def print_methods(rows: list[dict]) -> None:
    print("\nTable 1-2. Methods on the grid: six stress components, float64, times in ms "
          "(median and min of interleaved repeats)")
    head = (f"{'method':<12}{'grid':>7}{'z':>3}{'median':>10}{'min':>10}{'floor med':>10}{'floor min':>10}"
            f"{'ratio med':>10}{'ratio min':>10}{'facade':>9}{'error':>9}{'err 2':>9}{'estimate':>9}")
    print(head)
    print("-" * len(head))
    blank = ""
    for r in rows:
        med, lo = (1e3 * v for v in r["time"])
        mark = "~" if r.get("extrapolated") else " "
        if "floor" in r:
            fmed, fmin = (1e3 * v for v in r["floor"])
            floor = f"{fmed:10.2f}{fmin:10.2f}{med / fmed:10.2f}{lo / fmin:10.2f}"
        else:
            floor = f"{blank:>40}"
        fac = f"{1e3 * r['facade'][0]:9.2f}" if "facade" in r else f"{blank:>9}"
        err2 = r.get("err_facade", r.get("err_conv", float("nan")))
        est = f"{r['estimate']:9.1e}" if "estimate" in r else f"{blank:>9}"
        err = f"{r['err']:9.1e}" if np.isfinite(r["err"]) else f"{'-':>9}"
        err2 = f"{err2:9.1e}" if np.isfinite(err2) else f"{'-':>9}"
        print(f"{r['method']:<12}{r['n']:>5}^2{r['depths']:>3}{mark}{med:9.4g} {lo:9.4g}{floor}"
              f"{fac}{err}{err2}{est}")
    print("z: number of depths (1: 1 mm; 3: 0.5, 1, 2 mm). facade: HalfSpace.stress(method=...) median (adds\n"
          "validation and xarray labelling). error: spectral vs exact plane waves (closed form, docs/theory.md s3);\n"
          "dcfft vs the closed-form direct sum at 16 nodes per depth; closed_form (~: time scaled from 32 nodes,\n"
          "cost ~ n^4, infeasible on full grids) not compared. err 2: spectral through the facade vs exact;\n"
          "dcfft vs a converged reference (same Gaussian on a grid h/2, n <= 256). estimate: the facade's\n"
          "error_estimate for dcfft (relative to peak traction).")


def profile_breakdown(fun, repeats: int = 5, top: int = 4) -> tuple[float, float, list[tuple[str, float]]]:
    """cProfile split of one call, ms per call: (total, scipy.fft transforms, top other functions).

    numpy ufuncs are not profiled separately: their time counts in the Python function that
    calls them, which is what locates the glue between the FFTs.
    """
    import cProfile
    import pstats

    fun()
    prof = cProfile.Profile()
    prof.enable()
    for _ in range(repeats):
        fun()
    prof.disable()
    total = fft = 0.0
    others = []
    for (filename, _, name), (_, _, tottime, _, _) in pstats.Stats(prof).stats.items():
        total += tottime
        if "duccfft" in name or "pocketfft" in name:
            fft += tottime
        else:
            others.append((f"{Path(filename).stem}.{name}" if filename != "~" else name, tottime))
    others.sort(key=lambda item: -item[1])
    scale = 1e3 / repeats
    return total * scale, fft * scale, [(k, v * scale) for k, v in others[:top]]


def print_breakdown(n: int) -> None:
    rng = np.random.default_rng(7)
    per = plane_wave_load(n, plane_wave_modes(n, rng))
    iso = gaussian_load(n)
    print(f"\nWhere the time goes at {n}^2, one depth, six components (cProfile tottime, ms per call; "
          "numpy ufunc time counts in its calling function):")
    for title, fun in (("spectral.periodic_stress", lambda: periodic_stress(per, [1e-3], 0.5, IDENTITY)),
                       ("dcfft.dcfft_stress", lambda: dcfft_stress(iso, [1e-3]))):
        total, fft, others = profile_breakdown(fun)
        body = ", ".join(f"{k} {v:.1f}" for k, v in others)
        print(f"  {title}: total {total:.1f}; scipy.fft transforms {fft:.1f}; then {body}")


# -- table 3: sensors ---------------------------------------------------------------------------
def bench_sensors(counts, rng, quick: bool) -> list[dict]:
    """Off-grid sensors at one depth (1 mm), six components, p + qx + qy, 64^2 load grid."""
    n, depth = 64, 1e-3
    hs = HalfSpace(E=E_PA, nu=0.5)
    iso = gaussian_load(n)
    modes = plane_wave_modes(n, rng)
    per = plane_wave_load(n, modes)
    half = n * SPACING / 2
    rows = []
    for count in counts:
        pts = rng.uniform(-half, half - SPACING, size=(count, 2))
        reps = 1 if count >= 1000 else (3 if quick else 5)
        row = dict(count=count)
        t = interleaved({"closed": lambda: hs.stress(iso, depth, points=pts, method="closed_form", tol=1e-9),
                         "trig": lambda: hs.stress(per, depth, points=pts, method="spectral", tol=1e-9)}, reps,
                        warm_up=count < 1000)
        row.update(t)
        cf = hs.stress(iso, depth, points=pts, method="closed_form", tol=1e-9).data["stress"].values[0]  # (6, n)
        trig = hs.stress(per, depth, points=pts, method="spectral", tol=1e-9).data["stress"].values[0]
        row["trig_err"] = rel_err(trig, plane_wave_stress(n, modes, depth, 0.5, pts[:, 0], pts[:, 1]))
        frame = np.concatenate([iso.qx.ravel(), iso.qy.ravel(), iso.p.ravel()])
        dense_bytes = 6 * count * 3 * n * n * 8
        if dense_bytes <= 2**30:
            t0 = time.perf_counter()
            op = LoadToSensor(hs, (n, n), SPACING, sensors=pts, depth=depth, components=COMPONENTS,
                              loads=("qx", "qy", "p"))
            row["dense_build"] = time.perf_counter() - t0
            row["dense_apply"] = interleaved({"a": lambda: op.matvec(frame)}, reps)["a"]
            row["dense_err"] = rel_err(op.matvec(frame).reshape(6, count), cf)
            del op
        else:
            row["dense_skip"] = f"matrix {dense_bytes / 2**30:.1f} GiB"
        # fft path: sensors snapped to the nearest nodes
        snapped = np.round(pts / SPACING) * SPACING
        t0 = time.perf_counter()
        op = LoadToSensor(hs, (n, n), SPACING, sensors=snapped, depth=depth, components=COMPONENTS,
                          loads=("qx", "qy", "p"))
        row["fft_build"] = time.perf_counter() - t0
        row["fft_path"] = op.path
        row["fft_apply"] = interleaved({"a": lambda: op.matvec(frame)}, reps)["a"]
        ref = hs.stress(iso, depth, points=snapped, method="closed_form", tol=1e-9).data["stress"].values[0]
        row["fft_err"] = rel_err(op.matvec(frame).reshape(6, count), ref)
        rows.append(row)
    return rows


def print_sensors(rows: list[dict]) -> None:
    print("\nTable 3. Sensors at arbitrary points: 64^2 load grid (0.1 mm), depth 1 mm, six components, "
          "median s")
    head = (f"{'sensors':>8}{'closed':>9}{'trig':>9}{'trig err':>10}{'dense bld':>10}{'dense mv':>10}"
            f"{'dense agr':>10}{'fft bld':>9}{'fft mv':>9}{'fft agr':>9}")
    print(head)
    print("-" * len(head))
    for r in rows:
        if "dense_build" in r:
            dense = f"{r['dense_build']:10.4f}{r['dense_apply'][0]:10.5f}{r['dense_err']:10.1e}"
        else:
            dense = f"{'skipped: ' + r['dense_skip']:>30}"
        print(f"{r['count']:>8}{r['closed'][0]:9.4f}{r['trig'][0]:9.4f}{r['trig_err']:10.1e}{dense}"
              f"{r['fft_build']:9.4f}{r['fft_apply'][0]:9.5f}{r['fft_err']:9.1e}")
    print("closed: HalfSpace.stress(method='closed_form') on the isolated Gaussian; trig: method='spectral' on the\n"
          "periodic plane-wave load, exact trigonometric sums, err vs closed-form plane waves; dense: LoadToSensor\n"
          "off-grid path (build + one matvec), agreement vs closed; fft: LoadToSensor with sensors snapped to nodes\n"
          "(fft-padded path), agreement vs closed form at the snapped points.")


# -- table 4: memory ----------------------------------------------------------------------------
def traced_peak(fun) -> float:
    """tracemalloc peak (MiB) of one call, numpy buffers and the returned output included."""
    tracemalloc.start()
    try:
        out = fun()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    del out
    return peak / 2**20


def memory_child(which: str, n: int) -> None:
    """Entry for the /usr/bin/time -v subprocess: build the scene, run one method, exit."""
    depths = DEPTHS[3]
    load = plane_wave_load(n, plane_wave_modes(n, np.random.default_rng(0))) if which != "dcfft" else gaussian_load(n)
    if which == "spectral":
        periodic_stress(load, depths, 0.5, IDENTITY)
    elif which == "facade":
        HalfSpace(E=E_PA, nu=0.5).stress(load, list(depths), method="spectral", tol=1e-9)
    elif which == "dcfft":
        dcfft_stress(load, depths)


def max_rss_mib(which: str, n: int) -> float | None:
    if not Path("/usr/bin/time").exists():
        return None
    cmd = ["/usr/bin/time", "-v", sys.executable, str(Path(__file__).resolve()), "--memory-child", which,
           "--memory-n", str(n)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    match = re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr)
    return int(match.group(1)) / 1024 if match and proc.returncode == 0 else None


def bench_memory(n: int) -> list[tuple]:
    depths = DEPTHS[3]
    rows = []
    per = plane_wave_load(n, plane_wave_modes(n, np.random.default_rng(0)))
    iso = gaussian_load(n)
    hs = HalfSpace(E=E_PA, nu=0.5)
    out_mib = len(depths) * 6 * n * n * 8 / 2**20
    base = max_rss_mib("baseline", n)
    cases = [
        ("spectral", lambda: periodic_stress(per, depths, 0.5, IDENTITY)),
        ("facade", lambda: hs.stress(per, list(depths), method="spectral", tol=1e-9)),
        ("dcfft", lambda: dcfft_stress(iso, depths)),
    ]
    for name, fun in cases:
        peak = traced_peak(fun)
        rss = max_rss_mib(name, n)
        extra = rss - base if (rss is not None and base is not None) else None
        rows.append((name, peak, out_mib, rss, extra))
    return rows, base


def print_memory(rows, base, n: int) -> None:
    print(f"\nTable 4. Peak memory at {n}^2, six components, three depths (float64), MiB; target < 400 MB "
          f"(= {400e6 / 2**20:.0f} MiB)")
    head = f"{'method':<10}{'tracemalloc':>12}{'output':>8}{'max RSS':>9}{'RSS - base':>11}  met"
    print(head)
    print("-" * len(head))
    for name, peak, out_mib, rss, extra in rows:
        rss_s = f"{rss:9.0f}" if rss is not None else f"{'n/a':>9}"
        extra_s = f"{extra:11.0f}" if extra is not None else f"{'n/a':>11}"
        met = "yes" if peak < 400e6 / 2**20 else "NO"
        print(f"{name:<10}{peak:12.0f}{out_mib:8.0f}{rss_s}{extra_s}  {met}")
    print(f"base: max RSS of a child that imports tactilab and builds the load only = "
          f"{base:.0f} MiB" if base is not None else "base: /usr/bin/time not available")


# -- table 5: Tamaas ----------------------------------------------------------------------------
TAMAAS_SCRIPT = r'''
import sys, time, numpy as np
import tamaas as tm
data = np.load(sys.argv[1])
traction, depth, size, nu, E, repeats = (data["traction"], float(data["depth"]), float(data["size"]),
                                         float(data["nu"]), float(data["E"]), int(data["repeats"]))
n = traction.shape[0]
def build(layers):
    # volume_2d layers sit at z = l * Lz / (Nz - 1): with 2 layers, one at the surface, one at depth
    model = tm.Model(tm.model_type.volume_2d, [depth * (layers - 1), size, size], [layers, n, n])
    model.E, model.nu = E, nu
    tm.ModelFactory.registerVolumeOperators(model)
    model.traction[...] = traction
    grad, hooke = model.operators["boussinesq_gradient"], model.operators["hooke"]
    def run():
        grad(model.traction, model["strain"])
        hooke(model["strain"], model["stress"])
    run()
    return model, run
models = {layers: build(layers) for layers in (2, 3)}
times = {2: [], 3: []}
cpu = []
for _ in range(repeats):
    for layers, (_, run) in models.items():
        t0, c0 = time.perf_counter(), time.thread_time(); run(); times[layers].append(time.perf_counter() - t0)
        if layers == 2:
            cpu.append(time.thread_time() - c0)
np.savez(sys.argv[2], stress=np.array(models[2][0]["stress"])[1], times=np.array(times[2]),
         times3=np.array(times[3]), cpu=np.array(cpu), version=tm.__version__)
'''


def tamaas_python() -> Path | None:
    exe = TAMAAS_VENV / "bin" / "python"
    if not exe.exists():
        return None
    ok = subprocess.run([str(exe), "-c", "import tamaas"], capture_output=True)
    return exe if ok.returncode == 0 else None


def _run_tamaas(load: SurfaceLoad, depth: float, nu: float, repeats: int) -> dict | str:
    """Tamaas on ``load`` in its own venv (a subprocess, OMP_NUM_THREADS=1), timed inside it.

    Returns the peer's stress in our layout (6, ny, nx), its wall times (2 and 3 layers), its
    thread CPU times (2 layers) and version; or a line saying why it was skipped.
    """
    exe = tamaas_python()
    if exe is None:
        return (f"Tamaas skipped: no importable tamaas in {TAMAAS_VENV} (create it with "
                "'python3.12 -m venv .bench-venv && .bench-venv/bin/pip install tamaas' at the repository "
                "root, or set TACTILAB_TAMAAS_VENV)")
    n = load.shape[-1]
    # Tamaas grids are indexed (x, y) from x = 0; ours (y, x) from x = -L/2: transpose, and the
    # shift by half a period is the same for load and field, so the fields compare node by node.
    traction = np.stack([load.qx.T, load.qy.T, load.p.T], axis=-1)
    with tempfile.TemporaryDirectory() as tmp:
        src, dst, script = Path(tmp, "in.npz"), Path(tmp, "out.npz"), Path(tmp, "peer.py")
        np.savez(src, traction=traction, depth=depth, size=n * SPACING, nu=nu, E=E_PA, repeats=repeats)
        script.write_text(TAMAAS_SCRIPT)
        env = dict(os.environ, OMP_NUM_THREADS="1")
        proc = subprocess.run([str(exe), str(script), str(src), str(dst)], capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            return f"Tamaas skipped: the peer subprocess failed: {proc.stderr.strip().splitlines()[-1:]}"
        peer = dict(np.load(dst))
    # Tamaas shear is in Mandel form (x sqrt 2); measured on oblique plane waves, its channel 3
    # holds our xy and channel 5 our yz (channels 0-2 and 4 map to xx, yy, zz, zx directly).
    st, mandel = peer["stress"], np.sqrt(2.0)
    peer["fields"] = np.stack([st[..., 0].T, st[..., 1].T, st[..., 2].T, st[..., 5].T / mandel,
                               st[..., 4].T / mandel, st[..., 3].T / mandel])
    peer["version"] = str(peer["version"])
    return peer


def bench_tamaas(n: int, rng, repeats: int) -> dict | str:
    """Same periodic problem in tactilab and Tamaas (1 thread each); errors vs exact plane waves."""
    nu, depth = 0.49, 1e-3
    modes = plane_wave_modes(n, rng)
    load = plane_wave_load(n, modes)
    ref = plane_wave_grid_stress(n, modes, [depth], nu)[0]  # (6, ny, nx)
    own = {"tactilab core": lambda: periodic_stress(load, [depth], nu, IDENTITY),
           "tactilab facade": lambda: HalfSpace(E=E_PA, nu=nu).stress(load, depth, method="spectral", tol=1e-9)}
    before = interleaved(own, repeats)
    peer = _run_tamaas(load, depth, nu, repeats)
    if isinstance(peer, str):
        return peer
    peer_times = peer["times"]
    # Tamaas always evaluates the surface layer too: estimate its one-layer time as T2 - (T3 - T2)
    one_layer = float(2 * np.median(peer_times) - np.median(peer["times3"]))
    after = interleaved(own, repeats)
    ours = periodic_stress(load, [depth], nu, IDENTITY)[0]
    own_t = {k: (float(np.median([before[k][0], after[k][0]])), min(before[k][1], after[k][1])) for k in own}
    return dict(n=n, nu=nu, version=peer["version"], peer=(float(np.median(peer_times)), float(peer_times.min())),
                one_layer=one_layer,
                own=own_t, err_own=rel_err(ours, ref), err_peer=rel_err(peer["fields"], ref),
                agree=rel_err(peer["fields"], ours))


# -- table 0: the facade at the FFT floor, and against Tamaas ---------------------------------------
def interleaved_cpu(funcs: dict, repeats: int) -> dict[str, dict[str, float]]:
    """Like :func:`interleaved`, recording wall and thread-CPU time: {name: {wall_min, wall_med, cpu_min}}.

    Thread CPU time leaves out the time the (shared) machine spent on other processes. The order
    of the functions is shuffled in every repeat (seeded), so each runs about equally often after
    each other one: what ran before changes what is left in the caches (a fixed order would always
    run the same function after the floor's small working set and the same one after a warm call).
    """
    for f in funcs.values():
        f()
    wall = {name: [] for name in funcs}
    cpu = {name: [] for name in funcs}
    names = list(funcs)
    order = np.random.default_rng(0)
    for _ in range(repeats):
        for name in order.permutation(names):
            t0, c0 = time.perf_counter(), time.thread_time()
            funcs[name]()
            wall[name].append(time.perf_counter() - t0)
            cpu[name].append(time.thread_time() - c0)
    return {name: dict(wall_min=min(wall[name]), wall_med=float(np.median(wall[name])), cpu_min=min(cpu[name]))
            for name in funcs}


def bench_floor_table(sizes, repeats: int, rng, peer: bool = True) -> list[dict]:
    """The facade ``HalfSpace.stress(load, 1 mm, method="spectral")`` on a periodic p, qx, qy load
    (six stress components, one depth, float64, one FFT thread) against its FFT floor
    (3 rfft2 + 6 irfft2, timed interleaved in this process) and against Tamaas (same load)."""
    nu, depth = 0.49, 1e-3
    rows = []
    for n in sizes:
        modes = plane_wave_modes(n, rng)
        load = plane_wave_load(n, modes)
        hs = HalfSpace(E=E_PA, nu=nu)
        ref = plane_wave_grid_stress(n, modes, [depth], nu)[0]
        got = hs.stress(load, depth, method="spectral", tol=1e-9).data["stress"].values[0]
        t = interleaved_cpu({"facade": lambda: hs.stress(load, depth, method="spectral", tol=1e-9),
                             "labelled": lambda: hs.stress(load, depth, method="spectral", tol=1e-9).data,
                             "floor": spectral_floor(load, 1)}, repeats)
        row = dict(n=n, err=rel_err(got, ref), **{f"{k}_{m}": v for k, d in t.items() for m, v in d.items()})
        result = _run_tamaas(load, depth, nu, max(5, repeats // 2)) if peer else "Tamaas skipped (--no-peer)"
        if isinstance(result, str):
            row["peer_note"] = result
        else:
            row.update(peer_wall=float(result["times"].min()), peer_cpu=float(result["cpu"].min()),
                       peer_one_layer=float(2 * np.median(result["times"]) - np.median(result["times3"])),
                       peer_med=float(np.median(result["times"])), peer_agree=rel_err(result["fields"], got),
                       peer_version=result["version"])
        rows.append(row)
    return rows


def print_floor_table(rows: list[dict]) -> None:
    print("\nTable 0. The facade at the FFT floor: HalfSpace(E, nu=0.49).stress(load, 1 mm, method='spectral'),\n"
          "periodic p + qx + qy, six stress components, one depth, float64, 1 FFT thread; min over interleaved repeats")
    head = (f"{'size':>6}{'facade ms':>11}{'floor ms':>10}{'ratio':>7}{'ratio med':>10}{'ratio cpu':>10}"
            f"{'+data':>7}{'Tamaas ms':>11}{'speedup':>9}{'spd cpu':>9}{'spd 1-layer':>12}{'error':>9}")
    print(head)
    print("-" * len(head))
    for r in rows:
        fac, flo = r["facade_wall_min"], r["floor_wall_min"]
        line = (f"{r['n']:>4}^2{1e3 * fac:11.2f}{1e3 * flo:10.2f}{fac / flo:7.2f}"
                f"{r['facade_wall_med'] / r['floor_wall_med']:10.2f}{r['facade_cpu_min'] / r['floor_cpu_min']:10.2f}"
                f"{r['labelled_wall_min'] / flo:7.2f}")
        if "peer_wall" in r:
            line += (f"{1e3 * r['peer_wall']:11.2f}{r['peer_wall'] / fac:9.2f}"
                     f"{r['peer_cpu'] / r['facade_cpu_min']:9.2f}{r['peer_one_layer'] / r['facade_wall_med']:12.2f}")
        else:
            line += f"{'-':>11}{'-':>9}{'-':>9}{'-':>12}"
        print(line + f"{r['err']:9.1e}")
    notes = [r["peer_note"] for r in rows if "peer_note" in r]
    agree = [f"{r['n']}^2: {r['peer_agree']:.1e}" for r in rows if "peer_agree" in r]
    version = next((r["peer_version"] for r in rows if "peer_version" in r), None)
    print("ratio = facade / floor (min wall times; 'ratio med': medians; 'ratio cpu': thread CPU time, which leaves\n"
          "out time lost to other processes; '+data': the facade call plus its first access of result.data, which\n"
          "builds the labelled xarray Dataset, min wall). Tamaas ms: its min wall time for the same load "
          f"(Tamaas {version}, OMP_NUM_THREADS=1, two layers:\nit always evaluates the surface too); speedup = "
          "Tamaas / facade (wall, cpu); 'spd 1-layer': Tamaas charged for one layer,\nT(2) - [T(3) - T(2)], "
          "medians. error: facade vs the exact plane-wave closed form. Tamaas vs facade, max difference / peak: "
          + (", ".join(agree) if agree else "-") + ".\nTargets: ratio <= 1.5, speedup >= 3 at 256^2.")
    for note in dict.fromkeys(notes):
        print(note)


def print_tamaas(res) -> None:
    print("\nTable 5. Peer: Tamaas volume_2d + boussinesq_gradient + hooke vs tactilab spectral, same periodic load")
    if isinstance(res, str):
        print(res)
        return
    print(f"{res['n']}^2, one depth (1 mm), six stress components, nu = {res['nu']} (Tamaas's hooke refuses 0.5), "
          f"Tamaas {res['version']}, OMP_NUM_THREADS=1, scipy.fft 1 thread")
    head = f"{'code':<18}{'median s':>10}{'min s':>9}{'Tamaas/this':>12}{'error vs exact':>16}"
    print(head)
    print("-" * len(head))
    peer_med = res["peer"][0]
    print(f"{'Tamaas':<18}{res['peer'][0]:10.4f}{res['peer'][1]:9.4f}{1.0:12.2f}{res['err_peer']:16.1e}")
    for name, (med, lo) in res["own"].items():
        print(f"{name:<18}{med:10.4f}{lo:9.4f}{peer_med / med:12.2f}{res['err_own']:16.1e}")
    one = res["one_layer"]
    print(f"Tamaas vs tactilab, max difference / peak: {res['agree']:.1e}. Tamaas evaluates two layers\n"
          "(z = 0 and z = depth: its volume grid always starts at the surface). Charging it for one layer only\n"
          f"(T(2 layers) - [T(3) - T(2)], medians = {one:.4f} s) the ratio would be "
          f"{one / res['own']['tactilab core'][0]:.2f} (core) and {one / res['own']['tactilab facade'][0]:.2f} "
          "(facade).\nShear stored in Mandel form (x sqrt 2), divided back. Target: tactilab >= 3x faster.")


def bench_phases(n: int, repeats: int) -> dict[str, float]:
    """Minimum wall time (s) of each phase of the facade call of Table 0 and of the floor's parts,
    interleaved, order shuffled in each repeat: {phase: min}. Uses the solver's internals (forward/halfspace/_hotpath.py)."""
    from tactilab.forward.halfspace import _hotpath
    from tactilab.forward.halfspace.spectral import _cached_geometry, _real_coefficients

    nu, depth = 0.49, 1e-3
    load = plane_wave_load(n, plane_wave_modes(n, np.random.default_rng(1)))
    hs = HalfSpace(E=E_PA, nu=nu)
    names = tuple(sorted(load.components))
    key = (tuple(load.shape), tuple(load.spacing), "float64")
    g = _cached_geometry(*key)
    hs.stress(load, depth, method="spectral", tol=1e-9)  # fills the table cache
    fused = jit.enabled()  # the path periodic_stress takes now: compiled kernels or their NumPy twins
    block = _hotpath.work_block(g.rho.shape, np.complex128, len(names) + 2)
    spectra = dict(zip(names, block))
    tables = _hotpath.depth_tables(g, key, nu, names, IDENTITY, depth, np.dtype(float), np.dtype(complex),
                                   _real_coefficients, fused)
    out = np.empty((6,) + load.shape)
    spectrum = sfft.rfft2(load.p)
    field = periodic_stress(load, [depth], nu, IDENTITY)

    def forward():
        for name in names:
            _hotpath.rfftn_into(load.components[name], spectra[name], 1)

    def passes():
        for terms in tables:
            if fused:
                _hotpath.apply_fused(terms, block[:len(names)], block[-2])
            else:
                _hotpath.apply(terms, spectra, block[-2], block[-1])

    def inverse():
        for o in range(6):
            _hotpath.inverse_into(block[-2], out[o], 1)  # overwrites its input: the timing does not care

    funcs = {"facade": lambda: hs.stress(load, depth, method="spectral", tol=1e-9),
             "facade + .data": lambda: hs.stress(load, depth, method="spectral", tol=1e-9).data,
             "periodic_stress": lambda: periodic_stress(load, [depth], nu, IDENTITY),
             "3 forward transforms": forward,
             "6 compiled multiply-adds" if fused else "30 multiply-add passes": passes,
             "6 inverse transforms": inverse,
             "small-strain check": lambda: largest_strain(field, "stress", COMPONENTS, E_PA, nu),
             "floor": spectral_floor(load, 1),
             "floor: 3 rfft2": lambda: [sfft.rfft2(a) is None for a in load.components.values()],
             "floor: 6 irfft2": lambda: [sfft.irfft2(spectrum, s=load.shape) is None for _ in range(6)]}
    return {name: t["wall_min"] for name, t in interleaved_cpu(funcs, repeats).items()}


def print_phases(sizes, repeats: int) -> None:
    print(f"\nTable 0b. Where the facade call of Table 0 goes: minimum wall time over {repeats} interleaved repeats "
          "(order shuffled in each), ms and / floor")
    rows = {n: bench_phases(n, repeats) for n in sizes}
    print(f"{'phase':<26}" + "".join(f"{f'{n}^2 ms':>11}{'/ floor':>9}" for n in sizes))
    for phase in rows[sizes[0]]:
        print(f"{phase:<26}" + "".join(f"{1e3 * rows[n][phase]:11.3f}{rows[n][phase] / rows[n]['floor']:9.2f}"
                                        for n in sizes))


def kernels_in_use() -> str:
    """Which path the solver's elementwise passes take (tactilab.core.jit), for the header."""
    if jit.enabled():
        import numba

        return f"compiled (numba {numba.__version__})"
    if jit.available():
        return "NumPy (TACTILAB_JIT=0)"
    return "NumPy (numba not installed: the 'fast' extra)"


# -- driver -------------------------------------------------------------------------------------
def run_methods(sizes, quick: bool, rng) -> list[dict]:
    rows = []
    for n in sizes:
        reps = repeats_for(n, quick)
        for n_depth in (1, 3):
            rows.append(bench_spectral(n, n_depth, rng, reps))
            rows.append(bench_dcfft(n, n_depth, rng, max(3, reps // 2), converged=n <= 256))
            rows.append(bench_closed_form(n, n_depth, rng, reps))
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small grids and few repeats (< ~60 s)")
    parser.add_argument("--sizes", type=int, nargs="+", help="grid sizes n (n x n); default 128 256 512 1024")
    parser.add_argument("--no-peer", action="store_true", help="skip the Tamaas comparison")
    parser.add_argument("--floor-only", action="store_true",
                        help="only Table 0 (facade vs FFT floor vs Tamaas at 256^2 and 512^2), about a minute")
    parser.add_argument("--repeats", type=int, default=None,
                        help="interleaved repeats of Table 0 (default 101; 5 with --quick)")
    parser.add_argument("--phases", action="store_true",
                        help="only Table 0b: the facade call of Table 0 phase by phase (forward transforms, "
                             "multiply-add passes, inverse transforms) against the floor's parts")
    parser.add_argument("--memory-child", help=argparse.SUPPRESS)
    parser.add_argument("--memory-n", type=int, default=1024, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    sys.stdout.reconfigure(line_buffering=True)  # tables appear as they finish when piped to a file
    if args.memory_child:
        memory_child(args.memory_child, args.memory_n)
        return 0
    rng = np.random.default_rng(20261122)
    sizes = args.sizes or ([128, 256] if args.quick else [128, 256, 512, 1024])
    t_start = time.perf_counter()
    print(f"tactilab forward benchmark ({'quick' if args.quick else 'full'}): spacing {SPACING * 1e3} mm, "
          f"E = {E_PA:.0e} Pa, nu = 0.5 unless stated, float64, scipy {sfft.__name__} 1 thread, "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
    print(f"kernels: {kernels_in_use()}")
    floor_repeats = args.repeats or (5 if args.quick else 101)
    if args.phases:
        print_phases(args.sizes or [256, 512], args.repeats or (5 if args.quick else 101))
        return 0
    print_floor_table(bench_floor_table(args.sizes or [256, 512], floor_repeats, rng, not args.no_peer))
    if args.floor_only:
        print(f"\nload average at end {os.getloadavg()[0]:.1f}")
        return 0
    print_methods(run_methods(sizes, args.quick, rng))
    print_breakdown(256 if args.quick else 512)
    counts = [10, 100] if args.quick else [10, 100, 1000, 10000]
    print_sensors(bench_sensors(counts, rng, args.quick))
    mem_n = 256 if args.quick else 1024
    print_memory(*bench_memory(mem_n), mem_n)
    if args.no_peer:
        print("\nTable 5. Peer: skipped (--no-peer)")
    else:
        peer_n = 256 if args.quick else 512
        print_tamaas(bench_tamaas(peer_n, rng, 5 if args.quick else 11))
    print(f"\ntotal benchmark time {time.perf_counter() - t_start:.0f} s, load average at end "
          f"{os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

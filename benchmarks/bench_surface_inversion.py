"""Benchmark of the surface inversion: a 3-D fingertip scanning a ridged random profile.

The issue's configuration (the defaults: 500 frames, 20 um contact grid, 512 profile nodes over the
scanned strip): R = 10 mm, 0.5 N, E = 1 MPa, nu = 1/2, friction 0.5 (sliding), a y-uniform random
profile (self-affine, rms 5 um), 9 sensors (zz and zx) 2 mm apart at 2 mm depth, force and friction
free. Reduced runs shrink the force, the frame count and the grid. Printed: the time of the MAP and
the Laplace posterior split into scan solves, explicit Jacobians (by default only at the flat start,
where one frame's solves serve every frame, and at the MAP) and exact gradients (the Gauss-Newton
steps in between), the posterior mean's rms error against the truth, the 90 % band's coverage of
touched nodes, the context posterior, and the same error for the linearised inversion (the first
Gauss-Newton step from the flat surface: the full-contact linearisation around the smooth finger's
contact). ``--workers`` threads (default 2, this machine's cores) run chunks of the Jacobian's and the
gradients' solves and blocks of the scan solves' frames; the times are wall and process CPU.

    python benchmarks/bench_surface_inversion.py            # the issue's size, minutes
    python benchmarks/bench_surface_inversion.py --quick --jacobian-every 1
"""

from __future__ import annotations

import argparse
import contextlib
import math
import time

import numpy as np
from scipy.fft import next_fast_len
from scipy.stats import norm

from tactilab.data_schemas.sensors import SensorArray
from tactilab.forward import HalfSpace, HertzContact, SensorReadout, finger_gap
from tactilab.inversion import LogNormal, Normal, StationaryPrior
from tactilab.inversion.surface import invert_scan
from tactilab.inversion.surface_jacobian import ScanJacobian
from tactilab.inversion.surface_laplace import prior_root
from tactilab.inversion.surface_scan import ContactScan, ProfileGrid


@contextlib.contextmanager
def clocks(parts):
    """Time the calls of ``{label: (class, method name)}`` while inside: yields {label: [calls, wall
    seconds, process CPU seconds]} (on a shared machine the CPU time is the steadier figure)."""
    out, saved = {label: [0, 0.0, 0.0] for label in parts}, []
    for label, (cls, name) in parts.items():
        original = getattr(cls, name)
        saved.append((cls, name, original))

        def timed(*args, _f=original, _c=out[label], **kwargs):
            t, c = time.perf_counter(), time.process_time()
            try:
                return _f(*args, **kwargs)
            finally:
                _c[0] += 1
                _c[1] += time.perf_counter() - t
                _c[2] += time.process_time() - c

        setattr(cls, name, timed)
    try:
        yield out
    finally:
        for cls, name, original in saved:
            setattr(cls, name, original)


#: the contact grid's half-width in Hertz radii (then widened to a fast padded FFT size): the solved
#: contacts reach about 1.05 a here, so the frames' pressure stays well inside the grid
MARGIN = 1.25


def build(force, frames, spacing, depth, sensor_pitch, rms, ell, seed, margin=MARGIN, profile_nodes=0):
    """The scan (heights -> outputs), the true profile and the prior; the profile has ``profile_nodes``
    nodes over the scanned strip (0: the contact grid's spacing)."""
    E, nu, R = 1e6, 0.5, 10e-3
    a = HertzContact(force, R, E, nu).contact_radius
    n = 2 * int(math.ceil(margin * a / spacing))
    while next_fast_len(2 * n, real=True) != 2 * n:
        n += 2
    skin = HalfSpace(E=E, nu=nu)
    grid = (n, n)
    g = np.arange(3) - 1
    sensors = SensorArray(positions_m=np.array([[i * sensor_pitch, j * sensor_pitch] for j in g for i in g]),
                          depth_m=depth, components=("zz", "zx"))
    w = SensorReadout(skin, grid, spacing, sensors, loads=("p", "qx")).weights
    x = (np.arange(n) - n // 2) * spacing
    pos = np.arange(frames) * spacing
    px = np.linspace(x[0], x[-1] + pos[-1], profile_nodes) if profile_nodes else x[0] + spacing * np.arange(n + frames)
    scan = ContactScan(young_modulus=E, poisson_ratio=nu, grid_shape=grid, spacing=spacing,
                       shape_gap=finger_gap(grid, spacing, R), positions=pos, weights_p=w[: n * n],
                       weights_q=w[n * n: 2 * n * n], profile=ProfileGrid(x=px), normal_force=force, friction=0.5,
                       friction_direction=-1.0, tol=1e-8)
    prior = StationaryPrior(variance=rms**2, correlation_length=ell, kind="self_affine", hurst=0.8)
    rng = np.random.default_rng(seed)
    truth = prior_root(prior, (px.size,), float(px[1] - px[0])) @ rng.standard_normal(px.size)
    return scan, truth, prior, rng


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a reduced run (0.02 N, 8 frames, 40 um grid)")
    p.add_argument("--force", type=float, default=0.5, help="N")
    p.add_argument("--frames", type=int, default=500)
    p.add_argument("--grid-spacing", type=float, default=20e-6, help="m")
    p.add_argument("--depth", type=float, default=2e-3, help="sensor depth, m")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--profile", type=int, default=512, help="profile nodes over the strip (0: the grid's spacing)")
    p.add_argument("--margin", type=float, default=MARGIN, help="the contact grid's half-width in Hertz radii")
    p.add_argument("--jacobian-every", type=int, default=100,
                   help="Gauss-Newton iterations per explicit Jacobian (the exact gradient in between)")
    p.add_argument("--jacobian-tol", type=float, default=1e-4,
                   help="the Jacobian's restricted solves' tolerance (it sets only the Hessian: the MAP is the exact "
                        "gradient's zero)")
    p.add_argument("--gradient-tol", type=float, default=1e-6,
                   help="the exact gradients' restricted solves' tolerance (they steer; the MAP was unchanged)")
    p.add_argument("--map-tol", type=float, default=5e-3,
                   help="nats: the Gauss-Newton decrement at which the MAP search stops (invert_scan's map_tol)")
    p.add_argument("--workers", type=int, default=2, help="threads over chunks of the Jacobian's and gradients' solves and blocks of frames")
    p.add_argument("--solve-dtype", choices=("float32", "float64"), default="float32",
                   help="precision of the Jacobian's and gradients' restricted solves' iterations (float32 is refined "
                        "until the float64 residual meets their tolerances)")
    args = p.parse_args(argv)
    if args.quick:
        args.force, args.frames, args.grid_spacing, args.depth, args.margin = 0.02, 8, 40e-6, 0.3e-3, 1.5
        args.profile = 0
    scan, truth, prior, rng = build(args.force, args.frames, args.grid_spacing, args.depth,
                                    sensor_pitch=args.depth, rms=5e-6, ell=0.3e-3, seed=args.seed,
                                    margin=args.margin, profile_nodes=args.profile)
    t0 = time.perf_counter()
    clean = scan.solve(truth)
    t_solve = time.perf_counter() - t0
    sigma = 0.01 * np.abs(clean.outputs).max()
    data = clean.outputs + sigma * rng.standard_normal(clean.outputs.shape)
    context = {"normal_force": LogNormal(args.force, 0.2), "friction": Normal(0.5, 0.1)}
    parts = {"scan solves": (ContactScan, "solve"), "Jacobians": (ScanJacobian, "matrix"),
             "gradients": (ScanJacobian, "adjoint")}
    t0, c0 = time.perf_counter(), time.process_time()
    with clocks(parts) as spent:
        post = invert_scan(scan, data, sigma, prior=prior, context=context, rng=rng, n_draws=200,
                           jacobian_every=args.jacobian_every, jacobian_tol=args.jacobian_tol, workers=args.workers,
                           gradient_tol=args.gradient_tol, solve_dtype=args.solve_dtype, map_tol=args.map_tol)
    t_map, c_map = time.perf_counter() - t0, time.process_time() - c0
    lin = invert_scan(scan, data, sigma, prior=prior, context=context, rng=rng, n_draws=20, max_iter=1,
                       continuation=False)
    t = post.touched
    offset = np.mean(post.mean[t] - truth[t])  # the absolute level is not identified
    z90 = norm.ppf(0.95)
    print(f"grid {scan.grid_shape}, {scan.n_frames} frames, {scan.n_out} outputs, profile {scan.profile.size} nodes; "
          f"Jacobian tol {args.jacobian_tol:g}, gradient tol {args.gradient_tol:g} ({args.solve_dtype} iterations), "
          f"{args.workers} threads; MAP decrement tol {args.map_tol:g} nats")
    print(f"one scan solve: {t_solve:.2f} s; MAP + Laplace: {t_map:.1f} s (process CPU {c_map:.1f} s); {post.message}")
    rest, c_rest = t_map - sum(v[1] for v in spent.values()), c_map - sum(v[2] for v in spent.values())
    print("  of which " + "; ".join(f"{k}: {v[0]} x, {v[1]:.1f} s (CPU {v[2]:.1f} s)" for k, v in spent.items())
          + f"; the rest (the bound's draws, factorisations): {rest:.1f} s (CPU {c_rest:.1f} s)")
    hit = np.flatnonzero(clean.contact.any(axis=0).any(axis=0))
    print(f"contact reaches column {hit.min()} .. {hit.max()} of {scan.grid_shape[-1]} (the grid's margin)")
    err = np.sqrt(np.mean((post.mean[t] - truth[t] - offset) ** 2))
    cover = np.mean(np.abs(post.mean[t] - truth[t]) <= z90 * post.std[t])
    print(f"touched {post.touched_fraction:.2f}; rms error (level removed) {err * 1e6:.3f} um; "
          f"90 % band covers {cover:.2f} of the touched nodes")
    lo = np.mean(lin.mean[t] - truth[t])
    lin_err = np.sqrt(np.mean((lin.mean[t] - truth[t] - lo) ** 2))
    print(f"linearised (one Gauss-Newton step): rms error {lin_err * 1e6:.3f} um, chi2 {lin.chi2:.4g} (the MAP's "
          f"{post.chi2:.4g}) for {data.size} data")
    for name, c in post.context.items():
        print(f"{name}: {c['mean']:.4g} +- {c['sd']:.2g} (90 %: {c['q05']:.4g} .. {c['q95']:.4g})")


if __name__ == "__main__":
    main()

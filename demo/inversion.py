"""Inversion demo: a surface profile with its credible band, and a defect located by emcee."""

from __future__ import annotations

import pathlib
import time
import warnings
from collections.abc import Iterator

import numpy as np

E_SKIN, NU, DEPTH, DX, N = 1e6, 0.5, 1e-3, 50e-6, 1024


def _profile_operator():
    """Plane strain: rigid surface height H(x) sliding frictionless on the skin -> sigma_zz at depth."""
    from tactilab.inversion import rigid_surface_height_operator

    return rigid_surface_height_operator(N, DX, DEPTH, E_SKIN, NU)


def _profile_section(out: pathlib.Path, rng) -> Iterator[str]:
    from tactilab.inversion import StationaryPrior, gaussian_posterior, invert_linear, plot_criteria, plot_profile

    op = _profile_operator()
    x = (np.arange(N) - N // 2) * DX
    truth = (20e-6 * np.exp(-(((x + 8e-3) / 1.5e-3) ** 2)) + 10e-6 * np.cos(2 * np.pi * x / 4e-3)
             * np.exp(-((x / 5e-3) ** 2)) - 8e-6 * np.exp(-(((x - 12e-3) / 0.4e-3) ** 2)))
    truth -= truth.mean()  # a uniform height change loads nothing (k = 0 is not seen): heights are relative
    clean = op.matvec(truth)
    noise = 20.0  # Pa
    data = clean + rng.normal(0, noise, N)
    yield (f"[inversion] profile: plane-strain scan of a rigid surface (bump, 4 mm undulation, 0.4 mm pit) over "
           f"skin E = {E_SKIN / 1e6:g} MPa, sensor at {DEPTH * 1e3:g} mm, {N} samples every {DX * 1e6:g} µm, "
           f"noise {noise:g} Pa")
    t = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        tik = invert_linear(op, data, penalty="curvature", noise_std=noise, criterion="evidence")
    el = time.perf_counter() - t
    yield f"  Tikhonov ({tik.method} path, curvature penalty) in {el * 1e3:.1f} ms; lam chosen by: " + ", ".join(
        f"{k} {v:.3g}" for k, v in tik.criteria.lam.items())
    for w in caught:  # a warning, not a text line: the run summary counts every warning it printed
        warnings.warn(f"[inversion] profile: {w.message}", w.category, stacklevel=2)
    plot_criteria(tik.criteria, out / "profile_criteria.png", title="Profile inversion: regularisation criteria",
                  data_unit="Pa")
    # Gaussian prior: Matern-3/2, 0.5 mm; its variance chosen by the evidence (marginal likelihood)
    variances = np.geomspace(1e-13, 1e-8, 21)
    evid = [gaussian_posterior(op, data, StationaryPrior(v, 0.5e-3), noise).log_evidence for v in variances]
    best = float(variances[int(np.argmax(evid))])
    t = time.perf_counter()
    post = gaussian_posterior(op, data, StationaryPrior(best, 0.5e-3), noise)
    el = time.perf_counter() - t
    inside = float(np.mean(np.abs(truth - post.mean) <= 1.96 * post.std))
    err = float(np.linalg.norm(post.mean - truth) / np.linalg.norm(truth))
    band = post.resolvable_band(depth=DEPTH)
    yield (f"  exact Gaussian posterior ({post.method}) in {el * 1e3:.2f} ms; prior std {np.sqrt(best) * 1e6:.2g} µm "
           f"(max evidence); error {err:.2%}; truth inside the 95% band at {inside:.0%} of nodes; "
           f"pointwise std {post.std[0] * 1e6:.2g} µm")
    yield (f"  resolvable band: |k| < {band['k_max'] / 1e3:.2f} rad/mm (wavelengths > {band['wavelength_min'] * 1e3:.2f}"
           f" mm); rough rule ln(SNR)/Z = {band['k_c_estimate'] / 1e3:.2f} rad/mm")
    plot_profile(x, post.mean, post.std, out / "profile.png", truth=truth, ylabel="height (µm)", yscale=1e6,
                 title="Surface profile from one scanned sensor: posterior mean and 95% band")
    kern = post.resolution_kernel(N // 2)
    fwhm = float(np.sum(kern >= 0.5 * kern.max()) * DX)
    yield f"  resolution kernel at x = 0: FWHM {fwhm * 1e3:.2f} mm; files profile.png, profile_criteria.png"


def defect_demo_scene():
    """The defect section's scene: the example 'fingertip_defect' (a 0.5 mm bump) scanned at
    20 mm/s for 0.6 s (250 Hz) under 3 x 3 sensors 1 mm apart reading zz and zx (SI units).
    Also used by tests/test_inversion_defect_footprint.py and benchmarks/bench_defect_coverage.py."""
    from tactilab.data_schemas import Scan, SensorArray, load_example

    base = load_example("fingertip_defect")
    sensors = SensorArray(positions_m=np.array([[x, y] for y in (-1e-3, 0.0, 1e-3) for x in (-1e-3, 0.0, 1e-3)]),
                          depth_m=base.sensors.depth_m, components=("zz", "zx"), noise_std=base.sensors.noise_std)
    scan = Scan(speed_m_per_s=0.02, duration_s=0.6, sampling_rate_hz=250.0, start_position_m=-6e-3)
    return base.model_copy(update={"sensors": sensors, "scan": scan})


def _defect_section(out: pathlib.Path, rng, progress: bool) -> Iterator[str]:
    from tactilab.data_schemas import read_recording
    from tactilab.forward import simulate_scene

    from tactilab.inversion import invert_defect_position, plot_corner

    scene = defect_demo_scene()
    t = time.perf_counter()
    sim_dir = out / "defect_scan"
    list(simulate_scene(scene, sim_dir, rng=rng, plots=False))
    rec = read_recording(sim_dir / "recording.nc")
    yield (f"[inversion] defect: forward-simulated scan (tactilab.forward) of the example '{scene.name}' with 3 x 3 "
           f"sensors, {rec.n_times} samples, zz and zx, noise {scene.sensors.noise_std:g} Pa ({time.perf_counter() - t:.1f} s)")
    t = time.perf_counter()
    res, info = invert_defect_position(scene, rec, rng, max_data=400, progress=progress, max_steps=6000,
                                       check_every=250)
    el = time.perf_counter() - t
    res.to_netcdf(out / "defect_posterior.nc")
    truth = dict(zip(("x0", "y0"), info["truth"]))
    plot_corner(res.tree, out / "defect_corner.png", truth=truth)
    yield f"  emcee: {el:.1f} s, sensors {', '.join(info['sensor_ids'])}, every {info['time_stride']} samples"
    for line in res.message.splitlines():
        yield "  " + line
    post = res.tree["posterior"]
    surface = scene.surface
    yield (f"  defect modelled as the scene records it: a {surface.size_m * 1e3:g} mm {surface.shape}, the contact "
           f"pressure averaged over its footprint (a point model biases x0 by about one posterior sd here)")
    for name in ("x0", "y0"):
        v = post[name].values.ravel() * 1e3
        lo, hi = np.quantile(v, [0.025, 0.975])
        true = truth[name] * 1e3
        yield (f"  {name} = {v.mean():+.4f} ± {v.std():.4f} mm (95% interval {lo:+.4f} .. {hi:+.4f} mm; true "
               f"{true:+.4f} mm, {'inside' if lo <= true <= hi else 'OUTSIDE'}, {(true - v.mean()) / v.std():+.1f} sd)")
    yield ("  (a 95% interval misses the truth in about 1 of 20 noise draws; its coverage over many draws of this "
           "scan: docs/inversion.md)")
    yield "  files defect_posterior.nc (arviz DataTree), defect_corner.png"


def run_demo(report_dir: pathlib.Path, progress: bool = True) -> Iterator[str]:
    """Profile inversion with credible band and chosen regularisation; defect position by emcee.

    Parameters
    ----------
    report_dir : Path
        Folder for ``inversion/`` (PNG plots, posterior netCDF).
    progress : bool
        tqdm bar for the sampler.
    """
    out = pathlib.Path(report_dir) / "inversion"
    out.mkdir(parents=True, exist_ok=True)
    # one generator per section: each section's noise does not depend on what the other draws
    yield from _profile_section(out, np.random.default_rng([20261122, 1]))
    yield from _defect_section(out, np.random.default_rng([20261122, 2]), progress)
    yield f"  files in {out}"

"""Check: bias and interval coverage of the defect position on the demo's scene, point vs finite defect.

Run: ``python benchmarks/bench_defect_coverage.py [--draws 200]``

The scene of demo/inversion.py's defect section: the example 'fingertip_defect' (a 0.5 mm
raised-cosine bump, 50 um high, under a 0.8 N fingertip contact) scanned from -6 to +6 mm at
20 mm/s, 250 Hz, by 3 x 3 stress sensors (zz, zx) 1 mm apart at 3 mm depth, noise 10 Pa; the
inversion keeps 6 sensors and every 5th sample (``max_data=400``), as the demo does.

Table 1 -- noise-free recordings from the forward model (tactilab.forward) on its default contact
grid and on a 20 um grid: the least-squares x0 (y0 = 0, area fitted) and the rms residual of the
point-defect model and of the finite one (the scene's footprint, ``defect_footprint``).

Table 2 -- ``--draws`` noise draws of a recording (default grid: point and finite model; 20 um
grid: finite model): the exact posterior of x0 on a
grid (the sampler's likelihood, ``DefectPosterior``, with the area integrated out; y0
marginalised), how often its 95 % interval holds the truth, and the mean and sd of
z = (posterior mean - truth) / posterior sd (0 and 1 for a calibrated posterior).
"""

from __future__ import annotations

import argparse
import pathlib
import tempfile

import numpy as np

from tactilab.data_schemas.files import load_example
from tactilab.data_schemas.recording_io import read_recording
from tactilab.data_schemas.scene import Scan
from tactilab.data_schemas.sensors import SensorArray
from tactilab.forward.scene_simulation import simulate_scene
from tactilab.inversion.mcmc import DefectPosterior
from tactilab.inversion.scene_inversion import _fixed, defect_problem
from tactilab.inversion.scene_params import Normal

NOISE = 10.0


def demo_scene():
    base = load_example("fingertip_defect")
    sensors = SensorArray(positions_m=np.array([[x, y] for y in (-1e-3, 0.0, 1e-3) for x in (-1e-3, 0.0, 1e-3)]),
                          depth_m=base.sensors.depth_m, components=("zz", "zx"), noise_std=base.sensors.noise_std)
    scan = Scan(speed_m_per_s=0.02, duration_s=0.6, sampling_rate_hz=250.0, start_position_m=-6e-3)
    return base.model_copy(update={"sensors": sensors, "scan": scan})


def best_x0(model, data, fixed):
    xs = np.linspace(-20e-6, 20e-6, 161)
    g = model.design(dict(fixed, x0=xs, y0=np.zeros_like(xs)))
    area = g @ data / np.einsum("ij,ij->i", g, g)
    rss = np.sum((data[None] - area[:, None] * g) ** 2, axis=1)
    return xs[np.argmin(rss)], float(np.sqrt(rss.min() / data.size))


def grid_posterior(model, data, fixed):
    post = DefectPosterior(model, data, NOISE, {**fixed, "x0": Normal(0, 1), "y0": Normal(0, 1)}, Normal(0.0, 1e-6))
    xs, ys = np.linspace(-30e-6, 30e-6, 121), np.linspace(-80e-6, 80e-6, 41)
    ll = post.log_marginal_likelihood(np.array([(x, y) for y in ys for x in xs])).reshape(ys.size, xs.size)
    px = np.exp(ll - ll.max()).sum(axis=0)
    px /= px.sum()
    mean = px @ xs
    lo, hi = np.interp([0.025, 0.975], np.cumsum(px), xs)
    return mean, float(np.sqrt(px @ (xs - mean) ** 2)), lo, hi


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=200)
    args = parser.parse_args(argv)
    scene, fixed = demo_scene(), _fixed(demo_scene())
    recs = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, spacing in (("default", None), ("20 um", 20e-6)):
            folder = pathlib.Path(tmp) / name.replace(" ", "")
            list(simulate_scene(scene, folder, plots=False, grid_spacing=spacing))
            recs[name] = read_recording(folder / "recording.nc")
    print("Table 1: noise-free recordings, least-squares x0 (truth 0)")
    head = f"{'forward grid':>12s} {'model':>7s} {'x0 (um)':>8s} {'rms residual (Pa)':>18s}"
    print(head + "\n" + "-" * len(head))
    for name, rec in recs.items():
        for footprint in (False, True):
            model, data, _ = defect_problem(scene, rec, max_data=400, footprint=footprint)
            x0, rms = best_x0(model, data, fixed)
            print(f"{name:>12s} {'finite' if footprint else 'point':>7s} {x0 * 1e6:8.2f} {rms:18.3f}")
    print(f"\nTable 2: {args.draws} noise draws ({NOISE:g} Pa) of each recording, exact grid posterior of x0")
    head = f"{'forward grid':>12s} {'model':>7s} {'95% interval holds truth':>25s} {'mean z':>7s} {'sd z':>6s} {'mean sd (um)':>13s}"
    print(head + "\n" + "-" * len(head))
    for name, footprint in (("default", False), ("default", True), ("20 um", True)):
        rec = recs[name]
        values = np.asarray(rec.values)
        z, sds, hits = [], [], 0
        for seed in range(args.draws):
            noise = NOISE * np.random.default_rng(seed).standard_normal(values.shape)
            model, data, _ = defect_problem(scene, rec.model_copy(update={"values": values + noise}), max_data=400,
                                            footprint=footprint)
            mean, sd, lo, hi = grid_posterior(model, data, fixed)
            z.append(mean / sd)
            sds.append(sd)
            hits += lo <= 0.0 <= hi
        print(f"{name:>12s} {'finite' if footprint else 'point':>7s} {f'{hits} of {args.draws}':>25s} {np.mean(z):+7.2f} "
              f"{np.std(z):6.2f} {np.mean(sds) * 1e6:13.2f}", flush=True)


if __name__ == "__main__":
    main()

"""Check: bias and interval coverage of the defect position on the demo's scene, point vs finite defect.

Run: ``python benchmarks/bench_defect_coverage.py [--draws 200] [--scene demo|example]``

The scene of demo/inversion.py's defect section: the example 'fingertip_defect' (a 0.5 mm
raised-cosine bump, 50 um high, under a 0.8 N fingertip contact) scanned from -6 to +6 mm at
20 mm/s, 250 Hz, by 3 x 3 stress sensors (zz, zx) 1 mm apart at 3 mm depth, noise 10 Pa; the
inversion keeps 6 sensors and every 5th sample (``max_data=400``), as the demo does.

Table 1 -- noise-free recordings from the forward model (tactilab.forward) on its default contact
grid and on a 20 um grid: the least-squares x0 (y0 = 0, area fitted) and the rms residual of the
point-defect model and of the finite one (the scene's footprint, ``defect_footprint``).

``--scene example``: the example file's own scan (10 x 10 sensors, 1 kHz, -10 to +10 mm;
``max_data=500``, as ``tactilab invert --max-data 500`` in docs/inversion.md).

Table 2 -- ``--draws`` noise draws of a recording (default grid: point and finite model; 20 um
grid: finite model): the exact posteriors of x0 and y0 on a
grid (the sampler's likelihood, ``DefectPosterior``, with the area integrated out; y0
marginalised, and y0 with x0 marginalised), how often each 95 % interval holds the truth, and the mean and sd of
z = (posterior mean - truth) / posterior sd (0 and 1 for a calibrated posterior).
"""

from __future__ import annotations

import argparse
import pathlib
import tempfile

import numpy as np

from tactilab.data_schemas.files import load_example
from tactilab.data_schemas.recording_io import read_recording
from tactilab.forward.scene_simulation import simulate_scene
from tactilab.inversion.mcmc import DefectPosterior
from tactilab.demo.inversion import defect_demo_scene
from tactilab.inversion.scene_inversion import _fixed, defect_problem
from tactilab.inversion.scene_params import Normal

NOISE = 10.0


def best_x0(model, data, fixed):
    xs = np.linspace(-20e-6, 20e-6, 161)
    g = model.design(dict(fixed, x0=xs, y0=np.zeros_like(xs)))
    area = g @ data / np.einsum("ij,ij->i", g, g)
    rss = np.sum((data[None] - area[:, None] * g) ** 2, axis=1)
    return xs[np.argmin(rss)], float(np.sqrt(rss.min() / data.size))


def grid_posterior(model, data, fixed):
    """Exact marginal posteriors of x0 and y0 on a grid: (mean, sd, 2.5 %, 97.5 %) each, m."""
    post = DefectPosterior(model, data, NOISE, {**fixed, "x0": Normal(0, 1), "y0": Normal(0, 1)}, Normal(0.0, 1e-6))
    xs, ys = np.linspace(-30e-6, 30e-6, 121), np.linspace(-120e-6, 120e-6, 61)
    ll = post.log_marginal_likelihood(np.array([(x, y) for y in ys for x in xs])).reshape(ys.size, xs.size)
    w = np.exp(ll - ll.max())
    out = []
    for grid, p in ((xs, w.sum(axis=0)), (ys, w.sum(axis=1))):
        p = p / p.sum()
        mean = p @ grid
        lo, hi = np.interp([0.025, 0.975], np.cumsum(p), grid)
        out.append((mean, float(np.sqrt(p @ (grid - mean) ** 2)), lo, hi))
    return out


def example_scene():
    """The example 'fingertip_defect' itself: 10 x 10 sensors, 1 kHz, -10 to +10 mm."""
    return load_example("fingertip_defect")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=200)
    parser.add_argument("--scene", choices=("demo", "example"), default="demo",
                        help="the demo's scan (max_data 400) or the example file's own (max_data 500, as in docs)")
    args = parser.parse_args(argv)
    scene = defect_demo_scene() if args.scene == "demo" else example_scene()
    fixed, max_data = _fixed(scene), 400 if args.scene == "demo" else 500
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
            model, data, _ = defect_problem(scene, rec, max_data=max_data, footprint=footprint)
            x0, rms = best_x0(model, data, fixed)
            print(f"{name:>12s} {'finite' if footprint else 'point':>7s} {x0 * 1e6:8.2f} {rms:18.3f}")
    print(f"\nTable 2: {args.draws} noise draws ({NOISE:g} Pa) of each recording, exact grid posterior of x0 and y0 "
          "(z = (mean - truth) / sd)")
    head = (f"{'forward grid':>12s} {'model':>7s} {'x0: 95% holds truth':>20s} {'mean z':>7s} {'sd z':>6s} {'sd (um)':>8s}"
            f" {'y0: 95% holds truth':>20s} {'mean z':>7s} {'sd z':>6s} {'sd (um)':>8s}")
    print(head + "\n" + "-" * len(head))
    for name, footprint in (("default", False), ("default", True), ("20 um", True)):
        rec = recs[name]
        values = np.asarray(rec.values)
        stats = [([], [], [0]), ([], [], [0])]  # per coordinate: z, sd, hits
        for seed in range(args.draws):
            noise = NOISE * np.random.default_rng(seed).standard_normal(values.shape)
            model, data, _ = defect_problem(scene, rec.model_copy(update={"values": values + noise}),
                                            max_data=max_data, footprint=footprint)
            for (z, sds, hits), (mean, sd, lo, hi) in zip(stats, grid_posterior(model, data, fixed)):
                z.append(mean / sd)
                sds.append(sd)
                hits[0] += lo <= 0.0 <= hi
        cells = [f"{f'{h[0]} of {args.draws}':>20s} {np.mean(z):+7.2f} {np.std(z):6.2f} {np.mean(sd) * 1e6:8.2f}"
                 for z, sd, h in stats]
        print(f"{name:>12s} {'finite' if footprint else 'point':>7s} " + " ".join(cells), flush=True)


if __name__ == "__main__":
    main()

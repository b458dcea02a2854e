"""``tactilab invert RECORDING --scene SCENE``: defect position (emcee) and load profile (Gaussian)."""

from __future__ import annotations

import argparse
from pathlib import Path

from .batch_options import add_batch_options, run_invert_batch

NAME = "invert"
HELP = ("invert a sensor recording (recording.nc or .json, stress in Pa) of a defect scene: defect position "
        "(x0, y0 in mm) by emcee and the load profile along the scan (mm^2/mm) with its credible band; "
        "writes posterior.nc and PNG plots")

METHODS = ("all", "mcmc", "profile")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", type=Path, nargs="?", default=None,
                        help="recording file written by tactilab simulate (.nc, Pa) or a Recording JSON (SI units); "
                             "omit it with --batch DIR")
    parser.add_argument("--scene", type=Path, required=True,
                        help="scene file (.toml with units such as 0.8N, 3mm; or .json in SI) that produced it")
    parser.add_argument("--method", choices=METHODS, default="all",
                        help="mcmc: defect position posterior (emcee); profile: the defect-load density s(x) "
                             "along the scan line (mm^2 of effective defect area per mm of scan, NOT a surface "
                             "height) by the linear-Gaussian posterior with the four regularisation criteria; "
                             "all: both (default)")
    parser.add_argument("--criterion", choices=("gcv", "lcurve", "discrepancy", "evidence"), default="evidence",
                        help="regularisation criterion used for the profile (all four are plotted)")
    parser.add_argument("--sample", default="",
                        help="comma-separated extra parameters to sample besides x0, y0 (mm): friction "
                             "(uniform on [0, 1], dimensionless), depth (m), young_modulus (Pa), normal_force "
                             "(N); the last three log-normal around the scene value (x/1.35); e.g. friction,depth")
    parser.add_argument("--max-steps", type=int, default=20000,
                        help="emcee step limit per ensemble (steps; default 20000); stops earlier once converged")
    parser.add_argument("--max-data", type=int, default=1500,
                        help="largest number of data values used (time decimation and sensor selection; count)")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default: ./<recording stem>-inversion)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the samplers (integer)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_batch_options(parser)


def run(args: argparse.Namespace) -> int:
    if args.batch is not None:
        return run_invert_batch(args)
    if args.recording is None:
        raise ValueError("recording: give one recording file, or --batch DIR for a folder of them")
    import numpy as np

    from tactilab.data_schemas import load_scene, read_recording
    from tactilab.inversion.criteria import plot_criteria
    from tactilab.inversion.plots import plot_corner, plot_profile
    from tactilab.inversion.scene_inversion import defect_profile, invert_defect_position

    if args.max_steps < 1:
        raise ValueError(f"--max-steps: must be >= 1 step, got {args.max_steps}; e.g. 20000")
    if args.max_data < 10:
        raise ValueError(f"--max-data: must be >= 10 values, got {args.max_data}; e.g. 1500")
    scene = load_scene(args.scene)
    try:
        recording = read_recording(args.recording)
    except (OSError, ValueError) as err:  # name the command-line argument
        raise type(err)(f"RECORDING: {str(err).removeprefix('path: ')}") from None
    out = args.out if args.out is not None else Path(f"{args.recording.stem}-inversion")
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    if args.method in ("all", "profile"):
        post, crit, x = defect_profile(scene, recording, criterion=args.criterion, max_data=args.max_data)
        plot_profile(x, post.mean, post.std, out / "profile.png",
                     title=f"Defect-load density along the scan, not a height (lam by {args.criterion})")
        plot_criteria(crit, out / "criteria.png")
        choices = ", ".join(f"{k}={v:.3g}" for k, v in crit.lam.items())
        peak = x[int(np.argmax(np.abs(post.mean)))]
        print(f"profile: defect-load density s(x) along the scan line (mm^2 of effective point-defect area per mm "
              f"of scan at y = 0; the linear part of the defect model, not a surface height), {x.size} nodes, "
              f"lam by {args.criterion}; criteria: {choices}")
        print(f"profile: largest |load density| at x = {peak * 1e3:.3f} mm; files profile.png, criteria.png")
    if args.method in ("all", "mcmc"):
        extra = tuple(q.strip() for q in args.sample.split(",") if q.strip())
        res, info = invert_defect_position(scene, recording, rng, sample=extra,
                                           max_data=args.max_data, progress=not args.quiet, max_steps=args.max_steps)
        res.to_netcdf(out / "posterior.nc")
        plot_corner(res.tree, out / "corner.png")
        print(f"mcmc: sensors {', '.join(info['sensor_ids'])}, every {info['time_stride']} samples, "
              f"noise {info['noise_std']:g} Pa")
        print(res.message)
        table = res.summary[["mean", "sd", "ess_bulk", "ess_tail", "r_hat"]]
        print(table.to_string(float_format=lambda v: f"{v:.4g}"))
        print(f"files: {out / 'posterior.nc'} (arviz DataTree), {out / 'corner.png'}")
    return 0

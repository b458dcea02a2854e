"""``tactilab invert RECORDING --scene SCENE``: defect position (emcee) and load profile (Gaussian)."""

from __future__ import annotations

import argparse
from pathlib import Path

from .batch_options import add_batch_options, run_invert_batch
from .common import RunReport, add_report_options, choose_out
from .invert_surface import add_surface_arguments, run_surface, surface_lengths

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
                             "(uniform on [0, 1], dimensionless), depth (reported in mm), young_modulus (kPa), "
                             "normal_force (N); the last three log-normal around the scene value (x/1.35); e.g. friction,depth")
    parser.add_argument("--max-steps", type=int, default=20000,
                        help="emcee step limit per ensemble (steps; default 20000); stops earlier once converged")
    parser.add_argument("--max-data", type=int, default=1500,
                        help="largest number of data values used (time decimation and sensor selection; count)")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default: a new folder ./<recording stem>-inversion, then -2, -3, ...); "
                             "an existing non-empty one needs --force (with --batch, the same --out resumes)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the samplers (integer)")
    parser.add_argument("--allow-scene-mismatch", action="store_true",
                        help="invert although the scene differs from the one the recording says produced it "
                             "(contact radius, sensor positions, depth, sampling, material); for real data whose "
                             "metadata differ from the model scene; prints a warning naming what differs")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_surface_arguments(parser)
    add_report_options(parser)
    add_batch_options(parser)


def run(args: argparse.Namespace) -> int:
    if args.batch is not None:
        if args.target == "surface":
            raise ValueError("--target surface: not available with --batch; invert one recording at a time")
        if args.json:
            raise ValueError("--json: not available with --batch; the batch summary is in <--out>/invert_many.nc "
                             "(one row per recording) -- drop --json")
        return run_invert_batch(args)
    if args.recording is None:
        raise ValueError("recording: give one recording file, or --batch DIR for a folder of them")
    prior_lengths = surface_lengths(args)
    import numpy as np

    from tactilab.data_schemas import load_scene, read_recording
    from tactilab.inversion.criteria import plot_criteria
    from tactilab.inversion.plots import plot_corner, plot_profile
    from tactilab.inversion.scene_inversion import defect_problem, defect_profile, invert_defect_position

    if args.max_steps < 1:
        raise ValueError(f"--max-steps: must be >= 1 step, got {args.max_steps}; e.g. 20000")
    from tactilab.inversion import check_max_steps

    if args.method in ("all", "mcmc"):  # x0, y0 and the extra parameters (the defect area is integrated out)
        check_max_steps(args.max_steps, 2 + len([q for q in args.sample.split(",") if q.strip()]), name="--max-steps")
    if args.max_data < 10:
        raise ValueError(f"--max-data: must be >= 10 values, got {args.max_data}; e.g. 1500")
    scene = load_scene(args.scene)
    try:
        recording = read_recording(args.recording)
    except (OSError, ValueError) as err:  # name the command-line argument
        raise type(err)(f"RECORDING: {str(err).removeprefix('path: ')}") from None
    from tactilab.inversion import check_scene_recording

    check_scene_recording(scene, args.recording, sample=[q.strip() for q in args.sample.split(",") if q.strip()],
                          allow_mismatch=args.allow_scene_mismatch, name="--scene")
    report = RunReport("invert")
    out = report.watch(choose_out(args.out, Path(f"{args.recording.stem}-inversion"), args.force))
    if args.target == "surface":
        return run_surface(args, scene, recording, report, out, prior_lengths)
    _warn_model(report, recording, args.recording)
    rng = np.random.default_rng(args.seed)
    problem = defect_problem(scene, recording, max_data=args.max_data)  # prepared once, used by both methods
    _report_selection(report, recording, problem[2], args.max_data)
    methods, errors = [], []
    if args.method in ("all", "profile"):
        with report.collecting_warnings():
            post, crit, x = defect_profile(scene, recording, criterion=args.criterion, problem=problem)
            plot_profile(x, post.mean, post.std, out / "profile.png",
                         title=f"Defect-load density along the scan, not a height (lam by {args.criterion})")
            plot_criteria(crit, out / "criteria.png", data_unit=recording.unit)
        i = int(np.argmax(np.abs(post.mean)))
        # s(x) is in m^2 per m of scan; 1 m^2/m = 1e3 mm^2/mm
        report.computed.append(
            f"profile: defect-load density s(x) along the scan line at y = 0 (mm^2 of effective point-defect area "
            f"per mm of scan; not a surface height), {x.size} nodes over {x[0] * 1e3:.2f} .. {x[-1] * 1e3:.2f} mm; "
            f"largest |s| = {post.mean[i] * 1e3:.3g} mm^2/mm at x = {x[i] * 1e3:.3f} mm")
        methods.append(f"profile: linear-Gaussian posterior (white Tikhonov prior), lam by {args.criterion}; "
                       "criteria " + ", ".join(f"{k} {v:.3g}" for k, v in crit.lam.items()))
        errors.append(f"profile: 1-sigma credible band, {post.std[i] * 1e3:.3g} mm^2/mm at the peak "
                      f"(median {np.median(post.std) * 1e3:.3g} mm^2/mm)")
        report.data.update(profile_peak_x_mm=float(x[i] * 1e3), profile_peak_mm2_per_mm=float(post.mean[i] * 1e3),
                           profile_peak_sd_mm2_per_mm=float(post.std[i] * 1e3), lam=dict(crit.lam))
    if args.method in ("all", "mcmc"):
        extra = tuple(q.strip() for q in args.sample.split(",") if q.strip())
        with report.collecting_warnings():
            res, info = invert_defect_position(scene, recording, rng, sample=extra, problem=problem,
                                               progress=not (args.quiet or args.json), max_steps=args.max_steps)
            res.to_netcdf(out / "posterior.nc")
            plot_corner(res.tree, out / "corner.png")
        table = _table_in_display_units(res.summary[["mean", "sd", "ess_bulk", "ess_tail", "r_hat"]])
        for name, row in table.iterrows():
            report.computed.append(f"position posterior: {name} = {row['mean']:.4g} +- {row['sd']:.2g}")
        report.data["posterior"] = {name: {k: float(v) for k, v in row.items()} for name, row in table.iterrows()}
        report.data["converged"] = bool(res.converged)
        methods.append(f"position: emcee ({', '.join(res.summary.index)}; amplitude integrated out), "
                       f"noise {info['noise_std']:g} {recording.unit}")
        errors.append("position: posterior sd above; " + "; ".join(" ".join(line.split()) for line in res.message.splitlines()))
        if not args.json:
            print(table.to_string(float_format=lambda v: f"{v:.4g}"))
    report.method = "; ".join(methods)
    report.error_estimate = "; ".join(errors)
    report.emit(args.json)
    return 0


def _warn_model(report: RunReport, recording, path: Path) -> None:
    """One warning line (repeated in the summary) when the recording was made with another interface
    model than the modulation the defect inversion assumes, with that model's error the recording states."""
    from tactilab.data_schemas.interface_model import model_mismatch, recording_model

    from .common import print_warning

    line = model_mismatch(recording_model(recording, path), "modulation", "the defect inversion")
    if line is not None:
        print_warning(report.command, line)


DISPLAY_UNITS = {"x0": ("mm", 1e3), "y0": ("mm", 1e3), "depth": ("mm", 1e3), "amplitude": ("mm^2", 1e6),
                 "young_modulus": ("kPa", 1e-3), "normal_force": ("N", 1.0), "friction": ("", 1.0)}


def _table_in_display_units(table):
    """The posterior summary (SI) with lengths in mm, areas in mm^2, moduli in kPa; units in the row names."""
    rows = {}
    for name, row in table.iterrows():
        unit, factor = DISPLAY_UNITS.get(name, ("SI", 1.0))
        row = row.copy()
        row[["mean", "sd"]] = row[["mean", "sd"]] * factor
        rows[f"{name} [{unit}]" if unit else name] = row
    return type(table)(rows).T


def _report_selection(report: RunReport, recording, info: dict, max_data: int) -> None:
    kept = list(info["sensor_ids"])
    if len(kept) < len(recording.sensor_ids):
        left = [s for s in recording.sensor_ids if s not in kept]
        report.dropped.append(
            f"sensors: uses {len(kept)} of {len(recording.sensor_ids)} ({', '.join(kept)}): the defect inversion keeps "
            f"the sensors with the largest RMS signal (baseline removed); left out {len(left)} "
            f"({', '.join(left[:8])}{', ...' if len(left) > 8 else ''})")
    if info["time_stride"] > 1:
        report.dropped.append(f"samples: every {info['time_stride']}th time sample kept, so that at most "
                              f"--max-data {max_data} values enter the likelihood")
    report.data.update(sensors_used=kept, n_sensors=len(recording.sensor_ids), time_stride=int(info["time_stride"]))

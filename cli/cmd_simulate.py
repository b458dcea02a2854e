"""``tactilab simulate SCENE.toml``: scan a finger scene, write its recording and plots."""

from __future__ import annotations

import argparse
from pathlib import Path

from .common import RunReport, add_report_options, choose_out, staged_outputs
from .material_option import add_material_option, describe_material, read_material_option

NAME = "simulate"
HELP = ("simulate a finger scene file (TOML, units like 0.8N, 3mm, 20mm/s): write the sensors' recording "
        "(netCDF or Parquet) and PNG plots (mm, kPa, strain)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", type=Path,
                        help="scene file (.toml with unit suffixes, or .json in SI); see examples/*.toml")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default: a new folder ./<scene name>-simulation, then -2, -3, ...); "
                             "an existing non-empty one needs --force")
    parser.add_argument("--format", choices=("netcdf", "parquet"), default="netcdf",
                        help="recording file format: netcdf (recording.nc, xarray/h5netcdf; values in Pa or "
                             "strain) or parquet (tidy table; needs pyarrow)")
    parser.add_argument("--grid-spacing", default=None,
                        help="contact-grid spacing with a length unit, e.g. 50um (default: resolves the "
                             "contact, the sensor depth and the surface relief)")
    parser.add_argument("--seed", type=int, default=None,
                        help="seed of the sensor noise (noise_std of the scene's sensors); default: noise-free")
    add_material_option(parser)
    parser.add_argument("--no-plots", action="store_true", help="write the recording only")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_report_options(parser)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from tactilab.data_schemas.files import load_scene
    from tactilab.data_schemas.units import to_si
    from tactilab.forward.scene_simulation import simulate_scene

    spacing = None
    if args.grid_spacing is not None:
        spacing = to_si(args.grid_spacing, "length", name="--grid-spacing")
        if spacing <= 0:
            raise ValueError(f"--grid-spacing: must be > 0, got {args.grid_spacing!r}; e.g. 50um")
    scene = load_scene(args.scene)
    material = read_material_option(args, replaces=())
    report = RunReport("simulate")
    created = args.out is None or not args.out.exists()
    if material is not None:
        if material.has_viscoelastic_layers:
            raise ValueError("--material: a scene simulation takes an elastic or viscoelastic half-space or elastic "
                             "layers, got viscoelastic layers; give each layer its relaxed young_modulus without "
                             "terms, or solve viscoelastic layers with the stress, contact and synthesis commands")
        scene = scene.model_copy(update={"material": material})
        note = "; the scan is quasi-static: it uses the relaxed modulus" if material.is_viscoelastic else ""
        report.computed.append(f"skin from --material (replaces the scene's): {describe_material(material)}{note}")
    out = report.watch(choose_out(args.out, Path(f"{scene.name or args.scene.stem}-simulation"), args.force))
    rng = np.random.default_rng(args.seed) if args.seed is not None else None
    with report.collecting_warnings(), staged_outputs(out, created) as stage:  # no partial output if a warning is an error
        lines = simulate_scene(scene, stage, fmt=args.format, rng=rng, progress=not (args.quiet or args.json),
                               grid_spacing=spacing, plots=not args.no_plots)
    for line in lines:
        if line.startswith("recording: ") and scene.display is None:
            _model_data(report, out / Path(line.removeprefix("recording: ")).name)  # the stage moved into out
        if line.startswith("method: "):
            report.method = line.removeprefix("method: ")
        elif line.startswith("model errors: "):
            report.error_estimate = "interface " + line
        elif not line.startswith(("recording: ", "plots")):  # the files are listed below
            report.computed.append(line)
    if not report.method and scene.display is not None:
        report.method = ("display plane model: tractor line loads on the half-space, rows uniform in y; "
                         "compared with the real sliding surface where the scene has one")
    if not report.error_estimate:
        report.error_estimate = ("not estimated by this command (grid quadrature; refine --grid-spacing and compare "
                                 "to check convergence)")
    if args.seed is None and float(scene.sensors.noise_std) > 0:
        report.dropped.append(f"sensor noise (noise_std {scene.sensors.noise_std:g} in the recording's unit): "
                              "not added without --seed")
    if args.no_plots:
        report.dropped.append("plots: --no-plots")
    report.emit(args.json)
    return 0


def _model_data(report: RunReport, path: Path) -> None:
    """The interface model the recording states, machine-readable in the summary (``--json``)."""
    from tactilab.data_schemas import read_recording
    from tactilab.data_schemas.interface_model import recording_model

    stated = recording_model(read_recording(path), path)
    if stated is not None:
        report.data.update(interface_model=stated["model"], interface_model_tol=stated["tol"],
                           interface_model_errors=stated["errors"], interface_model_error_basis=stated["basis"])

"""``tactilab stress``: evaluate a load file at depths; write the field and a PNG map."""

from __future__ import annotations

import argparse
from pathlib import Path

from .common import RunReport, add_report_options, choose_out, staged_outputs

NAME = "stress"
HELP = ("strain (default; dimensionless, tensor shear) or stress (Pa) at given depths (mm) under a load file "
        "(.npz in SI, or .toml with units); writes field.nc and field.png")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("load", type=Path,
                        help=".npz with p, qx, qy (Pa) and spacing (m), or .toml with unit suffixes "
                             "(see tactilab.forward.load_files)")
    parser.add_argument("--depth", action="append", required=True,
                        help="receptor depth with unit, e.g. 1.25mm; repeat for several depths")
    parser.add_argument("--quantity", choices=("stress", "strain"), default="strain",
                        help="what to write: strain by default (dimensionless, tensor shear), or stress "
                             "(written in Pa, plotted in kPa)")
    parser.add_argument("--components", default="xx,yy,zz,yz,zx,xy",
                        help="comma-separated Voigt components (default all six)")
    parser.add_argument("--method", default="auto", choices=("auto", "spectral", "dcfft", "closed_form"),
                        help="solution method (default: auto, chosen from the scene and --tol)")
    parser.add_argument("--tol", type=float, default=1e-6, help="requested relative error, dimensionless (default 1e-6)")
    parser.add_argument("--young-modulus", default="1MPa", help="skin Young's modulus with unit (default 1MPa)")
    parser.add_argument("--nu", type=float, default=0.5, help="Poisson's ratio, dimensionless, in (-1, 0.5] (default 0.5)")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder for field.nc (SI) and field.png (mm, kPa or strain); default: a new "
                             "folder <load stem>-stress (then -2, -3, ...); an existing non-empty one needs --force")
    add_report_options(parser)


def run(args: argparse.Namespace) -> int:
    from tactilab.data_schemas.units import to_si
    from tactilab.forward.halfspace import HalfSpace
    from tactilab.forward.load_files import read_load, write_field

    report = RunReport("stress")
    depths = [to_si(d, "length", name="--depth") for d in args.depth]
    young = to_si(args.young_modulus, "pressure", name="--young-modulus")
    load = read_load(args.load)
    created = args.out is None or not args.out.exists()
    out = report.watch(choose_out(args.out, Path(f"{args.load.stem}-stress"), args.force))
    components = [c.strip() for c in args.components.split(",") if c.strip()]
    with report.collecting_warnings(), staged_outputs(out, created) as stage:  # no partial output if a warning is an error
        hs = HalfSpace(E=young, nu=args.nu)
        compute = hs.stress if args.quantity == "stress" else hs.strain
        result = compute(load, depths, components=components, method=args.method, tol=args.tol)
        write_field(result, stage)
    what = "stress (Pa)" if args.quantity == "stress" else "strain (dimensionless, tensor shear)"
    grid = " x ".join(str(n) for n in load.shape) + f" grid, spacing {load.dx * 1e3:g} mm"
    report.computed.append(f"{what}, components {', '.join(components)}, at depths "
                           f"{', '.join(f'{z * 1e3:g}' for z in depths)} mm on a {grid}; "
                           f"E = {young * 1e-3:g} kPa, nu = {args.nu:g}")
    report.method = f"{result.method} ({result.reason})"
    report.error_estimate = (f"estimated relative error {result.error_estimate:.1e} (max error relative to the field's peak; "
                             f"requested --tol {args.tol:g})")
    report.data.update(quantity=args.quantity, components=components, depths_mm=[z * 1e3 for z in depths],
                       method_name=result.method, relative_error=float(result.error_estimate))
    report.emit(args.json)
    return 0

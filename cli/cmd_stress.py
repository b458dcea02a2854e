"""``tactilab stress``: evaluate a load file at depths; write the field and a PNG map."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from .common import RunReport, add_report_options, choose_out, staged_outputs
from .material_option import RELAXED, add_material_option, describe_material, read_material_option, read_time_option

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
    parser.add_argument("--young-modulus", default=None, help="skin Young's modulus with unit (default 1MPa)")
    parser.add_argument("--nu", type=float, default=None, help="Poisson's ratio, dimensionless, in (-1, 0.5] (default 0.5)")
    add_material_option(parser)
    parser.add_argument("--time", default=None,
                        help="with a viscoelastic --material: how long the load has been held, with unit, e.g. 70ms "
                             "(default 0: the instantaneous response), or 'relaxed'; the strain creeps, the stress "
                             "does not; viscoelastic layers at a time between 0 and relaxed need one relaxation shape")
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
    material = read_material_option(args)
    skin, skin_text = _skin(args, material)
    load = read_load(args.load)
    created = args.out is None or not args.out.exists()
    out = report.watch(choose_out(args.out, Path(f"{args.load.stem}-stress"), args.force))
    components = [c.strip() for c in args.components.split(",") if c.strip()]
    with report.collecting_warnings(), staged_outputs(out, created) as stage:  # no partial output if a warning is an error
        compute = skin.stress if args.quantity == "stress" else skin.strain
        elastic = isinstance(skin, HalfSpace)
        if not elastic and args.method != "auto":
            raise ValueError(f"--method: a layered --material has its own solver, got --method {args.method}; "
                             "drop --method")
        options = {"method": args.method} if elastic else {}
        result = compute(load, depths, components=components, tol=args.tol, **options)
        write_field(result, stage)
    what = "stress (Pa)" if args.quantity == "stress" else "strain (dimensionless, tensor shear)"
    grid = " x ".join(str(n) for n in load.shape) + f" grid, spacing {load.dx * 1e3:g} mm"
    report.computed.append(f"{what}, components {', '.join(components)}, at depths "
                           f"{', '.join(f'{z * 1e3:g}' for z in depths)} mm on a {grid}; "
                           f"{skin_text}")
    report.method = f"{result.method} ({getattr(result, 'reason', 'the layered solver')})"
    report.error_estimate = (f"estimated relative error {result.error_estimate:.1e} (max error relative to the field's peak; "
                             f"requested --tol {args.tol:g})")
    report.data.update(quantity=args.quantity, components=components, depths_mm=[z * 1e3 for z in depths],
                       method_name=result.method, relative_error=float(result.error_estimate))
    report.emit(args.json)
    return 0


def _skin(args: argparse.Namespace, material):
    """The elastic skin the field is computed on, and its line for the report.

    A viscoelastic material under tractions held for ``--time`` t has the elastic stress and the
    strain of the elastic skin of modulus 1 / J(t) (the correspondence principle at constant nu);
    viscoelastic layers have those of ``ViscoelasticLayeredHalfSpace.at(t)``."""
    from tactilab.core import rules
    from tactilab.data_schemas.units import to_si
    from tactilab.forward import HalfSpace, skin_from_material

    time = read_time_option(args.time)
    if material is None or not (material.is_viscoelastic or material.has_viscoelastic_layers):
        if time is not None:
            raise ValueError("--time: only a viscoelastic --material (model prony or sls, or layers with Prony terms) "
                             "depends on time; drop --time")
    if material is None:
        young = to_si(args.young_modulus or "1MPa", "pressure", name="--young-modulus")
        nu = 0.5 if args.nu is None else rules.poisson_ratio(args.nu, "--nu")
        return HalfSpace(E=young, nu=nu), f"E = {young * 1e-3:g} kPa, nu = {nu:g}"
    skin = skin_from_material(material)
    text = describe_material(material)
    held = time or 0.0
    when = "until the skin has relaxed" if held == math.inf else f"for {held * 1e3:g} ms"
    if material.is_viscoelastic:
        skin = skin.at(held)
        text += (f"; tractions held {when}: the strain of the elastic skin of modulus 1/J(t) = "
                 f"{skin.E * 1e-3:g} kPa (the stress does not depend on the modulus)")
    elif material.has_viscoelastic_layers:
        skin = _held_layers(skin, held)
        moduli = ", ".join(f"{layer.E * 1e-3:.4g}" for layer in skin.layers)
        text += f"; tractions applied at t = 0 and held {when}: the elastic layers of moduli {moduli} kPa"
    return skin, text


def _held_layers(skin, held: float):
    """``skin.at(held)``: exact for any layers at 0 and relaxed; in between the layers must relax with one shape."""
    if 0.0 < held < math.inf:
        try:
            skin.relaxation_shape()
        except ValueError as exc:
            where = str(exc).partition(":")[0]
            raise ValueError(f"--time: a held load on viscoelastic layers at a time between 0 and {RELAXED} needs "
                             f"every material to relax with one shape (the same relaxation times and E_i / E_inf, on "
                             f"a rigid base), but {where} of the material differs; give --time 0ms (the glassy layers) "
                             f"or --time {RELAXED} (the relaxed layers), or proportional Prony series") from None
    return skin.at(held)

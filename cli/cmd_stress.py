"""``tactilab stress``: evaluate a load file at depths; write the field and a PNG map."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from .common import make_out

NAME = "stress"
HELP = "stress or strain at given depths under a load file (.npz in SI, or .toml with units)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("load", type=Path,
                        help=".npz with p, qx, qy (Pa) and spacing (m), or .toml with unit suffixes "
                             "(see tactilab.forward.load_files)")
    parser.add_argument("--depth", action="append", required=True,
                        help="receptor depth with unit, e.g. 1.25mm; repeat for several depths")
    parser.add_argument("--quantity", choices=("stress", "strain"), default="strain",
                        help="stress (written in Pa, plotted in kPa) or strain (dimensionless, tensor shear)")
    parser.add_argument("--components", default="xx,yy,zz,yz,zx,xy",
                        help="comma-separated Voigt components (default all six)")
    parser.add_argument("--method", default="auto", choices=("auto", "spectral", "dcfft", "closed_form"),
                        help="solution method (default: auto, chosen from the scene and --tol)")
    parser.add_argument("--tol", type=float, default=1e-6, help="requested relative error (default 1e-6)")
    parser.add_argument("--young-modulus", default="1MPa", help="skin Young's modulus with unit (default 1MPa)")
    parser.add_argument("--nu", type=float, default=0.5, help="Poisson's ratio, (-1, 0.5] (default 0.5)")
    parser.add_argument("--out", type=Path, default=Path("tactilab-stress"),
                        help="output folder for field.nc (SI) and field.png (mm, kPa)")


def run(args: argparse.Namespace) -> int:
    from tactilab.data_schemas.units import to_si
    from tactilab.forward.halfspace import AccuracyWarning, HalfSpace
    from tactilab.forward.load_files import read_load, write_field

    load = read_load(args.load)
    make_out(args.out)
    depths = [to_si(d, "length", name="--depth") for d in args.depth]
    hs = HalfSpace(E=to_si(args.young_modulus, "pressure", name="--young-modulus"), nu=args.nu)
    components = [c.strip() for c in args.components.split(",") if c.strip()]
    compute = hs.stress if args.quantity == "stress" else hs.strain
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", AccuracyWarning)
        result = compute(load, depths, components=components, method=args.method, tol=args.tol)
    for w in caught:  # one line each, like errors (the default format adds the source line)
        if issubclass(w.category, AccuracyWarning):
            print(f"tactilab stress: warning: {' '.join(str(w.message).split())}", file=sys.stderr)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    paths = write_field(result, args.out)
    print(f"method: {result.method} ({result.reason}); estimated relative error {result.error_estimate:.1e}")
    for p in paths:
        print(f"wrote {p}")
    return 0

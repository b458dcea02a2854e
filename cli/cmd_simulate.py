"""``tactilab simulate SCENE.toml``: scan a finger scene, write its recording and plots."""

from __future__ import annotations

import argparse
from pathlib import Path

from .common import make_out

NAME = "simulate"
HELP = ("simulate a finger scene file (TOML, units like 0.8N, 3mm, 20mm/s): write the sensors' recording "
        "(netCDF or Parquet) and PNG plots (mm, kPa, strain)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", type=Path,
                        help="scene file (.toml with unit suffixes, or .json in SI); see examples/*.toml")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default: ./<scene name>-simulation)")
    parser.add_argument("--format", choices=("netcdf", "parquet"), default="netcdf",
                        help="recording file format: netcdf (recording.nc, xarray/h5netcdf; values in Pa or "
                             "strain) or parquet (tidy table; needs pyarrow)")
    parser.add_argument("--grid-spacing", default=None,
                        help="contact-grid spacing with a length unit, e.g. 50um (default: resolves the "
                             "contact, the sensor depth and the surface relief)")
    parser.add_argument("--seed", type=int, default=None,
                        help="seed of the sensor noise (noise_std of the scene's sensors); default: noise-free")
    parser.add_argument("--no-plots", action="store_true", help="write the recording only")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


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
    out = make_out(args.out if args.out is not None else Path(f"{scene.name or args.scene.stem}-simulation"))
    rng = np.random.default_rng(args.seed) if args.seed is not None else None
    for line in simulate_scene(scene, out, fmt=args.format, rng=rng, progress=not args.quiet,
                               grid_spacing=spacing, plots=not args.no_plots):
        print(line)
    return 0

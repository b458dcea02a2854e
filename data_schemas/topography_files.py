"""Profilometer files (``.x3p``, ``.datx``, Gwyddion ``.gwy``, ...) read through SurfaceTopography.

An optional extra: ``pip install 'tactilab[topography]'`` installs the SurfaceTopography package,
whose readers cover the instrument formats (ISO 25178-72 X3P, Zygo DATX and MetroPro, Gwyddion,
Digital Surf SUR, Sensofar PLU, Wyko OPD, Keyence VK, ...). The file states its spacing and unit;
the result is the same :class:`~.height_map_record.HeightMap` as the core formats give, with the
same refusals (NaN or missing points, a unit that is not a length, a non-uniform line scan).
"""

from __future__ import annotations

import importlib
import pathlib

import numpy as np

from .height_map_record import HeightMap

#: suffixes handed to SurfaceTopography (lower case)
TOPOGRAPHY_SUFFIXES = (".x3p", ".datx", ".gwy", ".sur", ".plu", ".plux", ".opd", ".opdx", ".sdf", ".al3d",
                       ".vk4", ".vk6", ".zon", ".ibw", ".di", ".spm", ".mi", ".tmd", ".nms", ".frt", ".zmg")


def _package():
    try:
        return importlib.import_module("SurfaceTopography")
    except ImportError:
        raise ValueError("reading profilometer files (.x3p, .datx, .gwy, ...) needs the optional extra "
                         "'topography' (the SurfaceTopography package); install it with "
                         "pip install 'tactilab[topography]', or export the map as .npy, .csv or .nc") from None


def read_topography_file(path: pathlib.Path, spacing, height_unit, *, where: str, length_factor, check_heights,
                         to_metres) -> HeightMap:
    """Read an instrument file into a HeightMap in m (through SurfaceTopography).

    ``length_factor``, ``check_heights`` and ``to_metres`` are the core reader's own checks
    (:mod:`.height_map`), passed in so that every format refuses the same things in the same words.
    """
    if spacing is not None or height_unit is not None:
        raise ValueError(f"{where}: a profilometer file states its own spacing and unit; do not give spacing "
                         "or height_unit")
    package = _package()
    try:
        topography = package.open_topography(str(path)).topography()
    except Exception as exc:  # the readers raise many types; each becomes one line naming the file
        raise ValueError(f"{where}: SurfaceTopography cannot read it ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())[:200]}); check the file or export it as .npy, .csv or .nc") from None
    if not topography.is_uniform:
        raise ValueError(f"{where}: the line scan is not uniform (its points are not equally spaced); resample "
                         "it onto a regular grid")
    factor = length_factor(topography.unit, f"{where} (unit stated in the file)")
    if topography.has_undefined_data:
        raise ValueError(f"{where}: the map has undefined (missing) points; fill or crop them before reading")
    heights = np.asarray(topography.heights(), dtype=float)
    heights = check_heights(heights.T if heights.ndim == 2 else heights, where)  # SurfaceTopography is (nx, ny)
    sizes = np.atleast_1d(np.asarray(topography.physical_sizes, dtype=float))
    counts = np.atleast_1d(np.asarray(topography.nb_grid_pts))
    steps = to_metres(sizes / counts, factor)
    return HeightMap(heights_m=to_metres(heights, factor), spacing_x_m=float(steps[0]),
                     spacing_y_m=float(steps[1]) if heights.ndim == 2 else None)

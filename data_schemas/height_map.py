"""Measured height maps at the file edge: ``.npy``, ``.csv``, netCDF and profilometer files, read into a :class:`HeightMap`.

One reader for every command that takes a measured surface (``tactilab contact``, the scenes).
Files are data: ``.npy`` is read with ``allow_pickle=False``, netCDF through h5netcdf (HDF5), and a
netCDF variable stored outside the file (HDF5 external or virtual storage) is refused. Every file
states its units, or the caller does; a missing or wrong unit, NaN, a non-uniform or degenerate
grid each get a one-line error that names the file and the fix.

Formats
-------
``.npy``
    A real array, shape (nx,) (a profile) or (ny, nx), of heights in ``height_unit``; the node
    spacing is given by the caller (``spacing="20um"`` or ``("20um", "10um")``, x first).
``.csv``, labelled grid (the layout this reader writes about; comma separated)::

        height [um],0mm,0.02mm,0.04mm      <- top-left: "height [UNIT]"; then x of each column
        0mm,1.25,0.50,-0.30                <- y of the row (with a unit), then heights in UNIT
        0.02mm,0.75,0.10,-0.20

    One data row is a profile along x. Coordinates must be uniformly spaced (ascending or
    descending; descending ones are flipped to ascending). ``spacing`` and ``height_unit`` must
    not be given (the file states them).
``.csv``, plain matrix (no header: the first cell is a number)
    Rows are y, columns x, heights in ``height_unit``, node spacing ``spacing``, as for ``.npy``.
Profilometer formats (``.x3p``, ``.datx``, Gwyddion ``.gwy``, ``.sur``, ``.plu``, ``.opd``, ...)
    Read through the SurfaceTopography package, the optional extra ``topography``
    (``pip install 'tactilab[topography]'``; without it the error names the extra). The file
    states its spacing and unit (:mod:`.topography_files`).
``.nc`` (netCDF-4 / HDF5)
    One height variable (named ``height``, or the file's only variable with dimensions) of
    dimensions (y, x) or (x,), with a ``units`` attribute (a length unit: ``m``, ``mm``, ``um``,
    ``nm``), and coordinate variables ``x`` (and ``y``) with their own ``units``. CF packing
    (``scale_factor``, ``add_offset``) is applied; ``_FillValue`` nodes read as NaN and are refused.
    xarray writes this layout: ``ds.to_netcdf(path, engine="h5netcdf")`` with units attributes.
"""

from __future__ import annotations

import csv
import pathlib

import numpy as np

from tactilab.core import rules
from tactilab.core.units import canonical_unit

from .height_map_record import HeightMap
from .topography_files import TOPOGRAPHY_SUFFIXES, read_topography_file
from .units import UNITS, to_si

MAX_HEIGHT_MAP_NODES = 2**24  # 4096 x 4096 heights (134 MB as float64): larger maps exhaust memory downstream
_SUFFIXES = (".npy", ".csv", ".nc")


def _length_factor(unit, where: str) -> float:
    """SI factor of a length ``unit`` string; refuses a missing, unknown or non-length unit."""
    if unit is None or str(unit).strip() == "":
        raise ValueError(f"{where}: the height unit is missing; state it (e.g. 'um', 'nm', 'mm' or 'm')")
    unit = canonical_unit(str(unit).strip())
    dim = UNITS.get(unit, (None,))[0]
    if dim != "length":
        lengths = ", ".join(u for u, (d, _) in UNITS.items() if d == "length")
        raise ValueError(f"{where}: unit {unit!r} is not a length unit; use one of {lengths}")
    return UNITS[unit][1]


def _to_metres(values: np.ndarray, factor: float) -> np.ndarray:
    """values * factor; a power-of-ten unit below 1 m divides by its exact inverse (correct rounding)."""
    if factor == 1.0:
        return values.astype(float)
    inverse = round(1.0 / factor)
    if factor < 1.0 and inverse * factor == 1.0:
        return values.astype(float) / float(inverse)
    return values.astype(float) * factor


def _check_heights(heights: np.ndarray, where: str) -> np.ndarray:
    if heights.dtype.kind not in "iuf":
        raise ValueError(f"{where}: heights must be real numbers, got dtype {heights.dtype}; save a float array")
    if heights.ndim not in (1, 2) or min(heights.shape) < 2:
        raise ValueError(f"{where}: expected heights of shape (nx,) or (ny, nx) with at least 2 nodes per axis, "
                         f"got shape {heights.shape}")
    if heights.size > MAX_HEIGHT_MAP_NODES:
        raise ValueError(f"{where}: {heights.size} heights, above the limit {MAX_HEIGHT_MAP_NODES} (memory); "
                         "crop or resample the map")
    bad = ~np.isfinite(heights)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"{where}: {int(bad.sum())} height(s) are NaN or inf (first at index {idx}); "
                         "fill or crop the missing points before reading")
    return heights


def _caller_spacing(spacing, ndim: int, where: str) -> tuple[float, float | None]:
    """(dx, dy) in m from the caller's ``spacing`` (a length string with a unit, or a number in m)."""
    if spacing is None:
        raise ValueError(f"{where}: spacing is missing; this format carries no coordinates, so give the node "
                         "spacing with a unit, e.g. spacing='20um' (or ('20um', '10um'), x first)")
    values = list(spacing) if isinstance(spacing, (tuple, list)) else [spacing]
    if len(values) not in (1, ndim):
        raise ValueError(f"{where}: spacing must be one length or (dx, dy), got {spacing!r}")
    si = [to_si(v, "length", name="spacing") if isinstance(v, str) else v for v in values]
    checked = rules.spacing(si if len(si) > 1 else si[0], ndim, name=f"{where}: spacing")
    return checked[0], (checked[-1] if ndim == 2 else None)


def _uniform(coords: np.ndarray, axis: str, where: str) -> tuple[float, float, bool]:
    """(origin, spacing, flipped) of strictly monotonic, uniformly spaced coordinates."""
    steps = np.diff(coords)
    if not np.all(np.isfinite(coords)) or steps.size == 0 or not (np.all(steps > 0) or np.all(steps < 0)):
        raise ValueError(f"{where}: the {axis} coordinates must be finite and strictly increasing or decreasing, "
                         f"got {coords[:4].tolist()}...; give one value per node")
    flipped = bool(steps[0] < 0)
    if flipped:
        coords, steps = coords[::-1], -steps[::-1]
    spacing = float((coords[-1] - coords[0]) / (coords.size - 1))
    if np.max(np.abs(steps - spacing)) > 1e-6 * spacing:
        raise ValueError(f"{where}: the {axis} grid is not uniform (steps from {steps.min():.6g} m to "
                         f"{steps.max():.6g} m); resample the map onto a regular grid")
    return float(coords[0]), spacing, flipped


def _read_npy(path: pathlib.Path, spacing, height_unit) -> HeightMap:
    where = str(path)
    try:
        raw = np.load(path, allow_pickle=False, mmap_mode="r")
    except ValueError as exc:
        raise ValueError(f"{where}: not a plain numeric .npy array ({' '.join(str(exc).split())}); save it with "
                         "numpy.save from a float array") from None
    if not isinstance(raw, np.ndarray):
        raise ValueError(f"{where}: expected one array saved with numpy.save, got {type(raw).__name__}")
    if raw.dtype.kind in "iuf" and raw.size > MAX_HEIGHT_MAP_NODES:
        _check_heights(raw, where)  # refuses before reading the values
    heights = _check_heights(np.array(raw), where)
    dx, dy = _caller_spacing(spacing, heights.ndim, where)
    factor = _length_factor(height_unit, f"{where} (height_unit)")
    return HeightMap(heights_m=_to_metres(heights, factor), spacing_x_m=dx, spacing_y_m=dy)


def _number(cell: str) -> float | None:
    try:
        return float(cell)
    except ValueError:
        return None


def _read_csv(path: pathlib.Path, spacing, height_unit) -> HeightMap:
    where = str(path)
    if path.stat().st_size > 40 * MAX_HEIGHT_MAP_NODES:
        raise ValueError(f"{where}: {path.stat().st_size} bytes, too large for a height map of at most "
                         f"{MAX_HEIGHT_MAP_NODES} nodes; crop or resample the map")
    with path.open(newline="", encoding="utf-8") as fh:
        rows = [[c.strip() for c in row] for row in csv.reader(fh) if any(c.strip() for c in row)]
    if not rows:
        raise ValueError(f"{where}: the file is empty; write a height map (see tactilab.data_schemas.height_map)")
    if _number(rows[0][0]) is not None:  # a plain matrix
        try:
            heights = np.array([[float(c) for c in row] for row in rows])
        except ValueError:
            raise ValueError(f"{where}: a plain-matrix CSV must hold numbers only, in rows of equal length; "
                             "or give a labelled grid ('height [um]' in the top-left cell)") from None
        heights = _check_heights(heights[0] if heights.shape[0] == 1 else heights, where)
        dx, dy = _caller_spacing(spacing, heights.ndim, where)
        factor = _length_factor(height_unit, f"{where} (height_unit)")
        return HeightMap(heights_m=_to_metres(heights, factor), spacing_x_m=dx, spacing_y_m=dy)
    label = rows[0][0]
    if not (label.startswith("height [") and label.endswith("]")):
        raise ValueError(f"{where}: the top-left cell must be 'height [UNIT]' (e.g. 'height [um]'), got {label!r}")
    if spacing is not None or height_unit is not None:
        raise ValueError(f"{where}: a labelled CSV states its own coordinates and unit; do not give spacing or "
                         "height_unit (or drop the header row to use them)")
    factor = _length_factor(label[len("height ["):-1], f"{where} (top-left cell)")
    if any(len(row) != len(rows[0]) for row in rows):
        raise ValueError(f"{where}: every row must have {len(rows[0])} cells like the header; fill the missing ones")
    x = np.array([to_si(c, "length", name=f"{where}: header x") for c in rows[0][1:]])
    y = np.array([to_si(row[0], "length", name=f"{where}: row y") for row in rows[1:]])
    try:
        heights = np.array([[float(c) for c in row[1:]] for row in rows[1:]])
    except ValueError:
        raise ValueError(f"{where}: heights must be plain numbers (in the unit of the top-left cell)") from None
    profile = heights.shape[0] == 1
    heights = _check_heights(heights[0] if profile else heights, where)
    x0, dx, flip_x = _uniform(x, "x", where)
    y0, dy, flip_y = (y[0], None, False) if profile else _uniform(y, "y", where)
    if flip_x:
        heights = heights[..., ::-1]
    if flip_y:
        heights = heights[::-1]
    return HeightMap(heights_m=_to_metres(heights, factor), spacing_x_m=dx, spacing_y_m=dy, origin_m=(x0, y0))


def _nc_values(var, where: str) -> np.ndarray:
    """A netCDF variable's values as floats; refuses external storage, applies CF packing and fill values."""
    dset, name = var._h5ds, var.name.lstrip("/")  # the h5py dataset: external or virtual storage points outside
    if dset.external or dset.is_virtual:
        raise ValueError(f"{where}: variable {name!r} is stored outside the file (HDF5 external or virtual "
                         "storage); save the data inside the file")
    values = np.asarray(var[...])
    if values.dtype.kind not in "iuf":
        raise ValueError(f"{where}: variable {name!r} must be numeric, got dtype {values.dtype}")
    values = values.astype(float)
    attrs = dict(var.attrs)
    if "_FillValue" in attrs:
        values[values == float(np.asarray(attrs["_FillValue"]).ravel()[0])] = np.nan
    values = values * float(np.asarray(attrs.get("scale_factor", 1.0)).ravel()[0])
    return values + float(np.asarray(attrs.get("add_offset", 0.0)).ravel()[0])


def _unit_attr(var) -> str | None:
    unit = var.attrs.get("units")
    return unit.decode() if isinstance(unit, bytes) else unit


def _read_netcdf(path: pathlib.Path, spacing, height_unit) -> HeightMap:
    import h5netcdf

    where = str(path)
    if spacing is not None or height_unit is not None:
        raise ValueError(f"{where}: a netCDF height map states its own coordinates and units; do not give "
                         "spacing or height_unit")
    try:
        fh = h5netcdf.File(path, "r")
    except OSError:
        raise ValueError(f"{where}: not a netCDF-4 (HDF5) file; save it with xarray's to_netcdf(engine='h5netcdf') "
                         "or netCDF4 in the NETCDF4 format") from None
    with fh:
        data = {name: v for name, v in fh.variables.items() if v.dimensions and name not in ("x", "y")}
        name = "height" if "height" in data else (next(iter(data)) if len(data) == 1 else None)
        if name is None:
            raise ValueError(f"{where}: cannot tell the height variable among {sorted(data)}; name it 'height'")
        var = data[name]
        dims = tuple(var.dimensions)
        if dims not in (("x",), ("y", "x")):
            raise ValueError(f"{where}: variable {name!r} has dimensions {dims}; expected ('y', 'x') or ('x',)")
        if int(np.prod(var.shape)) > MAX_HEIGHT_MAP_NODES:
            raise ValueError(f"{where}: {int(np.prod(var.shape))} heights, above the limit {MAX_HEIGHT_MAP_NODES} "
                             "(memory); crop or resample the map")
        factor = _length_factor(_unit_attr(var), f"{where}: variable {name!r} units attribute")
        heights = _check_heights(_nc_values(var, where), f"{where}: variable {name!r}")
        coords = {}
        for axis in dims:
            if axis not in fh.variables:
                raise ValueError(f"{where}: coordinate variable {axis!r} is missing; store the {axis} of each node "
                                 "with a units attribute")
            cvar = fh.variables[axis]
            c_factor = _length_factor(_unit_attr(cvar), f"{where}: coordinate {axis!r} units attribute")
            coords[axis] = _uniform(_to_metres(_nc_values(cvar, where), c_factor), axis, where)
    x0, dx, flip_x = coords["x"]
    y0, dy, flip_y = coords.get("y", (0.0, None, False))
    if flip_x:
        heights = heights[..., ::-1]
    if flip_y:
        heights = heights[::-1]
    return HeightMap(heights_m=_to_metres(heights, factor), spacing_x_m=dx, spacing_y_m=dy, origin_m=(x0, y0))


def read_height_map(path, *, spacing=None, height_unit: str | None = None) -> HeightMap:
    """Read a measured height map (.npy, .csv, netCDF or a profilometer file) into a :class:`HeightMap` in m.

    Parameters
    ----------
    path : str or path-like
        The file; its suffix picks the format (see the module docstring for each layout).
    spacing : str, float or (dx, dy), optional
        Node spacing for formats without coordinates (``.npy``, a plain-matrix ``.csv``): a length
        with a unit (``"20um"``) or a number in m; ``(dx, dy)`` x first. Refused for files that
        carry their coordinates.
    height_unit : str, optional
        Unit of the heights in a ``.npy`` or plain-matrix ``.csv`` (``"um"``, ``"nm"``, ``"m"``);
        required there, refused elsewhere.

    Returns
    -------
    HeightMap
        ``heights_m`` shape (ny, nx) or (nx,) in m, ascending coordinates, the spacing in m and the
        position of node [0, 0] in ``origin_m`` (0 for formats without coordinates).

    Raises
    ------
    ValueError
        For an unknown suffix, NaN or inf heights, a missing or non-length unit, a missing spacing,
        a non-uniform or non-monotonic grid, a map above ``MAX_HEIGHT_MAP_NODES`` nodes, a pickled
        ``.npy``, a netCDF variable stored outside the file, or a profilometer file (``.x3p``,
        ``.datx``, ``.gwy``, ...) when the optional extra ``topography`` is not installed.
    OSError
        When the file cannot be opened.
    """
    path = pathlib.Path(path)
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES + TOPOGRAPHY_SUFFIXES:
        raise ValueError(f"{path}: unknown height-map format {path.suffix!r}; use .npy (with spacing and "
                         "height_unit), .csv, .nc (netCDF-4 with x/y coordinates in m) or a profilometer "
                         "format (.x3p, .datx, .gwy, ...: the optional extra 'topography')")
    if not path.is_file():
        raise FileNotFoundError(2, "No such file", str(path))
    if suffix == ".npy":
        return _read_npy(path, spacing, height_unit)
    if suffix == ".csv":
        return _read_csv(path, spacing, height_unit)
    if suffix == ".nc":
        return _read_netcdf(path, spacing, height_unit)
    return read_topography_file(path, spacing, height_unit, where=str(path), length_factor=_length_factor,
                                check_heights=_check_heights, to_metres=_to_metres)

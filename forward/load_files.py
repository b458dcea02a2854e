"""Load files at the edge: read surface tractions from ``.npz`` or ``.toml`` into a SurfaceLoad.

``.npz``: arrays ``p``, ``qx``, ``qy`` (any subset) in Pa, shape (nx,) or (ny, nx), a scalar
or pair ``spacing`` in m, and optionally a boolean ``periodic``.

``.toml``: a grid and analytic patches; quantities carry unit suffixes, converted to SI here::

    [grid]
    shape = [128, 128]          # [ny, nx], or [nx] for a plane-strain load
    spacing = "0.1mm"
    periodic = false

    [[patch]]                   # summed; shapes: "hertz", "gaussian", "disc"
    shape = "hertz"
    centre = ["0mm", "0mm"]
    radius = "3mm"              # contact radius (hertz, disc) or standard deviation (gaussian)
    pressure = "40kPa"          # peak normal pressure, into the skin
    traction_x = "12kPa"        # peak tangential traction along +x (optional)
    traction_y = "0kPa"
"""

from __future__ import annotations

import pathlib
import tomllib

import numpy as np

from tactilab.core.netcdf import write_netcdf
from tactilab.data_schemas.units import to_si

from .halfspace import SurfaceLoad

_PATCH_KEYS = {"shape", "centre", "radius", "pressure", "traction_x", "traction_y"}
MAX_GRID_NODES = 2**24  # 4096 x 4096: one float64 component is 134 MB, and the methods need a few


def _profile(shape: str, r2: np.ndarray, radius: float, where: str) -> np.ndarray:
    if shape == "hertz":
        return np.sqrt(np.clip(1.0 - r2 / radius**2, 0.0, None))
    if shape == "gaussian":
        return np.exp(-r2 / (2 * radius**2))
    if shape == "disc":
        return (r2 <= radius**2).astype(float)
    raise ValueError(f"{where}.shape: unknown patch shape {shape!r}; use 'hertz', 'gaussian' or 'disc'")


def _from_toml(path: pathlib.Path) -> SurfaceLoad:
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path}: not valid TOML ({err}); fix the syntax") from None
    grid = data.get("grid")
    if not isinstance(grid, dict):
        raise ValueError(f"{path}: missing [grid] table with shape and spacing")
    shape = grid.get("shape")
    if not isinstance(shape, list) or len(shape) not in (1, 2) or not all(isinstance(n, int) and n > 0 for n in shape):
        raise ValueError(f"{path}: grid.shape must be [nx] or [ny, nx] of positive integers, got {shape!r}")
    if int(np.prod(shape)) > MAX_GRID_NODES:
        raise ValueError(f"{path}: grid.shape {shape} has {int(np.prod(shape))} nodes, above the limit "
                         f"{MAX_GRID_NODES} (memory); use a coarser spacing or a smaller grid")
    spacing = to_si(grid.get("spacing", ""), "length", name="grid.spacing")
    if spacing <= 0:
        raise ValueError(f"grid.spacing: must be > 0, got {grid.get('spacing')!r}")
    periodic = grid.get("periodic", False)
    if not isinstance(periodic, bool):
        raise ValueError(f"{path}: grid.periodic must be true or false (TOML booleans, no quotes), got {periodic!r}")
    template = SurfaceLoad(p=np.zeros(shape), spacing=spacing, periodic=periodic)
    if template.ndim == 1:
        coords = (template.x,)
    else:
        yy, xx = np.meshgrid(template.y, template.x, indexing="ij")
        coords = (xx, yy)
    fields = {"p": np.zeros(shape), "qx": np.zeros(shape), "qy": np.zeros(shape)}
    patches = data.get("patch", [])
    if not patches:
        raise ValueError(f"{path}: no [[patch]] given; add at least one load patch")
    if not isinstance(patches, list) or not all(isinstance(patch, dict) for patch in patches):
        raise ValueError(f"{path}: patches must be an array of tables, one [[patch]] (double brackets) per "
                         f"patch, got {type(patches).__name__}")
    for k, patch in enumerate(patches):
        where = f"patch[{k}]"
        unknown = set(patch) - _PATCH_KEYS
        if unknown:
            raise ValueError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(_PATCH_KEYS)}")
        centre = patch.get("centre", ["0mm"] * template.ndim)
        if len(centre) != template.ndim:
            raise ValueError(f"{where}.centre: needs {template.ndim} coordinate(s), got {centre!r}")
        c = [to_si(v, "length", name=f"{where}.centre") for v in centre]
        radius = to_si(patch.get("radius", ""), "length", name=f"{where}.radius")
        if radius <= 0:
            raise ValueError(f"{where}.radius: must be > 0, got {patch.get('radius')!r}")
        r2 = sum((xi - ci) ** 2 for xi, ci in zip(coords, c))
        prof = _profile(patch.get("shape", "hertz"), r2, radius, where)
        for key, name in (("pressure", "p"), ("traction_x", "qx"), ("traction_y", "qy")):
            if key in patch:
                fields[name] += to_si(patch[key], "pressure", name=f"{where}.{key}") * prof
    given = {k: v for k, v in fields.items() if v.any()} or {"p": fields["p"]}
    return SurfaceLoad(**given, spacing=spacing, periodic=periodic)


def _from_npz(path: pathlib.Path) -> SurfaceLoad:
    try:
        archive = np.load(path)  # allow_pickle=False: a non-numpy file ends up here as ValueError
    except (ValueError, EOFError):
        raise ValueError(f"{path}: not a numpy .npz archive; write one with "
                         "numpy.savez(path, p=..., spacing=...)") from None
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise ValueError(f"{path}: holds a single array, not an .npz archive; write one with "
                         "numpy.savez(path, p=..., spacing=...)")
    with archive as data:
        names = [k for k in ("p", "qx", "qy") if k in data]
        if not names:
            raise ValueError(f"{path}: holds none of the arrays p, qx, qy (tractions in Pa)")
        if "spacing" not in data:
            raise ValueError(f"{path}: missing 'spacing' (grid spacing in m)")
        arrays = {k: np.array(data[k]) for k in names}
        spacing = np.array(data["spacing"]).tolist()
        periodic = bool(data["periodic"]) if "periodic" in data else False
    return SurfaceLoad(**arrays, spacing=spacing, periodic=periodic)


def read_load(path: str | pathlib.Path) -> SurfaceLoad:
    """Read a load file (``.npz`` in SI, or ``.toml`` with unit suffixes) into a SurfaceLoad.

    Raises
    ------
    ValueError
        Unknown suffix, missing fields, bad units or values (the message names the key).
    FileNotFoundError
        If the file does not exist.
    """
    path = pathlib.Path(path)
    if not path.exists():
        raise FileNotFoundError(2, "load file not found", str(path))
    if path.suffix == ".npz":
        return _from_npz(path)
    if path.suffix == ".toml":
        return _from_toml(path)
    raise ValueError(f"load file: unknown type {path.suffix!r} for {path}; use .npz (SI arrays) or .toml")


def write_field(result, folder: str | pathlib.Path, stem: str = "field") -> list[pathlib.Path]:
    """Save a FieldResult as netCDF (SI units in attributes) and a PNG map (mm, kPa).

    Returns the written paths.
    """
    from .plots import plot_field

    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    nc = folder / f"{stem}.nc"
    write_netcdf(result.data, nc)
    quantity = "stress" if "stress" in result.data and "strain" not in result.data else "strain"
    png = plot_field(result.data[quantity], folder / f"{stem}.png",
                     title=f"{quantity} by {result.method} (est. rel. error {result.error_estimate:.1e})")
    return [nc, png]

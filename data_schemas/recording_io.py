"""Recording files: netCDF (via h5netcdf), Parquet (tidy form) and JSON, beside the record.

:func:`write_recording` writes a :class:`~.recording.Recording` as ``recording.nc`` or
``recording.parquet``; :func:`read_recording` reads either back (or a JSON record written by
``Recording.save``) and gives the same record: values in SI (Pa, or strain with tensor shear),
sampling rate, start time, quantity, unit, description, and the sensor and component order.
:func:`recording_dataset` is the netCDF layout as an ``xarray.Dataset``. Parquet needs the
optional package pyarrow (the ``parquet`` extra).

Both files are self-describing: what the netCDF file keeps beside the values (the sensor
positions, the contact position per sample, the scene's scalar attributes such as ``depth_m``,
the writer's ``tactilab_version``) the Parquet file keeps in its schema metadata (pandas'
``DataFrame.attrs``), and :func:`read_recording_metadata` reads it back from either. The netCDF
file carries CF attributes (:func:`tactilab.core.netcdf.write_netcdf`).
"""

from __future__ import annotations

import importlib.util
import pathlib
from collections.abc import Mapping

import numpy as np
import xarray as xr

from tactilab.core.netcdf import write_netcdf
from tactilab.core.version import package_version

from .netcdf_files import check_self_contained
from .recording import Recording

#: File formats :func:`write_recording` writes
FORMATS: tuple[str, ...] = ("netcdf", "parquet")

_SHEAR_CONVENTION = "tensor shear eps_ij (engineering gamma = 2 eps)"


def recording_dataset(recording: Recording, *, positions_m=None, sensor_positions_m=None,
                      attrs: Mapping[str, float | str] | None = None) -> xr.Dataset:
    """The recording as an xarray Dataset in SI: ``values`` with dims (time, sensor, component).

    Parameters
    ----------
    recording : Recording
    positions_m : array_like, shape (n_times,), optional
        World x of the contact centre at each sample, m (coordinate ``contact_x``).
    sensor_positions_m : array_like, shape (n_sensors, 2), optional
        Sensor (x, y) in the finger frame, m (coordinates ``sensor_x``, ``sensor_y``).
    attrs : mapping, optional
        Further scalar attributes (SI, unit in the name, e.g. ``depth_m``).

    Returns
    -------
    xarray.Dataset
        ``values`` in Pa or strain (tensor shear); attributes ``quantity``, ``unit``,
        ``sampling_rate_hz``, ``start_time_s``, ``description``, ``shear_convention``.
    """
    ds = xr.Dataset(
        {"values": (("time", "sensor", "component"), recording.values,
                    {"long_name": f"{recording.quantity} read by each sensor (TENSOR shear for strain)"})},
        coords={"time": ("time", recording.times_s, {"units": "s", "long_name": "time of the sample"}),
                "sensor": ("sensor", list(recording.sensor_ids), {"long_name": "sensor id"}),
                "component": ("component", list(recording.components), {"long_name": "Voigt component"})},
        attrs=dict(quantity=recording.quantity, unit=recording.unit, sampling_rate_hz=recording.sampling_rate_hz,
                   start_time_s=recording.start_time_s, description=recording.description,
                   shear_convention=_SHEAR_CONVENTION),
    )
    ds["values"].attrs["units"] = recording.unit
    if sensor_positions_m is not None:
        pos = np.asarray(sensor_positions_m, dtype=float)
        if pos.shape != (recording.n_sensors, 2):
            raise ValueError(f"sensor_positions_m: need shape ({recording.n_sensors}, 2) (x, y per sensor, m), "
                             f"got {pos.shape}")
        ds = ds.assign_coords(
            sensor_x=("sensor", pos[:, 0], {"units": "m", "frame": "finger", "long_name": "sensor x in the finger frame"}),
            sensor_y=("sensor", pos[:, 1], {"units": "m", "frame": "finger", "long_name": "sensor y in the finger frame"}))
    if positions_m is not None:
        u = np.asarray(positions_m, dtype=float)
        if u.shape != (recording.n_times,):
            raise ValueError(f"positions_m: need one contact position per sample, shape ({recording.n_times},), "
                             f"got {u.shape}")
        ds = ds.assign_coords(contact_x=("time", u, {"units": "m", "frame": "world",
                                                     "long_name": "contact centre x at each sample"}))
    if attrs:
        ds.attrs.update(attrs)
    return ds


def write_recording(recording: Recording, out_dir, fmt: str = "netcdf", *, positions_m=None,
                    sensor_positions_m=None, attrs: Mapping[str, float | str] | None = None) -> pathlib.Path:
    """Write ``recording.nc`` (netCDF4 via h5netcdf) or ``recording.parquet`` (tidy form) into ``out_dir``.

    Parameters
    ----------
    recording : Recording
    out_dir : path
        An existing folder.
    fmt : {"netcdf", "parquet"}
        Parquet needs pyarrow; it stores the tidy DataFrame (``Recording.to_dataframe``) with
        the coordinates and attributes below in its schema metadata.
    positions_m, sensor_positions_m, attrs
        Extra coordinates and attributes, as in :func:`recording_dataset` (read back by
        :func:`read_recording_metadata`).

    Returns
    -------
    pathlib.Path
        The file written.
    """
    if fmt not in FORMATS:
        raise ValueError(f"format: must be one of {FORMATS}, got {fmt!r}")
    out_dir = pathlib.Path(out_dir)
    if fmt == "parquet":
        if importlib.util.find_spec("pyarrow") is None:
            raise ValueError("format: 'parquet' needs the optional package pyarrow (pip install pyarrow); "
                             "or write netcdf")
        ds = recording_dataset(recording, positions_m=positions_m, sensor_positions_m=sensor_positions_m,
                               attrs=attrs)  # validates the extras as for netCDF
        df = recording.to_dataframe()
        df.attrs.update(_parquet_extras(ds))
        path = out_dir / "recording.parquet"
        df.to_parquet(path)
        return path
    path = out_dir / "recording.nc"
    ds = recording_dataset(recording, positions_m=positions_m, sensor_positions_m=sensor_positions_m, attrs=attrs)
    write_netcdf(ds, path)
    return path


#: the record's own attributes (read by read_recording), apart from the scene's extras
_OWN = ("quantity", "unit", "sampling_rate_hz", "start_time_s", "description", "shear_convention")


def _parquet_extras(ds: xr.Dataset) -> dict:
    """What the netCDF file keeps beside the values, as JSON-ready Parquet metadata."""
    extras = {"tactilab_version": package_version(), "shear_convention": _SHEAR_CONVENTION,
              "scene_attrs": {k: (v.item() if isinstance(v, np.generic) else v)
                              for k, v in ds.attrs.items() if k not in _OWN}}
    if "sensor_x" in ds.coords:
        extras["sensor_positions_m"] = np.column_stack([ds["sensor_x"].values, ds["sensor_y"].values]).tolist()
    if "contact_x" in ds.coords:
        extras["positions_m"] = ds["contact_x"].values.tolist()
    return extras


def read_recording_metadata(path) -> dict:
    """What a recording file says about how it was made, beside its values.

    Parameters
    ----------
    path : path
        ``recording.nc`` or ``recording.parquet`` written by :func:`write_recording` (a JSON
        record keeps none of it).

    Returns
    -------
    dict
        ``sensor_positions_m`` (ndarray, shape (n_sensors, 2), m, finger frame, or None),
        ``positions_m`` (ndarray, shape (n_times,), contact centre x per sample, m, or None),
        ``attrs`` (the scene's scalar attributes, SI with the unit in the name, e.g.
        ``depth_m``, ``contact_radius_m``, ``normal_force_n``) and ``tactilab_version`` (of
        the writer, or None for files written before it was kept).

    Raises
    ------
    ValueError
        For another suffix (the JSON record included), or Parquet without pyarrow.
    """
    path = pathlib.Path(path)
    if path.suffix == ".nc":
        check_self_contained(path)
        with xr.open_dataset(path, engine="h5netcdf") as ds:
            sensors = (np.column_stack([ds["sensor_x"].values, ds["sensor_y"].values])
                       if "sensor_x" in ds.coords else None)
            positions = ds["contact_x"].values.copy() if "contact_x" in ds.coords else None
            attrs = {k: _number(v) for k, v in ds.attrs.items()
                     if k not in (*_OWN, "Conventions", "tactilab_version")}
            version = ds.attrs.get("tactilab_version")
    elif path.suffix == ".parquet":
        if importlib.util.find_spec("pyarrow") is None:
            raise ValueError(f"path: reading {path} needs the optional package pyarrow (pip install pyarrow)")
        import pandas as pd

        extras = dict(pd.read_parquet(path, columns=[]).attrs)  # pandas keeps DataFrame.attrs in the schema
        sensors = None if "sensor_positions_m" not in extras else np.asarray(extras["sensor_positions_m"], float)
        positions = None if "positions_m" not in extras else np.asarray(extras["positions_m"], float)
        attrs, version = dict(extras.get("scene_attrs", {})), extras.get("tactilab_version")
    else:
        raise ValueError(f"path: {path} is a {path.suffix!r} file; the metadata beside the values is kept in "
                         "recording.nc or recording.parquet (write_recording)")
    return {"sensor_positions_m": sensors, "positions_m": positions, "attrs": attrs,
            "tactilab_version": None if version is None else str(version)}


def read_recording(path) -> Recording:
    """Read a Recording written by :func:`write_recording` (``.nc`` or ``.parquet``) or a JSON record.

    Parameters
    ----------
    path : path
        ``recording.nc``, ``recording.parquet`` or a ``.json`` written by ``Recording.save``.

    Returns
    -------
    Recording
        Equal to the record written (values in SI, sensor and component order kept).

    Raises
    ------
    OSError
        If the file does not exist.
    ValueError
        An unsupported suffix, a netCDF file without ``values`` or with data stored outside
        itself (external storage, a virtual dataset, an external link), or Parquet without
        pyarrow.
    """
    path = pathlib.Path(path)
    if not path.exists():
        raise OSError(f"path: file {str(path)!r} not found; give the recording.nc, .parquet or .json "
                      "written with write_recording or Recording.save")
    if path.suffix == ".json":
        return _validated(path, lambda: Recording.load(path))
    if path.suffix == ".parquet":
        if importlib.util.find_spec("pyarrow") is None:
            raise ValueError(f"path: reading {path} needs the optional package pyarrow (pip install pyarrow); "
                             "or write the recording as netcdf")
        import pandas as pd

        df = pd.read_parquet(path)
        # pandas keeps DataFrame.attrs in the Parquet metadata; tuples come back as lists
        order = {k: tuple(df.attrs[k]) for k in ("sensor_ids", "components") if k in df.attrs}
        return _validated(path, lambda: Recording.from_dataframe(df, **order))
    if path.suffix != ".nc":
        raise ValueError(f"path: unsupported file type {path.suffix!r} ({path}); use .nc, .parquet or .json")
    check_self_contained(path)  # no external storage, virtual dataset or external link
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        if "values" not in ds:
            raise ValueError(f"path: {path} has no 'values' variable (time, sensor, component); "
                             "write it with write_recording")
        dims = tuple(ds["values"].dims)
        if dims != ("time", "sensor", "component"):
            raise ValueError(f"path: {path} holds 'values' with dimensions {dims}, not (time, sensor, component); "
                             "write it with write_recording")
        if "sampling_rate_hz" not in ds.attrs:
            raise ValueError(f"path: {path} lacks the attribute sampling_rate_hz (samples per second); "
                             "write it with write_recording")
        fields = dict(values=ds["values"].values, sampling_rate_hz=_number(ds.attrs["sampling_rate_hz"]),
                      sensor_ids=tuple(str(s) for s in ds["sensor"].values),
                      components=tuple(str(c) for c in ds["component"].values),
                      quantity=str(ds.attrs.get("quantity", "stress")), unit=str(ds.attrs.get("unit", "Pa")),
                      start_time_s=_number(ds.attrs.get("start_time_s", 0.0)),
                      description=str(ds.attrs.get("description", "")))
    return _validated(path, lambda: Recording(**fields))


def _number(value):
    """A scalar attribute as a float when it is one (else as is: the record's rule names it)."""
    try:
        return float(np.asarray(value).item())
    except (TypeError, ValueError):
        return value


def _validated(path, build) -> Recording:
    """``build()``, with a record's validation errors turned into ONE line naming the file."""
    from pydantic import ValidationError

    try:
        return build()
    except ValidationError as exc:
        parts = []
        for err in exc.errors()[:3]:
            loc = ".".join(str(x) for x in err.get("loc", ()))
            msg = str(err.get("msg", "")).removeprefix("Value error, ")
            parts.append(f"{loc}: {msg}" if loc else msg)
        raise ValueError(f"path: {path} is not a valid recording ({'; '.join(parts)}); fix the file or write it "
                         "with write_recording") from None

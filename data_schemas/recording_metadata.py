"""What a recording file says about the scene that produced it: its metadata, read without its values.

``tactilab simulate`` writes, next to the values, the scene's description: scalar attributes in SI with
the unit in the name (``depth_m``, ``contact_radius_m``, ``normal_force_n``, ``young_modulus_pa``, ...),
the sensors' positions (``sensor_x``, ``sensor_y``, finger frame, m) and the contact position of each
sample (``contact_x``, world frame, m). :func:`read_recording_metadata` returns them as one flat dict,
so a check can compare any field a writer adds (``forward.scene_recording`` does) without a list of
names here.
"""

from __future__ import annotations

import importlib.util
import pathlib
from typing import Any

import numpy as np

__all__ = ["read_recording_metadata"]

#: attributes of the file format itself, not of the scene
_FORMAT_KEYS = ("description", "shear_convention", "unit", "Conventions", "tactilab_version", "history", "title")


def read_recording_metadata(path) -> dict[str, Any]:
    """The scene description a recording file carries (empty where it carries none, e.g. a JSON record).

    Parameters
    ----------
    path : path
        ``recording.nc``, ``recording.parquet`` or a ``.json`` Recording.

    Returns
    -------
    dict
        Scalar attributes (floats or strings, SI), ``sampling_rate_hz``, ``components`` (tuple of
        str), ``n_sensors`` and, where written, ``sensor_positions_m`` (ndarray, shape (n_sensors, 2),
        m) and ``contact_x_m`` (ndarray, shape (n_times,), m).
    """
    path = pathlib.Path(path)
    if path.suffix == ".json":
        from .recording import Recording

        rec = Recording.load(path)
        return {"sampling_rate_hz": rec.sampling_rate_hz, "components": tuple(rec.components),
                "n_sensors": rec.n_sensors}
    if path.suffix == ".parquet":
        if importlib.util.find_spec("pyarrow") is None:
            return {}  # read_recording names the missing package
        import pandas as pd

        attrs = pd.read_parquet(path).attrs  # pandas keeps DataFrame.attrs in the Parquet metadata
        out = _flat(attrs)
        if "components" in attrs:
            out["components"] = tuple(str(c) for c in attrs["components"])
        return out
    import xarray as xr

    with xr.open_dataset(path, engine="h5netcdf") as ds:
        out = _flat(ds.attrs)
        out["components"] = tuple(str(c) for c in ds["component"].values) if "component" in ds.coords else ()
        out["n_sensors"] = int(ds.sizes.get("sensor", 0))
        if "sensor_x" in ds.coords and "sensor_y" in ds.coords:
            out["sensor_positions_m"] = np.stack([ds["sensor_x"].values, ds["sensor_y"].values], axis=1)
        if "contact_x" in ds.coords:
            out["contact_x_m"] = np.asarray(ds["contact_x"].values, dtype=float)
    return out


def _flat(attrs) -> dict[str, Any]:
    out = {}
    for key, value in dict(attrs).items():
        if key in _FORMAT_KEYS:
            continue
        v = np.asarray(value)
        if v.ndim == 0:
            out[key] = v.item() if v.dtype.kind in "biuf" else str(v.item())
        elif key.endswith("_m") or key.endswith("positions_m"):
            out[key] = v.astype(float)
    return out

"""What a recording file says about the scene that produced it, as one flat dict for a comparison.

``tactilab simulate`` writes, next to the values, the scene's description: scalar attributes in SI with
the unit in the name (``depth_m``, ``contact_radius_m``, ``normal_force_n``, ``young_modulus_pa``, ...),
the sensors' positions (finger frame, m) and the contact position of each sample (world frame, m).
:func:`tactilab.data_schemas.read_recording_metadata` (in ``recording_io``, the file format's one
reader) returns them grouped; :func:`scene_fields` flattens them with the record's own sampling rate,
components and sensor count, so a check can compare any field a writer adds
(``forward.scene_metadata`` does) without a list of names here.
"""

from __future__ import annotations

import pathlib
from typing import Any

import numpy as np

__all__ = ["scene_fields"]


def scene_fields(path) -> dict[str, Any]:
    """The scene description a recording file carries, flat (only the record's own fields for JSON).

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
    from .recording_io import read_recording, read_recording_metadata

    path = pathlib.Path(path)
    rec = read_recording(path)
    out: dict[str, Any] = {}
    if path.suffix != ".json":
        meta = read_recording_metadata(path)
        for key, value in meta["attrs"].items():
            v = np.asarray(value)
            if v.ndim == 0:
                out[key] = v.item() if v.dtype.kind in "biuf" else str(v.item())
        if meta["sensor_positions_m"] is not None:
            out["sensor_positions_m"] = np.asarray(meta["sensor_positions_m"], dtype=float)
        if meta["positions_m"] is not None:
            out["contact_x_m"] = np.asarray(meta["positions_m"], dtype=float)
    out.update(sampling_rate_hz=rec.sampling_rate_hz, components=tuple(rec.components), n_sensors=rec.n_sensors)
    return out

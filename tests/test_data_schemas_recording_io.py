"""One reader for the writer: ``write_recording`` -> ``read_recording`` gives back the same record.

The reader and writer live beside the record, in ``tactilab.data_schemas.recording_io``;
``tactilab simulate`` writes with it, ``tactilab invert`` and the inversion demo read with it.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
import xarray as xr

from tactilab.data_schemas.recording import Recording
from tactilab.data_schemas import read_recording, recording_dataset, write_recording


def record(rng, quantity="stress"):
    return Recording(values=rng.normal(0, 50.0, (7, 3, 2)), sampling_rate_hz=250.0, sensor_ids=("s2", "s0", "s1"),
                     components=("zz", "zx"), quantity=quantity, start_time_s=0.25,
                     description="round trip: sensors out of alphabetical order")


@pytest.mark.parametrize("fmt", ["netcdf", "parquet"])
def test_write_then_read_gives_the_same_record(fmt, rng, tmp_path):
    if fmt == "parquet" and importlib.util.find_spec("pyarrow") is None:
        with pytest.raises(ValueError, match="needs the optional package pyarrow"):
            write_recording(record(rng), tmp_path, fmt)
        return
    for quantity in ("stress", "strain"):
        rec = record(rng, quantity)
        path = write_recording(rec, tmp_path, fmt)
        assert read_recording(path) == rec


def test_json_round_trip(rng, tmp_path):
    rec = record(rng)
    assert read_recording(rec.save(tmp_path / "rec.json")) == rec


def test_read_recording_errors(tmp_path):
    with pytest.raises(OSError, match="not found"):
        read_recording(tmp_path / "missing.nc")
    (tmp_path / "rec.csv").write_text("x")
    with pytest.raises(ValueError, match="unsupported file type"):
        read_recording(tmp_path / "rec.csv")
    xr.Dataset({"other": ("t", np.zeros(3))}).to_netcdf(tmp_path / "bad.nc", engine="h5netcdf")
    with pytest.raises(ValueError, match="no 'values' variable"):
        read_recording(tmp_path / "bad.nc")


def test_parquet_reader_without_pyarrow_says_so(rng, tmp_path, monkeypatch):
    (tmp_path / "recording.parquet").write_bytes(b"PAR1")
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "pyarrow" else real(name, *a))
    with pytest.raises(ValueError, match="needs the optional package pyarrow"):
        read_recording(tmp_path / "recording.parquet")


def test_dataset_coordinates_and_their_shape_checks(rng, tmp_path):
    rec = record(rng)
    ds = recording_dataset(rec, positions_m=np.arange(7) * 1e-3, sensor_positions_m=np.zeros((3, 2)),
                           attrs={"depth_m": 3e-3})
    assert ds["values"].dims == ("time", "sensor", "component") and ds.attrs["depth_m"] == 3e-3
    assert ds["contact_x"].attrs["units"] == "m" and ds["sensor_x"].shape == (3,)
    with pytest.raises(ValueError, match=r"positions_m: need one contact position per sample, shape \(7,\)"):
        recording_dataset(rec, positions_m=np.zeros(3))
    with pytest.raises(ValueError, match=r"sensor_positions_m: need shape \(3, 2\)"):
        recording_dataset(rec, sensor_positions_m=np.zeros((2, 2)))
    path = write_recording(rec, tmp_path, positions_m=np.arange(7) * 1e-3)
    assert read_recording(path) == rec


@pytest.mark.parametrize("fmt", ["netcdf", "parquet"])
def test_both_files_keep_the_sensor_positions_depth_and_scene_metadata(fmt, rng, tmp_path):
    """Parquet recordings are self-describing: what the netCDF file keeps beside the values (sensor
    positions, contact positions, depth and the other scene attributes) comes back from either."""
    from tactilab.core import package_version
    from tactilab.data_schemas import read_recording_metadata

    # pyarrow is in the test extra
    rec = record(rng)
    sensors = rng.normal(0, 1e-3, (3, 2))
    positions = np.linspace(-2e-3, 2e-3, 7)
    scene = {"depth_m": 1.25e-3, "contact_radius_m": 4e-3, "normal_force_n": 0.5, "friction": 0.4}
    path = write_recording(rec, tmp_path, fmt, positions_m=positions, sensor_positions_m=sensors, attrs=scene)
    meta = read_recording_metadata(path)
    assert np.array_equal(meta["sensor_positions_m"], sensors) and np.array_equal(meta["positions_m"], positions)
    assert meta["attrs"] == scene and meta["tactilab_version"] == package_version()
    assert read_recording(path) == rec
    (tmp_path / "bare").mkdir()
    bare = read_recording_metadata(write_recording(rec, tmp_path / "bare", fmt))
    assert bare["sensor_positions_m"] is None and bare["positions_m"] is None and bare["attrs"] == {}


def test_recording_metadata_of_a_json_record_is_refused(rng, tmp_path):
    from tactilab.data_schemas import read_recording_metadata

    with pytest.raises(ValueError, match="the metadata beside the values is kept in recording.nc or recording.parquet"):
        read_recording_metadata(record(rng).save(tmp_path / "rec.json"))


def test_recording_metadata_of_parquet_without_pyarrow_says_so(tmp_path, monkeypatch):
    from tactilab.data_schemas import read_recording_metadata

    (tmp_path / "recording.parquet").write_bytes(b"PAR1")
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "pyarrow" else real(name, *a))
    with pytest.raises(ValueError, match="needs the optional package pyarrow"):
        read_recording_metadata(tmp_path / "recording.parquet")

"""``tactilab invert`` reports an invalid recording in one line, never a traceback (issue 26, item 5)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas import example_path
from tactilab.data_schemas.recording_io import read_recording

GOOD = np.ones((8, 1, 1))


def _nc(path, values, dims=("time", "sensor", "component"), attrs=None, name="values"):
    coords = {d: {"sensor": ["s0"], "component": ["zz"]}[d] for d in dims if d != "time"}
    attrs = {"sampling_rate_hz": 1000.0, "quantity": "stress", "unit": "Pa"} if attrs is None else attrs
    xr.Dataset({name: (dims, values)}, coords=coords, attrs=attrs).to_netcdf(path, engine="h5netcdf")
    return path


def _bad_at_3(value: float) -> np.ndarray:
    return np.where(np.arange(8)[:, None, None] == 3, value, GOOD)


CASES = {
    "nan": (lambda p: _nc(p, _bad_at_3(np.nan)), "values must be finite everywhere, got nan at index (3, 0, 0)"),
    "inf": (lambda p: _nc(p, _bad_at_3(np.inf)), "values must be finite everywhere, got inf at index (3, 0, 0)"),
    "zero_samples": (lambda p: _nc(p, np.ones((0, 1, 1))), "values must not be empty, got shape (0, 1, 1)"),
    "rate_zero": (lambda p: _nc(p, GOOD, attrs={"sampling_rate_hz": 0.0}), "sampling_rate_hz must be > 0"),
    "rate_nan": (lambda p: _nc(p, GOOD, attrs={"sampling_rate_hz": float("nan")}), "sampling_rate_hz must be finite"),
    "rate_text": (lambda p: _nc(p, GOOD, attrs={"sampling_rate_hz": "fast"}), "sampling_rate_hz: Input should be"),
    "rate_missing": (lambda p: _nc(p, GOOD, attrs={}), "lacks the attribute sampling_rate_hz"),
    "two_d": (lambda p: _nc(p, np.ones((8, 1)), dims=("time", "sensor")),
              "holds 'values' with dimensions ('time', 'sensor'), not (time, sensor, component)"),
    "no_values": (lambda p: _nc(p, GOOD, name="other"), "has no 'values' variable"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_invert_reports_an_invalid_netcdf_recording_in_one_line(tmp_path, capsys, case):
    make, expected = CASES[case]
    path = make(tmp_path / f"{case}.nc")
    with pytest.raises(ValueError, match="path: ") as raised:
        read_recording(path)
    assert type(raised.value) is ValueError  # never a pydantic error the command line cannot re-word
    code = cli_main(["invert", str(path), "--scene", str(example_path("fingertip_defect.toml")),
                     "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert err.startswith("tactilab invert: error: RECORDING: ") and expected in err, err


def test_invert_reports_an_invalid_json_recording_in_one_line(tmp_path, capsys):
    path = tmp_path / "r.json"
    path.write_text(json.dumps({"values": [[[1.0]]], "sampling_rate_hz": -5, "sensor_ids": ["s0"],
                                "components": ["zz"]}))
    code = cli_main(["invert", str(path), "--scene", str(example_path("fingertip_defect.toml")),
                     "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "sampling_rate_hz must be > 0" in err, err

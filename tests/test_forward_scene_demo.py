"""The finger-scan demo section writes its files and reports its oracles."""

from __future__ import annotations

import re

import pytest
import xarray as xr

from tactilab.demo.scenes import run_demo


@pytest.mark.slow
def test_scene_demo_writes_report(tmp_path):
    lines = list(run_demo(tmp_path, progress=False))
    out = tmp_path / "finger_scan"
    for name in ("recording.nc", "field_maps.png", "receptive_fields.png", "time_series.png", "spectrum.png",
                 "shape_invariance.csv", "fingerprint_spectrum.png", "wiener_kernel.png"):
        assert (out / name).stat().st_size > 1000, name
    text = "\n".join(lines)
    check = float(re.search(r"max difference ([0-9.]+) % of the peak", text).group(1))
    assert check < 2.0
    assert "spectral peak at 200 Hz" in text
    ds = xr.open_dataset(out / "recording.nc", engine="h5netcdf")
    assert ds["values"].shape == (500, 25, 2) and ds.attrs["unit"] == "Pa"
    ds.close()

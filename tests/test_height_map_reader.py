"""read_height_map: bit-exact round trips for .npy, .csv (both layouts) and netCDF; every refusal."""

import numpy as np
import pytest
import xarray as xr

from tactilab.data_schemas import HeightMap, read_height_map


def _heights(rng, shape=(5, 7)):
    return rng.standard_normal(shape) * 1e-6


def _write_nc(path, heights, x, y=None, h_unit="m", xy_unit="m", name="height"):
    coords = {"x": ("x", x, {"units": xy_unit} if xy_unit else {})}
    dims = ("x",)
    if y is not None:
        coords["y"] = ("y", y, {"units": xy_unit} if xy_unit else {})
        dims = ("y", "x")
    ds = xr.Dataset({name: (dims, heights, {"units": h_unit} if h_unit else {})}, coords=coords)
    ds.to_netcdf(path, engine="h5netcdf")
    return path


def _write_csv(path, heights, x_mm, y_mm, unit="m"):
    lines = [",".join([f"height [{unit}]"] + [f"{float(v)!r}mm" for v in x_mm])]
    for yv, row in zip(y_mm, np.atleast_2d(heights)):
        lines.append(",".join([f"{float(yv)!r}mm"] + [repr(float(h)) for h in row]))
    path.write_text("\n".join(lines) + "\n")
    return path


# ------------------------------------------------------------------------------------- round trips
def test_npy_round_trip_to_the_last_bit(tmp_path, rng):
    h = _heights(rng)
    np.save(tmp_path / "h.npy", h)
    hm = read_height_map(tmp_path / "h.npy", spacing="20um", height_unit="m")
    assert isinstance(hm, HeightMap)
    np.testing.assert_array_equal(hm.heights_m, h)
    assert (hm.spacing_x_m, hm.spacing_y_m, hm.origin_m) == (20e-6, 20e-6, (0.0, 0.0))
    np.save(tmp_path / "um.npy", h * 1e6)  # heights in um: divided by 1e6 exactly once
    hm = read_height_map(tmp_path / "um.npy", spacing=("20um", "10um"), height_unit="um")
    np.testing.assert_array_equal(hm.heights_m, (h * 1e6) / 1e6)
    assert (hm.spacing_x_m, hm.spacing_y_m) == (20e-6, 10e-6)


def test_npy_profile(tmp_path, rng):
    h = _heights(rng, (9,))
    np.save(tmp_path / "p.npy", h)
    hm = read_height_map(tmp_path / "p.npy", spacing=5e-6, height_unit="m")
    np.testing.assert_array_equal(hm.heights_m, h)
    assert hm.spacing_y_m is None


def test_labelled_csv_round_trip_to_the_last_bit(tmp_path, rng):
    h = _heights(rng)
    x_mm, y_mm = np.arange(7) * 0.02 - 0.06, np.arange(5) * 0.03 + 1.0
    hm = read_height_map(_write_csv(tmp_path / "h.csv", h, x_mm, y_mm))
    np.testing.assert_array_equal(hm.heights_m, h)
    assert hm.spacing_x_m == pytest.approx(20e-6, rel=1e-12) and hm.spacing_y_m == pytest.approx(30e-6, rel=1e-12)
    assert hm.origin_m == pytest.approx((-60e-6, 1e-3), rel=1e-12)


def test_labelled_csv_descending_rows_are_flipped_and_one_row_is_a_profile(tmp_path, rng):
    h = _heights(rng, (4, 6))
    hm = read_height_map(_write_csv(tmp_path / "d.csv", h[::-1], np.arange(6) * 0.01, np.arange(4)[::-1] * 0.01))
    np.testing.assert_array_equal(hm.heights_m, h)
    hm = read_height_map(_write_csv(tmp_path / "p.csv", h[0], np.arange(6) * 0.01, [0.0], unit="um"))
    np.testing.assert_array_equal(hm.heights_m, h[0] / 1e6)
    assert hm.heights_m.shape == (6,)


def test_plain_matrix_csv_round_trip(tmp_path, rng):
    h = _heights(rng)
    np.savetxt(tmp_path / "m.csv", h, delimiter=",", fmt="%.17g")
    hm = read_height_map(tmp_path / "m.csv", spacing="10um", height_unit="m")
    np.testing.assert_array_equal(hm.heights_m, h)


@pytest.mark.parametrize("unit", ["m", "um"])
def test_netcdf_round_trip_to_the_last_bit(tmp_path, rng, unit):
    h = _heights(rng)
    x, y = np.arange(7) * 2e-5 - 6e-5, np.arange(5) * 3e-5
    path = _write_nc(tmp_path / "h.nc", h if unit == "m" else h * 1e6, x, y, h_unit=unit)
    hm = read_height_map(path)
    np.testing.assert_array_equal(hm.heights_m, h if unit == "m" else (h * 1e6) / 1e6)
    assert hm.spacing_x_m == pytest.approx(2e-5, rel=1e-12) and hm.origin_m == pytest.approx((-6e-5, 0.0))


def test_netcdf_mm_coordinates_profile_and_cf_packing(tmp_path, rng):
    h = _heights(rng, (8,))
    hm = read_height_map(_write_nc(tmp_path / "p.nc", h, np.arange(8) * 0.01, xy_unit="mm"))
    np.testing.assert_array_equal(hm.heights_m, h)
    assert hm.spacing_x_m == pytest.approx(1e-5, rel=1e-12) and hm.heights_m.ndim == 1
    ds = xr.Dataset({"height": (("x",), np.array([0, 10, 20], dtype="int16"),
                                {"units": "um", "scale_factor": 0.5, "add_offset": 1.0})},
                    coords={"x": ("x", [0.0, 1e-5, 2e-5], {"units": "m"})})
    ds.to_netcdf(tmp_path / "packed.nc", engine="h5netcdf", encoding={"height": {"dtype": "int16"}})
    np.testing.assert_allclose(read_height_map(tmp_path / "packed.nc").heights_m, [1e-6, 6e-6, 11e-6], rtol=1e-12)


# ----------------------------------------------------------------------------------------- refusals
def test_refuses_nan_in_every_format(tmp_path):
    h = np.ones((4, 4))
    h[1, 2] = np.nan
    np.save(tmp_path / "n.npy", h)
    with pytest.raises(ValueError, match=r"n.npy: 1 height\(s\) are NaN or inf \(first at index \(1, 2\)\)"):
        read_height_map(tmp_path / "n.npy", spacing="1um", height_unit="um")
    _write_csv(tmp_path / "n.csv", h, np.arange(4) * 0.01, np.arange(4) * 0.01)
    with pytest.raises(ValueError, match="are NaN or inf"):
        read_height_map(tmp_path / "n.csv")
    _write_nc(tmp_path / "n.nc", h, np.arange(4.0), np.arange(4.0))
    with pytest.raises(ValueError, match="are NaN or inf"):
        read_height_map(tmp_path / "n.nc")


def test_refuses_missing_and_wrong_units(tmp_path):
    np.save(tmp_path / "h.npy", np.ones((4, 4)))
    with pytest.raises(ValueError, match=r"height_unit\): the height unit is missing"):
        read_height_map(tmp_path / "h.npy", spacing="1um")
    with pytest.raises(ValueError, match="unit 'kPa' is not a length unit"):
        read_height_map(tmp_path / "h.npy", spacing="1um", height_unit="kPa")
    with pytest.raises(ValueError, match="spacing is missing; this format carries no coordinates"):
        read_height_map(tmp_path / "h.npy", height_unit="um")
    with pytest.raises(ValueError, match="spacing: '1' has no unit"):
        read_height_map(tmp_path / "h.npy", spacing="1", height_unit="um")
    with pytest.raises(ValueError, match="spacing must be finite and > 0 m"), pytest.warns(UserWarning, match="outside the usual"):
        read_height_map(tmp_path / "h.npy", spacing="0um", height_unit="um")
    with pytest.raises(ValueError, match=r"spacing must be one length or \(dx, dy\)"):
        read_height_map(tmp_path / "h.npy", spacing=("1um", "1um", "1um"), height_unit="um")
    _write_nc(tmp_path / "u.nc", np.ones((3, 3)), np.arange(3.0), np.arange(3.0), h_unit=None)
    with pytest.raises(ValueError, match="variable 'height' units attribute: the height unit is missing"):
        read_height_map(tmp_path / "u.nc")
    _write_nc(tmp_path / "c.nc", np.ones((3, 3)), np.arange(3.0), np.arange(3.0), xy_unit="s")
    with pytest.raises(ValueError, match="coordinate .y. units attribute: unit .s. is not a length unit"):
        read_height_map(tmp_path / "c.nc")
    (tmp_path / "w.csv").write_text("height [Pa],0mm,1mm\n0mm,1,2\n1mm,3,4\n")
    with pytest.raises(ValueError, match="top-left cell\\): unit 'Pa' is not a length unit"):
        read_height_map(tmp_path / "w.csv")
    (tmp_path / "x.csv").write_text("height [um],0,1mm\n0mm,1,2\n1mm,3,4\n")
    with pytest.raises(ValueError, match="header x: '0' has no unit"):
        read_height_map(tmp_path / "x.csv")


def test_refuses_non_uniform_and_non_monotonic_grids(tmp_path):
    _write_nc(tmp_path / "g.nc", np.ones((3, 4)), np.array([0.0, 1.0, 2.0, 3.5]) * 1e-5, np.arange(3.0))
    with pytest.raises(ValueError, match="the x grid is not uniform"):
        read_height_map(tmp_path / "g.nc")
    _write_csv(tmp_path / "g.csv", np.ones((3, 3)), [0.0, 0.01, 0.02], [0.0, 0.02, 0.01])
    with pytest.raises(ValueError, match="the y coordinates must be finite and strictly increasing or decreasing"):
        read_height_map(tmp_path / "g.csv")


def test_refuses_bad_files_and_layouts(tmp_path):
    with pytest.raises(ValueError, match=r"unknown height-map format '.txt'"):
        read_height_map(tmp_path / "h.txt")
    with pytest.raises(FileNotFoundError):
        read_height_map(tmp_path / "absent.npy", spacing="1um", height_unit="um")
    np.save(tmp_path / "o.npy", np.array([{"a": 1}, None], dtype=object))
    with pytest.raises(ValueError, match="not a plain numeric .npy array"):
        read_height_map(tmp_path / "o.npy", spacing="1um", height_unit="um")
    np.save(tmp_path / "c.npy", np.ones((3, 3), dtype=complex))
    with pytest.raises(ValueError, match="heights must be real numbers, got dtype complex128"):
        read_height_map(tmp_path / "c.npy", spacing="1um", height_unit="um")
    np.save(tmp_path / "s.npy", np.ones((1, 5)))
    with pytest.raises(ValueError, match=r"at least 2 nodes per axis, got shape \(1, 5\)"):
        read_height_map(tmp_path / "s.npy", spacing="1um", height_unit="um")
    np.save(tmp_path / "big.npy", np.lib.stride_tricks.as_strided(np.zeros(1), (4097, 4097), (0, 0)))
    with pytest.raises(ValueError, match="above the limit 16777216 \\(memory\\)"):
        read_height_map(tmp_path / "big.npy", spacing="1um", height_unit="um")
    (tmp_path / "e.csv").write_text("\n")
    with pytest.raises(ValueError, match="the file is empty"):
        read_height_map(tmp_path / "e.csv")
    (tmp_path / "t.csv").write_text("1,2\n3,x\n")
    with pytest.raises(ValueError, match="a plain-matrix CSV must hold numbers only"):
        read_height_map(tmp_path / "t.csv", spacing="1um", height_unit="um")
    (tmp_path / "l.csv").write_text("z [um],0mm,1mm\n0mm,1,2\n1mm,3,4\n")
    with pytest.raises(ValueError, match="the top-left cell must be 'height \\[UNIT\\]'"):
        read_height_map(tmp_path / "l.csv")
    (tmp_path / "r.csv").write_text("height [um],0mm,1mm\n0mm,1,2\n1mm,3\n")
    with pytest.raises(ValueError, match="every row must have 3 cells"):
        read_height_map(tmp_path / "r.csv")
    (tmp_path / "v.csv").write_text("height [um],0mm,1mm\n0mm,1,2\n1mm,3,a\n")
    with pytest.raises(ValueError, match="heights must be plain numbers"):
        read_height_map(tmp_path / "v.csv")
    (tmp_path / "k.csv").write_text("height [um],0mm,1mm\n0mm,1,2\n1mm,3,4\n")
    with pytest.raises(ValueError, match="a labelled CSV states its own coordinates and unit"):
        read_height_map(tmp_path / "k.csv", spacing="1um")
    (tmp_path / "n3.nc").write_bytes(b"CDF\x01" + bytes(64))
    with pytest.raises(ValueError, match="not a netCDF-4 \\(HDF5\\) file"):
        read_height_map(tmp_path / "n3.nc")


def test_refuses_netcdf_layouts(tmp_path):
    path = _write_nc(tmp_path / "h.nc", np.ones((3, 3)), np.arange(3.0), np.arange(3.0))
    with pytest.raises(ValueError, match="states its own coordinates and units"):
        read_height_map(path, height_unit="um")
    ds = xr.Dataset({"a": (("y", "x"), np.ones((3, 3)), {"units": "m"}), "b": (("y", "x"), np.ones((3, 3)))},
                    coords={"x": ("x", np.arange(3.0), {"units": "m"}), "y": ("y", np.arange(3.0), {"units": "m"})})
    ds.to_netcdf(tmp_path / "two.nc", engine="h5netcdf")
    with pytest.raises(ValueError, match=r"cannot tell the height variable among \['a', 'b'\]; name it 'height'"):
        read_height_map(tmp_path / "two.nc")
    xr.Dataset({"height": (("x", "y"), np.ones((3, 3)), {"units": "m"})}).to_netcdf(tmp_path / "t.nc",
                                                                                 engine="h5netcdf")
    with pytest.raises(ValueError, match=r"dimensions \('x', 'y'\); expected \('y', 'x'\) or \('x',\)"):
        read_height_map(tmp_path / "t.nc")
    xr.Dataset({"height": (("y", "x"), np.ones((3, 3)), {"units": "m"})}).to_netcdf(tmp_path / "nc.nc",
                                                                                 engine="h5netcdf")
    with pytest.raises(ValueError, match="coordinate variable .y. is missing"):
        read_height_map(tmp_path / "nc.nc")


def test_refuses_netcdf_external_storage(tmp_path):
    """A variable whose data live in another file (HDF5 external storage) is refused, not followed."""
    import h5py

    path = _write_nc(tmp_path / "ext.nc", np.ones((3, 3)), np.arange(3.0), np.arange(3.0))
    raw = tmp_path / "outside.bin"
    np.ones((3, 3)).tofile(raw)
    with h5py.File(path, "a") as f:
        attrs = dict(f["height"].attrs)
        del f["height"]
        dset = f.create_dataset("height", shape=(3, 3), dtype="<f8", external=[(str(raw), 0, 72)])
        dset.dims[0].attach_scale(f["y"])
        dset.dims[1].attach_scale(f["x"])
        for k, v in attrs.items():
            if k not in ("DIMENSION_LIST",):
                dset.attrs[k] = v
    with pytest.raises(ValueError, match="variable 'height' is stored outside the file"):
        read_height_map(path)

"""The ``random_rough`` and ``measured`` surface kinds (data_schemas/lab_surfaces.py) in scene files and scans.

Measured maps: a scene file naming a file next to it, for each core format (``.npy``, both ``.csv``
layouts, netCDF) and the profilometer formats of the optional extra (``.x3p``, Gwyddion ``.gwy``):
the surface's heights at the map's nodes equal the written heights to the last bit. Refusals:
NaN, a wrong unit, a non-uniform grid, paths that leave the scene's folder or pass a symlink, a
scan that leaves the map, a missing extra. Random rough plates: reproducible by seed, the same
heights whatever the simulation grid.
"""

import math
import os
import sys

import numpy as np
import pytest
import xarray as xr

from tactilab.data_schemas import MeasuredSurface, RandomRoughSurface, load_scene, random_rough_surface
from tactilab.forward import Surface, scanned_surface, scene_finger, scene_recording

SCENE = """
name = "lab surface"
[material]
young_modulus = "1MPa"
poisson_ratio = 0.5
[surface]
{surface}
[contact]
normal_force = "0.5N"
finger_radius = "10mm"
friction_coefficient = 0.5
[sensors]
quantity = "strain"
components = ["zz"]
depth = "1mm"
positions = [["0mm", "0mm"]]
[scan]
speed = "10mm/s"
duration = "{duration}"
sampling_rate = "1kHz"
start_position = "{start}"
"""


def scene_file(folder, surface: str, duration="20ms", start="0mm"):
    path = folder / "scene.toml"
    path.write_text(SCENE.format(surface=surface, duration=duration, start=start))
    return path


def heights(rng, shape=(6, 9)):
    return rng.standard_normal(shape) * 3e-6


def nodes(record):
    m = record.height_map
    return np.meshgrid(m.x_m, m.y_m)


# ------------------------------------------------------------------------------------- measured: round trips
def test_npy_scene_round_trip_to_the_last_bit(tmp_path, rng):
    h = heights(rng)
    np.save(tmp_path / "plate.npy", h)
    scene = load_scene(scene_file(tmp_path, 'kind = "measured"\npath = "plate.npy"\nspacing = "20um"\n'
                                            'height_unit = "m"'))
    assert scene.surface.kind == "measured"
    x, y = nodes(scene.surface)
    assert np.array_equal(scene.surface.height_at(x, y), h)
    assert scene.surface.height_map.spacing_x_m == pytest.approx(20e-6, rel=1e-15)


@pytest.mark.parametrize("layout", ["labelled", "plain"])
def test_csv_scene_round_trip_to_the_last_bit(tmp_path, rng, layout):
    h = heights(rng)
    if layout == "labelled":
        lines = [",".join(["height [m]"] + [f"{0.02 * i!r}mm" for i in range(h.shape[1])])]
        lines += [",".join([f"{0.02 * j!r}mm"] + [repr(float(v)) for v in row]) for j, row in enumerate(h)]
        extra = ""
    else:
        lines = [",".join(repr(float(v)) for v in row) for row in h]
        extra = '\nspacing = "20um"\nheight_unit = "m"'
    (tmp_path / "plate.csv").write_text("\n".join(lines) + "\n")
    scene = load_scene(scene_file(tmp_path, f'kind = "measured"\npath = "plate.csv"{extra}'))
    x, y = nodes(scene.surface)
    assert np.array_equal(scene.surface.height_at(x, y), h)


def test_netcdf_scene_round_trip_to_the_last_bit_and_json_beside_it(tmp_path, rng):
    h = heights(rng)
    x, y = np.arange(h.shape[1]) * 2e-5, np.arange(h.shape[0]) * 2e-5
    xr.Dataset({"height": (("y", "x"), h, {"units": "m"})},
               coords={"x": ("x", x, {"units": "m"}), "y": ("y", y, {"units": "m"})}).to_netcdf(
        tmp_path / "plate.nc", engine="h5netcdf")
    scene = load_scene(scene_file(tmp_path, 'kind = "measured"\npath = "plate.nc"'))
    X, Y = nodes(scene.surface)
    assert np.array_equal(scene.surface.height_at(X, Y), h)
    again = type(scene).load(scene.save(tmp_path / "scene.json"))  # a JSON scene resolves beside itself too
    assert again == scene and np.array_equal(again.surface.height_at(X, Y), h)


@pytest.mark.parametrize("suffix", [".x3p", ".gwy"])
def test_profilometer_formats_through_the_extra(tmp_path, rng, suffix):
    from SurfaceTopography import Topography

    h = heights(rng)
    topography = Topography(h.T.copy(), (h.shape[1] * 2e-5, h.shape[0] * 2e-5), unit="m")  # it is (nx, ny)
    getattr(topography, "to_" + suffix[1:])(str(tmp_path / f"plate{suffix}"))
    scene = load_scene(scene_file(tmp_path, f'kind = "measured"\npath = "plate{suffix}"'))
    X, Y = nodes(scene.surface)
    assert np.array_equal(scene.surface.height_at(X, Y), h)
    assert scene.surface.height_map.spacing_y_m == pytest.approx(2e-5, rel=1e-12)


def test_a_missing_extra_is_named(tmp_path, monkeypatch):
    (tmp_path / "plate.x3p").write_bytes(b"PK")
    monkeypatch.setitem(sys.modules, "SurfaceTopography", None)  # as if not installed
    with pytest.raises(ValueError, match=r"needs the optional extra 'topography'.*pip install 'tactilab\[topography\]'"):
        load_scene(scene_file(tmp_path, 'kind = "measured"\npath = "plate.x3p"'))


# ------------------------------------------------------------------------------------- measured: refusals
def test_nan_wrong_unit_and_non_uniform_grid_are_refused(tmp_path, rng):
    h = heights(rng)
    h[2, 3] = math.nan
    np.save(tmp_path / "nan.npy", h)
    with pytest.raises(ValueError, match=r"nan\.npy: 1 height\(s\) are NaN or inf \(first at index \(2, 3\)\)"):
        load_scene(scene_file(tmp_path, 'kind = "measured"\npath = "nan.npy"\nspacing = "20um"\nheight_unit = "m"'))
    np.save(tmp_path / "ok.npy", heights(rng))
    with pytest.raises(ValueError, match=r"ok\.npy \(height_unit\): unit 'kPa' is not a length unit"):
        load_scene(scene_file(tmp_path, 'kind = "measured"\npath = "ok.npy"\nspacing = "20um"\nheight_unit = "kPa"'))
    lines = ["height [um],0mm,0.02mm,0.05mm", "0mm,1,2,3", "0.02mm,4,5,6"]
    (tmp_path / "uneven.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"uneven\.csv: the x grid is not uniform"):
        load_scene(scene_file(tmp_path, 'kind = "measured"\npath = "uneven.csv"'))


def test_paths_must_stay_in_the_scene_folder(tmp_path, rng):
    inner = tmp_path / "scene"
    inner.mkdir()
    np.save(tmp_path / "outside.npy", heights(rng))
    common = '\nspacing = "20um"\nheight_unit = "m"'
    with pytest.raises(ValueError, match=r"path: '\.\./outside\.npy' must lie inside the scene's folder"):
        load_scene(scene_file(inner, f'kind = "measured"\npath = "../outside.npy"{common}'))
    with pytest.raises(ValueError, match=r"path: must be a file name relative to the scene's folder"):
        load_scene(scene_file(inner, f'kind = "measured"\npath = "{tmp_path / "outside.npy"}"{common}'))
    os.symlink(tmp_path / "outside.npy", inner / "link.npy")
    with pytest.raises(ValueError, match=r"path: 'link\.npy' must lie inside the scene's folder with no '\.\.' or "
                                         r"symlink"):
        load_scene(scene_file(inner, f'kind = "measured"\npath = "link.npy"{common}'))
    with pytest.raises(ValueError, match=r"path: .*missing\.npy is not a regular file"):
        load_scene(scene_file(inner, f'kind = "measured"\npath = "missing.npy"{common}'))


def test_a_larger_map_is_cropped_and_a_smaller_one_refused_with_both_sizes(tmp_path, rng):
    big = random_rough_surface((400, 400), 25e-6, rms_height=2e-6, rng=rng)  # 10 mm square
    np.save(tmp_path / "big.npy", big)
    surface = 'kind = "measured"\npath = "big.npy"\nspacing = "25um"\nheight_unit = "m"\norigin = ["-5mm", "-5mm"]'
    scene = load_scene(scene_file(tmp_path, surface, duration="20ms", start="-0.1mm"))
    rec = scene_recording(scene, grid_spacing=0.1e-3)  # the strip (about 4 mm) is read out of the 10 mm map
    assert rec.values.shape == (20, 1, 1) and np.all(np.isfinite(rec.values))
    small = load_scene(scene_file(tmp_path, surface.replace('["-5mm", "-5mm"]', '["-1mm", "-1mm"]')))
    finger = scene_finger(small, grid_spacing=0.1e-3)
    with pytest.raises(ValueError, match=r"surface: the measured map covers x in \[-0\.001, 0\.008975\] m "
                                         r"\(9\.975 mm\), y in .* smaller than the strip the scan touches"):
        scanned_surface(small.surface, [0.0, 1e-4], finger)
    with pytest.raises(ValueError, match=r"big\.npy: the point \(-0\.002, 0\) m lies off the measured map"):
        small.surface.height_at(-2e-3, 0.0)


def test_the_exact_models_wider_strip_is_checked_against_the_map_naming_both_sizes(tmp_path, rng):
    """The contact grid of the exact and linear models reads 1.5 Hertz radii around the centre, the
    modulation's finger grid about one: a map between the two serves the modulation and is refused
    by SceneFrames with the message naming both sizes, not met later as a point off the map."""
    from tactilab.forward import SceneFrames
    from tactilab.forward.scene_frames import grid_reach

    step = 25e-6  # a=1.41 mm at 0.5 N: the finger grid reads 1.6 mm, the contact grid 2.2 mm (0.1 mm nodes)
    def map_scene(half_width, name):
        n = int(round(2 * half_width / step)) + 1
        np.save(tmp_path / f"{name}.npy", heights(rng, (n, n + 8)))
        origin = f'["{-half_width * 1e3:.4f}mm", "{-half_width * 1e3:.4f}mm"]'
        surface = (f'kind = "measured"\npath = "{name}.npy"\nspacing = "25um"\nheight_unit = "m"\n'
                   f"origin = {origin}")
        return load_scene(scene_file(tmp_path, surface, duration="20ms", start="0mm"))

    narrow = map_scene(1.9e-3, "narrow")
    finger = scene_finger(narrow, grid_spacing=0.1e-3)
    u = narrow.scan.positions_m
    _, reach = grid_reach(finger)
    assert finger.grid()[0][-1] < 1.9e-3 < reach == pytest.approx(2.2e-3)
    scanned_surface(narrow.surface, u, finger)  # the modulation's strip is on the map
    with pytest.raises(ValueError, match=r"surface: the measured map covers x in \[-0\.0019, .* smaller than the strip "
                                         r"the scan touches, x in \[-0\.0022, .* reaches 0\.0022 m around it\)"):
        SceneFrames.from_scene(narrow, grid_spacing=0.1e-3)
    wide = map_scene(2.3e-3, "wide")
    frames = SceneFrames.from_scene(wide, grid_spacing=0.1e-3)
    X, Y = np.meshgrid(frames.x + u[-1], frames.y)
    assert np.array_equal(frames.heights(frames.n_frames - 1), wide.surface.height_at(X, Y))
    with pytest.raises(ValueError, match=r"reach: the half-width the scan reads .* got -1\.0"):
        scanned_surface(wide.surface, u, finger, reach=-1.0)


def test_levelling_removes_the_mean_and_the_plane(tmp_path, monkeypatch):
    y, x = np.mgrid[0:5, 0:7]
    np.save(tmp_path / "tilted.npy", 1e-6 * (3 + 0.5 * x - 0.25 * y))
    base = dict(path="tilted.npy", spacing_m=1e-5, height_unit="m")
    monkeypatch.chdir(tmp_path)  # built from Python, the folder is the current one
    assert abs(MeasuredSurface(**base, level="mean").height_map.heights_m.mean()) < 1e-20
    assert np.abs(MeasuredSurface(**base, level="plane").height_map.heights_m).max() < 1e-20
    raw = MeasuredSurface(**base)
    assert raw.height_map.heights_m[0, 0] == 3e-6 and raw.replace(level="mean").level == "mean"


# ------------------------------------------------------------------------------------- random rough
def test_random_rough_is_reproducible_by_seed_and_independent_of_the_grid():
    kw = dict(rms_height_m=5e-6, hurst=0.8, long_cutoff_m=1e-3, short_cutoff_m=80e-6, spacing_m=20e-6,
              size_m=(2e-3, 2e-3))
    one, two, other = RandomRoughSurface(seed=3, **kw), RandomRoughSurface(seed=3, **kw), RandomRoughSurface(seed=4, **kw)
    assert np.array_equal(one.heights_m, two.heights_m) and not np.array_equal(one.heights_m, other.heights_m)
    assert np.sqrt(np.mean(one.heights_m**2)) == pytest.approx(5e-6, rel=1e-12)
    ref = random_rough_surface((100, 100), 20e-6, rms_height=5e-6, long_cutoff=1e-3, short_cutoff=80e-6,
                               rng=np.random.default_rng(3))
    assert np.array_equal(one.heights_m, ref)  # the seed feeds numpy.random.default_rng, nothing else
    # two simulation grids (10 and 30 um) read the same heights where they meet: the plate is not redrawn
    fine = np.arange(-150, 150) * 10e-6 + 3e-6
    coarse = fine[::3]
    assert np.array_equal(one.height_at(fine, 1e-4)[::3], one.height_at(coarse, 1e-4))
    assert np.abs(np.diff(one.height_at(fine, 0.0))).max() < 5e-6  # continuous between nodes (no jumps)
    X, Y = np.meshgrid(np.arange(100) * 20e-6, np.arange(100) * 20e-6)
    assert np.array_equal(one.height_at(X, Y), one.heights_m)  # at its own nodes: the nodes
    assert np.array_equal(one.height_at(X + 2e-3, Y - 4e-3), one.heights_m)  # periodic over size_m


def test_random_rough_in_a_scene_file_scans(tmp_path):
    surface = ('kind = "random_rough"\nrms_height = "5um"\nhurst = 0.8\nlong_cutoff = "1mm"\n'
               'short_cutoff = "80um"\nseed = 1\nspacing = "20um"\nsize = ["2mm", "2mm"]')
    scene = load_scene(scene_file(tmp_path, surface))
    assert isinstance(scene.surface, RandomRoughSurface) and scene.surface.long_cutoff_m == pytest.approx(1e-3)
    assert scene_finger(scene).spacing <= 20e-6 * (1 + 1e-12)  # the grid resolves the plate's own nodes
    strip = Surface(length=4e-3, features=(scene.surface,), x_start=-2e-3)
    assert strip.height(0.0, 0.0) == scene.surface.heights_m[0, 0]
    # the scan's strips on a 20 um and a 40 um finger grid: the same heights at the nodes they share
    fine, coarse = scene_finger(scene, grid_spacing=20e-6), scene_finger(scene, grid_spacing=40e-6)
    xf, xc = fine.grid()[0], coarse.grid()[0]
    hf = scanned_surface(scene.surface, [1e-4], fine).height(1e-4 + xf, 0.0)
    hc = scanned_surface(scene.surface, [1e-4], coarse).height(1e-4 + xc, 0.0)
    common, in_fine, in_coarse = np.intersect1d(np.round(xf / 1e-6), np.round(xc / 1e-6), return_indices=True)
    assert common.size > 50
    assert np.abs(hf[in_fine] - hc[in_coarse]).max() <= 1e-12 * scene.surface.heights_m.std()


@pytest.mark.parametrize("kwargs, match", [
    (dict(), r"rms_height_m, rms_slope: give exactly one of them"),
    (dict(rms_height_m=1e-6, rms_slope=0.1), r"rms_height_m, rms_slope: give exactly one of them"),
    (dict(rms_height_m=1e-6, size_m=(1.01e-3, 1e-3)), r"size_m: the x side 0\.00101 m must be a whole number"),
    (dict(rms_height_m=1e-6, size_m=(1e-3, 1e-3), spacing_m=1e-6), r"size_m: 1000 x 1000 nodes|above the limit"),
    (dict(rms_height_m=1e-6, hurst=1.5), r"hurst: the Hurst exponent must be in \(0, 1\]"),
    (dict(rms_height_m=1e-6, short_cutoff_m=10e-6), r"short_cutoff: .* is below 2 node spacings"),
])
def test_random_rough_refuses_bad_parameters(kwargs, match):
    base = dict(seed=0, spacing_m=20e-6, size_m=(1e-3, 1e-3))
    if "size_m" in kwargs and kwargs.get("spacing_m") == 1e-6:
        kwargs = dict(kwargs, size_m=(5e-3, 5e-3))  # 5000^2 nodes: over the limit
    with pytest.raises(ValueError, match=match):
        RandomRoughSurface(**(base | kwargs))

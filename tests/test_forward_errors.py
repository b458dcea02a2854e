"""Forward-model guards that no other test triggered (one pytest.raises(match=) per raise)."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.sensors import SensorArray
from tactilab.forward.contact import HertzContact, stick_radius
from tactilab.forward.display_scene import display_gain
from tactilab.forward.halfspace.fields import compliance_matrix, output_weights, tensor
from tactilab.forward.finger import BiomimeticFinger
from tactilab.forward.load_files import read_load
from tactilab.forward.halfspace.spectral import _TABLE_CACHE_MAX_ENTRIES, _cached_geometry, _table, _table_uncached


def test_display_gain_rejects_a_depth_where_no_drive_renders():
    """At Z = 1e-12 m the pair sum S_Psi(d) is negative: no gain exists, so it must not return one."""
    display = DisplayDescription.braille_row()
    gain, pitch = display_gain(display, 1e-3, 1e6)
    assert gain > 0 and pitch == pytest.approx(2 * display.pitch_x_m)
    with pytest.raises(ValueError, match=r"display: S_Psi\(d\) = -.* is not positive"):
        display_gain(display, 1e-12, 1e6)


@pytest.mark.parametrize("modulus", [np.nan, np.inf, 0.0, -1e6])
def test_display_gain_rejects_bad_young_modulus(modulus):
    with pytest.raises(ValueError, match="young_modulus: Young's modulus must be finite and > 0 Pa"):
        display_gain(DisplayDescription.braille_row(), 1e-3, modulus)


def test_tensor_needs_all_six_components():
    field = xr.DataArray(np.zeros((2, 4)), dims=("component", "x"), coords={"component": ["zz", "zx"]})
    with pytest.raises(ValueError, match=r"field: invariants need all six components, missing \['xx', 'yy', 'yz', 'xy'\]"):
        tensor(field)


def test_read_load_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="load file not found") as info:
        read_load(tmp_path / "nope.npz")
    assert info.value.filename == str(tmp_path / "nope.npz")


def test_spectral_table_rejects_unknown_component():
    """The coefficient table is looked up by Voigt name; a wrong name must not fall through silently."""
    g = _cached_geometry((4, 4), (1e-3, 1e-3), "float64")
    assert len(_table_uncached(g, 0.5, "zz")) == 4
    with pytest.raises(ValueError, match="components: unknown component 'xz'"):
        _table_uncached(g, 0.5, "xz")


def test_compliance_matrix_rejects_bad_material():
    """A NaN modulus used to give a NaN compliance (and NaN strains downstream) without a word."""
    assert compliance_matrix(2e6, 0.5)[0, 0] == pytest.approx(0.5e-6)
    with pytest.raises(ValueError, match="young_modulus: Young's modulus must be finite and > 0 Pa, got nan"):
        compliance_matrix(np.nan, 0.5)
    with pytest.raises(ValueError, match=r"nu: Poisson's ratio must lie in \(-1, 0.5\]"):
        output_weights("strain", ("zz",), 1e6, np.nan)


def test_stick_radius_rejects_nan_tangential_force():
    with pytest.raises(ValueError, match="tangential_force: must be finite"):
        stick_radius(HertzContact(1.0), 0.5, np.nan)


def test_point_response_rejects_non_finite_forces():
    sensors = SensorArray.grid(2, 2, 1e-3, 2e-3, quantity="stress", components=("zz",))
    finger = BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, grid_spacing=0.2e-3)
    assert np.all(np.isfinite(finger.point_response(0.0, 0.0, 0.1, 1.0)))
    with pytest.raises(ValueError, match="fz: point forces and their positions must be finite"):
        finger.point_response(0.0, 0.0, 0.1, np.nan)
    with pytest.raises(ValueError, match="xs: point forces and their positions must be finite"):
        finger.point_response(np.inf, 0.0, 0.1, 1.0)


def test_spectral_table_cache_stays_bounded_over_a_sweep_in_nu():
    """The per-geometry table cache was keyed on nu without a bound: a sweep over nu grew it forever."""
    g = _cached_geometry((4, 4), (1e-3, 1e-3), "float64")
    for nu in np.linspace(0.0, 0.5, 40):
        for component in ("zz", "zx"):
            assert _table(g, nu, component) is not None
    assert len(g.tables) <= _TABLE_CACHE_MAX_ENTRIES
    fresh = _table(g, 0.5, "zz")  # the latest entries are still served from the cache
    assert _table(g, 0.5, "zz") is fresh


@pytest.mark.parametrize("text,match", [
    ("[grid\n", r"bad.toml: not valid TOML \(.*\); fix the syntax"),
    ("[grid]\nshape = [100000, 100000]\nspacing = '0.1mm'\n",
     r"grid.shape \[100000, 100000\] has 10000000000 nodes, above the limit 16777216"),  # was a MemoryError
    ("[grid]\nshape = [8, 8]\nspacing = '0.1mm'\nperiodic = 'false'\n[[patch]]\nradius = '1mm'\n",
     "grid.periodic must be true or false"),  # the string 'false' used to mean True
    ("[grid]\nshape = [8, 8]\nspacing = '0.1mm'\n[patch]\nradius = '1mm'\n",
     r"patches must be an array of tables, one \[\[patch\]\]"),
])
def test_read_load_toml_mistakes(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        read_load(path)


def test_read_load_npz_mistakes(tmp_path):
    garbage = tmp_path / "garbage.npz"
    garbage.write_text("not numpy")
    with pytest.raises(ValueError, match="garbage.npz: not a numpy .npz archive; write one with numpy.savez"):
        read_load(garbage)
    single = tmp_path / "single.npz"
    with open(single, "wb") as fh:
        np.save(fh, np.ones(3))
    with pytest.raises(ValueError, match="single.npz: holds a single array, not an .npz archive"):
        read_load(single)


def test_synthesis_messages_show_numpy_scalars_as_numbers():
    """Array entries used to appear as 'np.float64(nan)' in the message."""
    from tactilab.forward.synthesis import depth_scaling

    with pytest.raises(ValueError, match=r"depths: must be finite and > 0 m, got nan; give a finite value"):
        depth_scaling([1e-3, np.nan])


def test_display_scene_outputs_memory_guard(monkeypatch):
    """A display scene with 1e6 sensors ran for minutes towards ~11 GiB; now it is refused at once."""
    import tactilab.forward.display_scene as display_scene
    from tactilab.data_schemas.files import load_example

    scene = load_example("tractor_display")
    values, _, _ = display_scene.display_scene_outputs(scene)
    monkeypatch.setattr(display_scene, "MAX_OUTPUT_VALUES", values.size)  # the Voigt field is 6 / 3 x larger
    with pytest.raises(ValueError, match=r"sensors: 250 frames x 41 sensors need .* GiB of work arrays"):
        display_scene.display_scene_outputs(scene)

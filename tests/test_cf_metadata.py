"""CF-style metadata on the netCDF files tactilab writes (issue 25): ``Conventions = "CF-1.10"``,
``tactilab_version``, ``units`` and ``long_name`` on every variable, ``positive = "down"`` on depth,
one dimension order for the same fields, and units on posterior variables (what ``az.summary``
users see). Each writer's file is opened back and checked with ``cf_problems``."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from test_inversion_sampler import FAST, toy
from test_models import GRATING, _frame

from tactilab.core import cf_problems, cf_ready, package_version, write_netcdf, write_netcdf_atomic
from tactilab.data_schemas import Recording
from tactilab.data_schemas.recording_io import write_recording
from tactilab.experiments import TransductionModel, fit_transduction
from tactilab.forward import HalfSpace, HertzContact, SurfaceLoad, solve_contact
from tactilab.forward.contact_files import write_contact
from tactilab.forward.load_files import write_field
from tactilab.inversion import sample_posterior
from tactilab.inversion.mcmc import _PARAMETER_ATTRS
from tactilab.inversion.scene_params import NONLINEAR


def _open(path):
    return xr.open_datatree(path, engine="h5netcdf")


def _checked(path):
    tree = _open(path)
    assert cf_problems(tree) == [], cf_problems(tree)
    assert tree.attrs["Conventions"] == "CF-1.10" and tree.attrs["tactilab_version"] == package_version()
    return tree


def test_the_check_has_teeth():
    bare = xr.Dataset({"p": (("depth",), [1.0, 2.0])}, coords={"depth": [1e-3, 2e-3]})
    problems = cf_problems(bare)
    assert "global attribute Conventions missing" in problems and "/ p: no units" in problems
    assert "/ depth: positive is not 'down'" in problems and "/ p: no long_name" in problems
    ready = cf_ready(bare)
    assert ready["depth"].attrs == {"long_name": "depth below the skin surface", "units": "m", "positive": "down"}
    assert cf_problems(ready) == ["/ p: no units"]  # units are the writer's to state, never guessed
    assert bare.attrs == {} and bare["depth"].attrs == {}  # the input is not modified
    for call in (cf_problems, cf_ready):
        with pytest.raises(ValueError, match="data: must be an xarray Dataset or DataTree"):
            call([1.0])


def test_recording_netcdf(tmp_path):
    rec = Recording(values=np.ones((4, 2, 3)), sampling_rate_hz=100.0, sensor_ids=("a", "b"),
                    components=("xx", "zz", "zx"), quantity="stress", unit="Pa")
    path = write_recording(rec, tmp_path, positions_m=np.arange(4) * 1e-3, sensor_positions_m=[[0, 0], [1e-3, 0]],
                           attrs={"depth_m": 1e-3})
    ds = _checked(path).to_dataset()
    assert ds["values"].attrs["units"] == "Pa" and ds["sensor_x"].attrs["units"] == "m"


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_strain_field_and_contact_files(tmp_path):
    skin = HalfSpace(E=1e6, nu=0.5)
    hertz = HertzContact(finger_radius=10e-3, normal_force=0.5, young_modulus=1e6, poisson_ratio=0.5)
    x = np.arange(-32, 32) * 0.1e-3
    load = SurfaceLoad(p=hertz.pressure(x[None, :], x[:, None]), spacing=0.1e-3)
    result = skin.strain(load, [1e-3, 2e-3], invariants=True)
    nc, _ = write_field(result, tmp_path / "field")
    ds = _checked(nc).to_dataset()
    # one dimension order for the same fields; depth positive down
    assert ds["strain"].dims == ds["deviatoric"].dims == ("depth", "component", "y", "x")
    assert ds["depth"].attrs["positive"] == "down" and ds["strain"].attrs["units"] == "1"
    gap = (x[None, :] ** 2 + x[:, None] ** 2) / (2 * 10e-3)
    solution = solve_contact(skin, gap, 0.1e-3, normal_force=0.5)
    written = write_contact(solution, tmp_path / "contact")
    _checked(next(p for p in written if p.suffix == ".nc"))


def test_posterior_variables_carry_units(tmp_path, rng):
    model = toy(rng)
    model.variable_attrs = {"a": {"units": "m", "long_name": "intercept"}, "b": {"units": "Pa", "long_name": "slope"},
                            "data": {"units": "Pa", "long_name": "observations"}}
    tree = sample_posterior(model, rng, **dict(FAST, max_steps=400))
    assert tree["posterior"]["a"].attrs["units"] == "m" and tree["observed_data"]["data"].attrs["units"] == "Pa"
    back = _checked(write_netcdf(tree, tmp_path / "posterior.nc"))
    assert back["posterior"]["b"].attrs["units"] == "Pa" and back["sample_stats"]["lp"].attrs["units"] == "1"
    # the defect posterior names a unit for every parameter it can sample or integrate out
    assert set(NONLINEAR) | {"amplitude"} <= set(_PARAMETER_ATTRS)


def test_transduction_fit_tree(tmp_path):
    model = TransductionModel("zx@1mm")
    fit = fit_transduction(model, _frame(model, 10, [1e-6, 2e-6], np.random.default_rng(0)))
    assert fit.tree["posterior"]["threshold_strain"].attrs["units"] == "1"
    path = write_netcdf_atomic(fit.tree, tmp_path / "fit.nc")
    back = _checked(path)
    assert back["constant_data"]["pitch_m"].attrs["units"] == "m"

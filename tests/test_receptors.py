"""Receptor hypotheses (forward/receptors.py) and their string grammar (data_schemas/hypothesis.py)."""

import numpy as np
import pytest
import xarray as xr
from hypothesis import given
from hypothesis import strategies as st

from tactilab.data_schemas import parse_hypothesis
from tactilab.core import COMPONENTS as VOIGT
from tactilab.data_schemas.hypothesis import RECEPTOR_COMPONENTS, format_depth
from tactilab.forward import ReceptorHypothesis, invariants


def test_parse_examples_in_si():
    assert ReceptorHypothesis.parse("zx@1mm") == ReceptorHypothesis(("zx",), (1e-3,))
    h = ReceptorHypothesis.parse("xx,xz@1mm,2mm")
    assert h.components == ("xx", "zx") and h.depths == (1e-3, 2e-3) and h.shear == "tensor"
    h = ReceptorHypothesis.parse("max_shear@1.25mm:engineering")
    assert h.components == ("max_shear",) and h.depths == (1.25e-3,) and h.shear == "engineering"
    assert ReceptorHypothesis.parse("volumetric@500um").depths == (5e-4,)
    spec = parse_hypothesis(" xx , zx @ 1.25mm ;noise=1e-3")
    assert spec == (("xx", "zx"), (1.25e-3,), "tensor", 1e-3)


@pytest.mark.parametrize("text", ["zx@1mm", "xx,zx@1mm,2mm", "max_shear@1.25mm:engineering",
                                  "volumetric,yy@0.5mm;noise=0.002", "von_mises,octahedral,deviatoric_norm@3mm"])
def test_str_round_trips(text):
    h = ReceptorHypothesis.parse(text)
    assert ReceptorHypothesis.parse(str(h)) == h
    assert str(h) == text


@given(st.lists(st.floats(1e-7, 1e-1, allow_nan=False), min_size=1, max_size=4),
       st.sampled_from(["tensor", "engineering"]), st.one_of(st.none(), st.floats(1e-9, 1.0)))
def test_round_trip_any_depths(depths, shear, noise):
    h = ReceptorHypothesis(("xx", "zx"), tuple(depths), noise, shear)
    assert ReceptorHypothesis.parse(str(h)) == h


def test_format_depth_falls_back_to_metres_when_mm_would_round():
    d = 0.1 + 0.2  # 0.30000000000000004
    assert ReceptorHypothesis.parse(f"xx@{format_depth(d)}").depths == (d,)


def test_weights_tensor_and_engineering():
    h = ReceptorHypothesis(("xx", "zx", "volumetric"), (1e-3,))
    assert h.linear
    np.testing.assert_array_equal(h.weights(), [[1, 0, 0, 0, 0, 0], [0, 0, 0, 0, 1, 0], [1, 1, 1, 0, 0, 0]])
    he = ReceptorHypothesis(("yz", "zx", "xy", "zz"), (1e-3,), shear="engineering")
    np.testing.assert_array_equal(he.weights(), [[0, 0, 0, 2, 0, 0], [0, 0, 0, 0, 2, 0],
                                                 [0, 0, 0, 0, 0, 2], [0, 0, 1, 0, 0, 0]])


def test_readout_order_is_depth_component_receptor(rng):
    h = ReceptorHypothesis(("zz", "xx", "xy"), (1e-3, 2e-3), shear="engineering")
    strain = rng.normal(size=(2, 4, 5, 6))  # (depth, frame, receptor, 6)
    r = h.readout(strain)
    assert r.shape == (4, 2 * 3 * 5)
    expected = np.empty((4, 2, 3, 5))
    for d in range(2):
        for f in range(4):
            for c, name in enumerate(h.components):
                for k in range(5):
                    factor = 2.0 if name == "xy" else 1.0
                    expected[f, d, c, k] = factor * strain[d, f, k, VOIGT.index(name)]
    np.testing.assert_array_equal(r, expected.reshape(4, -1))
    assert h.n_readouts(5) == 30


def _field(strain):
    """(n, 6) strain as the component-first DataArray that forward.invariants takes."""
    return xr.DataArray(strain.T, dims=["component", "x"], coords={"component": list(VOIGT)})


def test_nonlinear_invariants_match_independent_forms(rng):
    strain = rng.normal(size=(1, 50, 6)) * 1e-3
    ds = invariants(_field(strain[0]))
    h = ReceptorHypothesis(("max_shear", "von_mises", "octahedral", "deviatoric_norm"), (1e-3,))
    assert not h.linear
    r = h.readout(strain).reshape(4, 50)
    np.testing.assert_allclose(r[0], ds["max_shear"].values, rtol=1e-12)
    np.testing.assert_allclose(r[1], ds["von_mises"].values, rtol=1e-12)
    e1, e2, e3 = ds["principal"].values.T
    oct_engineering = 2.0 / 3.0 * np.sqrt((e1 - e2) ** 2 + (e2 - e3) ** 2 + (e3 - e1) ** 2)
    np.testing.assert_allclose(2 * r[2], oct_engineering, rtol=1e-12)
    mean = (e1 + e2 + e3) / 3
    np.testing.assert_allclose(r[3], np.sqrt((e1 - mean) ** 2 + (e2 - mean) ** 2 + (e3 - mean) ** 2), rtol=1e-12)
    he = ReceptorHypothesis(h.components, (1e-3,), shear="engineering")
    np.testing.assert_allclose(he.readout(strain).reshape(4, 50), r * [[2], [1], [2], [1]], rtol=1e-12)


def test_linear_readout_equals_weights_and_volumetric_is_trace(rng):
    strain = rng.normal(size=(1, 7, 6))
    h = ReceptorHypothesis(("volumetric", "xz"), (2e-3,))
    r = h.readout(strain).reshape(2, 7)
    np.testing.assert_allclose(r[0], strain[0, :, :3].sum(axis=1))
    np.testing.assert_allclose(r[1], strain[0, :, 4])


@pytest.mark.parametrize("kwargs,match", [
    (dict(components=("xx", "shear")), r"components: unknown component 'shear'; use one of xx"),
    (dict(components=()), "components: give at least one component"),
    (dict(components=("xz", "zx")), "components: each component may appear once"),
    (dict(components=(3,)), "components: each component must be a string"),
    (dict(depths=()), "depths: give at least one receptor depth"),
    (dict(depths=(0.0,)), r"depths: a receptor depth must be finite and > 0 m, got 0.0"),
    (dict(depths=(float("nan"),)), "depths: a receptor depth must be finite and > 0 m, got nan"),
    (dict(depths=("deep",)), "depths: expected a depth in m, got 'deep'"),
    (dict(noise_std=0.0), r"noise_std: must be finite and > 0 \(strain per reading\), got 0.0"),
    (dict(noise_std=-1e-3), "noise_std: must be finite and > 0"),
    (dict(noise_std=float("nan")), "noise_std: must be finite and > 0"),
    (dict(noise_std="loud"), "noise_std: expected a number"),
    (dict(shear="gamma"), "shear: must be 'tensor' or 'engineering', got 'gamma'"),
])
def test_bad_hypotheses_are_named(kwargs, match):
    args = dict(components=("xx",), depths=(1e-3,)) | kwargs
    with pytest.raises(ValueError, match=match):
        ReceptorHypothesis(**args)


def test_weights_refuse_invariants_and_readout_checks_shape():
    h = ReceptorHypothesis(("xx", "von_mises"), (1e-3,))
    with pytest.raises(ValueError, match=r"weights: the invariants \['von_mises'\] are nonlinear"):
        h.weights()
    with pytest.raises(ValueError, match=r"strain: expected shape \(n_depths=1, ..., n_receptors, 6\)"):
        h.readout(np.zeros((2, 5, 6)))
    with pytest.raises(ValueError, match="strain: must be finite"):
        h.readout(np.full((1, 5, 6), np.nan))


@pytest.mark.parametrize("text,match", [
    ("xx", "hypothesis: expected exactly one '@'"),
    ("xx@1mm@2mm", "hypothesis: expected exactly one '@'"),
    ("xx,,zx@1mm", "hypothesis: empty component name"),
    ("@1mm", "hypothesis: empty component name"),
    ("xx@", "hypothesis: empty depth"),
    ("xx@1mm,", "hypothesis: empty depth"),
    ("foo@1mm", "components: unknown component 'foo'"),
    ("xx@1kPa", "hypothesis depth: unit 'kPa' measures pressure"),
    ("xx@1furlong", "hypothesis depth: unknown unit 'furlong'"),
    ("xx@-1mm", "hypothesis depth: a receptor depth must be finite and > 0 m"),
    ("xx@1mm:gamma", "hypothesis: unknown shear convention 'gamma'"),
    ("xx@1mm;noise=0", "noise_std: must be finite and > 0"),
    ("xx@1mm;noise=abc", "hypothesis: noise must be a number"),
    ("xx@1mm;gain=2", r"hypothesis: after ';' expected 'noise=VALUE'"),
])
def test_bad_strings_are_named(text, match):
    with pytest.raises(ValueError, match=match):
        ReceptorHypothesis.parse(text)


def test_parse_refuses_non_strings():
    with pytest.raises(ValueError, match="hypothesis: expected a string"):
        parse_hypothesis(3)


def test_every_component_name_is_accepted():
    h = ReceptorHypothesis(RECEPTOR_COMPONENTS, (1e-3,))
    assert h.readout(np.ones((1, 2, 6))).shape == (len(RECEPTOR_COMPONENTS) * 2,)

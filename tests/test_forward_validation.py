"""One input rule per quantity (core/rules.py, the solver's door re-exports it), the same at every entry point.

Each rule has a ``pytest.raises(match=...)`` test of its message: the argument, the rule, the
value and the fix.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.forward import HalfSpace, HertzContact, SurfaceLoad
from tactilab.forward.halfspace import dcfft_stress, positive, point_green, transfer
from tactilab.forward.halfspace import validation as check


def test_positive_rule():
    assert positive(2.5, "width") == 2.5
    with pytest.raises(ValueError, match=r"width: must be finite and > 0 m, got -1.0; give a finite value > 0 in m"):
        positive(-1.0, "width")
    with pytest.raises(ValueError, match=r"rate: must be finite and > 0 Hz, got nan; sample faster"):
        positive(np.float64(np.nan), "rate", "Hz", "sample faster")
    with pytest.raises(ValueError, match=r"width: must be finite and > 0 m, got 'wide'"):
        positive("wide", "width")
    with pytest.raises(ValueError, match=r"flag: must be finite and > 0, got True; give a finite value > 0$"):
        positive(True, "flag", "1")


def test_young_modulus_rule():
    with pytest.raises(ValueError, match=r"E: Young's modulus must be finite and > 0 Pa, got 0.0; give E in Pa"):
        HalfSpace(E=0.0)
    with pytest.raises(ValueError, match=r"young_modulus: Young's modulus must be finite and > 0 Pa, got inf"):
        HertzContact(1.0, young_modulus=np.inf)


@pytest.mark.parametrize("nu", [0.51, -1.0, np.nan, "soft"])
def test_poisson_ratio_rule(nu):
    rule = r"Poisson's ratio must lie in \(-1, 0.5\] \(0.5 = incompressible\), got .*; skin is close to 0.5"
    with pytest.raises(ValueError, match="nu: " + rule):
        HalfSpace(1e6, nu)
    with pytest.raises(ValueError, match="poisson_ratio: " + rule):
        HertzContact(1.0, poisson_ratio=nu)
    with pytest.raises(ValueError, match="nu: " + rule):
        transfer(np.ones(3), None, 1e-3, nu, "p")


def test_depth_rule_is_the_same_at_every_entry_point():
    load = SurfaceLoad(p=np.ones((3, 3)), spacing=1e-4)
    rule = r"every depth must be finite and > 0 m \(z points into the skin\), got {} at index {}; give depths below"
    with pytest.raises(ValueError, match="depth: " + rule.format("-0.001", 1)):
        HalfSpace(1e6).stress(load, [1e-3, -1e-3])
    with pytest.raises(ValueError, match="depths: " + rule.format("nan", 0)):
        dcfft_stress(load, [np.nan])
    with pytest.raises(ValueError, match="depth: " + rule.format("0.0", 0)):
        HalfSpace(1e6).operator((3, 3), 1e-4, depth=0.0)
    with pytest.raises(ValueError, match="depth: " + rule.format("inf", 0)):
        transfer(np.ones(3), None, np.inf, 0.5, "p")
    with pytest.raises(ValueError, match=r"depth: expected one depth in m, got shape \(2,\); give a single number"):
        check.depth([1e-3, 2e-3])
    with pytest.raises(ValueError, match=r"depth: expected one depth or a non-empty 1-D sequence of depths in m"):
        HalfSpace(1e6).stress(load, [])


def test_spacing_rule():
    with pytest.raises(ValueError, match=r"spacing: grid spacing must be finite and > 0 m, got -0.0001; give it in m, e.g. 1.25e-3"):
        SurfaceLoad(p=np.ones(4), spacing=-1e-4)
    with pytest.raises(ValueError, match=r"spacing: expected one value or 2 values \(dx, dy\) in m, got 3"):
        SurfaceLoad(p=np.ones((2, 2)), spacing=(1e-4, 1e-4, 1e-4))


def test_components_rule_and_aliases():
    assert check.components(None) == check.COMPONENTS
    assert check.components(("xz", "zy", "yx", "zz")) == ("zx", "yz", "xy", "zz")
    assert check.components("xz") == ("zx",)
    with pytest.raises(ValueError, match=r"components: unknown component 'qq'; valid names are .*aliases"):
        check.components(("zz", "qq"))
    with pytest.raises(ValueError, match=r"components: names repeat in \('zx', 'xz'\) \(aliases count"):
        check.components(("zx", "xz"))
    with pytest.raises(ValueError, match=r"components: empty selection"):
        check.components(())
    with pytest.raises(ValueError, match=r"components: expected a sequence of names"):
        check.components(3)
    np.testing.assert_array_equal(point_green("xz", "x", 1e-3, 0.0, 1e-3), point_green("zx", "x", 1e-3, 0.0, 1e-3))


def test_finite_array_rule_names_the_first_bad_index():
    with pytest.raises(ValueError, match=r"tractions: must be finite \(no NaN or inf\) in Pa, got inf at index 2"):
        check.finite_array([0.0, 1.0, np.inf, np.nan], "tractions", "Pa")
    with pytest.raises(ValueError, match=r"grid: must be finite .* got nan at index \(1, 0\)"):
        check.finite_array([[0.0, 1.0], [np.nan, 0.0]], "grid", "m")


def test_dcfft_stress_accepts_the_aliases_like_the_facade():
    """``HalfSpace.stress(..., components=("xz",))`` worked while ``dcfft_stress`` raised."""
    rng = np.random.default_rng(3)
    load = SurfaceLoad(p=rng.normal(size=(6, 7)), qx=rng.normal(size=(6, 7)), spacing=1e-4)
    facade = HalfSpace(1e6, 0.4).stress(load, 3e-4, components=("xz",), method="dcfft")
    direct = dcfft_stress(load, [3e-4], nu=0.4, components=("xz",))
    np.testing.assert_allclose(direct[0, 0], facade.data["stress"].values[0, 0], rtol=1e-12, atol=1e-12)
    assert list(facade.data["stress"]["component"].values) == ["zx"]


@pytest.mark.parametrize("method", ["closed_form", "dcfft", "spectral"])
def test_depth_is_validated_once_along_the_call_chain(monkeypatch, method):
    calls = []
    original = check.depths

    def counting(value, name="depth"):
        calls.append(name)
        return original(value, name)

    monkeypatch.setattr(check, "depths", counting)
    load = SurfaceLoad(p=np.ones((4, 5)), spacing=1e-4, periodic=method == "spectral")
    HalfSpace(1e6).stress(load, [2e-4, 4e-4], components=("zz",), method=method)
    assert calls == ["depth"]

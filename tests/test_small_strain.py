"""The small-strain rule: a linear-elastic answer whose largest strain exceeds 0.1 warns
(PlausibilityWarning), and ``tactilab --strict`` makes it an error."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tactilab.data_schemas.plausibility import SMALL_STRAIN_LIMIT, PlausibilityWarning, check_small_strain
from tactilab.forward import HalfSpace
from tactilab.forward.halfspace.fields import compliance_matrix, largest_strain
from tactilab.forward.halfspace.loads import SurfaceLoad

STRAIN_MESSAGE = (r"HalfSpace\.strain: the largest strain is .* above the small-strain limit 0\.1 of linear "
                  r"elasticity, so the answer is outside the model; lower the load or check the Young's modulus")


def _fingertip_load(n: int = 32, spacing: float = 0.25e-3) -> SurfaceLoad:
    """A Hertz-like pressure of 42 kPa peak over a 3 mm radius (about 0.8 N): a fingertip."""
    x = (np.arange(n) - n / 2) * spacing
    rho2 = x[None, :] ** 2 + x[:, None] ** 2
    return SurfaceLoad(p=42e3 * np.sqrt(np.clip(1 - rho2 / 3e-3 ** 2, 0, None)), spacing=spacing)


def test_a_1kpa_skin_under_a_fingertip_load_warns_and_1mpa_does_not(kernel_path):
    load = _fingertip_load()
    with pytest.warns(PlausibilityWarning, match=STRAIN_MESSAGE):
        HalfSpace(E=1e3).strain(load, 1e-3, components=("zz",))
    with pytest.warns(PlausibilityWarning, match=r"HalfSpace\.stress: the largest strain is"):
        HalfSpace(E=1e3).stress(load, 1e-3)  # all six stress components: Hooke's law gives the strain
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        HalfSpace(E=1e6).strain(load, 1e-3, components=("zz",))  # 1000x smaller: about 2 % at most


def test_the_stress_bound_equals_the_strain_bound_with_all_six_components(kernel_path):
    """Oracle: the bound from a stress field (Hooke's law) is the max |eps_ij| of the strain field."""
    rng = np.random.default_rng(3)
    stress = rng.normal(size=(2, 6, 5, 4)) * 1e3
    E, nu = 2e5, 0.4
    strain = np.einsum("ij,dj...->di...", compliance_matrix(E, nu), stress)
    comps = ("xx", "yy", "zz", "yz", "zx", "xy")
    assert largest_strain(stress, "stress", comps, E, nu) == pytest.approx(np.abs(strain).max(), rel=1e-12)
    assert largest_strain(strain, "strain", comps, E, nu) == np.abs(strain).max()
    assert largest_strain(stress[:, 3:], "stress", comps[3:], E, nu) == pytest.approx(np.abs(strain[:, 3:]).max())


@pytest.mark.parametrize("largest", [0.2, float("nan")])
def test_check_small_strain_flags_large_and_nan(largest):
    with pytest.warns(PlausibilityWarning, match=r"^here: the largest strain is (0\.2 \(20 %\)|nan)"):
        check_small_strain(largest, "here")
    check_small_strain(SMALL_STRAIN_LIMIT, "here")  # the limit itself passes


def test_the_stress_command_warns_and_strict_makes_it_an_error(tmp_path, capsys):
    from pathlib import Path

    from tactilab.cli.main import main

    load = Path(__file__).resolve().parents[1] / "examples" / "fingertip_load.toml"
    argv = ["stress", str(load), "--depth", "1mm", "--young-modulus", "1kPa", "--components", "zz"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "warning: HalfSpace.strain: the largest strain is 20" in err and "small-strain limit 0.1" in err
    assert main(["--strict", *argv, "--out", str(tmp_path / "b")]) == 2
    assert "error: HalfSpace.strain: the largest strain is 20" in capsys.readouterr().err


def test_largest_strain_flags_nan_in_any_component(kernel_path):
    """The check reads max and min per component: a NaN anywhere must come out as NaN (flagged)."""
    import math

    comps = ("xx", "yy", "zz", "yz", "zx", "xy")
    for quantity in ("stress", "strain"):
        for k in range(6):
            values = np.zeros((1, 6, 4, 4))
            values[0, k, 1, 2] = np.nan
            assert math.isnan(largest_strain(values, quantity, comps, 1e6, 0.45)), (quantity, k)

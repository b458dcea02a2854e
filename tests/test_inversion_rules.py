"""The inversion's entry points take their input rules from tactilab.core.rules. Poisson's ratio:
nu in (-1, 0.5] everywhere (the solver's and the material record's rule), no longer [0, 0.5]. A negative nu (an auxetic material) gives the
same operators as the solver, and nu outside the range is refused with the rule's message."""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.forward import HalfSpace
from tactilab.inversion.operators import normal_pressure_to_szz_multiplier
from tactilab.inversion import (
    DefectScanModel, FourierDiagonal, gaussian_posterior, GridLoadFamily, IndentationFamily, SinusoidFamily, TractorFamily, halfspace_fourier_operator, halfspace_strain_operator,
    rigid_surface_height_operator, rigid_surface_height_strain_operator,
)


DX = 1e-4
DEPTH = 5e-4
E = 1e6
RULE = r"Poisson's ratio must lie in \(-1, 0.5\]"

ENTRY_POINTS = {
    "halfspace_fourier_operator": lambda nu: halfspace_fourier_operator((16,), DX, DEPTH, nu),
    "halfspace_strain_operator": lambda nu: halfspace_strain_operator((16,), DX, DEPTH, E, nu),
    "rigid_surface_height_operator": lambda nu: rigid_surface_height_operator(16, DX, DEPTH, E, nu),
    "rigid_surface_height_strain_operator": lambda nu: rigid_surface_height_strain_operator(16, DX, DEPTH, E, nu),
    "DefectScanModel": lambda nu: DefectScanModel([0.0], [[0.0, 0.0]], poisson_ratio=nu),
    "SinusoidFamily": lambda nu: SinusoidFamily(4e-3, nu=nu),
    "TractorFamily": lambda nu: TractorFamily([0.0], E, nu=nu),
    "GridLoadFamily": lambda nu: GridLoadFamily((8,), DX, young_modulus=E, nu=nu),
    "IndentationFamily": lambda nu: IndentationFamily((8,), DX, E, nu=nu),
}


@pytest.mark.parametrize("name", sorted(ENTRY_POINTS))
@pytest.mark.parametrize("nu", [-0.99, -0.3, 0.0, 0.25, 0.5])
def test_every_entry_point_accepts_nu_in_the_physical_range(name, nu):
    made = ENTRY_POINTS[name](nu)
    assert getattr(made, "nu", getattr(made, "poisson_ratio", nu)) == nu  # kept as given where it is stored


@pytest.mark.parametrize("name", sorted(ENTRY_POINTS))
@pytest.mark.parametrize("nu", [-1.0, 0.51, float("nan")])
def test_every_entry_point_refuses_nu_outside_it(name, nu):
    with pytest.raises(ValueError, match=RULE):
        ENTRY_POINTS[name](nu)


def test_negative_nu_operator_is_the_solvers():
    """An auxetic nu = -0.3: the inversion's circulant operator is the solver's periodic map."""
    nu = -0.3
    op = halfspace_fourier_operator((32,), DX, DEPTH, nu, "p", "yy")
    solver = HalfSpace(E, nu).operator((32,), DX, depth=DEPTH, components=("yy",), loads=("p",), periodic=True)
    x = np.random.default_rng(0).normal(size=32)
    want = solver @ x
    np.testing.assert_allclose(op @ x, want, rtol=0, atol=1e-12 * np.abs(want).max())
    # plane strain: sigma_yy = nu (sigma_xx + sigma_zz) depends on nu: the negative value is used, not clipped to 0
    zero = halfspace_fourier_operator((32,), DX, DEPTH, 0.0, "p", "yy")
    assert np.abs(op @ x - zero @ x).max() > 1e-3 * np.abs(want).max()


def test_depth_and_spacing_follow_the_one_rule():
    """Depths and grid spacings of the inversion's operators are checked by tactilab.core.rules."""
    with pytest.raises(ValueError, match="depth: every depth must be finite and > 0 m"):
        rigid_surface_height_operator(16, DX, 0.0, E)
    with pytest.raises(ValueError, match="spacing: grid spacing must be finite and > 0 m"):
        rigid_surface_height_strain_operator(16, -DX, DEPTH, E)
    with pytest.raises(ValueError, match="dx: grid spacing must be finite and > 0 m"):
        normal_pressure_to_szz_multiplier(16, 0.0, DEPTH)
    op = FourierDiagonal(normal_pressure_to_szz_multiplier(16, DX, DEPTH), DX)
    post = gaussian_posterior(op, np.zeros(16), np.ones(16), 1.0)
    with pytest.raises(ValueError, match="depth: every depth must be finite and > 0 m"):
        post.resolvable_band(depth=-1e-3)

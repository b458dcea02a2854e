"""A catalogue of known answers: the reported ``error_estimate`` against the true error.

Each case runs the facade (``HalfSpace.stress`` / ``strain``) with a method and compares the
result with an answer computed apart from the solver: the Boussinesq/Cerruti and Flamant closed
forms for point and line forces, a Hankel-transform quadrature for Gaussian loads, the closed
form of a periodic pressure, the sliding-sinusoid formulas of docs/theory.md section 4a, and
the inversion's height operator for a pressure from a deflection. The true error is
``max |computed - answer| / max |computed|`` (the estimate's own scale). Asserted:

- coverage: the true error never exceeds the estimate;
- usefulness: the estimate is at most 100x the true error wherever the true error is above 1e-13.

Usefulness is not asserted for loads narrower than the grid spacing (a Gaussian of 0.5 spacings)
at depths of 10 spacings and more: there the estimate is 450x to 4300x the true error (it grows
like depth^2 through its rescaling from peak traction to peak field while the error, the
sampling of the load's total force, stays at 3 %). Coverage is asserted for them.

Not in this catalogue (the estimate does not cover them yet; they need the estimate to carry the
rounding of the load relative to a field much weaker than the load): the sliding sinusoid's
strain at nu = 0.4999 and 0.5 within 1e-3 grid spacings of the surface (the strain cancels to
3e-6 of its load scale; true error 1e-12 to 2e-12, estimate 5e-14), and any periodic field deeper than several
periods (1e-20 of the load; the load's rounding dominates, true error about 1). Hertz contacts,
the tractor pair and continuous loads sampled on a grid (the error of representing the load)
were not here before the estimate covered the sampling of a continuous load; they are now (the
last section), with Hamilton's closed form for the sliding Hertz contact
(benchmarks/hamilton_reference.py).
"""

from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.special import j0

from tactilab.forward import (AccuracyWarning, DeflectionLoad, HalfSpace, HertzContact, SurfaceLoad, TractionField,
                              pair_phi_psi, pressure_from_deflection, sliding_sinusoid_strain)
from tactilab.forward.halfspace import line_load_stress, point_load_stress

_SPEC = importlib.util.spec_from_file_location(
    "hamilton_reference", Path(__file__).resolve().parents[1] / "benchmarks" / "hamilton_reference.py")
hamilton = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(hamilton)

H = 1e-4  # grid spacing, m
NUS = (0.0, 0.3, 0.49, 0.4999, 0.5)
NODAL_METHODS = ("closed_form", "dcfft")


def _true_error(got: np.ndarray, answer: np.ndarray) -> float:
    return float(np.abs(got - answer).max() / np.abs(got).max())


def _check(true_error: float, estimate: float, useful: bool = True) -> None:
    assert true_error <= estimate, f"true error {true_error:.3g} above the estimate {estimate:.3g}"
    if useful and true_error > 1e-13:
        assert estimate <= 100 * true_error, f"estimate {estimate:.3g} > 100x the true error {true_error:.3g}"


def _run(load, depth, method, components=None, nu=0.5, quantity="stress"):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)  # forced methods past tol say so; tested elsewhere
        hs = HalfSpace(1e6, nu)
        call = hs.stress if quantity == "stress" else hs.strain
        return call(load, depth, components=components, method=method)


# ----------------------------------------------------------------------------- point and line forces
@pytest.mark.parametrize("nu", NUS)
def test_point_forces_against_boussinesq_and_cerruti(nu):
    """A single loaded node is a point force F = traction x cell area: exact for the nodal methods."""
    n = 21
    x = (np.arange(n) - n // 2) * H
    yy, xx = np.meshgrid(x, x, indexing="ij")
    for direction, force in (("p", "fz"), ("qx", "fx"), ("qy", "fy")):
        values = np.zeros((n, n))
        values[n // 2, n // 2] = 1e4
        load = SurfaceLoad(**{direction: values}, spacing=H)
        for depth in (1e-3 * H, 0.5 * H, 3 * H, 30 * H, 100 * n * H):  # to 100 domain lengths
            answer = np.moveaxis(point_load_stress(xx, yy, np.full_like(xx, depth), nu=nu,
                                                   **{force: 1e4 * H * H}), -1, 0)
            for method in NODAL_METHODS:
                result = _run(load, depth, method, nu=nu)
                _check(_true_error(result.data["stress"].values[0], answer), result.error_estimate)


@pytest.mark.parametrize("nu", NUS)
def test_line_forces_against_flamant(nu):
    n = 41
    x = (np.arange(n) - n // 2) * H
    for direction, force in (("p", "fz"), ("qx", "fx"), ("qy", "fy")):
        values = np.zeros(n)
        values[n // 2] = 1e4
        load = SurfaceLoad(**{direction: values}, spacing=H)
        for depth in (1e-3 * H, 0.5 * H, 3 * H, 30 * H, 100 * n * H):
            answer = line_load_stress(x, np.full_like(x, depth), nu=nu, **{force: 1e4 * H}).T
            for method in NODAL_METHODS:
                result = _run(load, depth, method, nu=nu)
                _check(_true_error(result.data["stress"].values[0], answer), result.error_estimate)


# ----------------------------------------------------------------------------- Gaussian loads
def _gaussian_answer(n: int, width: float, depth: float, p0: float) -> np.ndarray:
    """sigma_zz under p0 exp(-r^2 / 2 w^2) by quadrature of its Hankel transform:
    sigma_zz(r, z) = -(1 / 2 pi) int P(rho) (1 + rho z) e^{-rho z} J0(rho r) rho d rho,
    P(rho) = 2 pi w^2 p0 exp(-rho^2 w^2 / 2) (composite 64-point Gauss-Legendre)."""
    rho_max = 12.0 / width
    t, w0 = np.polynomial.legendre.leggauss(64)
    edges = np.unique(np.concatenate([np.linspace(0, min(rho_max, 40 / depth), 41), np.linspace(0, rho_max, 81)]))
    a, b = edges[:-1, None], edges[1:, None]
    rho = (0.5 * (b - a) * (t + 1) + a).ravel()
    weights = (0.5 * (b - a) * w0).ravel()
    spectrum = 2 * np.pi * width**2 * p0 * np.exp(-((rho * width) ** 2) / 2)
    integrand = -(1 + rho * depth) * np.exp(-rho * depth) * spectrum * rho / (2 * np.pi) * weights
    i = np.arange(n) - n // 2
    r2 = i[:, None] ** 2 + i[None, :] ** 2  # radii in grid units, squared: exact
    radii, inverse = np.unique(r2, return_inverse=True)
    values = j0(np.outer(np.sqrt(radii) * H, rho)) @ integrand
    return values[inverse].reshape(r2.shape)


@pytest.mark.parametrize("nu", [0.0, 0.5])
@pytest.mark.parametrize("width_in_spacings", [0.5, 2.0])
def test_gaussian_loads_against_quadrature(nu, width_in_spacings):
    width, p0 = width_in_spacings * H, -1e4
    n = 2 * int(round(max(8 * width, 8 * H) / H)) + 1
    x = (np.arange(n) - n // 2) * H
    xx, yy = np.meshgrid(x, x)
    load = SurfaceLoad(p=p0 * np.exp(-(xx**2 + yy**2) / (2 * width**2)), spacing=H)
    for depth in (1e-3 * H, 0.5 * H, 3 * H, 10 * H, 30 * H):
        answer = _gaussian_answer(n, width, depth, p0)
        for method in NODAL_METHODS:
            result = _run(load, depth, method, components=("zz",), nu=nu)
            useful = not (width < H and depth >= 10 * H)  # see the module docstring
            _check(_true_error(result.data["stress"].values[0, 0], answer), result.error_estimate, useful)


# ----------------------------------------------------------------------------- periodic loads
@pytest.mark.parametrize("nu", NUS)
def test_periodic_pressure_against_its_closed_form(nu):
    """p = P0 + P cos(kx): sigma_zz = -P0 - P (1 + kz) e^{-kz} cos(kx) (docs/theory.md section 3),
    on a 1-D grid and on a 2-D grid that does not vary in y."""
    n, cycles, p0, p1 = 64, 3, -2e3, 5e3
    x = (np.arange(n) - n // 2) * H
    k = 2 * np.pi * cycles / (n * H)
    p = p0 + p1 * np.cos(k * x)
    for load in (SurfaceLoad(p=p, spacing=H, periodic=True),
                 SurfaceLoad(p=np.tile(p, (8, 1)), spacing=H, periodic=True)):
        for depth in (1e-3 * H, 0.5 * H, 3 * H, 30 * H, 100 * n * H):
            answer = -p0 - p1 * (1 + k * depth) * np.exp(-k * depth) * np.cos(k * x)
            result = _run(load, depth, "spectral", components=("zz",), nu=nu)
            got = result.data["stress"].values[0, 0]
            _check(_true_error(got, np.broadcast_to(answer, got.shape)), result.error_estimate)


@pytest.mark.parametrize("nu", NUS)
def test_sliding_sinusoid_and_pressure_from_deflection(nu):
    """The paper's sliding sinusoid (docs/theory.md section 4a, tensor shear) from the periodic
    pressure of its deflection, and the inversion's height -> sigma_zz operator."""
    from tactilab.forward import sliding_sinusoid_strain
    from tactilab.inversion.operators import rigid_surface_height_operator

    n, pitch, amplitude, young = 128, 2e-3, 20e-6, 2e5
    x = (np.arange(n) - n // 2) * (pitch / n)
    deflection = amplitude * np.sin(2 * np.pi * x / pitch)
    load = pressure_from_deflection(deflection, pitch / n, young, nu)
    assert load.periodic
    depths = (0.5e-3, 2e-3) if nu > 0.49 else (1e-3 * pitch / n, 0.5e-3, 2e-3)  # see the module docstring
    for depth in depths:
        strain = HalfSpace(young, nu).strain(load, depth)
        answer = sliding_sinusoid_strain(x, depth, amplitude, pitch, nu=nu).T
        _check(_true_error(strain.data["strain"].values[0], answer), strain.error_estimate)
        stress = HalfSpace(young, nu).stress(load, depth, components=("zz",))
        height_answer = rigid_surface_height_operator(n, pitch / n, depth, young, nu) @ deflection
        _check(_true_error(stress.data["stress"].values[0, 0], height_answer), stress.error_estimate)


# ----------------------------------------------------------------------------- continuous loads
@pytest.mark.parametrize("nu", NUS)
def test_sliding_hertz_contact_against_hamilton(nu):
    """A Hertz contact sliding with friction (a continuous load, HertzContact.load) against Hamilton's
    closed form (benchmarks/hamilton_reference.py), grids a/4 .. a/64, depth a/2. The estimate covers
    the method and the sampling of the contact on the grid; before it did, a/16 reported 1.1e-14
    against a true error of 2.3e-3."""
    contact = HertzContact(0.5, finger_radius=0.01, young_modulus=1e6, poisson_ratio=nu)
    a, p0, mu = contact.contact_radius, contact.peak_pressure, 0.3
    for div in (4, 8, 16, 32, 64):
        load = contact.load(friction=mu, condition="sliding", spacing=a / div)
        methods = ("dcfft", "closed_form") if div <= 8 else ("dcfft",)
        for method in methods:
            result = _run(load, a / 2, method, nu=nu)
            assert result.data.attrs["error_covers"] == "method+sampling"
            got = result.data["stress"]
            xx, yy = np.meshgrid(got.x.values, got.y.values)
            answer = hamilton.hamilton_stress(xx, yy, a / 2, a=a, p0=p0, mu=mu, nu=nu)
            _check(_true_error(got.values[0], answer), result.error_estimate)


def test_nodal_loads_say_the_estimate_is_for_the_values_as_given():
    contact = HertzContact(0.5, finger_radius=0.01, young_modulus=1e6)
    nodal = contact.load(friction=0.3).nodal()
    result = _run(nodal, 1e-3, "dcfft")
    assert result.data.attrs["error_covers"] == "method"
    assert "sampling_error_estimate" not in result.data.attrs


def test_tractor_pair_against_its_closed_form():
    """The paper's tractor pair q [-delta(x + d) + delta(x - d)] (docs/theory.md 4a, nu = 1/2) as
    two nodal line loads: exact for the nodal methods, so the estimate covers the method only."""
    n, q, d, young = 401, 50.0, 1e-3, 1e6
    x = (np.arange(n) - n // 2) * H
    qx = np.zeros(n)
    qx[n // 2 - 10], qx[n // 2 + 10] = -q / H, q / H
    load = SurfaceLoad(qx=qx, spacing=H)
    for depth in (0.5e-3, 1e-3, 3e-3):
        phi, psi = pair_phi_psi(x, d, depth)
        for method in NODAL_METHODS:
            result = _run(load, depth, method, components=("xx", "zz", "zx"), quantity="strain")
            assert result.data.attrs["error_covers"] == "method"
            answer = np.stack([3 * q * phi, -3 * q * phi, 3 * q * psi / 2]) / (np.pi * young)
            _check(_true_error(result.data["strain"].values[0], answer), result.error_estimate)


@pytest.mark.parametrize("nu", NUS)
def test_periodic_pressure_from_a_deflection_profile(nu):
    """A sinusoidal profile given as a function (DeflectionLoad, periodic) against the sliding
    sinusoid (docs/theory.md 4a); and a triangle-wave profile, whose kinks the grid cannot resolve,
    against the sum of its Fourier series."""
    n, pitch, amplitude, young = 64, 2e-3, 20e-6, 2e5
    hs = HalfSpace(young, nu)
    sine = DeflectionLoad(lambda x: amplitude * np.sin(2 * np.pi * x / pitch), young, nu, shape=n,
                          spacing=pitch / n)
    for depth in (0.5e-3, 2e-3):
        result = hs.strain(sine, depth)
        assert result.data.attrs["error_covers"] == "method+sampling"
        answer = sliding_sinusoid_strain(result.data.x.values, depth, amplitude, pitch, nu=nu).T
        _check(_true_error(result.data["strain"].values[0], answer), result.error_estimate)
    def triangle(x):  # period `pitch`, peak `amplitude`, kinks at 0 and pitch/2
        return amplitude * (1 - 4 * np.abs((x / pitch) % 1.0 - 0.5))
    tri = DeflectionLoad(triangle, young, nu, shape=n, spacing=pitch / n)
    for depth in (0.05e-3, 0.2e-3):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", AccuracyWarning)
            result = hs.strain(tri, depth, tol=1.0)
        x = result.data.x.values
        answer = np.zeros((6, x.size))
        for m in range(1, 4000, 2):  # triangle = -sum 8 A/(pi m)^2 cos(2 pi m x/p), odd m
            coef = -8 * amplitude / (np.pi * m) ** 2
            answer += sliding_sinusoid_strain(x + pitch / (4 * m), depth, coef, pitch / m, nu=nu).T
        _check(_true_error(result.data["strain"].values[0], answer), result.error_estimate)


def test_callable_traction_field_against_gaussian_quadrature():
    """A Gaussian pressure given as a function (TractionField), width 1.5 grid spacings, at 0.5, 2
    and 5 spacings deep: coverage and usefulness. Its sampling error falls faster than any power of
    h; the Richardson bound (which trusts at most second-order convergence) erred large, 5x to 1e6x
    (true error 2.1e-9, estimate 1.9e-3 at 5 spacings). The spectral estimate (the load's content
    near and beyond the grid scale through the depth's transfer, forward/halfspace/continuous.py)
    brings it to 3x to 4.3x; see docs/forward_methods.md."""
    width, p0 = 1.5 * H, -1e4
    n = 41
    field = TractionField(p=lambda x, y: p0 * np.exp(-(x**2 + y**2) / (2 * width**2)), shape=(n, n),
                          spacing=H)
    for depth in (0.5 * H, 2 * H, 5 * H):
        result = _run(field, depth, "dcfft", components=("zz",))
        assert result.data.attrs["error_covers"] == "method+sampling"
        _check(_true_error(result.data["stress"].values[0, 0], _gaussian_answer(n, width, depth, p0)),
               result.error_estimate)
        assert result.data.attrs["sampling_spectral"] < result.data.attrs["sampling_richardson"]


def test_auto_keeps_a_smooth_callable_load_on_its_grid_when_tol_is_met():
    """tol chooses the grid: the Gaussian above at 5 spacings deep with tol=1e-6 meets tol on its
    own grid (the Richardson bound, 1.9e-3, used to force two halvings), and the result keeps its
    promise against quadrature."""
    width, p0, n, depth = 1.5 * H, -1e4, 41, 5 * H
    field = TractionField(p=lambda x, y: p0 * np.exp(-(x**2 + y**2) / (2 * width**2)), shape=(n, n),
                          spacing=H)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        result = HalfSpace(1e6, 0.5).stress(field, depth, components=("zz",), tol=1e-6)
    assert result.data.attrs["grid_refinements"] == 0 and result.error_estimate <= 1e-6
    true = _true_error(result.data["stress"].values[0, 0], _gaussian_answer(n, width, depth, p0))
    _check(true, result.error_estimate)

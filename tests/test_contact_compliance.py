"""Surface compliance of the half-space and its grid operators (forward/contact/compliance.py).

Oracles: Boussinesq and Cerruti surface displacements (Johnson, Contact Mechanics, eqs. 3.19-3.21,
3.86), Flamant's line-load displacements (Johnson 2.19-2.24), Love's uniform pressure on a
rectangle, the exact response to a sinusoidal traction, numerical quadrature of the point kernels
over a pixel, and dot tests (Betti's reciprocity).
"""

import math

import numpy as np
import pytest
from scipy import integrate

from tactilab.forward.contact import ContactCompliance
from tactilab.forward.halfspace import HalfSpace

E = 1.0e6


def point_displacement(u, v, nu):
    """Surface displacement (rows uz, ux, uy) at (u, v) of unit point forces (columns Fz, Fx, Fy)."""
    G = E / (2 * (1 + nu))
    r = math.hypot(u, v)
    c = (1 - 2 * nu) / (4 * math.pi * G * r * r)
    t = 1 / (2 * math.pi * G * r)
    return np.array([[(1 - nu) * t, c * u, c * v],
                     [-c * u, t * ((1 - nu) + nu * u * u / r**2), t * nu * u * v / r**2],
                     [-c * v, t * nu * u * v / r**2, t * ((1 - nu) + nu * v * v / r**2)]])


@pytest.mark.parametrize("nu", [0.0, 0.3, 0.5])
@pytest.mark.parametrize("shape,spacing", [((32,), 1e-4), ((33,), 1e-4), ((16, 24), (1e-4, 2e-4)), ((15, 17), 1e-4)])
@pytest.mark.parametrize("periodic", [True, False])
def test_dot_test_reciprocity(nu, shape, spacing, periodic, rng):
    C = ContactCompliance(HalfSpace(E, nu), shape, spacing, periodic)
    t1 = [rng.standard_normal(shape) for _ in range(C.n_components)]
    t2 = [rng.standard_normal(shape) for _ in range(C.n_components)]
    u1, u2 = C.apply(*t1), C.apply(*t2)
    a = sum(float((x * y).sum()) for x, y in zip(u1, t2) if x is not None)
    b = sum(float((x * y).sum()) for x, y in zip(t1, u2) if x is not None)
    assert abs(a - b) <= 1e-12 * abs(a)
    # the cross blocks are each other's adjoint
    c1 = float((C.normal_from_tangential(*t1[1:]) * t2[0]).sum())
    c2 = sum(float((x * y).sum()) for x, y in zip(C.tangential_from_normal(t2[0]), t1[1:]) if x is not None)
    assert abs(c1 - c2) <= 1e-12 * max(abs(c1), 1e-30) + 1e-30


@pytest.mark.parametrize("nu", [0.3, 0.5])
def test_pixel_influence_is_the_integral_of_the_point_kernels(nu):
    hs = HalfSpace(E, nu)
    dx, dy = 1e-3, 2e-3
    for X, Y in [(0.7e-3, 1.3e-3), (3e-3, -2e-3), (0.0, 1.5e-3)]:
        K = hs.surface_influence(X, Y, (dx, dy))
        for i in range(3):
            for j in range(3):
                ref = integrate.dblquad(lambda ys, xs: point_displacement(X - xs, Y - ys, nu)[i, j],
                                        -dx / 2, dx / 2, -dy / 2, dy / 2, epsabs=1e-16, epsrel=1e-10)[0]
                assert K[i, j] == pytest.approx(ref, rel=1e-8, abs=1e-22)


def test_love_centre_of_a_square():
    """Johnson 3.25: the centre of a square of side 2a under p sinks 8 a ln(1 + sqrt 2) p / (pi E*)."""
    nu, a = 0.3, 0.5e-3
    K = HalfSpace(E, nu).surface_influence(0.0, 0.0, (2 * a, 2 * a))
    assert K[0, 0] == pytest.approx(8 * a * math.log(1 + math.sqrt(2)) * (1 - nu**2) / (math.pi * E), rel=1e-14)
    assert K[0, 1] == 0.0 and K[1, 2] == 0.0


@pytest.mark.parametrize("nu", [0.25, 0.5])
def test_isolated_far_field_is_boussinesq_and_cerruti(nu):
    n, h = 64, 1e-4
    C = ContactCompliance(HalfSpace(E, nu), (n, n), h, periodic=False)
    t = np.zeros((n, n))
    t[0, 0] = 1.0  # one node of unit traction: a force h^2 (N) at the corner node
    uz, ux, uy = C.apply(t, t, t)
    j, i = 40, 25  # field node (y index, x index)
    expected = point_displacement(i * h, j * h, nu) @ np.array([1.0, 1.0, 1.0]) * h * h
    r = math.hypot(i, j)
    assert np.allclose([uz[j, i], ux[j, i], uy[j, i]], expected, rtol=0.2 / r**2 * 5, atol=0)


def test_plane_strain_flamant():
    """Plane strain: a line load N gives uz difference (2/(pi E*)) N ln(x1/x2); a tangential one uz = beta Q/E* sign."""
    nu, n, h = 0.3, 128, 1e-4
    Es, beta = E / (1 - nu**2), (1 - 2 * nu) / (2 * (1 - nu))
    C = ContactCompliance(HalfSpace(E, nu), (n,), h, periodic=False)
    t = np.zeros(n)
    t[10] = 1.0
    uz = C.normal(t)
    assert uz[90] - uz[50] == pytest.approx(-2 / (math.pi * Es) * h * math.log(80 / 40), rel=1e-3)
    uzq = C.normal_from_tangential(t)
    assert uzq[50] == pytest.approx(beta * h / Es, rel=1e-12)
    assert uzq[3] == pytest.approx(-beta * h / Es, rel=1e-12)
    assert uzq[10] == 0.0


@pytest.mark.parametrize("nu", [0.3, 0.5])
def test_periodic_sinusoid_exact(nu):
    n, h, m = 48, 1e-4, 5
    Es, G, beta = E / (1 - nu**2), E / (2 * (1 + nu)), (1 - 2 * nu) / (2 * (1 - nu))
    x = (np.arange(n) - n // 2) * h
    k = 2 * np.pi * m / (n * h)
    c = np.cos(k * x)
    C1 = ContactCompliance(HalfSpace(E, nu), (n,), h, periodic=True)
    assert np.allclose(C1.normal(c), 2 / (Es * k) * c, rtol=0, atol=1e-12 * 2 / (Es * k))
    assert np.allclose(C1.normal_from_tangential(c), beta * 2 / (Es * k) * np.sin(k * x), atol=1e-12 * 2 / (Es * k))
    # 3-D: a wave along y; qy across it moves uy with 1/(G k) (1 - nu), qx along the crest with 1/(G k)
    C2 = ContactCompliance(HalfSpace(E, nu), (n, 16), (2e-4, h), periodic=True)
    c2 = np.broadcast_to(c[:, None], (n, 16))
    ux, uy = C2.tangential(c2, c2)
    assert np.allclose(ux, c2 / (G * k), atol=1e-12 / (G * k))
    assert np.allclose(uy, (1 - nu) * c2 / (G * k), atol=1e-12 / (G * k))
    # uniform traction: no displacement (k = 0 is a rigid shift)
    assert np.abs(C1.normal(np.ones(n))).max() < 1e-25


def test_surface_compliance_matrix_is_hermitian_and_positive(rng):
    hs = HalfSpace(E, 0.3)
    kx, ky = rng.standard_normal(50) * 1e3, rng.standard_normal(50) * 1e3
    M = hs.surface_compliance(kx, ky)
    assert np.allclose(M, np.conj(np.swapaxes(M, -1, -2)))
    assert np.all(np.linalg.eigvalsh(M) > 0)
    k = np.hypot(kx, ky)
    assert np.allclose(M[:, 0, 0].real, 2 * (1 - 0.09) / (E * k))
    assert np.all(hs.surface_compliance(0.0, 0.0) == 0)
    assert hs.surface_compliance(np.array([2.0]), None).shape == (1, 2, 2)


def test_bad_inputs():
    hs = HalfSpace(E, 0.5)
    with pytest.raises(ValueError, match="shape: expected"):
        ContactCompliance(hs, (2, 2, 2), 1e-4, True)
    with pytest.raises(ValueError, match="skin: an isolated contact needs a skin with surface_influence"):
        ContactCompliance(object(), (8,), 1e-4, False)
    with pytest.raises(ValueError, match="periodic: must be True or False"):
        ContactCompliance(hs, (8,), 1e-4, "yes")
    C = ContactCompliance(hs, (8,), 1e-4, True)
    with pytest.raises(ValueError, match=r"p: expected shape \(8,\)"):
        C.normal(np.zeros(9))
    with pytest.raises(ValueError, match="qy: a plane-strain grid has no y traction"):
        C.tangential(np.zeros(8), np.zeros(8))
    with pytest.raises(ValueError, match="a plane-strain grid has only"):
        C.spectrum("uy", "p")
    with pytest.raises(ValueError, match="reference_length: must be finite and > 0 m, got None"):
        hs.surface_influence(0.0, None, (1e-4,))
    with pytest.raises(ValueError, match="spacing: grid spacing must be finite and > 0 m"):
        hs.surface_influence(0.0, 0.0, (1e-4, -1e-4))


@pytest.mark.parametrize("shape,spacing", [((32,), 1e-4), ((16, 24), (1e-4, 2e-4))])
def test_stiffness_inverts_the_periodic_compliance(shape, spacing, rng):
    C = ContactCompliance(HalfSpace(E, 0.3), shape, spacing, periodic=True)
    p = rng.standard_normal(shape)
    p -= p.mean()
    assert np.allclose(C.stiffness(C.normal(p)), p, atol=1e-10 * np.abs(p).max())
    assert C.stiffness(np.ones(shape)).min() > 0  # a uniform gap still moves the pressure
    a, b = rng.standard_normal(shape), rng.standard_normal(shape)
    assert float((C.stiffness(a) * b).sum()) == pytest.approx(float((a * C.stiffness(b)).sum()), rel=1e-12)


def test_one_entry_equals_the_full_matrix(rng):
    hs = HalfSpace(E, 0.3)
    x, y = rng.standard_normal(20) * 1e-3, rng.standard_normal(20) * 1e-3
    full = hs.surface_influence(x, y, (1e-4, 2e-4))
    for i in range(3):
        for j in range(3):
            assert np.array_equal(hs.surface_influence(x, y, (1e-4, 2e-4), entry=(i, j)), full[:, i, j])
    line = hs.surface_influence(x, None, (1e-4,), reference_length=1e-2)
    assert np.array_equal(hs.surface_influence(x, None, (1e-4,), reference_length=1e-2, entry=(0, 1)), line[:, 0, 1])


@pytest.mark.parametrize("shape,periodic", [((32,), True), ((33,), False), ((16, 24), True), ((15, 17), False)])
def test_direct_summation_of_point_loads_equals_the_fft_product(shape, periodic, rng):
    """The clipped nodes' correction of the contact solver: influence coefficients summed directly."""
    C = ContactCompliance(HalfSpace(E, 0.3), shape, (1e-4, 2e-4)[:len(shape)], periodic)
    nodes = np.concatenate([[0], 1 + rng.choice(math.prod(shape) - 1, 4, replace=False)])  # 0: a corner
    values = rng.standard_normal(5)
    c = np.zeros(shape)
    c.flat[nodes] = values
    u = 1e-10 * rng.standard_normal(shape)
    expected = u + C.normal(c)
    C.add_normal_point_loads(u, nodes, values)
    assert np.allclose(u, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    assert C.direct_limit >= 1


class _SpectralOnly:
    """A skin known only by its surface_compliance (as a layered skin is)."""

    def __init__(self, skin):
        self.skin = skin

    def __repr__(self) -> str:
        return f"_SpectralOnly({self.skin!r})"

    def surface_compliance(self, kx, ky=None):
        return self.skin.surface_compliance(kx, ky)


@pytest.mark.parametrize("shape", [(12,), (10, 12)])
def test_isolated_grid_of_a_spectral_only_skin_is_the_padded_periodic_grid_cropped(shape, rng):
    """The fallback's aperiodic convolution equals the periodic operator on the grid PADDED_PERIODS times
    the zero-padded one, on tractions zero outside the grid, cropped; and it stays symmetric (Betti)."""
    from tactilab.forward.contact.compliance import PADDED_PERIODS

    skin = _SpectralOnly(HalfSpace(E, 0.3))
    iso = ContactCompliance(skin, shape, 1e-4, False)
    assert iso.padded_periodic
    big_shape = tuple(2 * PADDED_PERIODS * n for n in shape)
    big = ContactCompliance(skin, big_shape, 1e-4, True)
    where = tuple(slice(0, n) for n in shape)
    tractions = [rng.standard_normal(shape) for _ in range(len(shape) + 1)]
    padded = []
    for t in tractions:
        b = np.zeros(big_shape)
        b[where] = t
        padded.append(b)
    got = iso.apply(*tractions)
    ref = big.apply(*padded)
    for g, r in zip(got, ref):
        if g is not None:
            assert np.allclose(g, r[where], rtol=0, atol=1e-12 * np.abs(r).max())
    other = [rng.standard_normal(shape) for _ in range(len(shape) + 1)]
    lhs = sum(float(np.sum(u * t)) for u, t in zip(iso.apply(*tractions), other) if u is not None)
    rhs = sum(float(np.sum(u * t)) for u, t in zip(iso.apply(*other), tractions) if u is not None)
    assert lhs == pytest.approx(rhs, rel=1e-10)


@pytest.mark.parametrize("periodic", [True, False])
@pytest.mark.parametrize("shape", [(24, 32), (17, 10), (31,)])
def test_fast_products_equal_the_padded_convolution(shape, periodic, rng):
    """The pruned (isolated) and into-buffer (periodic) products equal the textbook transform:
    rfftn of the (zero-padded) grid, times the block's spectrum, irfftn, cropped to the grid."""
    if periodic and any(n % 2 for n in shape):
        shape = tuple(n + n % 2 for n in shape)
    spacing = (1e-5, 2e-5)[: len(shape)] if len(shape) == 2 else 1e-5
    comp = ContactCompliance(HalfSpace(E=1e6, nu=0.4), shape, spacing, periodic)
    axes = tuple(range(-len(shape), 0))
    p, qx = rng.random(shape), rng.standard_normal(shape)
    crop = tuple(slice(0, n) for n in shape)

    def reference(value, row, col):
        from scipy import fft as sfft

        spec = sfft.rfftn(value, s=comp.fft_shape, axes=axes) * comp.spectrum(row, col)
        return sfft.irfftn(spec, s=comp.fft_shape, axes=axes)[crop]

    uz = reference(p, "uz", "p")
    assert np.allclose(comp.normal(p), uz, rtol=0, atol=1e-13 * np.abs(uz).max())
    out = np.full(shape, np.nan)
    assert comp.normal(p, out=out) is out and np.allclose(out, uz, rtol=0, atol=1e-13 * np.abs(uz).max())
    ux = reference(qx, "ux", "qx")
    assert np.allclose(comp.tangential(qx)[0] if len(shape) == 1 else comp.tangential(qx, None)[0], ux,
                       rtol=0, atol=1e-13 * np.abs(ux).max())
    # the preconditioner into a given array equals its fresh result; repeated calls reuse the work spectrum
    fresh = comp.stiffness(uz)
    again = np.empty(shape)
    assert comp.stiffness(uz, out=again) is again and np.array_equal(again, fresh)
    assert np.array_equal(comp.normal(p), comp.normal(p))


@pytest.mark.parametrize("shape", [(24, 32), (17, 10)])
def test_padded_products_reuse_their_buffers_and_fall_back_to_scipy(shape, rng, monkeypatch):
    """An isolated 2-D grid's normal product runs through kept per-thread work arrays: products of other
    tractions after it (the padding zeroed again each time) equal the textbook zero-padded transform,
    and so does the path through scipy.fft's public functions (where its transform binding is absent)."""
    from scipy import fft as sfft

    from tactilab.forward.halfspace import _hotpath

    comp = ContactCompliance(HalfSpace(E=1e6, nu=0.4), shape, (1e-5, 2e-5), False)

    def reference(value):
        spec = sfft.rfftn(value, s=comp.fft_shape) * comp.spectrum("uz", "p")
        return sfft.irfftn(spec, s=comp.fft_shape)[: shape[0], : shape[1]]

    for _ in range(3):
        p = rng.standard_normal(shape)
        uz = reference(p)
        np.testing.assert_allclose(comp.normal(p), uz, rtol=0, atol=1e-13 * np.abs(uz).max())
    monkeypatch.setattr(_hotpath, "_RAW", None)
    np.testing.assert_allclose(comp.normal(p), uz, rtol=0, atol=1e-13 * np.abs(uz).max())

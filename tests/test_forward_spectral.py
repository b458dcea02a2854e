"""Oracles for the periodic spectral solver (docs/theory.md sections 2, 3 and 5)."""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.forward.halfspace.facade import HalfSpace
from tactilab.forward.halfspace.loads import SurfaceLoad
from tactilab.forward.halfspace import angular_wavenumbers
from tactilab.forward.halfspace.spectral import VOIGT, periodic_stress, pressure_from_deflection, transfer

I6 = np.eye(6)


def _grid(n, h):
    return (np.arange(n) - n // 2) * h


def _plane_wave_expected(x, y, z, kvec, P, Q, nu):
    """Stress of p = P cos(k.r), q = Q cos(k.r) from the 1-D closed forms of docs/theory.md s3
    (plus antiplane shear) in the wave's frame, rotated to (x, y). Shape (6, *x.shape)."""
    k = np.hypot(*kvec)
    c, s = kvec / k
    xp = c * x + s * y
    e = np.exp(-k * z)
    cos, sin = np.cos(k * xp), np.sin(k * xp)
    qpar, qperp = c * Q[0] + s * Q[1], -s * Q[0] + c * Q[1]
    szz = -P * (1 + k * z) * e * cos - qpar * k * z * e * sin
    sxx_ = -P * (1 - k * z) * e * cos - qpar * (2 - k * z) * e * sin
    sxz_ = -P * k * z * e * sin - qpar * (1 - k * z) * e * cos
    syy_ = nu * (sxx_ + szz)
    syz_ = -qperp * e * cos
    sxy_ = -qperp * e * sin
    local = np.zeros((3, 3) + np.shape(x))
    local[0, 0], local[1, 1], local[2, 2] = sxx_, syy_, szz
    local[0, 1] = local[1, 0] = sxy_
    local[0, 2] = local[2, 0] = sxz_
    local[1, 2] = local[2, 1] = syz_
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    glob = np.einsum("ia,jb,ab...->ij...", R, R, local)
    pairs = [(0, 0), (1, 1), (2, 2), (1, 2), (2, 0), (0, 1)]
    return np.array([glob[i, j] for i, j in pairs])


@pytest.mark.parametrize("nu", [0.5, 0.3, 0.4999999, -0.5])
def test_oblique_plane_waves_match_rotated_closed_forms(rng, nu):
    ny, nx, h = 24, 32, 1e-4
    x, y = np.meshgrid(_grid(nx, h), _grid(ny, h))
    for _ in range(3):
        mx, my = rng.integers(1, 6), rng.integers(-5, 6)
        kvec = 2 * np.pi * np.array([mx / (nx * h), my / (ny * h)])
        P, Q = float(rng.normal()) * 1e3, rng.normal(size=2) * 1e3
        phase = kvec[0] * x + kvec[1] * y
        load = SurfaceLoad(p=P * np.cos(phase), qx=Q[0] * np.cos(phase), qy=Q[1] * np.cos(phase),
                           spacing=h, periodic=True)
        z = rng.uniform(0.05, 4) / np.hypot(*kvec)  # k z <= 4: the field stays above roundoff
        got = periodic_stress(load, [z], nu, I6)[0]
        want = _plane_wave_expected(x, y, z, kvec, P, Q, nu)
        scale = np.abs(want).max()
        assert np.abs(got - want).max() / scale < 1e-12


def test_one_dimensional_sinusoids_match_theory_section_3(rng):
    n, h = 64, 5e-5
    x = _grid(n, h)
    for _ in range(5):
        k = 2 * np.pi * rng.integers(1, 20) / (n * h)
        z = rng.uniform(0.05, 2) * 1e-3
        e = np.exp(-k * z)
        P, Q = rng.normal(size=2) * 1e4
        s = periodic_stress(SurfaceLoad(p=P * np.cos(k * x), spacing=h, periodic=True), [z], 0.5, I6)[0]
        ref = {"zz": -P * (1 + k * z) * e * np.cos(k * x), "xx": -P * (1 - k * z) * e * np.cos(k * x),
               "zx": -P * k * z * e * np.sin(k * x)}
        for comp, r in ref.items():
            assert np.abs(s[VOIGT.index(comp)] - r).max() < 1e-12 * abs(P)
        s = periodic_stress(SurfaceLoad(qx=Q * np.cos(k * x), spacing=h, periodic=True), [z], 0.5, I6)[0]
        ref = {"zx": -Q * (1 - k * z) * e * np.cos(k * x), "zz": -Q * k * z * e * np.sin(k * x),
               "xx": -Q * (2 - k * z) * e * np.sin(k * x)}
        for comp, r in ref.items():
            assert np.abs(s[VOIGT.index(comp)] - r).max() < 1e-12 * abs(Q)


def test_zero_mode_carries_the_total_load():
    """rho = 0 limits of docs/theory.md s2: 3-D sigma_xx = sigma_yy = -(1 + 2 nu) P / 2; 1-D sigma_xx = -P."""
    P, Qx, Qy, nu = 2e3, 300.0, -150.0, 0.3
    load = SurfaceLoad(p=np.full((8, 8), P), qx=np.full((8, 8), Qx), qy=np.full((8, 8), Qy), spacing=1e-4,
                       periodic=True)
    s = periodic_stress(load, [1e-3, 5e-2], nu, I6)
    want = [-(1 + 2 * nu) * P / 2, -(1 + 2 * nu) * P / 2, -P, -Qy, -Qx, 0.0]
    np.testing.assert_allclose(s[..., 3, 3], np.array([want, want]), atol=1e-9 * P)
    s1 = periodic_stress(SurfaceLoad(p=np.full(8, P), spacing=1e-4, periodic=True), [1e-3], nu, I6)[0]
    np.testing.assert_allclose(s1[:, 0], [-P, -2 * nu * P, -P, 0, 0, 0], atol=1e-9 * P)


def test_surface_boundary_conditions_are_met():
    """sigma_zz(z -> 0) = -p, sigma_zx = -qx, sigma_yz = -qy for a smooth load."""
    n, h = 64, 1e-4
    x, y = np.meshgrid(_grid(n, h), _grid(n, h))
    g = np.exp(-(x**2 + y**2) / (2 * (6 * h) ** 2))
    load = SurfaceLoad(p=1e3 * g, qx=300 * g, qy=-200 * g, spacing=h, periodic=True)
    s = periodic_stress(load, [1e-13], 0.5, I6)[0]  # the q terms of sigma_zz scale with rho z
    np.testing.assert_allclose(s[2], -load.p, atol=1e-4)
    np.testing.assert_allclose(s[4], -load.qx, atol=1e-4)
    np.testing.assert_allclose(s[3], -load.qy, atol=1e-4)


def _spectral_derivative(f, h, axis):
    n = f.shape[axis]
    k = 2 * np.pi * np.fft.fftfreq(n, h)
    shape = [1] * f.ndim
    shape[axis] = n
    return np.fft.ifft(1j * k.reshape(shape) * np.fft.fft(f, axis=axis), axis=axis).real


@pytest.mark.parametrize("nu", [0.5, 0.25])
def test_equilibrium_and_compatibility(nu):
    """div sigma = 0 (d/dx, d/dy spectrally, d/dz by central differences) and the
    Saint-Venant compatibility of the tensor strain in the x-z plane."""
    n, h, z, dz = 48, 1e-4, 1e-3, 1e-6
    x, y = np.meshgrid(_grid(n, h), _grid(n, h))
    g = np.exp(-(x**2 + 2 * y**2) / (2 * (5 * h) ** 2))
    load = SurfaceLoad(p=1e3 * g, qx=400 * np.roll(g, 3, 1), qy=-250 * g, spacing=h, periodic=True)
    s = periodic_stress(load, [z - dz, z, z + dz], nu, I6)
    dzs = (s[2] - s[0]) / (2 * dz)
    mid = s[1]
    sxx, syy, szz, syz, szx, sxy = mid
    d = lambda f, ax: _spectral_derivative(f, h, ax)  # noqa: E731
    res = [d(sxx, 1) + d(sxy, 0) + dzs[4], d(sxy, 1) + d(syy, 0) + dzs[3], d(szx, 1) + d(syz, 0) + dzs[2]]
    scale = np.abs(mid).max() / (5 * h)
    for r in res:
        assert np.abs(r).max() < 1e-6 * scale
    hs = HalfSpace(1e5, nu)
    eps = hs.strain(load, [z - dz, z, z + dz], method="spectral").data["strain"].values
    exx, ezz, ezx = eps[1, 0], eps[1, 2], eps[1, 4]
    d2z = lambda k: (eps[2, k] - 2 * eps[1, k] + eps[0, k]) / dz**2  # noqa: E731
    dz1 = lambda k: (eps[2, k] - eps[0, k]) / (2 * dz)  # noqa: E731
    lhs = d2z(0) + d(d(ezz, 1), 1)
    rhs = 2 * d(dz1(4), 1)
    assert np.abs(lhs - rhs).max() < 1e-4 * np.abs(rhs).max()
    assert np.isfinite([exx, ezx]).all()


def test_superposition_and_mirror_symmetry(rng):
    n, h = 32, 1e-4
    a, b = rng.normal(size=(2, n, n)) * 1e3
    la, lb = SurfaceLoad(p=a, spacing=h, periodic=True), SurfaceLoad(p=b, spacing=h, periodic=True)
    sab = periodic_stress(SurfaceLoad(p=a + b, spacing=h, periodic=True), [5e-4], 0.5, I6)
    np.testing.assert_allclose(sab, periodic_stress(la, [5e-4], 0.5, I6) + periodic_stress(lb, [5e-4], 0.5, I6),
                               atol=1e-9 * np.abs(sab).max())
    # p mirrored in x (about node n//2): sigma_xx, zz even; sigma_zx odd.
    sym = a + a[:, (-np.arange(n)) % n]  # even about index 0 ...
    sym = np.roll(sym, n // 2, axis=1)   # ... moved to the centre node
    s = periodic_stress(SurfaceLoad(p=sym, spacing=h, periodic=True), [4e-4], 0.5, I6)[0]
    mirror = lambda f: np.roll(np.roll(f, -(n // 2), 1)[:, (-np.arange(n)) % n], n // 2, 1)  # noqa: E731
    np.testing.assert_allclose(mirror(s[0]), s[0], atol=1e-9 * np.abs(s).max())
    np.testing.assert_allclose(mirror(s[4]), -s[4], atol=1e-9 * np.abs(s).max())


def test_extremes_no_overflow_and_linearity(rng):
    n, h = 64, 1e-4
    load = SurfaceLoad(p=rng.normal(size=(n, n)), qx=rng.normal(size=(n, n)), spacing=h, periodic=True)
    kmax = np.pi / h
    deep = 1e4 / kmax  # rho * Z up to 1e4 at the Nyquist wavenumber
    s = periodic_stress(load, [deep, 1e3 * deep], 0.5, I6)
    assert np.isfinite(s).all()
    base = periodic_stress(load, [3e-4], 0.5, I6)
    for amp in [1e-9, 1e-3, 1e3, 1e9]:
        scaled = periodic_stress(load.scaled(amp), [3e-4], 0.5, I6)
        assert np.abs(scaled / amp - base).max() <= 1e-12 * np.abs(base).max()
    zero = periodic_stress(SurfaceLoad(p=np.zeros((8, 8)), spacing=h, periodic=True), [1e-3], 0.5, I6)
    assert not zero.any()


def test_nu_half_is_the_continuous_limit(rng):
    load = SurfaceLoad(p=rng.normal(size=(16, 16)), qy=rng.normal(size=(16, 16)), spacing=1e-4, periodic=True)
    a = HalfSpace(1e6, 0.5).strain(load, 5e-4).data["strain"].values
    b = HalfSpace(1e6, 0.4999999).strain(load, 5e-4).data["strain"].values
    assert np.abs(a - b).max() < 1e-6 * np.abs(a).max()


def test_incompressible_strain_has_no_volume_change(rng):
    load = SurfaceLoad(p=rng.normal(size=(16, 16)), qx=rng.normal(size=(16, 16)), spacing=1e-4, periodic=True)
    ds = HalfSpace(2e5, 0.5).strain(load, [3e-4, 1e-3], invariants=True).data
    assert np.abs(ds["volumetric"]).max() < 1e-12 * np.abs(ds["strain"]).max()


def test_sliding_sinusoid_strain_of_theory_4a():
    """H(x) = A sin(2 pi x / p) pressed frictionless into an incompressible skin gives
    eps = C [sin, 0, -sin, 0, 2 cos (engineering), 0], C = 4 pi^2 A Z / p^2 e^{-2 pi Z / p},
    independent of E."""
    n, pitch, A, Z = 64, 2e-3, 20e-6, 1e-3
    h = pitch / n * 4
    x = _grid(n, h)
    H = A * np.sin(2 * np.pi * x / pitch)
    C = 4 * np.pi**2 * A * Z / pitch**2 * np.exp(-2 * np.pi * Z / pitch)
    arg = 2 * np.pi * x / pitch
    for E in (1e5, 3e6):
        hs = HalfSpace(E, 0.5)
        eps = hs.strain(hs.pressure_from_deflection(H, h), Z).data["strain"].values[0]
        np.testing.assert_allclose(eps[0], C * np.sin(arg), atol=1e-12 * C)
        np.testing.assert_allclose(eps[2], -C * np.sin(arg), atol=1e-12 * C)
        np.testing.assert_allclose(2 * eps[4], 2 * C * np.cos(arg), atol=1e-12 * C)
        np.testing.assert_allclose(eps[1], 0, atol=1e-12 * C)


def test_transfer_matches_the_solver_and_validates(rng):
    n, h, z = 32, 1e-4, 4e-4
    load = SurfaceLoad(qx=rng.normal(size=n), spacing=h, periodic=True)
    (xi,) = angular_wavenumbers((n,), h, half=True)
    T = transfer(xi, None, z, 0.5, "qx", ("zz", "zx"))
    spec = np.fft.rfft(load.qx)
    T[:, -1] = T[:, -1].real  # Nyquist: the solver keeps the real (mirror-averaged) part
    want = np.fft.irfft(T * spec, n)
    got = periodic_stress(load, [z], 0.5, np.eye(6)[[2, 4]])[0]
    np.testing.assert_allclose(got, want, atol=1e-12 * np.abs(want).max())
    with pytest.raises(ValueError, match="load_component"):
        transfer(xi, None, z, 0.5, "px")
    with pytest.raises(ValueError, match="depth"):
        transfer(xi, None, -1.0, 0.5, "p")
    with pytest.raises(ValueError, match="unknown component"):
        transfer(xi, None, z, 0.5, "p", ("zzz",))


def test_pressure_from_deflection_validates():
    with pytest.raises(ValueError, match="deflection"):
        pressure_from_deflection(np.array([0.0, np.nan]), 1e-4, 1e5, 0.5)


def test_angular_wavenumbers_are_x_first_in_rad_per_m():
    # an anisotropic grid: nx = 8 nodes at dx = 1 mm, ny = 4 nodes at dy = 3 mm
    xi, eta = angular_wavenumbers((4, 8), (1e-3, 3e-3))
    assert xi.shape == (1, 8) and eta.shape == (4, 1)
    np.testing.assert_allclose(xi[0, 1], 2 * np.pi / (8 * 1e-3))   # fundamental along x, rad/m
    np.testing.assert_allclose(eta[1, 0], 2 * np.pi / (4 * 3e-3))  # fundamental along y, rad/m
    np.testing.assert_allclose(xi[0, 4], -np.pi / 1e-3)            # fftfreq order: Nyquist negative
    half_xi, half_eta = angular_wavenumbers((4, 8), (1e-3, 3e-3), half=True)
    np.testing.assert_allclose(half_xi[0], np.abs(xi[0, :5]))
    np.testing.assert_array_equal(half_eta, eta)
    (x_only,) = angular_wavenumbers((8,), 1e-3)
    np.testing.assert_array_equal(x_only, xi[0])
    # the wavenumbers diagonalise the grid's shift along x, not y
    f = np.cos(2 * np.pi * np.arange(8) * 1e-3 / 8e-3)[None, :] * np.ones((4, 1))
    spec = np.fft.fft2(f)
    peak = np.unravel_index(np.argmax(np.abs(spec)), spec.shape)
    assert np.hypot(xi[0, peak[1]], eta[peak[0], 0]) == pytest.approx(2 * np.pi / 8e-3)
    assert eta[peak[0], 0] == 0.0


def test_angular_wavenumbers_validation():
    with pytest.raises(ValueError, match=r"shape: expected a 1-D \(nx,\) or 2-D"):
        angular_wavenumbers((2, 2, 2), 1e-3)
    with pytest.raises(ValueError, match=r"spacing: grid spacing must be finite and > 0 m, got \(0.001, -0.001\)"):
        angular_wavenumbers((4, 4), (1e-3, -1e-3))


def test_inversion_and_solver_share_one_wavenumber_helper():
    from tactilab.inversion import operators, penalties

    assert operators.angular_wavenumbers is angular_wavenumbers
    assert penalties.angular_wavenumbers is angular_wavenumbers
    assert "def angular_wavenumbers" not in open(operators.__file__).read()


@pytest.mark.parametrize("shape", [(96,), (24, 32)])
def test_pressure_from_deflection_is_periodic_and_matches_the_inversion_model(rng, shape):
    """Regression: the load came back marked isolated, so the facade solved it as an isolated
    load (6 % off the inversion's model) while reporting an error estimate of ~1e-14."""
    from tactilab.inversion.operators import halfspace_fourier_operator, rigid_surface_height_operator

    E, nu, h, depth = 2e5, 0.45, 1e-4, 4e-4
    spacing = h if len(shape) == 1 else (h, 1.3 * h)
    # a random smooth periodic relief, 20 um rms
    spec = np.fft.fftn(rng.normal(size=shape))
    (xi, *rest) = angular_wavenumbers(shape, spacing)
    rho = np.hypot(xi, rest[0]) if rest else np.abs(xi)
    deflection = np.fft.ifftn(spec * np.exp(-(rho * 2e-4) ** 2)).real
    deflection *= 20e-6 / deflection.std()
    load = pressure_from_deflection(deflection, spacing, E, nu)
    assert load.periodic
    assert HalfSpace(E, nu).pressure_from_deflection(deflection, spacing).periodic
    result = HalfSpace(E, nu).stress(load, depth, components=("zz",))
    assert result.method == "spectral"
    got = result.data["stress"].values[0, 0]
    # the inversion's model of the same physics: height -> sigma_zz at depth
    if len(shape) == 1:
        want = rigid_surface_height_operator(shape[0], h, depth, E, nu) @ deflection
    else:
        p_to_szz = halfspace_fourier_operator(shape, spacing, depth, nu).multiplier
        want = np.fft.ifftn(np.fft.fftn(deflection) * p_to_szz * E * rho / (2 * (1 - nu**2))).real
    true_error = np.abs(got - want.reshape(got.shape)).max() / np.abs(got).max()
    assert true_error <= result.error_estimate


# -- the hot path (forward/halfspace/_hotpath.py): caches, transforms into place, threads ----------
def _random_periodic_load(rng, shape=(24, 32), h=1e-4):
    return SurfaceLoad(p=rng.normal(size=shape) * 1e3, qx=rng.normal(size=shape) * 1e3,
                       qy=rng.normal(size=shape) * 1e3, spacing=h, periodic=True)


def test_cached_transfer_tables_give_bitwise_the_fresh_result(rng, monkeypatch, kernel_path):
    from tactilab.forward.halfspace import _hotpath
    from tactilab.forward.halfspace.spectral import clear_transfer_cache

    load = _random_periodic_load(rng)
    weights = np.vstack([I6, rng.normal(size=(2, 6))])  # stress rows and mixed (strain-like) rows
    clear_transfer_cache()
    miss = periodic_stress(load, [3e-4, 1e-3], 0.3, weights)
    hit = periodic_stress(load, [3e-4, 1e-3], 0.3, weights)
    monkeypatch.setattr(_hotpath, "TRANSFER_CACHE_BYTES", 0)  # too small: tables built per call
    uncached = periodic_stress(load, [3e-4, 1e-3], 0.3, weights)
    assert np.array_equal(miss, hit) and np.array_equal(miss, uncached)


def test_transfer_cache_stays_within_its_budget_over_a_depth_sweep(rng, monkeypatch, kernel_path):
    from tactilab.forward.halfspace import _hotpath

    load = _random_periodic_load(rng)
    # bytes of the 18 tables of one depth: complex on the NumPy path, real for the compiled kernel
    one_depth = 6 * 3 * 24 * (32 // 2 + 1) * (8 if kernel_path == "compiled" else 16)
    monkeypatch.setattr(_hotpath, "TRANSFER_CACHE_BYTES", 3 * one_depth)
    _hotpath.clear_transfer_cache()
    depths = np.linspace(1e-4, 2e-3, 10)
    for z in depths:
        periodic_stress(load, [z], 0.5, I6)
    held = sum(_hotpath._table_bytes(entry) for entry in _hotpath._TRANSFER_CACHE.values())
    assert 0 < held <= 3 * one_depth and len(_hotpath._TRANSFER_CACHE) == 3
    # the latest depths are the ones kept (least recently used out first)
    assert [key[2] for key in _hotpath._TRANSFER_CACHE] == [float(z) for z in depths[-3:]]


def test_fft_threads_and_the_public_fft_fallback_give_bitwise_identical_results(rng, monkeypatch):
    import scipy.fft as sfft

    from tactilab.forward.halfspace import _hotpath

    for shape in [(24, 32), (25, 33), (64,)]:
        load = _random_periodic_load(rng, shape)
        one = periodic_stress(load, [5e-4], 0.4, I6, workers=1)
        assert np.array_equal(one, periodic_stress(load, [5e-4], 0.4, I6, workers=2))
        assert np.array_equal(one, periodic_stress(load, [5e-4], 0.4, I6, workers=-1))
        with sfft.set_workers(2):
            assert np.array_equal(one, periodic_stress(load, [5e-4], 0.4, I6))
        with monkeypatch.context() as m:
            m.setattr(_hotpath, "_RAW", None)  # scipy's public rfftn/irfftn and a copy
            assert np.array_equal(one, periodic_stress(load, [5e-4], 0.4, I6))


def test_bad_fft_thread_count_is_refused(rng):
    load = _random_periodic_load(rng)
    with pytest.raises(ValueError, match=r"workers: must be a thread count >= 1, or negative .* got 0"):
        periodic_stress(load, [5e-4], 0.4, I6, workers=0)


def test_successive_results_never_share_the_reused_work_buffers(rng):
    a, b = _random_periodic_load(rng), _random_periodic_load(rng)
    first = periodic_stress(a, [5e-4], 0.5, I6)
    kept = first.copy()
    second = periodic_stress(b, [5e-4], 0.5, I6)
    assert np.array_equal(first, kept) and not np.shares_memory(first, second)
    assert np.array_equal(periodic_stress(a, [5e-4], 0.5, I6), kept)


def test_labelled_results_are_independent_and_their_shared_coordinates_read_only(rng):
    load = _random_periodic_load(rng)
    hs = HalfSpace(1e6, 0.5)
    pts = np.array([[1e-4, 2e-4], [3e-4, -4e-4], [0.0, 5e-4]])
    one = hs.stress(load, [5e-4], points=pts, method="spectral")
    pts[0, 0] = 9.0  # the caller reuses its array: earlier and later results keep their coordinates
    two = hs.stress(load.scaled(2.0), [5e-4], points=pts, method="spectral")
    assert one.data.x.values[0] == 1e-4 and two.data.x.values[0] == 9.0
    three = hs.stress(load.scaled(2.0), [5e-4], method="spectral")
    four = hs.stress(load, [5e-4], method="spectral")
    assert np.allclose(three.data["stress"].values, 2 * four.data["stress"].values, rtol=1e-12, atol=1e-9)
    assert not np.shares_memory(three.data["stress"].values, four.data["stress"].values)
    three.data["stress"].attrs["note"] = "mine"
    assert "note" not in four.data["stress"].attrs
    with pytest.raises(ValueError, match="read-only"):
        four.data.x.values[0] = 1.0


def test_results_are_labelled_on_first_access_with_the_arguments_of_the_call(rng):
    """The Dataset is built lazily; depths and points the caller changes afterwards do not leak in."""
    load = _random_periodic_load(rng)
    hs = HalfSpace(1e6, 0.5)
    depths, pts = np.array([5e-4, 1e-3]), np.array([[1e-4, 2e-4], [3e-4, -4e-4]])
    res = hs.stress(load, depths, points=pts, method="spectral")
    grid = hs.stress(load, depths, method="spectral")
    depths[0], pts[0, 0] = 7.0, 9.0
    assert "data" not in vars(res)  # not labelled yet
    assert res.data.depth.values.tolist() == [5e-4, 1e-3] and res.data.x.values[0] == 1e-4
    assert res.data is res.data  # built once, then kept
    direct = periodic_stress(load, [5e-4, 1e-3], 0.5, I6)
    assert np.array_equal(grid.data["stress"].values, direct)
    assert grid.data.attrs["method"] == "spectral" and grid.data.attrs["error_estimate"] == grid.error_estimate


def test_varies_in_y_reads_past_equal_leading_rows():
    rows = np.ones((6, 8))
    assert not SurfaceLoad(p=rows, spacing=1e-4).varies_in_y()
    rows[4, 3] = 2.0  # rows 0 and 1 agree; a later row differs
    assert SurfaceLoad(p=rows, spacing=1e-4).varies_in_y()
    assert SurfaceLoad(p=np.ones((6, 8)), qy=rows, spacing=1e-4).varies_in_y()
    assert SurfaceLoad(p=np.arange(48.0).reshape(6, 8), spacing=1e-4).varies_in_y()
    assert not SurfaceLoad(p=np.ones((1, 8)), spacing=1e-4).varies_in_y()

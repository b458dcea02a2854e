"""Oracles for the zero-padded convolution with the sampled kernel (method 3, DC-FFT).

References: the direct node sum of the closed-form kernels (the same sum computed another
way), the multipole expansion of an isolated smooth load far away, linearity, and a
refined-grid reference for the sampling error estimate.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from tactilab.forward.halfspace.dcfft import dcfft_error_estimate, dcfft_stress, padded_shape
from tactilab.forward.halfspace.kernels import COMPONENTS, direct_stress, point_load_stress
from tactilab.forward.halfspace.loads import SurfaceLoad


def _nodes(load: SurfaceLoad, depth: float) -> np.ndarray:
    if load.ndim == 1:
        return np.column_stack([load.x, np.full(load.shape[0], depth)])
    yy, xx = np.meshgrid(load.y, load.x, indexing="ij")
    return np.column_stack([xx.ravel(), yy.ravel(), np.full(xx.size, depth)])


def _gaussian_load(ndim, spacing, half_width, width, amps, centre=(0.0, 0.0), refine=1):
    """Gaussian bump of standard deviation ``width`` (m), peak ``amps`` = {name: Pa}."""
    h = spacing / refine
    n = 2 * int(round(half_width / spacing)) * refine + 1
    x = (np.arange(n) - n // 2) * h
    if ndim == 1:
        r2 = (x - centre[0]) ** 2
    else:
        xx, yy = np.meshgrid(x, x)
        r2 = (xx - centre[0]) ** 2 + (yy - centre[1]) ** 2
    g = np.exp(-r2 / (2 * width**2))
    return SurfaceLoad(**{k: a * g for k, a in amps.items()}, spacing=(h,) * ndim)


# ----------------------------------------------------------------------------- exactness
@pytest.mark.parametrize("shape, spacing", [((6, 9), (1e-4, 1.5e-4)), ((13,), (1e-4,)), ((1, 5), (1e-4, 1e-4)),
                                            ((4, 1), (2e-4, 1e-4)), ((1,), (1e-4,))])
def test_dcfft_equals_direct_node_sum(rng, shape, spacing):
    """Same sum two ways, including depths below the spacing and loads touching the edges."""
    p, qx, qy = rng.normal(size=(3,) + shape) * 1e4
    load = SurfaceLoad(p=p, qx=qx, qy=qy, spacing=spacing)
    assert all(m % 2 == 0 and m >= 2 * n - 1 for m, n in zip(padded_shape(shape), shape))
    depths = [0.3e-4, 2e-4, 1e-3]
    nu = rng.uniform(-0.5, 0.5)
    comps = tuple(rng.permutation(COMPONENTS)[:4])
    got = dcfft_stress(load, depths, nu=nu, components=comps)
    assert got.shape == (3, 4) + shape
    for d, depth in enumerate(depths):
        ref = direct_stress(load, _nodes(load, depth), nu=nu, components=comps).T.reshape((4,) + shape)
        np.testing.assert_allclose(got[d], ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_dcfft_isolated_gaussian_matches_point_load_far_away():
    """Far from a smooth bump, the stress is that of a point force of the same total force,
    plus the second-moment correction (w^2/2) laplacian_s K; the remainder is O((w/R)^4)."""
    h, width, depth = 1e-4, 1.5e-4, 4e-3
    load = _gaussian_load(2, h, 6.4e-3, width, {"p": 2e4, "qx": -7e3})
    got = dcfft_stress(load, [depth], nu=0.45)[0]
    area = h * h
    force_z, force_x = load.p.sum() * area, load.qx.sum() * area
    m2 = (load.p * load.x[None, :] ** 2).sum() * area / force_z  # discrete second moment per axis

    def kernel(x, y):
        return point_load_stress(x, y, depth, force_x, 0.0, force_z, nu=0.45)

    yy, xx = np.meshgrid(load.y, load.x, indexing="ij")
    far = (np.hypot(xx, yy) > 3e-3) & (np.abs(xx) < 5e-3) & (np.abs(yy) < 5e-3)
    x, y = xx[far], yy[far]
    step = 1e-4
    lap = (kernel(x + step, y) + kernel(x - step, y) + kernel(x, y + step) + kernel(x, y - step) - 4 * kernel(x, y)) / step**2
    approx = kernel(x, y) + 0.5 * m2 * lap
    scale = np.abs(got).max()
    err_point = np.abs(np.moveaxis(got, 0, -1)[far] - kernel(x, y)).max() / scale
    err_corrected = np.abs(np.moveaxis(got, 0, -1)[far] - approx).max() / scale
    assert err_corrected < 2e-5  # (w/R)^4 ~ 2e-5 at R = 3 mm; the corrected form is far closer
    assert err_corrected < 0.05 * err_point


def test_dcfft_linearity_over_eighteen_decades(rng):
    load = SurfaceLoad(p=rng.normal(size=(5, 7)), qx=rng.normal(size=(5, 7)), spacing=2e-4)
    base = dcfft_stress(load, [3e-4, 1e-3], nu=0.5)
    for factor in (1e-9, 1e-3, 1e3, 1e9):
        scaled = dcfft_stress(load.scaled(factor), [3e-4, 1e-3], nu=0.5)
        np.testing.assert_allclose(scaled, factor * base, rtol=1e-12, atol=1e-12 * factor * np.abs(base).max())
    other = SurfaceLoad(qy=rng.normal(size=(5, 7)), spacing=2e-4)
    both = SurfaceLoad(p=load.p, qx=load.qx, qy=other.qy, spacing=2e-4)
    np.testing.assert_allclose(dcfft_stress(both, [1e-3]), dcfft_stress(load, [1e-3]) + dcfft_stress(other, [1e-3]),
                               atol=1e-12 * np.abs(base).max())


def test_dcfft_zero_loads_and_inactive_components():
    zero = SurfaceLoad(p=np.zeros((4, 6)), qx=np.zeros((4, 6)), spacing=1e-4)
    out = dcfft_stress(zero, [1e-4, 2e-4], components=("zz", "xy"))
    assert out.shape == (2, 2, 4, 6) and not out.any()
    # plane strain: an in-plane load drives no antiplane stress, an antiplane one nothing else
    line = SurfaceLoad(p=np.ones(8), spacing=1e-4)
    assert not dcfft_stress(line, [2e-4], components=("yz", "xy")).any()
    anti = dcfft_stress(SurfaceLoad(qy=np.ones(8), spacing=1e-4), [2e-4])
    assert not anti[0, [0, 1, 2, 4]].any() and anti[0, [3, 5]].any()


def test_dcfft_extreme_depths_stay_finite(rng):
    """Depth from 1e-8 to 1e7 grid spacings: finite values, and an estimate that flags the shallow end."""
    load = SurfaceLoad(p=rng.normal(size=(6, 6)), qx=rng.normal(size=(6, 6)), spacing=1e-4)
    out = dcfft_stress(load, [1e-12, 1e-8, 1e-4, 1.0, 1e3])
    assert np.all(np.isfinite(out))
    # at the shallowest depth the node under each force sees -3 F / (2 pi Z^2) (Boussinesq)
    expected = -3 * load.p * 1e-8 / (2 * np.pi * 1e-24)
    np.testing.assert_allclose(out[0, 2], expected, rtol=1e-6)
    assert dcfft_error_estimate(load.spacing, 1e-12) > 1e3
    assert dcfft_error_estimate(load.spacing, 1e3) == pytest.approx(30 * np.finfo(float).eps)
    line = SurfaceLoad(p=rng.normal(size=7), qy=rng.normal(size=7), spacing=1e-4)
    assert np.all(np.isfinite(dcfft_stress(line, [1e-12, 1e3])))


def test_dcfft_float32(rng):
    load = SurfaceLoad(p=rng.normal(size=(16, 20)) * 1e4, qx=rng.normal(size=(16, 20)) * 1e4, spacing=1e-4)
    ref = dcfft_stress(load, [2e-4, 1e-3])
    got = dcfft_stress(load, [2e-4, 1e-3], dtype=np.float32)
    assert got.dtype == np.float32
    err = np.abs(got - ref).max() / np.abs(ref).max()
    assert err < 2e-6  # measured 1.3e-7; single precision eps is 1.2e-7


def test_dcfft_peak_memory_stays_near_the_reused_buffers():
    """Output + load spectra + about five padded arrays, independent of depths x components.

    Reused: one kernel buffer, its spectrum, one accumulator, one inverse transform; at this
    small size the kernel formula's temporaries on the (n x n) quadrant add about one more.
    """
    n = 96
    g = np.ones((n, n))
    load = SurfaceLoad(p=g, qx=g, qy=g, spacing=1e-4)
    padded = padded_shape(load.shape)
    spectrum_bytes = padded[0] * (padded[1] // 2 + 1) * 16
    tracemalloc.start()
    try:
        out = dcfft_stress(load, [1e-4, 3e-4, 1e-3], nu=0.5)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < out.nbytes + (3 + 5) * spectrum_bytes
    # 18 (component, depth) results never sit in complex form at once
    assert peak < out.nbytes + 18 * spectrum_bytes / 2


# ----------------------------------------------------------------------------- error estimate
def _measured_error(ndim, ratio, width_factor, amps, depth=1e-3):
    h, width = ratio * depth, width_factor * depth
    coarse = _gaussian_load(ndim, h, 8 * width, width, amps, centre=(0.13 * width, -0.21 * width))
    fine = _gaussian_load(ndim, h, 8 * width, width, amps, centre=(0.13 * width, -0.21 * width), refine=3)
    a = dcfft_stress(coarse, [depth], nu=0.4)[0]
    b = dcfft_stress(fine, [depth], nu=0.4)[0][(slice(None),) + (slice(None, None, 3),) * ndim]
    measured = np.abs(a - b).max() / sum(abs(v) for v in amps.values())
    return measured, dcfft_error_estimate(coarse.spacing, depth, load_width=width)


@pytest.mark.parametrize("ratio", [2.0, 1.0, 0.5, 0.35, 0.25, 0.15, 0.05])
def test_error_estimate_bounds_measured_error_1d(ratio):
    """Against a 3x refined grid (its own error is the cube of the coarse one)."""
    for amps, width_factor, factor in (({"p": 1.0, "qx": 0.6}, 1.0, 3.0), ({"p": 1.0}, 0.3, 4.5),
                                       ({"qy": 1.0}, 1.0, 30.0)):
        measured, estimate = _measured_error(1, ratio, width_factor, amps)
        assert measured <= estimate
        if measured > 1e-13:  # above the rounding floor the bound is tight within `factor`
            assert estimate <= factor * measured
        else:
            assert estimate <= 40 * max(measured, 2.2e-16)


@pytest.mark.parametrize("ratio", [2.0, 1.0, 0.5, 0.25])
def test_error_estimate_bounds_measured_error_2d(ratio):
    measured, estimate = _measured_error(2, ratio, 1.0, {"p": 1.0, "qx": 0.6, "qy": -0.4})
    assert measured <= estimate <= 3.0 * measured


def test_error_estimate_behaviour():
    est = [dcfft_error_estimate(r * 1e-3, 1e-3) for r in (2.0, 1.0, 0.5, 0.25, 0.1)]
    assert all(a > b for a, b in zip(est, est[1:]))
    assert est[0] > 0.5  # depth below the spacing: the estimate says the result is not accurate
    assert est[-1] == pytest.approx(30 * np.finfo(float).eps, rel=1e-3)
    assert dcfft_error_estimate((1e-4,), 2e-4, dtype=np.float32) > 30 * np.finfo(np.float32).eps
    assert dcfft_error_estimate((1e-4, 4e-4), 5e-4) > dcfft_error_estimate(1e-4, 5e-4)
    assert dcfft_error_estimate(1e-4, 5e-4, load_width=1e-4) > dcfft_error_estimate(1e-4, 5e-4)
    assert np.isfinite(dcfft_error_estimate(1.0, 1e-6))


# ----------------------------------------------------------------------------- bad input
def test_dcfft_bad_input_raises():
    load = SurfaceLoad(p=np.ones((3, 3)), spacing=1e-4)
    with pytest.raises(ValueError, match=r"depths: every depth must be finite and > 0 m .*got -0.001 at index 1"):
        dcfft_stress(load, [1e-3, -1e-3])
    with pytest.raises(ValueError, match="depths: every depth must be finite and > 0 m"):
        dcfft_stress(load, [0.0])
    with pytest.raises(ValueError, match="depths: every depth must be finite and > 0 m"):
        dcfft_stress(load, [np.nan])
    with pytest.raises(ValueError, match="depths: expected one depth or a non-empty 1-D"):
        dcfft_stress(load, [])
    with pytest.raises(ValueError, match="depths: expected one depth or a non-empty 1-D"):
        dcfft_stress(load, [[1e-3, 2e-3]])
    with pytest.raises(ValueError, match="depths: expected one depth or a 1-D sequence"):
        dcfft_stress(load, ["deep"])
    with pytest.raises(ValueError, match="components: unknown component 'qq'"):
        dcfft_stress(load, [1e-3], components=("zz", "qq"))
    with pytest.raises(ValueError, match="nu: Poisson's ratio must lie"):
        dcfft_stress(load, [1e-3], nu=-1.0)
    with pytest.raises(ValueError, match="dtype: expected float32 or float64, got complex128"):
        dcfft_stress(load, [1e-3], dtype=complex)
    with pytest.raises(ValueError, match="dtype: expected float32 or float64"):
        dcfft_stress(load, [1e-3], dtype="not-a-type")
    with pytest.raises(ValueError, match="load: expected a SurfaceLoad"):
        dcfft_stress(np.ones((3, 3)), [1e-3])
    with pytest.raises(ValueError, match="spacing: expected"):
        dcfft_error_estimate((1e-4, 1e-4, 1e-4), 1e-3)
    with pytest.raises(ValueError, match="spacing: grid spacing must be finite and > 0 m"):
        dcfft_error_estimate(-1e-4, 1e-3)
    with pytest.raises(ValueError, match="spacing: grid spacing must be finite and > 0 m"):
        dcfft_error_estimate(("a", 1e-4), 1e-3)
    with pytest.raises(ValueError, match="depth: every depth must be finite and > 0 m"):
        dcfft_error_estimate(1e-4, -1e-3)
    with pytest.raises(ValueError, match="load_width: must be finite and > 0 m"):
        dcfft_error_estimate(1e-4, 1e-3, load_width=0.0)


def test_one_engine_three_routes_agree(rng):
    """dcfft_stress, the operator's fft-padded path and the scan maps run the same DC-FFT
    engine (one padding rule) and agree with the direct sum over nodes."""
    from tactilab.data_schemas.sensors import SensorArray
    from tactilab.forward import HalfSpace, HertzContact
    from tactilab.forward.finger import BiomimeticFinger
    from tactilab.forward.halfspace import compliance_matrix
    from tactilab.forward.halfspace import dcfft_kernel_spectrum
    from tactilab.forward.scan_maps import ScanMaps

    comps = ("zz", "zx", "xx")
    # route 1 and 2: the same random load through dcfft_stress and the operator
    shape, spacing, depth, nu = (11, 14), (1e-4, 1.2e-4), 2.5e-4, 0.45
    p, qx = rng.normal(size=(2, *shape))
    load = SurfaceLoad(p=p, qx=qx, spacing=spacing)
    direct = direct_stress(load, _nodes(load, depth), nu=nu, components=comps).T.reshape((len(comps),) + shape)
    via_stress = dcfft_stress(load, [depth], nu, comps)[0]
    op = HalfSpace(1e6, nu).operator(shape, spacing, depth=depth, components=comps, loads=("p", "qx"))
    assert op.path == "fft-padded"
    # one padding rule, one kernel sampling: the operator holds the engine's spectra
    padded = padded_shape(shape)
    assert op._spectra.shape[-2:] == (padded[0], padded[1] // 2 + 1)
    np.testing.assert_array_equal(op._spectra, dcfft_kernel_spectrum(shape, spacing, depth, nu, op.weights, ("z", "x")))
    via_operator = (op @ np.concatenate([p.ravel(), qx.ravel()])).reshape(len(comps), *shape)
    scale = np.abs(direct).max()
    np.testing.assert_allclose(via_stress, direct, atol=1e-12 * scale)
    np.testing.assert_allclose(via_operator, direct, atol=1e-12 * scale)
    # route 3: the scan maps of a finger's (modulated) contact tractions, as strain
    sensors = SensorArray(positions_m=[[0.0, 0.0]], depth_m=1e-3, components=comps, quantity="strain")
    finger = BiomimeticFinger(HertzContact(0.8), sensors, friction=0.4, grid_spacing=0.25e-3)
    maps = ScanMaps(finger)
    modulation = 1 + 0.3 * rng.normal(size=(maps.n, maps.n))
    got = maps.apply(modulation)
    assert maps.kernel.shape[-2:] == (padded_shape((maps.n,) * 2)[0], padded_shape((maps.n,) * 2)[1] // 2 + 1)
    fp, fq = maps.tractions * modulation
    contact = SurfaceLoad(p=fp, qx=fq, spacing=finger.spacing)
    E, nu_f = finger.contact.young_modulus, finger.contact.poisson_ratio
    stress = dcfft_stress(contact, [finger.depth], nu_f)[0]  # all six, Voigt order
    strain = np.einsum("ij,j...->i...", compliance_matrix(E, nu_f), stress)[[COMPONENTS.index(c) for c in comps]]
    np.testing.assert_allclose(got, strain, atol=1e-12 * np.abs(strain).max())
    op_f = HalfSpace(E, nu_f).operator((maps.n, maps.n), finger.spacing, depth=finger.depth, components=comps,
                                       loads=("p", "qx"), quantity="strain")
    np.testing.assert_allclose((op_f @ np.concatenate([fp.ravel(), fq.ravel()])).reshape(got.shape), got,
                               atol=1e-12 * np.abs(strain).max())

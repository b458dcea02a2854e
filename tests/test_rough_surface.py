"""random_rough_surface: the requested rms height and slope exactly, the self-affine PSD, seeds, bad inputs."""

import numpy as np
import pytest

from tactilab.data_schemas import random_rough_surface
from tactilab.forward import random_rough_surface as forward_rough_surface


def _slope_spectral(h, spacing):
    """rms |grad h| from the spectrum (exact derivative), (dx, dy) x first."""
    axes = [2 * np.pi * np.fft.fftfreq(n, d) for n, d in zip(h.shape, reversed(spacing))]
    spec = np.fft.fftn(h)
    total = 0.0
    for ax, q in enumerate(axes):
        shape = [1] * h.ndim
        shape[ax] = -1
        total += np.mean(np.fft.ifftn(1j * q.reshape(shape) * spec).real ** 2)
    return np.sqrt(total)


def _slope_forward_difference(h, spacing):
    """rms |grad h| by periodic forward differences (h[i+1] - h[i]) / d."""
    total = 0.0
    for ax, d in zip(range(h.ndim), reversed(spacing)):
        total += np.mean(((np.roll(h, -1, axis=ax) - h) / d) ** 2)
    return np.sqrt(total)


@pytest.mark.parametrize(("shape", "spacing"), [((128, 64), (2e-5, 1e-5)), ((256,), (5e-6,)), ((65, 63), (1e-5, 1e-5))])
def test_rms_height_is_the_requested_one(shape, spacing, rng):
    h = random_rough_surface(shape, spacing if len(shape) == 2 else spacing[0], rms_height=2e-6, rng=rng)
    assert h.shape == shape
    assert np.sqrt(np.mean(h**2)) == pytest.approx(2e-6, rel=1e-12)
    assert abs(h.mean()) < 1e-12 * 2e-6


@pytest.mark.parametrize("short", [None, 4, 8])
def test_rms_slope_is_the_requested_one_and_finite_differences_read_less(short, rng):
    """Spectral slope = request; forward differences read between the stated sinc bound and the request."""
    spacing = (1e-5, 1e-5)
    cut = None if short is None else short * 1e-5
    h = random_rough_surface((128, 128), spacing, rms_slope=0.1, hurst=0.8, short_cutoff=cut, rng=rng)
    assert _slope_spectral(h, spacing) == pytest.approx(0.1, rel=1e-10)
    fd = _slope_forward_difference(h, spacing)
    x = np.pi * 1e-5 / (2e-5 if cut is None else cut)
    assert 0.1 * np.sin(x) / x * (1 - 1e-9) <= fd < 0.1
    # the forward-difference reading is exactly the spectrum seen through 2 sin(q d / 2) / d
    axes = [2 * np.pi * np.fft.fftfreq(128, 1e-5)] * 2
    qy, qx = np.meshgrid(*axes, indexing="ij")
    power = np.abs(np.fft.fft2(h)) ** 2 / h.size**2
    expected = np.sqrt(np.sum(((2 * np.sin(qx * 5e-6) / 1e-5) ** 2 + (2 * np.sin(qy * 5e-6) / 1e-5) ** 2) * power))
    assert fd == pytest.approx(expected, rel=1e-10)


def test_profile_rms_slope(rng):
    h = random_rough_surface((512,), 2e-5, rms_slope=0.05, hurst=0.5, rng=rng)
    assert _slope_spectral(h, (2e-5,)) == pytest.approx(0.05, rel=1e-10)


@pytest.mark.parametrize(("shape", "hurst", "exponent"), [((256, 256), 0.8, -3.6), ((256, 256), 0.3, -2.6),
                                                         ((1024,), 0.8, -2.6)])
def test_psd_is_the_self_affine_power_law_and_flat_below_the_long_cutoff(shape, hurst, exponent, rng):
    dx = 1e-5
    n = shape[0]
    long_cut, short_cut = n * dx / 8, n * dx / 64  # wavenumber indices 8 and 64
    h = random_rough_surface(shape, dx, rms_height=1e-6, hurst=hurst, long_cutoff=long_cut,
                             short_cutoff=short_cut, rng=rng)
    power = np.abs(np.fft.fftn(h)) ** 2
    line = power[(0,) * (len(shape) - 1)] if len(shape) == 2 else power  # modes along x (ky = 0)
    k = np.arange(1, 80)
    c = line[k]
    slope = np.polyfit(np.log(k[8:64]), np.log(c[8:64]), 1)[0]  # indices 9..64, inside the band
    assert slope == pytest.approx(exponent, abs=1e-9)
    np.testing.assert_allclose(c[:8], c[7], rtol=1e-9)  # flat below the long cut-off (indices 1..8)
    assert np.all(c[64:] < 1e-20 * c[0])  # nothing above the short cut-off
    assert abs(power.flat[0]) < 1e-20 * c[0]  # zero mean


def test_seeded_reproducibility_and_independence():
    a = random_rough_surface((64, 64), 1e-5, rms_height=1e-6, rng=np.random.default_rng(7))
    b = random_rough_surface((64, 64), 1e-5, rms_height=1e-6, rng=np.random.default_rng(7))
    c = random_rough_surface((64, 64), 1e-5, rms_height=1e-6, rng=np.random.default_rng(8))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    d = forward_rough_surface((64, 64), 1e-5, rms_height=1e-6, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(a, d)  # the forward face gives the same function


def test_periodic_over_the_grid(rng):
    """Band-limited and periodic: tiling two copies leaves the spectrum on the even modes only."""
    h = random_rough_surface((64,), 1e-5, rms_height=1e-6, rng=rng)
    spec = np.fft.fft(np.concatenate([h, h]))
    assert np.max(np.abs(spec[1::2])) < 1e-12 * np.max(np.abs(spec))


@pytest.mark.parametrize(("kwargs", "match"), [
    ({}, "give exactly one of them"),
    ({"rms_height": 1e-6, "rms_slope": 0.1}, "give exactly one of them"),
    ({"rms_height": -1e-6}, r"rms_height: must be finite and > 0 m, got -1e-06"),
    ({"rms_slope": float("nan")}, r"rms_slope: must be finite and > 0, got nan"),
    ({"rms_height": 1e-6, "hurst": 1.5}, r"hurst: the Hurst exponent must be in \(0, 1\]"),
    ({"rms_height": 1e-6, "hurst": 0.0}, r"hurst: the Hurst exponent must be in \(0, 1\]"),
    ({"rms_height": 1e-6, "rng": 3}, "rng: expected a numpy.random.Generator"),
    ({"rms_height": 1e-6, "short_cutoff": 1e-5}, "short_cutoff: .* is below 2 node spacings"),
    ({"rms_height": 1e-6, "short_cutoff": 1e-4, "long_cutoff": 5e-5}, "short_cutoff: must be shorter than"),
    ({"rms_height": 1e-6, "long_cutoff": float("inf")}, r"long_cutoff: must be finite and > 0 m, got inf"),
    ({"rms_height": 1e-6, "short_cutoff": 1.0, "long_cutoff": 2.0}, "short_cutoff: .* leaves no mode"),
    ({"rms_height": 1e-6, "shape": (3, 64)}, r"shape: expected \(nx,\) for a profile"),
    ({"rms_height": 1e-6, "shape": "big"}, r"shape: expected \(nx,\) or \(ny, nx\) integers"),
    ({"rms_height": 1e-6, "spacing": 0.0}, "spacing: grid spacing must be finite and > 0 m"),
    ({"rms_height": 1e-6, "spacing": (1e-5, 1e-5, 1e-5)}, r"spacing: expected one value or 2 values \(dx, dy\)"),
])
def test_bad_inputs(kwargs, match):
    args = {"shape": (32, 32), "spacing": 1e-5, "rng": np.random.default_rng(0), **kwargs}
    with pytest.raises(ValueError, match=match):
        random_rough_surface(args.pop("shape"), args.pop("spacing"), **args)

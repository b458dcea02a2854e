"""Exploration studies with the biomimetic finger (docs/theory.md 4b).

- :func:`linear_kernel`: the true first-order kernel of a y-invariant texture,
  ``g1(xi) = int [qx(xi, eta) G_x + p(xi, eta) G_z] d eta`` (output per unit modulation per m).
- :func:`wiener_kernel`: the first-order Wiener / Lee--Schetzen estimate by cross-correlating a
  random +-1 input with the output; :func:`kernel_identification` reports its error against
  the true (binned) kernel for several record lengths.
- :func:`texture_spectrum`: output power spectrum while scanning a random texture; with
  fingerprint ridges of period lambda it peaks at ``v / lambda`` (the band-pass pre-filter).
- :func:`shape_invariance`: which exploration parameters change the SHAPE of a sensor's
  response to a defect (normalised correlation) and which only scale it.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy import signal

from tactilab.data_schemas.sensors import SensorArray

from .contact import HertzContact
from .finger import BiomimeticFinger
from .scanning import scan_outputs
from .surfaces import RandomSquareWaveGrating, Surface


def _one_output(finger: BiomimeticFinger, sensor: int, component: int) -> tuple[int, int]:
    ns, nc = finger.sensors.n_sensors, finger.sensors.n_components
    if not (0 <= sensor < ns):
        raise ValueError(f"sensor: index must be in [0, {ns}), got {sensor!r}")
    if not (0 <= component < nc):
        raise ValueError(f"component: index must be in [0, {nc}), got {component!r}")
    return sensor, component


def linear_kernel(finger: BiomimeticFinger, xi, *, sensor: int = 0, component: int = 0,
                  n_eta: int = 801) -> np.ndarray:
    """True first-order kernel g1(xi) of a y-invariant texture (Pa or strain per m of texture).

    Parameters
    ----------
    finger : BiomimeticFinger
    xi : array_like, shape (n,)
        Finger-frame x positions, m.
    sensor, component : int
        Which output.
    n_eta : int
        Trapezoid nodes across the contact (y).

    Returns
    -------
    ndarray, shape (n,): the y-integral of (interfacial traction x point-load response).
    """
    _one_output(finger, sensor, component)
    xi = np.asarray(xi, dtype=float)
    a = finger.contact.contact_radius
    eta = np.linspace(-a, a, int(n_eta))
    XI, ETA = np.meshgrid(xi, eta, indexing="ij")
    p, q = finger.traction(XI, ETA)
    resp = finger.point_response(XI, ETA, q, p)[..., sensor, component]
    return np.trapezoid(resp, eta, axis=1)


def wiener_kernel(inputs, outputs, max_lag: int) -> np.ndarray:
    """First-order Wiener (Lee--Schetzen) kernel by circular cross-correlation.

    With ``y_n = c + sum_m k_m x_{n+m}`` and a white +-1 input ``x`` (one period of a periodic
    sequence), ``k_m = <(y_n - mean y) x_{n+m}> / var(x)``.

    Parameters
    ----------
    inputs : array_like, shape (N,)
        The input sequence (bits +-1).
    outputs : array_like, shape (N,)
        The output samples, one per input step.
    max_lag : int
        Lags m = -max_lag .. max_lag are returned.

    Returns
    -------
    ndarray, shape (2 max_lag + 1,): the kernel per input step, lag -max_lag first.
    """
    x = np.asarray(inputs, dtype=float)
    y = np.asarray(outputs, dtype=float)
    if x.ndim != 1 or x.shape != y.shape or x.size < 2:
        raise ValueError(f"inputs, outputs: need two 1-D arrays of the same length >= 2, got {x.shape} and {y.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("inputs, outputs: contain NaN or inf; a Wiener kernel needs finite records")
    n = x.size
    if int(max_lag) != max_lag or not 0 <= max_lag < n // 2:
        raise ValueError(f"max_lag: must be an integer in [0, {n // 2}) for a record of {n} samples, got {max_lag!r}")
    xc, yc = x - x.mean(), y - y.mean()
    var = float(np.mean(xc * xc))
    if var == 0:
        raise ValueError("inputs: constant input has no variance; use a random +-1 sequence")
    # circular cross-correlation r_m = mean_n yc_n xc_{n+m}
    r = np.real(np.fft.ifft(np.conj(np.fft.fft(yc)) * np.fft.fft(xc))) / n
    lags = np.arange(-int(max_lag), int(max_lag) + 1)
    return r[lags % n] / var


def kernel_identification(finger: BiomimeticFinger, rng: np.random.Generator, *, bit_length: float = 0.1e-3,
                          record_lengths=(256, 1024, 4096, 16384), sensor: int = 0, component: int = 0,
                          noise_std: float = 0.0, repeats: int = 1) -> pd.DataFrame:
    """Recover the first-order kernel from scans of random square-wave gratings.

    For each record length N (bits), a fresh random +-1 grating of N bits of ``bit_length`` (m)
    is scanned one bit per frame; the Wiener estimate is compared with the true kernel binned to
    bits (the exact discrete kernel of the simulation) and with the continuous
    :func:`linear_kernel` times the bit length. ``repeats`` gratings per length are averaged:
    the error of one record fluctuates (leakage through the random autocorrelation of the input),
    its mean falls like 1 / sqrt(N).

    Returns
    -------
    DataFrame with columns ``bits``, ``record_m`` (m), ``repeats``, ``noise_std`` (output unit,
    added white noise), ``error_binned`` (mean relative L2 error), ``error_binned_std`` and
    ``error_continuous``; ``attrs`` holds ``lags_m``, ``true_kernel`` (per bit) and the last
    ``estimates`` per record length, for plots.
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}; use numpy.random.default_rng(seed)")
    if not math.isfinite(noise_std) or noise_std < 0:
        raise ValueError(f"noise_std: must be finite and >= 0, got {noise_std!r}")
    h = finger.spacing
    ratio = bit_length / h
    if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
        raise ValueError(f"bit_length: must be a whole number of grid spacings ({h:g} m), got {bit_length!r}; "
                         f"use grid_spacing=bit_length/k on the finger")
    sensor, component = _one_output(finger, sensor, component)
    weights = finger.node_weights()
    X, _, W = weights
    w = W[:, sensor * finger.sensors.n_components + component]
    start = -(round(ratio) // 2 + 0.5) * h  # bin edges at node midpoints: no floor() ties
    bins = np.floor((X - start) / bit_length).astype(int)
    max_lag = int(np.abs(bins).max())
    true = np.zeros(2 * max_lag + 1)
    np.add.at(true, bins + max_lag, w)
    lags = np.arange(-max_lag, max_lag + 1)
    cont = linear_kernel(finger, lags * bit_length, sensor=sensor, component=component) * bit_length
    if int(repeats) < 1:
        raise ValueError(f"repeats: need at least 1 random grating per record length, got {repeats!r}")
    rows, last = [], {}
    for n in record_lengths:
        if int(n) != n or n <= 2 * max_lag + 1:
            raise ValueError(f"record_lengths: each must be an integer > {2 * max_lag + 1} bits (the kernel "
                             f"support), got {n!r}")
        n = int(n)
        errors = []
        for _ in range(int(repeats)):
            grating = RandomSquareWaveGrating.from_rng(rng, n, bit_length, 1.0, start=start)
            reach = (n + 2 * max_lag + 2) * bit_length
            surface = Surface(length=2 * reach, width=1.0, features=(grating,), x_start=-reach)
            y = scan_outputs(finger, surface, np.arange(n) * bit_length, reference_height_m=1.0,
                             weights=weights, batch=512)[:, sensor, component]
            if noise_std > 0:
                y = y + noise_std * rng.standard_normal(y.shape)
            est = wiener_kernel(grating.bits, y, max_lag)
            last[n] = est
            errors.append((np.linalg.norm(est - true) / np.linalg.norm(true),
                           np.linalg.norm(est - cont) / np.linalg.norm(cont)))
        e = np.array(errors)
        rows.append(dict(bits=n, record_m=n * bit_length, repeats=int(repeats), noise_std=noise_std,
                         error_binned=float(e[:, 0].mean()), error_binned_std=float(e[:, 0].std()),
                         error_continuous=float(e[:, 1].mean())))
    table = pd.DataFrame(rows)
    # the last estimate per length and the true binned kernel, for plots (lags in m)
    table.attrs.update(lags_m=lags * bit_length, true_kernel=true, estimates=last)
    return table


def texture_spectrum(finger: BiomimeticFinger, rng: np.random.Generator, *, speed: float = 0.1,
                     sampling_rate: float = 4000.0, duration: float = 0.5, bit_length: float = 0.05e-3,
                     sensor: int = 0, component: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Power spectral density of one output while scanning a random +-1 texture.

    Returns
    -------
    freqs : ndarray, Hz
    psd : ndarray, (output unit)^2 / Hz (Welch, Hann windows of 1/4 of the record).
    """
    from .scanning import check_scan

    n = check_scan(speed, sampling_rate, duration)
    sensor, component = _one_output(finger, sensor, component)
    length = speed * duration + 4 * finger.contact.contact_radius
    bits = int(math.ceil(length / bit_length)) + 2
    grating = RandomSquareWaveGrating.from_rng(rng, bits, bit_length, 1.0, start=-2 * finger.contact.contact_radius)
    surface = Surface(length=4 * length, width=1.0, features=(grating,), x_start=-2 * length)
    u = speed * np.arange(n) / sampling_rate
    y = scan_outputs(finger, surface, u, reference_height_m=1.0)[:, sensor, component]
    return signal.welch(y - y.mean(), fs=sampling_rate, nperseg=max(16, n // 4))


# ------------------------------------------------------------------------------ shape invariance
BASELINE = dict(normal_force=0.8, finger_radius=0.1, young_modulus=2e6, poisson_ratio=0.5, depth=3e-3,
                y_offset=0.0, sensor_x=0.0, friction=0.5, speed=0.05)
"""Reference exploration parameters of :func:`shape_invariance` (SI)."""

VARIATIONS = dict(normal_force=(0.5, 1.0), depth=(2.5e-3, 3.5e-3), y_offset=(0.5e-3, 1.0e-3),
                  speed=(0.02, 0.2), young_modulus=(1.5e6, 3e6), poisson_ratio=(0.4, 0.45),
                  finger_radius=(0.07, 0.14), sensor_x=(1.0e-3, 2.0e-3), friction=(0.0, 1.0))
"""Tested values per parameter (SI); speeds in m/s, positions in m."""


def _defect_response(params: dict, u: np.ndarray, component: str = "zz",
                     sampling_rate: float = 1000.0) -> tuple[np.ndarray, float]:
    contact = HertzContact(params["normal_force"], params["finger_radius"], params["young_modulus"],
                           params["poisson_ratio"])
    sensors = SensorArray(positions_m=[[params["sensor_x"], params["y_offset"]]], depth_m=params["depth"],
                          components=(component,))
    finger = BiomimeticFinger(contact, sensors, friction=params["friction"])
    # sample the scan in time (speed v, rate fs), then express it against finger position u = v t
    t = np.arange(0, (u[-1] - u[0]) / params["speed"] + 0.5 / sampling_rate, 1.0 / sampling_rate)
    ut = u[0] + params["speed"] * t
    rf = finger.receptive_field(ut, 0.0, 0.0, strength=1e-8)[:, 0, 0]
    return np.interp(u, ut, rf), contact.contact_radius


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    return float(a @ b / math.sqrt((a @ a) * (b @ b)))


def shape_invariance(baseline: dict | None = None, variations: dict | None = None, *,
                     component: str = "zz", window: float = 8e-3, n: int = 801) -> pd.DataFrame:
    """Normalised correlation between a sensor's defect response at baseline and with one
    exploration parameter changed.

    The response is the receptive field (docs/theory.md 4b) of one stress sensor (``component``,
    ``"zz"`` or ``"zx"``; Pa) for a point defect
    at the origin, against finger position u in [-window, window] (m). ``corr_position`` compares
    the two curves against u; ``corr_contact_scaled`` against u / a (a = contact radius), the frame
    in which a contact that grows or shrinks would keep its shape. ``gain`` is the ratio of peak
    magnitudes (varied / baseline).

    Returns
    -------
    DataFrame with columns ``parameter``, ``baseline``, ``value``, ``corr_position``,
    ``corr_contact_scaled``, ``gain``.
    """
    base = dict(BASELINE if baseline is None else baseline)
    vary = dict(VARIATIONS if variations is None else variations)
    if component not in ("zz", "zx"):
        raise ValueError(f"component: the study reads a 'zz' or 'zx' stress sensor, got {component!r}")
    for key in vary:
        if key not in BASELINE:
            raise ValueError(f"variations: unknown parameter {key!r}; use one of {sorted(BASELINE)}")
    u = np.linspace(-window, window, int(n))
    ref, a_ref = _defect_response(base, u, component)
    s = np.linspace(-window / a_ref, window / a_ref, int(n))
    ref_s = np.interp(s * a_ref, u, ref)
    rows = []
    for key, values in vary.items():
        for value in values:
            params = dict(base, **{key: value})
            resp, a = _defect_response(params, u, component)
            resp_s = _defect_response(params, s * a, component)[0]
            rows.append(dict(parameter=key, component=component, baseline=base[key], value=value,
                             corr_position=_corr(ref, resp), corr_contact_scaled=_corr(ref_s, resp_s),
                             gain=float(np.abs(resp).max() / np.abs(ref).max())))
    return pd.DataFrame(rows)

"""The founding papers' studies through the solved contact: each study as a function of its sizes.

A fingertip (R = 10 mm, E = 1 MPa, nu = 1/2, friction 0.5, full sliding) scans raised-cosine bumps
of 0.4 mm base or random square-wave gratings; one strain sensor (zz and zx) under the contact
centre at 1 mm reads it. A defect's response is the scan over it minus the scan over a flat plate
(the receptive field as a function of the finger position u). Every function takes the interface
model (``"exact"``: every frame's contact solved; ``"modulation"``: docs/theory.md 4b; ``"linear"``)
and returns the study's key figures; ``benchmarks/bench_scene_studies.py`` tabulates them at full
size (docs/scenes.md, "The founding papers' studies") and the scene-models demo section prints one
line per study at a reduced size.

- :func:`receptive_field_change`: (a) does the normal force, or the bump's height, change the
  shape of a bump's receptive field? Pearson correlation with a reference response over u and
  over u / a (a the Hertz radius), and the gain per um of height.
- :func:`fingerprint_band_pass`: (b) ridged against smooth skin scanning a random fine texture:
  the sensor spectrum's peak and the ridged / smooth ratio at v / lambda.
- :func:`wiener_kernels`: (c) the first-order Wiener kernel identified from random gratings.
- :func:`superposition_error`: (d) two bumps at separation s against the sum of their single
  responses (the interaction between defects).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import welch

from tactilab.data_schemas import FlatSurface, HeightMap, IsolatedDefect, Scene, SensorArray, SkinMaterial
from tactilab.data_schemas import SquareWaveGrating
from tactilab.data_schemas.scene import Contact, Scan

from .contact import HertzContact
from .exploration import wiener_kernel
from .scene_models import scene_signals

#: the studies' skin and finger: E (Pa), nu, fingertip radius (m), friction coefficient
E_PA, NU, RADIUS, MU = 1e6, 0.5, 0.01, 0.5
#: the bump scans' speed (m/s) and sampling rate (Hz): one 40 um node per frame
SPEED, RATE = 0.04, 1000.0
#: a bump's base diameter, m
BUMP = 0.4e-3
#: the strain components the sensor reads
STUDY_COMPONENTS = ("zz", "zx")
#: the fingerprint ridges (period, height), m
RIDGES = (0.5e-3, 20e-6)


def study_scene(surface, force: float, model: str, start: float, stop: float, *, speed: float = SPEED,
                rate: float = RATE, ridges: tuple[float, float] | None = None) -> Scene:
    """A finger scan from ``start`` to ``stop`` (m, contact centre) over ``surface`` at ``force`` (N);
    ``ridges`` (period, height) in m; speed in m/s, rate in Hz."""
    duration = max((stop - start) / speed, 1 / rate)
    period, height = (None, None) if ridges is None else ridges
    return Scene(material=SkinMaterial(young_modulus_pa=E_PA, poisson_ratio=NU), surface=surface,
                 contact=Contact(normal_force_n=force, finger_radius_m=RADIUS, friction_coefficient=MU, model=model,
                                 fingerprint_period_m=period, fingerprint_height_m=height),
                 sensors=SensorArray(positions_m=[[0.0, 0.0]], depth_m=1e-3, quantity="strain",
                                     components=STUDY_COMPONENTS),
                 scan=Scan(speed_m_per_s=speed, duration_s=duration, sampling_rate_hz=rate, start_position_m=start))


def defect_response(surface, force: float, model: str, start: float, stop: float,
                    grid_spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """``(u, response)``: the positions (m, shape (n_frames,)) and the scan over ``surface`` minus the
    scan over a flat plate (strain, shape (n_frames, 2): zz, zx), on a grid of ``grid_spacing`` m."""
    values, info = scene_signals(study_scene(surface, force, model, start, stop), model, grid_spacing=grid_spacing)
    flat, _ = scene_signals(study_scene(FlatSurface(), force, model, 0.0, 0.0), model, grid_spacing=grid_spacing)
    return info["frames"].positions, values[:, 0, :] - flat[0, 0, :]


def bump(height: float, x0: float = 0.0) -> IsolatedDefect:
    """A raised-cosine bump of 0.4 mm base and ``height`` m at world x = ``x0`` m."""
    return IsolatedDefect(shape="bump", size_m=BUMP, height_m=height, position_m=(x0, 0.0))


def two_bumps(height: float, separation: float, spacing: float) -> HeightMap:
    """Two bumps at x = 0 and x = separation, sampled on a map of ``spacing`` / 4 (exact at the finger's nodes)."""
    step = spacing / 4
    x = np.arange(-BUMP, separation + BUMP + step, step)
    y = np.arange(-BUMP, BUMP + step, step)
    X, Y = np.meshgrid(x, y)
    h = bump(height).height_at(X, Y) + bump(height, separation).height_at(X, Y)
    return HeightMap(heights_m=h, spacing_x_m=step, spacing_y_m=step, origin_m=(float(x[0]), float(y[0])))


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two equally long series."""
    a, b = a - a.mean(), b - b.mean()
    return float(a @ b / np.sqrt((a @ a) * (b @ b)))


def contact_radius(force: float) -> float:
    """The smooth finger's Hertz radius at ``force`` N, m."""
    return HertzContact(force, finger_radius=RADIUS, young_modulus=E_PA, poisson_ratio=NU).contact_radius


def receptive_field_change(model: str, force: float, height: float, reach: float, grid_spacing: float, *,
                           reference=None, reference_case: tuple[float, float] = (0.5, 20e-6)):
    """(a) A bump's receptive field at ``force`` (N) and ``height`` (m) against the reference case's.

    Parameters
    ----------
    model : str
    force, height : float
        The changed case, N and m.
    reach : float
        The scan runs from -reach to reach (m, contact centre).
    grid_spacing : float
        The contact grid's spacing, m (one node per frame at 40 mm/s and 1 kHz when 40 um).
    reference : (u, response), optional
        The reference's :func:`defect_response` if already computed.
    reference_case : (force, height)
        N and m.

    Returns
    -------
    correlations : list of (float, float)
        Per component (zz, zx): Pearson correlation over u and over u / a.
    gain : float
        Peak |zz| per um of height over the reference's.
    """
    f_ref, h_ref = reference_case
    u, ref = defect_response(bump(h_ref), f_ref, model, -reach, reach, grid_spacing) if reference is None else reference
    _, r = defect_response(bump(height), force, model, -reach, reach, grid_spacing)
    a_ref, a = contact_radius(f_ref), contact_radius(force)
    scaled = np.linspace(-reach / a_ref, reach / a_ref, 400) * min(1.0, a_ref / a)  # inside both scans
    corr = [(correlation(r[:, c], ref[:, c]),
             correlation(np.interp(scaled, u / a, r[:, c]), np.interp(scaled, u / a_ref, ref[:, c])))
            for c in range(len(STUDY_COMPONENTS))]
    gain = (np.abs(r[:, 0]).max() / (height * 1e6)) / (np.abs(ref[:, 0]).max() / (h_ref * 1e6))
    return corr, float(gain)


def superposition_error(model: str, height: float, separations, reach: float, grid_spacing: float) -> dict:
    """(d) ``{s: max |r_pair - r_1 - r_2| / max |r_pair| per component}`` for two bumps of ``height`` (m)
    at each separation ``s`` (m) along the scan, r_2 being r_1 moved by s (the same bump s later: the
    scan is translation invariant; ``s`` a whole number of frames)."""
    top = max(separations)
    _, single = defect_response(bump(height), 0.5, model, -reach, reach + top, grid_spacing)
    out = {}
    for s in separations:
        _, pair = defect_response(two_bumps(height, s, grid_spacing), 0.5, model, -reach, reach + top, grid_spacing)
        shift = int(round(s / (SPEED / RATE)))
        moved = np.zeros_like(single)
        moved[shift:] = single[:single.shape[0] - shift]  # the second bump, s later
        out[s] = np.abs(pair - single - moved).max(axis=0) / np.abs(pair).max(axis=0)
    return out


def random_grating(bit: float, amplitude: float, n_bits: int, start: float, seed: int) -> SquareWaveGrating:
    """A random +-``amplitude`` square-wave grating of ``n_bits`` bits of ``bit`` m from ``start`` m."""
    return SquareWaveGrating(pattern="random", element_width_m=bit, amplitude_m=amplitude, length_m=n_bits * bit,
                             start_m=start, seed=seed)


def fingerprint_band_pass(model: str, grid_spacing: float, rate: float, frames: int, force: float) -> dict:
    """(b) Ridged (0.5 mm, 20 um) and smooth skin scanning random +-2 um bars of ``grid_spacing`` m at one node
    per frame (speed ``grid_spacing * rate``): the zz Welch spectra.

    Returns
    -------
    dict
        ``"peak"`` (Hz: the ridged spectrum's peak above 40 Hz), ``"ratio"`` (ridged / smooth PSD at
        v / lambda), ``"smooth"`` (the smooth PSD at v / lambda over its peak above 40 Hz),
        ``"resolution"`` (Hz, the bin), ``"band"`` (v / lambda, Hz).
    """
    speed, period = grid_spacing * rate, RIDGES[0]
    reach = 1.6 * HertzContact(force, finger_radius=RADIUS, young_modulus=E_PA).contact_radius
    length = frames * grid_spacing
    n_bits = int(np.ceil((length + 2 * reach) / grid_spacing)) + 2
    texture = random_grating(grid_spacing, 2e-6, n_bits, -reach - grid_spacing, 5)
    psd = {}
    for ridged in (True, False):
        values, _ = scene_signals(study_scene(texture, force, model, 0.0, length, speed=speed, rate=rate,
                                              ridges=RIDGES if ridged else None), model, grid_spacing=grid_spacing)
        f, psd[ridged] = welch(values[:, 0, 0], fs=rate, nperseg=frames // 4)
    band = f > 40.0  # above the contact's own low-pass envelope
    at = int(np.argmin(np.abs(f - speed / period)))
    return {"peak": float(f[band][np.argmax(psd[True][band])]), "ratio": float(psd[True][at] / psd[False][at]),
            "smooth": float(psd[False][at] / psd[False][band].max()), "resolution": float(f[1] - f[0]),
            "band": speed / period}


def wiener_kernels(amplitudes, grid_spacing: float, n_bits: int, models=("exact", "linear", "modulation"),
                   force: float = 0.5) -> dict:
    """(c) ``{(model, A): kernel per um of A}`` (zz, lags 0 to 3.5 mm) identified with
    :func:`~.exploration.wiener_kernel` from a random +-A grating of ``n_bits`` bits of ``grid_spacing`` m
    scanned one bit per frame (the same bit sequence at every A); the modulation only at the first
    A (h / h_ref: the same record at every amplitude)."""
    speed, max_lag = grid_spacing * RATE, int(round(3.5e-3 / grid_spacing))
    reach = 1.6 * HertzContact(force, finger_radius=RADIUS, young_modulus=E_PA).contact_radius
    pad = int(np.ceil(reach / grid_spacing)) + 2
    kernels = {}
    for amplitude in amplitudes:
        texture = random_grating(grid_spacing, amplitude, n_bits + 2 * pad, -pad * grid_spacing, 7)
        bits = texture.signs()[pad:pad + n_bits]  # the bit under the contact centre at each frame
        for model in models:
            if model == "modulation" and amplitude != amplitudes[0]:
                continue
            scan = study_scene(texture, force, model, 0.5 * grid_spacing, (n_bits + 0.5) * grid_spacing, speed=speed)
            values, _ = scene_signals(scan, model, grid_spacing=grid_spacing)
            kernels[(model, amplitude)] = wiener_kernel(bits, values[:, 0, 0], max_lag) / (amplitude * 1e6)
    return kernels


def kernel_error(kernel: np.ndarray, reference: np.ndarray) -> dict:
    """A Wiener kernel against a reference: ``"error"`` (relative L2), ``"one_minus_corr"`` and ``"gain"``
    (the least-squares factor kernel ~ gain x reference)."""
    scale = float(np.linalg.norm(reference))
    return {"error": float(np.linalg.norm(kernel - reference)) / scale,
            "one_minus_corr": 1 - correlation(kernel, reference), "gain": float(kernel @ reference) / scale**2}

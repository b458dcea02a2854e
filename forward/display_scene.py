"""Display scenes: a laterotactile display rendering the scene's (virtual) surface to the skin.

Plane model of docs/theory.md 4a (the one :mod:`.tractor_display` uses): every row of tractors gets
the same travelling-wave drive ``q_n(t) = gain H(x_n + V t)`` (N/m), and the stress at the
sensor depth is the superposition of the tractors' plane-strain kernels
(:func:`.tractors.tractor_stress_kernel`, tractors of the display's footprint width);
``sigma_yy = nu (sigma_xx + sigma_zz)``, sensors' y is ignored (rows uniform in y).

The gain renders a sinusoid of the display's natural pitch ``p = 4 d`` (d = pitch_x / 2) with the
strain amplitude of the real sliding surface: ``Q / A = 8 sqrt(2) pi^3 Z E e^{-2 pi Z/p} / (3 k2' p^2)``
with ``k2' = S_Psi(x = d)`` of THIS display (its own spacing and ``columns // 2`` pairs, not the
optimum), docs/theory.md 4a. The drive samples the surface a quarter pitch ahead, which puts the
rendered strain in phase with the real sliding grating's. At p = 4 d the tractors sample the
wave twice per period, so the rendered field is a standing wave: its normalised correlation with
the real travelling wave is bounded by about 1 / sqrt(2). A drive over the display's traction
limit raises ValueError.
"""

from __future__ import annotations

import math

import numpy as np

from .halfspace import output_weights
from .scanning import MAX_OUTPUT_VALUES
from .tractor_display import travelling_wave_drive
from tactilab.core import rules as check
from .tractors import array_phi_psi, sliding_sinusoid_strain, tractor_stress_kernel


def display_gain(display, depth: float, young_modulus: float) -> tuple[float, float]:
    """Line load per unit virtual height ((N/m)/m) and the rendered pitch 4 d (m) of a display.

    Parameters
    ----------
    display : DisplayDescription
        The display (its ``pitch_x_m`` = 2 d and ``columns``).
    depth : float
        Receptor depth Z in m (> 0).
    young_modulus : float
        Skin Young's modulus E in Pa (> 0).

    Returns
    -------
    gain : float
        Line load per tractor per unit virtual surface height, (N/m)/m.
    pitch : float
        Rendered grating pitch 4 d in m.
    """
    young_modulus = check.young_modulus(young_modulus)
    d = float(display.pitch_x_m) / 2
    pairs = max(1, int(display.columns) // 2)
    k2p = float(array_phi_psi(np.array([d]), d, depth, pairs)[1][0])
    if not math.isfinite(k2p) or k2p <= 0:
        raise ValueError(f"display: S_Psi(d) = {k2p!r} 1/m at depth {depth!r} m is not positive, so no drive "
                         "renders a grating; check pitch_x and the sensor depth")
    p = 4 * d
    gain = 8 * math.sqrt(2) * math.pi ** 3 * depth * young_modulus * math.exp(-2 * math.pi * depth / p) / (
        3 * k2p * p * p)
    return gain, p


def display_scene_outputs(scene) -> tuple[np.ndarray, np.ndarray, dict]:
    """Sensor outputs of a display scene.

    Returns
    -------
    values : ndarray, shape (n_times, n_sensors, n_components): Pa or strain (tensor shear).
    line_loads : ndarray, shape (n_times, columns), N/m.
    info : dict with ``gain`` ((N/m)/m), ``rendered_pitch`` (m), ``peak_traction`` (Pa) and, for a
        sinusoidal virtual surface, ``real`` (the real sliding grating's outputs, same shape).
    """
    display, sensors, material, scan = scene.display, scene.sensors, scene.material, scene.scan
    if display is None:
        raise ValueError("scene.display: the scene has no display; use the finger simulation")
    if scan.speed_m_per_s <= 0:
        raise ValueError(f"speed: a rendered scan needs a speed > 0 m/s, got {scan.speed_m_per_s!r}")
    (E, nu), depth = material.half_space_constants("the display scene"), sensors.depth_m
    gain, pitch = display_gain(display, depth, E)
    t = scan.times_s
    width = float(display.tractor_width_m)
    limit = display.max_traction_pa
    surf = scene.surface
    virtual_pitch = surf.period_m if getattr(surf, "kind", "") == "sinusoidal_grating" else pitch
    # a quarter-pitch sampling lead puts the rendered strain in phase with the real one (docs/theory.md 4a)
    q = travelling_wave_drive(display.tractor_x_m, lambda x: surf.height_at(x), scan.speed_m_per_s,
                              t, gain, lead=scan.start_position_m + virtual_pitch / 4, traction_limit=limit,
                              footprint=width if limit is not None else None)
    xs = sensors.positions_m[:, 0]
    size = t.size * xs.size * 6 + xs.size * display.tractor_x_m.size * 3  # Voigt field and kernel
    if size > MAX_OUTPUT_VALUES:
        raise ValueError(
            f"sensors: {t.size} frames x {xs.size} sensors need ~{size * 8 / 2**30:.3g} GiB of work arrays, above "
            f"the limit {MAX_OUTPUT_VALUES * 8 / 2**30:.3g} GiB; use fewer sensors, a shorter scan or a lower "
            "sampling rate")
    kernel = tractor_stress_kernel(xs[:, None] - display.tractor_x_m[None, :], depth, width)  # (nx, ntr, 3)
    plane = np.einsum("tn,xnc->txc", q, kernel)
    voigt = np.zeros(plane.shape[:-1] + (6,))
    voigt[..., 0], voigt[..., 2], voigt[..., 4] = plane[..., 0], plane[..., 1], plane[..., 2]
    voigt[..., 1] = nu * (plane[..., 0] + plane[..., 1])
    W = output_weights(sensors.quantity, sensors.components, E, nu)
    values = voigt @ W.T
    info = dict(gain=gain, rendered_pitch=pitch, peak_traction=float(np.abs(q).max()) / width)
    if getattr(surf, "kind", "") == "sinusoidal_grating" and sensors.quantity == "strain":
        real = sliding_sinusoid_strain(xs, depth, surf.amplitude_m, surf.period_m, scan.speed_m_per_s,
                                       t + scan.start_position_m / scan.speed_m_per_s, nu)
        info["real"] = real[..., [check.COMPONENTS.index(c) for c in sensors.components]]
    return values, q, info

"""Demo section: what surface did the finger touch? A simulated scan of a known random profile, inverted.

A fingertip (radius 10 mm, 0.02 N, skin E = 1 MPa, nu = 0.5, friction 0.4) slides 0.25 mm at
40 mm/s over a random self-affine profile (rms 1 um, Hurst 0.8, wavelengths 0.16 to 0.4 mm, ridges
along y); three stress sensors 0.3 mm deep record sigma_zz and sigma_zx with 5 Pa of noise. The scan
is simulated with the exact model (every frame's contact solved, ``scene_signals``), then inverted
with :func:`~tactilab.inversion.invert_surface` (Laplace, the normal force free under a log-normal
prior). Reduced sizes (a 50 um contact grid, six frames) keep the section to a few seconds; the
full-size figures are ``benchmarks/bench_surface_inversion.py``'s (docs/inversion.md, "The surface
a finger touched").
"""

from __future__ import annotations

import pathlib
import warnings
from collections.abc import Iterator

import numpy as np

from tactilab.data_schemas import (Contact, FlatSurface, HeightMap, Recording, Scan, Scene, SensorArray, SkinMaterial,
                                   random_rough_surface)
from tactilab.forward import AccuracyWarning, scene_signals
from tactilab.inversion import LogNormal, StationaryPrior, invert_surface, scene_scan

#: the contact grid's spacing and the profile's, m (reduced: the demo runs every section)
GRID = 50e-6
#: the sensors' noise, Pa
NOISE = 5.0
#: the normal force, N
FORCE = 0.02


def demo_scene() -> Scene:
    """The section's scene (SI), over a flat surface: :func:`simulate` puts the random profile in."""
    sensors = SensorArray.grid(3, 1, 0.3e-3, 0.3e-3, quantity="stress", components=("zz", "zx"))
    return Scene(
        name="surface_inversion_demo",
        description="a fingertip sliding over a known random profile, for the surface inversion",
        material=SkinMaterial(young_modulus_pa=1e6, poisson_ratio=0.5),
        surface=FlatSurface(),
        contact=Contact(normal_force_n=FORCE, finger_radius_m=10e-3, friction_coefficient=0.4, model="exact"),
        sensors=sensors.replace(noise_std=NOISE),
        scan=Scan(speed_m_per_s=0.04, duration_s=0.006, sampling_rate_hz=1000.0, start_position_m=-0.1e-3),
    )


def simulate(rng: np.random.Generator) -> tuple[Scene, Recording, np.ndarray, np.ndarray]:
    """The scene over a random profile, its noisy exact-model recording, and the truth on the profile grid.

    The profile is drawn on the inversion's own nodes (``HeightMap`` interpolates linearly between
    them, as the inversion does), so the truth is exactly representable. Returns
    ``(scene, recording, x, truth)`` with ``x`` and ``truth`` in m.
    """
    scene = demo_scene()
    x = scene_scan(scene, grid_spacing=GRID).profile.x
    pad = 8  # nodes beyond the strip on each side: the surface continues past what the finger reads
    heights = random_rough_surface((x.size + 2 * pad,), GRID, rms_height=1e-6, hurst=0.8, long_cutoff=0.4e-3,
                                   short_cutoff=0.16e-3, rng=rng)
    surface = HeightMap(heights_m=heights, spacing_x_m=GRID, origin_m=(float(x[0] - pad * GRID), 0.0))
    scene = scene.replace(surface=surface)
    values, _ = scene_signals(scene, "exact", grid_spacing=GRID)
    noisy = values + NOISE * rng.standard_normal(values.shape)
    recording = Recording.from_sensors(scene.sensors, noisy, scene.scan.sampling_rate_hz)
    return scene, recording, x, heights[pad:pad + x.size]


def run_demo(report_dir: pathlib.Path, progress: bool = True) -> Iterator[str]:
    """Simulate and invert the scan; write ``surface/surface.png``; yield report lines."""
    out = pathlib.Path(report_dir) / "surface"
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(28)
    yield "== what surface did the finger touch? (docs/inversion.md, The surface a finger touched) =="
    with warnings.catch_warnings():  # the reduced grid: the contact engine's resolution notes
        warnings.simplefilter("ignore", AccuracyWarning)
        scene, recording, x, truth = simulate(rng)
        prior = StationaryPrior(variance=(1e-6) ** 2, correlation_length=0.1e-3, kind="matern52")
        post = invert_surface(scene, recording, prior=prior, context={"normal_force": LogNormal(FORCE, 0.2)},
                              rng=rng, grid_spacing=GRID, n_draws=200, truth=truth)
    t = post.touched
    offset = float(np.mean(post.mean[t] - truth[t]))  # the level is not identifiable: compare the relief
    error = float(np.sqrt(np.mean((post.mean[t] - truth[t] - offset) ** 2)))
    relief = float(np.std(truth[t]))
    sd, _, _ = post.relief(0.9)
    yield (f"scan: {recording.n_times} frames over {x.size} profile nodes at {GRID * 1e6:g} um, random profile "
           f"rms {np.std(truth) * 1e6:.2f} um, noise {NOISE:g} Pa, the exact model")
    yield (f"touched fraction {post.touched_fraction:.2f}; relief error (rms over touched nodes) "
           f"{error * 1e6:.3f} um against a relief of {relief * 1e6:.2f} um rms (posterior relief sd, median "
           f"{np.median(sd[t]) * 1e6:.3f} um); resolved wavelengths >= "
           f"{post.resolvable_band['wavelength_min'] * 1e3:.2f} mm")
    force = post.context["normal_force"]
    yield (f"context posterior: normal_force = {force['mean']:.5f} +- {force['sd']:.1g} N (90 % "
           f"[{force['q05']:.5f}, {force['q95']:.5f}], truth {FORCE:g} N, prior sd 20 %)")
    path = post.plot(out / "surface.png")
    yield f"figure: {path}"

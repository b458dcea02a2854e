"""``geometry="patch"`` on a real scene: h(x, y) under a sensor array, from noise-free data of the scene engine.

A fingertip (R = 10 mm, 2 mN, E = 1 MPa) slides over a random 2-D surface (rms 0.3 um) given as a
``height_map`` on the patch's own nodes (the engine reads it bilinearly, as the inversion does), three
frames; an 8 x 8 array of stress sensors 30 um deep records sigma_zz and sigma_zx. Oracles: the scene
engine's recording (``scene_signals``, exact model) and Hertz's contact radius for which nodes the
finger can and cannot have touched.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tactilab.data_schemas import Contact, FlatSurface, HeightMap, Scan, Scene, SensorArray, SkinMaterial
from tactilab.data_schemas.recording import Recording
from tactilab.data_schemas.rough_surface import random_rough_surface
from tactilab.forward import AccuracyWarning
from tactilab.forward.scene_models import scene_signals
from tactilab.inversion import StationaryPrior, invert_surface, scene_scan

GRID, SPACING, FORCE, RADIUS, E = 25e-6, 75e-6, 0.002, 10e-3, 1e6


def _scene(surface) -> Scene:
    sensors = SensorArray.grid(8, 8, 50e-6, 30e-6, quantity="stress", components=("zz", "zx"))
    return Scene(name="patch", description="a fingertip over a random 2-D surface, for the patch inversion",
                 material=SkinMaterial(young_modulus_pa=E, poisson_ratio=0.5), surface=surface,
                 contact=Contact(normal_force_n=FORCE, finger_radius_m=RADIUS, friction_coefficient=0.3,
                                 model="exact", tol=1e-10),
                 sensors=sensors, scan=Scan(speed_m_per_s=0.075, duration_s=0.003, sampling_rate_hz=1000.0,
                                            start_position_m=-75e-6))


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_patch_noise_free_recovers_the_touched_relief_and_flags_the_rest(rng):
    profile = scene_scan(_scene(FlatSurface()), geometry="patch", spacing=SPACING, grid_spacing=GRID).profile
    pad = 4  # the surface continues past the patch
    heights = random_rough_surface((profile.y.size + 2 * pad, profile.x.size + 2 * pad), SPACING, rms_height=0.3e-6,
                                   short_cutoff=4 * SPACING, rng=rng)
    truth = heights[pad:-pad, pad:-pad]
    surface = HeightMap(heights_m=heights, spacing_x_m=SPACING, spacing_y_m=SPACING,
                        origin_m=(float(profile.x[0] - pad * SPACING), float(profile.y[0] - pad * SPACING)))
    scene = _scene(surface)
    with warnings.catch_warnings():  # a coarse contact grid: the engine's resolution note
        warnings.simplefilter("ignore", AccuracyWarning)
        values, _ = scene_signals(scene, "exact", grid_spacing=GRID)
        noise = 1e-4 * float(np.abs(values).max())  # the likelihood's scale; the data carry no noise
        scene = scene.replace(sensors=scene.sensors.replace(noise_std=noise))
        recording = Recording.from_sensors(scene.sensors, values, scene.scan.sampling_rate_hz)
        post = invert_surface(scene, recording, geometry="patch", spacing=SPACING, rng=rng, grid_spacing=GRID,
                              prior=StationaryPrior(variance=(1e-6) ** 2, kind="white"), n_draws=200)
    assert post.geometry == "patch" and post.mean.shape == truth.shape == (profile.y.size, profile.x.size)
    touched = post.touched
    # the touched relief (the level is not identifiable) to the engine's accuracy, or within the posterior's
    # relief sd at the barely touched rim nodes; the data, not the prior (sd 1 um), set it
    sd, _, _ = post.relief(0.9)
    error = post.mean[touched] - truth[touched]
    error -= error.mean()
    assert np.all(np.abs(error) < 4 * sd[touched] + 1e-3 * truth.std())
    assert np.median(np.abs(error)) < 1e-3 * truth.std() and sd[touched].max() < 1e-2 * 1e-6
    # Hertz: nodes within half the contact radius of the path are touched, those beyond it (and the
    # bilinear stencil and the roughness's reach) are not, and carry an upper bound instead
    a = (3 * FORCE * RADIUS * (1 - 0.25) / (4 * E)) ** (1 / 3)
    X, Y = np.meshgrid(post.x, post.y)
    u = scene_scan(scene, geometry="patch", spacing=SPACING, grid_spacing=GRID).positions
    dist = np.hypot(X - np.clip(X, u.min(), u.max()), Y)
    assert touched[dist < a / 2].all() and not touched[dist > a + 2 * SPACING].any()
    assert 0.2 < post.touched_fraction < 0.8
    assert np.isfinite(post.upper_bound[~touched]).all() and np.isnan(post.upper_bound[touched]).all()
    # far from the finger the white prior keeps its sd (its bound lies well above)
    far = dist > a + 2 * SPACING
    assert far.sum() >= 10 and abs(np.median(post.std[far]) / 1e-6 - 1) < 0.1

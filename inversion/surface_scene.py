"""What surface did the finger touch? :func:`invert_surface`: a scene and its recording in, a surface posterior out.

The scan is the scene's own (:class:`tactilab.forward.scene_frames.SceneFrames`, the grid and the
frames that ``tactilab simulate`` solves with ``[contact] model = "exact"``): the same contact grid,
finger curvature and fingerprint ridges, friction direction and sensor weights
(:class:`tactilab.forward.SensorReadout`). Only the surface is unknown.

The profile grid (the rule). ``"line"``: a profile h(x) with ridges along y, over the strip the
finger's grid sweeps, ``[min(u) + x_0, max(u) + x_last]``; ``"patch"``: h(x, y) over the same strip
and the grid's width in y. Default spacing: the contact grid's (the forward model reads the surface
at its nodes; a coarser grid is interpolated linearly onto them, a finer one is refused). A periodic
cell's profile is its period, on its own nodes.
"""

from __future__ import annotations

import numpy as np

from tactilab.forward import SensorReadout, finger_gap
from tactilab.forward.scene_frames import SceneFrames

from tactilab.core import rules

from .surface import invert_scan
from .surface_scan import ContactScan, ProfileGrid

__all__ = ["invert_surface", "scene_scan", "GEOMETRIES"]

#: the unknown's geometries
GEOMETRIES = ("line", "patch")


def scene_scan(scene, recording=None, *, geometry: str = "line", spacing: float | None = None,
               grid_spacing: float | None = None, tol: float = 1e-10) -> ContactScan:
    """The scene's scan as a :class:`ContactScan` (heights -> sensor outputs), checked against ``recording``.

    Parameters
    ----------
    scene : data_schemas Scene
        A finger (``normal_force``, ``finger_radius``) or a periodic cell (``mean_pressure``).
    recording : data_schemas Recording, optional
        Checked: the scene's sensors (ids, components, quantity), its sampling rate and samples.
    geometry : {"line", "patch"}
    spacing : float, optional
        Profile spacing in m (default: the contact grid's; not finer than it).
    grid_spacing : float, optional
        The contact grid's spacing in m (default: the scene's, as ``tactilab simulate`` chooses it).
    tol : float
        The frames' contact-solver tolerance.
    """
    if geometry not in GEOMETRIES:
        raise ValueError(f"geometry: must be one of {GEOMETRIES}, got {geometry!r}")
    if spacing is not None:
        spacing = rules.spacing(spacing, 1)[0]
    if scene.contact is None:
        raise ValueError("scene.contact: a surface inversion needs a finger (or a periodic cell) touching the "
                         "surface; a display scene has no contact to invert")
    if recording is not None:
        _check_recording(scene, recording)
    frames = SceneFrames.from_scene(scene, grid_spacing)
    c = scene.contact
    if np.any(frames.slip_ratios < 1) or (c.adhesion > 0 and c.friction_coefficient > 0):
        raise ValueError("scene.contact: the surface inversion assumes full sliding in every frame; this scene has "
                         "partial slip (scan onset or adhesion > 0); drop the onset and the adhesion, or invert the "
                         "sliding part of the scan")
    h = float(frames.spacing[0])
    shape = frames.shape
    ridges = frames.ridges()
    shape_gap = -ridges if frames.periodic else finger_gap(shape, frames.spacing, c.finger_radius_m) - ridges
    n_nodes = int(np.prod(shape))
    readout = SensorReadout(frames.skin, shape, frames.spacing, scene.sensors, periodic=frames.periodic,
                            loads=("p", "qx"))
    w = readout.weights
    profile = _profile(frames, geometry, h if spacing is None else float(spacing), h)
    m = scene.material
    load = {"mean_pressure": c.mean_pressure_pa} if frames.periodic else {"normal_force": c.normal_force_n}
    return ContactScan(young_modulus=m.young_modulus_pa, poisson_ratio=m.poisson_ratio, grid_shape=shape,
                       spacing=h, shape_gap=np.ascontiguousarray(shape_gap), positions=frames.positions,
                       weights_p=w[:n_nodes], weights_q=w[n_nodes:2 * n_nodes], profile=profile,
                       quantity=scene.sensors.quantity, friction=c.friction_coefficient,
                       friction_direction=frames.direction, periodic=frames.periodic, tol=tol, **load)


def _profile(frames, geometry: str, spacing: float, grid: float) -> ProfileGrid:
    if spacing < grid * (1 - 1e-9):
        raise ValueError(f"spacing: the profile's spacing must be at least the contact grid's {grid:.4g} m (the "
                         f"forward model reads the surface at its nodes), got {spacing!r}; give spacing >= {grid:.4g}")
    if frames.periodic:
        period = grid * frames.shape[-1]
        count = period / spacing
        if geometry != "line" or abs(count - round(count)) > 1e-6 * count:
            raise ValueError(f"spacing: a periodic cell's profile is a 'line' over its period {period:.4g} m with a "
                             f"whole number of nodes, got geometry {geometry!r} and spacing {spacing!r} "
                             f"({count:.4g} nodes); give a spacing that divides the period")
        return ProfileGrid(x=frames.x[0] + spacing * np.arange(int(round(count))), periodic=True)
    x0 = float(frames.positions.min() + frames.x[0])
    x1 = float(frames.positions.max() + frames.x[-1])
    x = x0 + spacing * np.arange(int(np.ceil((x1 - x0) / spacing - 1e-9)) + 1)
    if geometry == "line":
        return ProfileGrid(x=x)
    y0, y1 = float(frames.y[0]), float(frames.y[-1])
    y = y0 + spacing * np.arange(int(np.ceil((y1 - y0) / spacing - 1e-9)) + 1)
    return ProfileGrid(x=x, y=y)


def _check_recording(scene, recording) -> None:
    recording.check_matches(scene.sensors)
    s = scene.scan
    if recording.n_times != s.n_samples:
        raise ValueError(f"recording: {recording.n_times} samples, but the scene's scan has {s.n_samples} "
                         "(duration x sampling rate); pair the recording with the scene that produced it")
    if abs(recording.sampling_rate_hz - s.sampling_rate_hz) > 1e-9 * s.sampling_rate_hz:
        raise ValueError(f"recording.sampling_rate_hz: {recording.sampling_rate_hz!r} Hz, but the scene samples at "
                         f"{s.sampling_rate_hz!r} Hz; pair the recording with the scene that produced it")
    values = np.asarray(recording.values, dtype=float)
    if not np.all(np.isfinite(values)):
        raise ValueError("recording.values: the surface inversion needs finite sensor values (no NaN or inf); drop "
                         "or repair the bad samples")


def invert_surface(scene, recording, *, geometry: str = "line", spacing: float | None = None, prior=None,
                   context: dict | None = None, method: str = "laplace", rng: np.random.Generator,
                   grid_spacing: float | None = None, n_draws: int = 400, truth=None, **options):
    """The surface a finger scan touched: its posterior from the scene and the recording.

    Parameters
    ----------
    scene : data_schemas Scene
        The scan's finger, skin, sensors and motion (the surface record is not used: it is the unknown).
    recording : data_schemas Recording
        The sensors' time series (Pa or tensor strain), the scene's sensors and sampling.
    geometry : {"line", "patch"}
        ``"line"``: a profile h(x), ridges along y; ``"patch"``: h(x, y) under the finger.
    spacing : float, optional
        Profile spacing, m (the rule: module docstring).
    prior : StationaryPrior or None
        The heights' prior (e.g. ``StationaryPrior(variance=(5e-6)**2, correlation_length=0.2e-3,
        kind="self_affine", hurst=0.8)``); None: flat (the grid must then be resolved by the data).
    context : dict, optional
        ``normal_force`` (N), ``friction``, ``young_modulus`` (Pa) -> a float (fixed) or a
        ``Uniform``, ``Normal`` or ``LogNormal`` prior (free, marginalised); default: the scene's values.
    method : {"laplace", "mcmc"}
    rng : numpy.random.Generator
    grid_spacing : float, optional
        The contact grid's spacing, m (default: the scene's).
    n_draws : int
        Posterior draws kept.
    truth : ndarray, optional
        The true profile on the profile grid (m), for the figure.
    **options
        Passed to :func:`~tactilab.inversion.surface.invert_scan` (``max_iter``, ``mcmc_options``).

    Returns
    -------
    SurfacePosterior
    """
    if spacing is not None:
        spacing = rules.spacing(spacing, 1)[0]
    scan = scene_scan(scene, recording, geometry=geometry, spacing=spacing, grid_spacing=grid_spacing)
    noise = float(scene.sensors.noise_std)
    if not noise > 0:
        raise ValueError(f"scene.sensors.noise_std: the likelihood needs the noise level ({recording.unit}) > 0, got "
                         f"{noise!r}; give the sensors' noise_std in the scene")
    data = np.asarray(recording.values, dtype=float).reshape(recording.n_times, -1)
    return invert_scan(scan, data, noise, prior=prior, context=context, method=method, rng=rng, n_draws=n_draws,
                       truth=truth, **options)

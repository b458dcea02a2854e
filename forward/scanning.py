"""Scanning a surface with the biomimetic finger: sensor time series as a data_schemas Recording.

The surface modulates the interfacial stress (docs/theory.md 4b): at finger position u (world x of
the contact centre) the traction at finger node (x, y) is ``traction(x, y) * M(x + u, y)`` with
``M = max(0, 1 + h / h_ref)`` (``h_ref`` defaults to the surface's peak |height|, so a +-A grating
is the T = +-1 texture of the paper and a bump of height h is a load of strength = its
footprint). The outputs are linear in M, so the whole scan is ONE matrix product:
``outputs[t] = M_t @ W`` with the per-node weights ``W`` (:meth:`BiomimeticFinger.node_weights`)
built once; frames are evaluated in batches. When the frame step is a whole number of grid
spacings (speed / rate = k h), the surface is sampled once on a world strip and each frame is a
window of it (no per-frame surface evaluation).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from tactilab.data_schemas.recording import Recording

from .finger import BiomimeticFinger
from .surfaces import Feature, RecordFeature, Surface, as_feature

if TYPE_CHECKING:  # type hints only
    from tactilab.data_schemas.scene import Scene
    from tactilab.data_schemas.surface import Surface as SurfaceRecord


def feature_peak(feature: Feature) -> float:
    """Largest |height| (m) of a feature: a record's peak, or a texture's amplitude."""
    if isinstance(feature, RecordFeature):
        return feature.peak()
    return abs(float(getattr(feature, "amplitude", 0.0)))


def scanned_surface(record_or_features: SurfaceRecord | Feature | Iterable[Feature], positions: ArrayLike,
                    finger: BiomimeticFinger, *,
                    width: float | None = None, reach: float | None = None) -> Surface:
    """The strip of surface a scan touches, holding the given features; raises if a defect
    lies outside it (the finger would never touch it) or a measured map does not cover it.

    The strip is ``x in [min(u) - reach, max(u) + reach]``, ``|y| <= width / 2``: the one extent
    both the check and the returned surface use, so a scan never reads a point the check did not
    cover.

    Parameters
    ----------
    record_or_features : data_schemas surface record, Feature, or iterable of them
    positions : ndarray
        World x of the contact centre per frame, m.
    finger : BiomimeticFinger
    width : float, optional
        Strip width across the scan (m); default ``2 * reach``.
    reach : float, optional
        How far the scan reads around the contact centre, along x (m, > 0); default the finger
        grid's half-width (the modulation model's grid). A caller reading a wider grid (the exact
        and linear models' contact grid, ``SceneFrames``) passes its own.
    """
    if isinstance(record_or_features, Feature):
        feats = (record_or_features,)
    elif hasattr(record_or_features, "height_at"):
        feats = (RecordFeature(record_or_features),)
    elif isinstance(record_or_features, Iterable):
        feats = tuple(as_feature(f) for f in record_or_features)
    else:
        raise ValueError(f"surface: expected a surface record or Feature(s), got {type(record_or_features).__name__}")
    if reach is None:
        reach = float(finger.grid()[0][-1])
    elif not (math.isfinite(reach) and reach > 0):
        raise ValueError(f"reach: the half-width the scan reads around the contact centre must be finite and > 0 m, "
                         f"got {reach!r}; omit it for the finger grid's")
    reach = float(reach)
    u = np.asarray(positions, dtype=float)
    x0, x1, half = float(u.min()) - reach, float(u.max()) + reach, (reach if width is None else width / 2)
    for f in feats:
        known = f.coverage() if isinstance(f, RecordFeature) else None
        if known is not None:
            _check_coverage(known, (x0, x1, -half, half), getattr(f, "label", "measured"), u, reach)
        b = f.bounds() if isinstance(f, Feature) else None
        if b is None:
            continue
        ylo, yhi = (b[2] if math.isfinite(b[2]) else -half), (b[3] if math.isfinite(b[3]) else half)
        if b[0] < x0 or b[1] > x1 or ylo < -half or yhi > half:
            raise ValueError(
                f"surface: the {getattr(f, 'label', type(f).__name__)} at x in [{b[0]:.6g}, {b[1]:.6g}] m, "
                f"y in [{b[2]:.6g}, {b[3]:.6g}] m lies outside the surface strip the scan touches "
                f"(x in [{x0:.6g}, {x1:.6g}] m, |y| <= {half:.4g} m: the contact centre moves from {u.min():.6g} "
                f"to {u.max():.6g} m along y = 0 and reaches {reach:.4g} m around it); move the defect into "
                "the strip or change the scan's start position, speed or duration"
            )
    return Surface(length=x1 - x0, width=2 * half, features=feats, x_start=x0)


def _check_coverage(known, strip, label: str, u: np.ndarray, reach: float) -> None:
    """Refuse a scan whose strip leaves a measured map, naming both sizes (a larger map is cropped)."""
    (kx0, kx1, ky0, ky1), (sx0, sx1, sy0, sy1) = known, strip
    tol = 1e-9 * (sx1 - sx0)
    if sx0 < kx0 - tol or sx1 > kx1 + tol or sy0 < ky0 - tol or sy1 > ky1 + tol:
        ky = "every y" if not math.isfinite(ky0) else f"y in [{ky0:.6g}, {ky1:.6g}] m ({(ky1 - ky0) * 1e3:.4g} mm)"
        raise ValueError(
            f"surface: the {label} map covers x in [{kx0:.6g}, {kx1:.6g}] m ({(kx1 - kx0) * 1e3:.4g} mm), {ky}, "
            f"smaller than the strip the scan touches, x in [{sx0:.6g}, {sx1:.6g}] m ({(sx1 - sx0) * 1e3:.4g} mm), "
            f"y in [{sy0:.6g}, {sy1:.6g}] m ({(sy1 - sy0) * 1e3:.4g} mm: the contact centre moves from {u.min():.6g} "
            f"to {u.max():.6g} m and reaches {reach:.4g} m around it); shorten the scan, move it with the "
            "scan's start position or the map's origin_m, or measure a larger area")


def reference_height(surface: Surface) -> float:
    """Default h_ref: the largest feature peak |height| (m); 1 m for a flat surface (no effect)."""
    peaks = [feature_peak(f) for f in surface.features]
    peak = max(peaks, default=0.0)
    return peak if peak > 0 else 1.0


MAX_OUTPUT_VALUES = 2**27  # 1 GiB of float64 outputs (or surface strip) per scan
MAX_FRAMES = 2**24


def scan_outputs(finger: BiomimeticFinger, surface: Surface, positions: ArrayLike, *, y_offset: float = 0.0,
                 reference_height_m: float | None = None, batch: int = 256,
                 weights=None, progress: bool = False) -> np.ndarray:
    """Sensor outputs while the finger slides over ``surface``.

    Parameters
    ----------
    finger : BiomimeticFinger
    surface : Surface
        Features in the world frame (see :func:`scanned_surface`).
    positions : array_like, shape (n_frames,)
        World x of the contact centre at each frame, m.
    y_offset : float
        World y of the contact centre (the scan line), m.
    reference_height_m : float, optional
        h_ref in m (height that doubles the interfacial stress); default the surface peak.
    batch : int
        Frames per matrix product (memory ~ batch x n_nodes doubles).
    weights : tuple, optional
        ``finger.node_weights()`` if already computed (reuse across scans).
    progress : bool
        Show a tqdm bar over batches.

    Returns
    -------
    ndarray, shape (n_frames, n_sensors, n_components): Pa (stress) or strain (tensor shear).
    """
    u = np.atleast_1d(np.asarray(positions, dtype=float))
    if u.ndim != 1 or u.size == 0 or not np.all(np.isfinite(u)):
        raise ValueError(f"positions: need a non-empty finite 1-D array of finger positions in m, got shape {u.shape}")
    if not isinstance(surface, Surface):
        raise ValueError(f"surface: expected a forward.surfaces.Surface, got {type(surface).__name__}; "
                         "wrap records with scanned_surface(...)")
    if int(batch) < 1:
        raise ValueError(f"batch: frames per product must be >= 1, got {batch!r}")
    h_ref = reference_height(surface) if reference_height_m is None else reference_height_m
    X, Y, W = finger.node_weights() if weights is None else weights
    n_s, n_c = finger.sensors.n_sensors, finger.sensors.n_components
    if u.size * W.shape[1] > MAX_OUTPUT_VALUES:
        raise ValueError(
            f"positions: {u.size} frames x {W.shape[1]} outputs (sensors x components) = {u.size * W.shape[1]} "
            f"values, above the limit {MAX_OUTPUT_VALUES} (memory); shorten the scan, lower the sampling rate "
            "or use fewer sensors")
    out = np.empty((u.size, W.shape[1]))
    starts = range(0, u.size, int(batch))
    if progress:
        from tqdm import tqdm

        starts = tqdm(starts, desc="scan frames", unit="batch")
    h = finger.spacing
    steps = (u - u[0]) / h
    strip = None
    on_nodes = np.allclose(steps, np.round(steps), rtol=0.0, atol=1e-6)
    reach_x, reach_y = (float(np.abs(X).max()), float(np.abs(Y).max())) if X.size else (0.0, 0.0)
    strip_size = (steps.max() - steps.min() + 2 * reach_x / h + 3) * (2 * reach_y / h + 3)
    if on_nodes and strip_size <= MAX_OUTPUT_VALUES:
        # frames land on grid nodes: sample the surface ONCE on a world strip and slide over it
        # (unless that strip would be too large: then sample per batch, slower but bounded memory)
        k = np.round(steps).astype(np.int64)
        ix, iy = np.round(X / h).astype(np.int64), np.round(Y / h).astype(np.int64)
        c0, r0 = ix.min() + k.min(), iy.min()
        cols = np.arange(c0, ix.max() + k.max() + 1)
        rows = np.arange(r0, iy.max() + 1)
        strip = surface.modulation(u[0] + cols[None, :] * h, y_offset + rows[:, None] * h,
                                   reference_height=h_ref)
    for i0 in starts:
        uu = u[i0:i0 + int(batch), None]
        if strip is None:
            M = surface.modulation(X[None, :] + uu, Y[None, :] + y_offset, reference_height=h_ref)
        else:
            M = strip[iy - r0, ix[None, :] + k[i0:i0 + int(batch), None] - c0]
        out[i0:i0 + uu.shape[0]] = M @ W
    return out.reshape(u.size, n_s, n_c)


def check_scan(speed: float, sampling_rate: float, duration: float) -> int:
    """Validate scan timing and return the number of frames ``floor(duration * sampling_rate)``.

    Parameters
    ----------
    speed : float
        Finger speed in m/s (> 0).
    sampling_rate : float
        Sensor sampling rate in Hz (> 0).
    duration : float
        Record length in s (> 0); at most ``MAX_FRAMES`` frames.
    """
    if not math.isfinite(speed) or speed <= 0:
        raise ValueError(f"speed: a scan time series needs a finger speed > 0 m/s, got {speed!r}; "
                         "give e.g. 0.05 (5 cm/s), or use receptive_field() for a static map")
    if not math.isfinite(sampling_rate) or sampling_rate <= 0:
        raise ValueError(f"sampling_rate: must be finite and > 0 Hz, got {sampling_rate!r}")
    if not math.isfinite(duration) or duration <= 0:
        raise ValueError(f"duration: must be finite and > 0 s, got {duration!r}")
    n = int(math.floor(duration * sampling_rate + 1e-9))
    if n < 1:
        raise ValueError(f"duration: {duration!r} s at {sampling_rate!r} Hz gives no sample; record for longer")
    if n > MAX_FRAMES:
        raise ValueError(f"duration: {duration!r} s at {sampling_rate!r} Hz gives {n} frames, above the limit "
                         f"{MAX_FRAMES} (memory); shorten the scan or lower the sampling rate")
    return n


def scan_recording(finger: BiomimeticFinger, surface: SurfaceRecord | Feature | Surface, *, speed: float,
                   sampling_rate: float,
                   duration: float, start_position: float = 0.0, y_offset: float = 0.0,
                   reference_height_m: float | None = None, progress: bool = False,
                   description: str = "") -> Recording:
    """Scan at constant ``speed`` (m/s) and return the sensors' time series as a Recording.

    ``surface`` is a data_schemas surface record, a Feature or a :class:`Surface`; the contact
    centre is at world x = ``start_position + speed * t`` (m) for ``t = i / sampling_rate`` (s),
    ``i < duration * sampling_rate``.

    Raises
    ------
    ValueError
        For a speed <= 0 (no time series), a bad rate or duration, or a defect off the scanned strip.
    """
    n = check_scan(float(speed), float(sampling_rate), float(duration))
    u = float(start_position) + float(speed) * np.arange(n) / float(sampling_rate)
    surf = surface if isinstance(surface, Surface) else scanned_surface(surface, u, finger)
    values = scan_outputs(finger, surf, u, y_offset=y_offset, reference_height_m=reference_height_m,
                          progress=progress)
    return Recording.from_sensors(finger.sensors, values, float(sampling_rate), description=description)


def surface_spacing(record: SurfaceRecord) -> float | None:
    """Grid spacing (m) that resolves a surface record's relief, or None (flat): an isolated
    defect needs size / 6 (its load is integrated node by node), a random or regular square
    wave element / 2, a sinusoid period / 8, a height map, random rough or measured surface its
    own spacing."""
    kind = getattr(record, "kind", None)
    if kind == "defect":
        return float(record.size_m) / 6
    if kind == "square_wave_grating":
        return float(record.element_width_m) / 2
    if kind == "sinusoidal_grating":
        return float(record.period_m) / 8
    if kind == "height_map":
        return float(record.spacing_x_m)
    if kind == "random_rough":
        return float(record.spacing_m)
    if kind == "measured":
        return float(record.height_map.spacing_x_m)
    return None


def scene_finger(scene: Scene, grid_spacing: float | None = None) -> BiomimeticFinger:
    """The finger of a Scene, with a grid fine enough for its surface (:func:`surface_spacing`)
    unless ``grid_spacing`` (m) is given."""
    finger = BiomimeticFinger.from_scene(scene, grid_spacing=grid_spacing)
    need = surface_spacing(scene.surface)
    if grid_spacing is None and need is not None and need < finger.spacing:
        finger = BiomimeticFinger.from_scene(scene, grid_spacing=need)
    return finger


def scene_recording(scene: Scene, *, progress: bool = False, grid_spacing: float | None = None) -> Recording:
    """Simulate a data_schemas Scene with a finger contact: the sensors' Recording.

    The contact grid resolves the surface (:func:`scene_finger`) unless ``grid_spacing`` (m) is given.
    """
    finger = scene_finger(scene, grid_spacing)
    s = scene.scan
    return scan_recording(finger, scene.surface, speed=s.speed_m_per_s, sampling_rate=s.sampling_rate_hz,
                          duration=s.duration_s, start_position=s.start_position_m, progress=progress,
                          description=f"tactilab simulate: {scene.name or 'scene'}; {scene.description}".strip())

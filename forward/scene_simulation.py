"""Simulate a finger scene to files: the sensors' recording (netCDF or Parquet) and PNG plots.

Used by ``tactilab simulate SCENE.toml``; everything is SI inside, the figures use mm / kPa.
The recording files are written and read by :mod:`tactilab.data_schemas.recording_io`.
"""

from __future__ import annotations

import math
import pathlib
import time

import numpy as np

from tactilab.data_schemas.interface_model import model_attrs, model_statement
from tactilab.data_schemas.plausibility import check_small_strain
from tactilab.data_schemas.recording import Recording
from tactilab.data_schemas.recording_io import FORMATS, write_recording

from .finger_plots import plot_field_maps, plot_receptive_fields, plot_spectrum, plot_time_series
from .halfspace import largest_strain
from .scanning import check_scan, reference_height, scan_outputs, scanned_surface, scene_finger
from .scene_layered import refuse_layered_modulation
from .scene_metadata import recording_attrs
from .scene_model_files import simulate_contact_model as _simulate_contact_model
from .surfaces import RecordFeature


def simulate_scene(scene, out_dir, *, fmt: str = "netcdf", rng: np.random.Generator | None = None,
                   progress: bool = False, grid_spacing: float | None = None, plots: bool = True) -> list[str]:
    """Scan a finger scene and write its recording and figures; return lines describing what was done.

    Parameters
    ----------
    scene : data_schemas Scene
        With a ``contact`` (finger) and a scan speed > 0.
    out_dir : path
        Created if missing.
    fmt : {"netcdf", "parquet"}
    rng : numpy Generator, optional
        If given and the sensors have ``noise_std > 0``, white measurement noise is added.
    progress : bool
        tqdm bar over frame batches.
    grid_spacing : float, optional
        Contact-grid spacing in m (default: resolves the contact, depth and the surface relief).
    plots : bool
        Write the PNG figures.
    """
    if fmt not in FORMATS:
        raise ValueError(f"format: must be one of {FORMATS}, got {fmt!r}")
    if scene.display is not None:
        return _simulate_display(scene, pathlib.Path(out_dir), fmt, rng, plots)
    s = scene.scan
    n = check_scan(s.speed_m_per_s, s.sampling_rate_hz, s.duration_s)
    if scene.material.is_layered:  # a layered skin: the solved contact (models exact and linear)
        refuse_layered_modulation(scene.contact.model)
    if scene.contact.model != "modulation" or scene.contact.periodic or s.onset_s > 0:
        return _simulate_contact_model(scene, pathlib.Path(out_dir), fmt, rng, progress, grid_spacing, plots)
    finger = scene_finger(scene, grid_spacing)
    u = s.start_position_m + s.speed_m_per_s * np.arange(n) / s.sampling_rate_hz
    surface = scanned_surface(scene.surface, u, finger)
    h_ref = reference_height(surface)
    t0 = time.perf_counter()
    weights = finger.node_weights()
    values = scan_outputs(finger, surface, u, reference_height_m=h_ref, weights=weights, progress=progress)
    elapsed = time.perf_counter() - t0
    c = finger.contact  # values: (frame, sensor, component); one max over them (before noise)
    check_small_strain(largest_strain(np.moveaxis(values, 2, 1), finger.sensors.quantity, finger.sensors.components,
                                      c.young_modulus, c.poisson_ratio), "simulate (sensor readings)")
    noise = float(scene.sensors.noise_std)
    if rng is not None and noise > 0:
        values = values + noise * rng.standard_normal(values.shape)
    tol = float(scene.contact.tol)
    basis = "not estimated: the scene sets model = modulation"
    rec = Recording.from_sensors(finger.sensors, values, s.sampling_rate_hz,
                                 description=f"tactilab simulate: {scene.name or 'scene'}. {scene.description} "
                                             + model_statement("modulation", tol, {}, basis))
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    # what invert checks the scene against, and the interface model the recording was made with
    attrs = dict(recording_attrs(finger), **model_attrs("modulation", tol, {}, basis, "the scene's [contact] model"))
    path = write_recording(rec, out, fmt, positions_m=u, sensor_positions_m=finger.sensors.positions_m, attrs=attrs)
    scale = 1e-3 if rec.quantity == "stress" else 1.0
    unit = "kPa" if rec.quantity == "stress" else "strain"
    lines = [
        f"scene {scene.name or '(unnamed)'}: Hertz contact a = {c.contact_radius * 1e3:.2f} mm, "
        f"p0 = {c.peak_pressure * 1e-3:.1f} kPa at {c.normal_force:g} N; mu = {finger.friction:g}, "
        f"adhesion = {finger.adhesion:g}",
        "interface model: modulation (the scene's [contact] model; docs/theory.md 4b, M = 1 + h / h_ref)",
        f"model errors: {basis}",
        f"scan: {n} frames at {s.sampling_rate_hz:g} Hz, {s.speed_m_per_s * 1e3:g} mm/s, contact centre "
        f"{u[0] * 1e3:.2f} -> {u[-1] * 1e3:.2f} mm; {finger.sensors.n_sensors} sensors x "
        f"{finger.sensors.n_components} components at {finger.depth * 1e3:.2f} mm depth",
        f"method: precomputed node-weight matrix ({weights[0].size} loaded nodes, grid {finger.spacing * 1e6:.0f} um), "
        f"batched frames: {elapsed:.3f} s ({1e3 * elapsed / n:.3f} ms per frame)",
        f"output range: {values.min() * scale:.4g} .. {values.max() * scale:.4g} {unit}"
        + (f" (noise std {noise * scale:.3g} {unit} added)" if rng is not None and noise > 0 else ""),
        f"recording: {path}",
    ]
    if plots:
        defect = next((f for f in surface.features if isinstance(f, RecordFeature) and f.record.kind == "defect"), None)
        at = u[int(np.argmin(np.abs(u - defect.record.position_m[0])))] if defect is not None else u[n // 2]
        maps, method = plot_field_maps(finger, out / "field_maps.png", surface=surface, position=at,
                                       reference_height_m=h_ref)
        strength = 1e-8
        if defect is not None and math.isfinite(defect.integral()) and defect.integral() != 0:
            strength = defect.integral() / h_ref
        rf = plot_receptive_fields(finger, out / "receptive_fields.png", strength=strength)
        ts = plot_time_series(rec, out / "time_series.png", positions=u)
        files = [str(maps), str(rf), str(ts)]
        if n >= 64:
            files.append(str(plot_spectrum(rec, out / "spectrum.png")))
        lines.append(f"plots (maps by {method}): " + ", ".join(files))
    return lines


def _simulate_display(scene, out: pathlib.Path, fmt: str, rng, plots: bool) -> list[str]:
    """A display scene: the display renders ``scene.surface`` (module :mod:`.display_scene`)."""
    from .display_scene import display_scene_outputs
    from .finger_plots import plot_rendered_vs_real

    s = scene.scan
    check_scan(s.speed_m_per_s, s.sampling_rate_hz, s.duration_s)
    values, loads, info = display_scene_outputs(scene)
    noise = float(scene.sensors.noise_std)
    clean = values
    if rng is not None and noise > 0:
        values = values + noise * rng.standard_normal(values.shape)
    rec = Recording.from_sensors(scene.sensors, values, s.sampling_rate_hz,
                                 description=f"tactilab simulate (display): {scene.name or 'scene'}. {scene.description}")
    out.mkdir(parents=True, exist_ok=True)
    path = write_recording(rec, out, fmt, positions_m=s.positions_m,  # what invert checks the scene against
                           attrs=dict(depth_m=float(scene.sensors.depth_m),
                                      young_modulus_pa=scene.material.young_modulus_pa,
                                      poisson_ratio=scene.material.poisson_ratio))
    d = scene.display
    limit = d.max_traction_pa
    lines = [
        f"scene {scene.name or '(unnamed)'}: display {d.display_id} ({d.rows} x {d.columns} tractors, pitch "
        f"{d.pitch_x_m * 1e3:g} mm) renders {scene.surface.kind} at {s.speed_m_per_s * 1e3:g} mm/s "
        "(plane model: rows uniform in y)",
        f"drive: gain {info['gain']:.4g} (N/m)/m (strain-matched at the rendered pitch "
        f"{info['rendered_pitch'] * 1e3:.3g} mm, depth {scene.sensors.depth_m * 1e3:g} mm); peak traction "
        f"{info['peak_traction'] / 1e3:.3g} kPa" + (f" (limit {limit / 1e3:g} kPa)" if limit is not None else ""),
        f"recording: {path}",
    ]
    if "real" in info:
        real = info["real"]
        for c, comp in enumerate(scene.sensors.components):
            a, b = clean[..., c].ravel(), real[..., c].ravel()
            corr = float(a @ b / math.sqrt((a @ a) * (b @ b))) if a.any() and b.any() else float("nan")
            ratio = float(np.abs(a).max() / np.abs(b).max()) if b.any() else float("nan")
            lines.append(f"rendered vs real sliding grating, {comp}: normalised correlation {corr:.3f}, "
                         f"peak ratio {ratio:.3f}")
    if plots:
        files = [plot_time_series(rec, out / "time_series.png", positions=s.positions_m)]
        if rec.n_times >= 64:
            files.append(plot_spectrum(rec, out / "spectrum.png"))
        if "real" in info:
            files.append(plot_rendered_vs_real(scene.sensors, clean, info["real"], out / "rendered_vs_real.png",
                                               sampling_rate_hz=s.sampling_rate_hz))
        lines.append("plots: " + ", ".join(str(f) for f in files))
    return lines

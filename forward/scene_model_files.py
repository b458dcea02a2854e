"""``tactilab simulate`` for a scene through its interface model: recording, statement of the model, plots.

Used by :func:`.scene_simulation.simulate_scene` for every finger or periodic-cell scene except a
finger with ``model = "modulation"`` and no onset (today's node-weight scan, unchanged). The
recording states the model it was made with and the error of the cheaper models for the scene
(:mod:`tactilab.data_schemas.interface_model`).
"""

from __future__ import annotations

import math
import pathlib

import numpy as np

from tactilab.data_schemas.interface_model import model_attrs, model_statement
from tactilab.data_schemas.plausibility import check_small_strain
from tactilab.data_schemas.recording import Recording
from tactilab.data_schemas.recording_io import write_recording

from .contact import solve_contact
from .finger_plots import plot_field_maps, plot_receptive_fields, plot_spectrum, plot_time_series
from .halfspace import largest_strain
from .scene_models import scene_signals
from .scene_layered import describe_layers
from .scene_metadata import recording_attrs
from .surfaces import RecordFeature

_MODEL_WORDS = {"exact": "every frame's contact solved (solve_contact, warm-started from the previous frame)",
                "linear": "the finger's pressure plus the texture's full-contact pressure E* |k| H / 2, clipped at 0",
                "modulation": "docs/theory.md 4b's M = 1 + h / h_ref on the finger's traction"}


def _errors_line(info: dict) -> str:
    if not info["errors"]:
        return f"model errors: {info['error_basis']}"
    listed = ", ".join(f"{m} {e:.2g}" for m, e in info["errors"].items())
    return (f"model errors: {listed} of the sensor signal (max |error| / max |signal| per sensor and component; "
            f"{info['error_basis']}); tol {info['tol']:g}")


def simulate_contact_model(scene, out: pathlib.Path, fmt: str, rng, progress: bool, grid_spacing, plots: bool):
    """Simulate ``scene`` through ``scene.contact.model`` and write its files; return the summary lines."""
    values, info = scene_signals(scene, grid_spacing=grid_spacing, progress=progress)
    frames = info.pop("frames")
    m = scene.material
    check_small_strain(largest_strain(np.moveaxis(values, 2, 1), scene.sensors.quantity, scene.sensors.components,
                                      m.young_modulus_pa, m.poisson_ratio), "simulate (sensor readings)")
    noise = float(scene.sensors.noise_std)
    if rng is not None and noise > 0:
        values = values + noise * rng.standard_normal(values.shape)
    s = scene.scan
    statement = model_statement(info["model"], info["tol"], info["errors"], info["error_basis"])
    rec = Recording.from_sensors(scene.sensors, values, s.sampling_rate_hz,
                                 description=f"tactilab simulate: {scene.name or 'scene'}. {scene.description} "
                                             + statement)
    out.mkdir(parents=True, exist_ok=True)
    # what invert checks the scene against (a cell: its sensors and skin), and the interface model
    scene_attrs = recording_attrs(frames.finger) if not frames.periodic else dict(
        depth_m=float(scene.sensors.depth_m), young_modulus_pa=m.young_modulus_pa, poisson_ratio=m.poisson_ratio,
        mean_pressure_pa=frames.mean_pressure, friction=frames.friction, grid_spacing_m=float(frames.spacing[0]))
    if frames.layered:  # the top layer's constants, as the scene states them, and the layers in words
        scene_attrs.update(young_modulus_pa=m.young_modulus_pa, poisson_ratio=m.poisson_ratio,
                           skin_layers=describe_layers(m))
    attrs = dict(scene_attrs, **model_attrs(info["model"], info["tol"], info["errors"], info["error_basis"],
                                            info["reason"]))
    path = write_recording(rec, out, fmt, positions_m=frames.positions, sensor_positions_m=scene.sensors.positions_m,
                           attrs=attrs)
    n = frames.n_frames
    if frames.periodic:
        what = (f"periodic cell of {frames.shape[-1]} nodes at {frames.spacing[0] * 1e6:.3g} um"
                + (" (plane strain)" if len(frames.shape) == 1 else "")
                + f", mean pressure {frames.mean_pressure * 1e-3:.3g} kPa; mu = {frames.friction:g}")
    else:
        c = frames.finger.contact
        what = (f"Hertz contact a = {c.contact_radius * 1e3:.2f} mm, p0 = {c.peak_pressure * 1e-3:.1f} kPa at "
                f"{c.normal_force:g} N; mu = {frames.friction:g}, adhesion = {frames.finger.adhesion:g}; contact grid "
                f"{frames.shape[1]} x {frames.shape[0]} nodes at {frames.spacing[0] * 1e6:.3g} um")
        if frames.layered:  # the Hertz contact only sizes the grid there
            what = (f"layered skin ({describe_layers(m)}), contact solved on it (the grid sized by the Hertz "
                    "contact of its softest material: " + what[0].lower() + what[1:]
                    + f"; sensors read through the layers' transfer, truncation estimate "
                    f"{frames.readout().error_estimate:.1e})")
    iters = f"; median {info['iterations']:.0f} contact iterations per frame" if info["iterations"] is not None else ""
    scale, unit = (1e-3, "kPa") if rec.quantity == "stress" else (1.0, "strain")
    lines = [
        f"scene {scene.name or '(unnamed)'}: {what}; onset {s.onset_s * 1e3:g} ms",
        f"interface model: {info['model']} ({info['reason']})",
        _errors_line(info),
        f"scan: {n} frames at {s.sampling_rate_hz:g} Hz, {s.speed_m_per_s * 1e3:g} mm/s; {scene.sensors.n_sensors} "
        f"sensors x {scene.sensors.n_components} components at {scene.sensors.depth_m * 1e3:.2f} mm depth",
        f"method: {info['model']} model, {_MODEL_WORDS[info['model']]}; sensors read by one weight matrix: "
        f"{info['seconds']:.3f} s ({1e3 * info['seconds'] / n:.3f} ms per frame{iters})",
        f"output range: {values.min() * scale:.4g} .. {values.max() * scale:.4g} {unit}"
        + (f" (noise std {noise * scale:.3g} {unit} added)" if rng is not None and noise > 0 else ""),
        f"recording: {path}",
    ]
    if plots:
        files = [plot_time_series(rec, out / "time_series.png", positions=frames.positions)]
        if n >= 64:
            files.append(plot_spectrum(rec, out / "spectrum.png"))
        if not frames.periodic and not frames.layered:  # the finger's maps and receptive fields (modulation model)
            files.extend(_finger_figures(scene, frames, out))
        if info["model"] == "exact":
            mid = n // 2
            sol = solve_contact(frames.skin, frames.gap(mid), frames.spacing, periodic=frames.periodic,
                                **frames.load)
            files.append(sol.plot(out / "contact_pressure.png"))
        lines.append("plots: " + ", ".join(str(f) for f in files)
                     + ("" if frames.periodic or frames.layered
                        else " (field_maps and receptive_fields: the modulation model's)"))
    return lines


def _finger_figures(scene, frames, out: pathlib.Path) -> list:
    surface = frames._surface
    h_ref = frames._h_ref
    defect = next((f for f in surface.features if isinstance(f, RecordFeature) and f.record.kind == "defect"), None)
    u = frames.positions
    at = u[int(np.argmin(np.abs(u - defect.record.position_m[0])))] if defect is not None else u[u.size // 2]
    maps, _ = plot_field_maps(frames.finger, out / "field_maps.png", surface=surface, position=at,
                              reference_height_m=h_ref)
    strength = 1e-8
    if defect is not None and math.isfinite(defect.integral()) and defect.integral() != 0:
        strength = defect.integral() / h_ref
    return [maps, plot_receptive_fields(frames.finger, out / "receptive_fields.png", strength=strength)]

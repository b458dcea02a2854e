"""Demo section: one texture scanned through each interface model, and the error of the cheaper ones.

A fingertip (radius 10 mm, 0.5 N, skin E = 1 MPa, nu = 0.5, friction 0.5) slides at 20 mm/s over a
sinusoidal grating (period 1 mm, amplitude 10 um); five strain sensors 0.5 mm deep record eps_zz
and eps_zx. The grating's full-contact pressure p* = pi E* A / L (42 kPa) is about half the contact's
mean pressure (80 kPa): the centre of the contact follows the grating, its rim does not. The scan is
simulated with the exact model (every frame's contact solved), the linear superposition and the
modulation of docs/theory.md 4b; ``"auto"`` says which the scene requires at tol 1 %, and the figure
shows how far off the cheaper ones are.

Then the founding papers' four studies through the solved contact (docs/scenes.md, "The founding
papers' studies"), one line each at a reduced size (about 4 s in all; the tables come from
``benchmarks/bench_scene_studies.py`` at full size, through the same ``tactilab.forward`` functions).
"""

from __future__ import annotations

import pathlib
import warnings
from collections.abc import Iterator

import numpy as np

from tactilab.data_schemas import Contact, Scan, Scene, SensorArray, SinusoidalGrating, SkinMaterial
from tactilab.forward import (AccuracyWarning, SceneFrames, choose_model, fingerprint_band_pass, kernel_error,
                              receptive_field_change, run_model, signal_error, superposition_error, wiener_kernels)

MODELS = ("exact", "linear", "modulation")


def demo_scene() -> Scene:
    """The section's scene (SI)."""
    return Scene(
        name="grating_through_the_contact",
        description="fingertip sliding over a 1 mm, 10 um sinusoidal grating, through each interface model",
        material=SkinMaterial(young_modulus_pa=1e6, poisson_ratio=0.5),
        surface=SinusoidalGrating(period_m=1e-3, amplitude_m=10e-6),
        contact=Contact(normal_force_n=0.5, finger_radius_m=10e-3, friction_coefficient=0.5, tol=1e-2),
        sensors=SensorArray.grid(5, 1, 0.4e-3, 0.5e-3, quantity="strain", components=("zz", "zx")),
        scan=Scan(speed_m_per_s=0.02, duration_s=0.1, sampling_rate_hz=1000.0, start_position_m=-1e-3),
    )


def plot_models(times_s, runs: dict, errors: dict, sensor: int, path: pathlib.Path, title: str,
                sensor_x: float = 0.0) -> pathlib.Path:
    """Each model's signal at one sensor (top) and the cheaper models' error against the exact one,
    relative to the exact signal's largest magnitude (bottom), per component (PNG)."""
    from matplotlib.figure import Figure

    exact = runs["exact"]
    n_comp = exact.shape[2]
    fig = Figure(figsize=(6 * n_comp, 7.5), layout="constrained")
    axes = fig.subplots(2, n_comp, squeeze=False)
    t = np.asarray(times_s) * 1e3
    style = {"exact": dict(color="k", lw=2), "linear": dict(color="tab:blue", ls="--"),
             "modulation": dict(color="tab:red", ls=":")}
    for c, comp in enumerate(("zz", "zx")[:n_comp]):
        scale = np.abs(exact[:, sensor, c]).max()
        for name, values in runs.items():
            axes[0, c].plot(t, values[:, sensor, c] * 1e3, label=name, **style[name])
            if name != "exact":
                axes[1, c].plot(t, (values[:, sensor, c] - exact[:, sensor, c]) / scale * 100, **style[name],
                                label=f"{name} (scene error {errors[name] * 100:.2g} %)")
        axes[0, c].set(title=f"strain {comp} at the sensor at x = {sensor_x * 1e3:.1f} mm", xlabel="time (ms)",
                       ylabel=f"eps_{comp} (x 1e-3)")
        axes[1, c].axhline(0, color="k", lw=0.5)
        axes[1, c].set(title=f"error against the exact model, % of max |exact {comp}|", xlabel="time (ms)",
                       ylabel="error (%)")
        for ax in axes[:, c]:  # below the panel: curves fill the whole panel, a legend inside hides some
            ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3, frameon=False)
    fig.suptitle(title, fontsize=10)
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    return path


def run_demo(report_dir: pathlib.Path, progress: bool = True) -> Iterator[str]:
    """Scan the demo grating with each model; write ``scene_models/models.png``; yield report lines."""
    out = pathlib.Path(report_dir) / "scene_models"
    out.mkdir(parents=True, exist_ok=True)
    scene = demo_scene()
    frames = SceneFrames.from_scene(scene)
    yield "== one texture through each interface model (docs/scenes.md, Interface models) =="
    runs, seconds = {}, {}
    for name in MODELS:
        run = run_model(frames, name, progress=progress)
        runs[name], seconds[name] = run.values, run.seconds
    errors = {m: signal_error(runs[m], runs["exact"]) for m in ("linear", "modulation")}
    choice = choose_model(frames, scene.contact.tol)
    for name in MODELS:
        err = "reference" if name == "exact" else f"error {errors[name] * 100:.2g} % of the signal"
        yield f"{name}: {seconds[name]:.2f} s for {frames.n_frames} frames ({err})"
    yield f"auto at tol {scene.contact.tol:g}: {choice.model} ({choice.reason})"
    # the sensor where the linear model is furthest off (the scene error is the largest over sensors)
    scale = np.abs(runs["exact"]).max(axis=0)
    worst = (np.abs(runs["linear"] - runs["exact"]).max(axis=0) / np.maximum(scale, 1e-3 * scale.max())).max(axis=1)
    sensor = int(np.argmax(worst))
    title = (f"grating 1 mm, 10 um under a 0.5 N fingertip: p_bar/p* = {choice.pressures['ratio']:.2f}; "
             f"auto picks {choice.model}")
    path = plot_models(scene.scan.times_s, runs, errors, sensor, out / "models.png", title,
                       sensor_x=float(scene.sensors.positions_m[sensor, 0]))
    yield f"figure: {path}"
    yield from study_lines()


def study_lines() -> Iterator[str]:
    """The founding papers' studies at a reduced size, one line each with its key figure (about 4 s).

    Sizes: 80 um nodes and a 20-frame-per-mm scan for the bumps (a, d), 128 frames of 50 um bars for
    the fingerprint (b, at 0.2 N) and 128 bits of 80 um for the Wiener kernel (c); the full-size
    tables (docs/scenes.md) differ in the digits, not in the findings.
    """
    yield "== the founding papers' studies through the solved contact, reduced (docs/scenes.md) =="
    with warnings.catch_warnings():  # coarse demo grids: the contact engine's resolution notes
        warnings.simplefilter("ignore", AccuracyWarning)
        (exact, gain), (_, mod_gain) = (receptive_field_change(m, 0.5, 50e-6, 1.6e-3, 80e-6)
                                         for m in ("exact", "modulation"))
        yield (f"(a) shape invariance, a 50 um bump against a 20 um one at 0.5 N: exact corr zz "
               f"{exact[0][0]:.4f}, zx {exact[1][0]:.4f}, gain per um {gain:.2f}; modulation gain per um "
               f"{mod_gain:.2f} (h / h_ref: blind to the height)")
        band = {m: fingerprint_band_pass(m, 50e-6, 2000.0, 128, 0.2) for m in ("exact", "modulation")}
        yield (f"(b) fingerprint band-pass, ridged / smooth skin's PSD at v / lambda = {band['exact']['band']:.0f} Hz: "
               f"exact {band['exact']['ratio']:.3g}, modulation {band['modulation']['ratio']:.3g}")
        kernels = wiener_kernels((1e-6, 20e-6), 80e-6, 128, models=("exact", "linear"))
        shallow, deep = (kernel_error(kernels[("exact", a)], kernels[("linear", 1e-6)]) for a in (1e-6, 20e-6))
        yield (f"(c) Wiener kernel of the solved contact per um of depth: gain {shallow['gain']:.2f} at 1 um, "
               f"{deep['gain']:.2f} at 20 um of the linear kernel (rel. error {shallow['error']:.2f}, "
               f"{deep['error']:.2f}): the non-linearity grows with the texture's depth")
        pair = {m: superposition_error(m, 20e-6, (0.4e-3,), 1.6e-3, 80e-6)[0.4e-3] for m in ("exact", "modulation")}
        yield (f"(d) two 20 um bumps 0.4 mm apart, superposition error (zz / zx): exact {pair['exact'][0]:.2g} / "
               f"{pair['exact'][1]:.2g}, modulation {pair['modulation'][0]:.1g} / {pair['modulation'][1]:.1g}")

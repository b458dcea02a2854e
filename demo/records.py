"""Demo section for ``tactilab demo``: the built-in example scenes, checked and drawn.

Loads each built-in TOML scene (units converted to SI once), saves it as an SI JSON record,
reloads the JSON and checks it equals the scene, and draws one figure per scene: the surface
height profile along the scan (mm, µm) and the sensor / tractor layout in the finger frame (mm).
"""

from __future__ import annotations

import pathlib
from collections.abc import Iterator

import numpy as np

from tactilab.data_schemas import Scene, list_examples, load_example


def _plot_scene(scene: Scene, path: pathlib.Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 4), layout="constrained")
    ax_h, ax_s = fig.subplots(1, 2)
    scan = scene.scan
    lo = min(scan.positions_m[0], scan.positions_m[-1]) - 5e-3
    hi = max(scan.positions_m[0], scan.positions_m[-1]) + 5e-3
    x = np.linspace(lo, hi, 2001)
    y = scene.surface.position_m[1] if hasattr(scene.surface, "position_m") else 0.0
    ax_h.plot(x * 1e3, scene.surface.height_at(x, np.full_like(x, y)) * 1e6)
    ax_h.axvspan(scan.positions_m[0] * 1e3, scan.positions_m[-1] * 1e3, alpha=0.15,
                 label="contact centre during the scan")
    ax_h.set(title=f"{scene.name}: surface ({scene.surface.kind})", xlabel="x (mm)", ylabel="height (µm)")
    ax_h.legend(loc="lower right", fontsize=8)
    pos = scene.sensors.positions_m * 1e3
    ax_s.plot(pos[:, 0], pos[:, 1], "o", ms=3,
              label=f"{scene.sensors.n_sensors} {scene.sensors.quantity} sensors at "
                    f"{scene.sensors.depth_m * 1e3:g} mm")
    if scene.display is not None:
        t = scene.display.tractor_positions_m * 1e3
        ax_s.plot(t[:, 0], t[:, 1], "s", mfc="none", ms=8, label=f"{scene.display.n_tractors} tractors")
    ax_s.set(title="finger frame layout", xlabel="x (mm)", ylabel="y (mm)", aspect="equal")
    ys = ax_s.get_ylim()
    half = max((ys[1] - ys[0]) / 2, 0.25 * np.ptp(pos[:, 0]), 1.0)  # a 1-D row of sensors is not squashed flat
    mid = (ys[0] + ys[1]) / 2
    ax_s.set_ylim(mid - half, mid + half)
    ax_s.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8)
    fig.savefig(path, dpi=110)


def run_demo(report_dir: pathlib.Path, progress: bool = True) -> Iterator[str]:
    """Load, round-trip and draw the built-in scenes; yield one line per step.

    Parameters
    ----------
    report_dir : Path
        Folder to write ``scene_<name>.json`` and ``scene_<name>.png`` into.
    progress : bool
        Unused (the section is instantaneous); kept for the common demo signature.
    """
    out = pathlib.Path(report_dir) / "scenes"
    out.mkdir(parents=True, exist_ok=True)
    names = list_examples()
    yield f"[data_schemas] {len(names)} built-in scenes (TOML with units, converted to SI once)"
    for name in names:
        scene = load_example(name)
        json_path = scene.save(out / f"scene_{name}.json")
        same = Scene.load(json_path) == scene
        _plot_scene(scene, out / f"scene_{name}.png")
        yield (f"  {name}: {scene.sensors.n_sensors} {scene.sensors.quantity} sensors at "
               f"{scene.sensors.depth_m * 1e3:g} mm, {scene.scan.n_samples} samples; "
               f"JSON round-trip {'exact' if same else 'NOT exact'} -> {json_path.name}, scene_{name}.png")
    yield f"  files in {out}"

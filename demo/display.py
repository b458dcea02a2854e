"""Demo: a tractor display rendering a virtual grating next to the real sliding grating.

Designs the tractor spacing for receptors at 1.25 mm (docs/theory.md 4a), drives a one-row
display as a travelling wave that follows a virtual sinusoid, and compares the strain at depth
with that of the real grating sliding over the finger. Also computes the same drive on a
STReSS2-like 6 x 10 array of finite patches in 3-D, to measure the plane-strain approximation.
"""

from __future__ import annotations

import pathlib
from collections.abc import Iterator

import numpy as np

from tactilab.data_schemas import DisplayDescription

from tactilab.forward import (display_patch_strain_3d, matching_line_load, optimal_half_spacing,
                              render_virtual_surface, sliding_sinusoid_strain)

DEPTH = 1.25e-3  # m, receptor depth of the demo
AMPLITUDE = 50e-6  # m, virtual grating amplitude
SPEED = 20e-3  # m/s, scanning speed
YOUNG = 200e3  # Pa, skin modulus (the strain does not depend on it; the traction does)


def _rms(a: np.ndarray, axis=0) -> np.ndarray:
    return np.sqrt(np.mean(a * a, axis=axis))


def run_demo(report_dir: pathlib.Path, progress: bool = True) -> Iterator[str]:
    """Render a virtual grating with a designed tractor row; write a PNG and a CSV.

    Parameters
    ----------
    report_dir : pathlib.Path
        Folder for ``display_strain.png`` and ``display_strain.csv`` (created if missing).
    progress : bool
        Show a tqdm bar for the 3-D array computation.

    Yields
    ------
    str
        Lines to print: the design, the drive, the match errors and where the files are.
    """
    from matplotlib.figure import Figure
    from tqdm import tqdm

    report_dir = pathlib.Path(report_dir)
    report_dir.mkdir(parents=True, exist_ok=True)
    design = optimal_half_spacing(DEPTH)
    d, pitch = design.d, design.pitch
    yield (f"tactile synthesis: receptors at Z = {DEPTH * 1e3:g} mm, window {design.width * 1e3:g} mm, "
           f"{design.pairs} pairs -> optimal half spacing d = {d * 1e3:.4f} mm (d/Z = {design.d_over_depth:.3f}), "
           f"k2 = {design.k2 * 1e-3:.4f} /mm, k2' = {design.k2_prime * 1e-3:.4f} /mm, "
           f"relative residual {design.relative_residual:.3f} ({len(design.minima)} local minima scanned)")
    display = DisplayDescription.braille_row(n_tractors=2 * design.pairs, pitch_x_m=2 * d)
    q_amp = matching_line_load(AMPLITUDE, None, None, YOUNG, design)
    tau_amp = q_amp / display.tractor_width_m
    yield (f"display: one row of {display.columns} tractors, pitch {display.pitch_x_m * 1e3:.3f} mm, footprint "
           f"{display.tractor_width_m * 1e3:.3f} mm; virtual grating A = {AMPLITUDE * 1e6:g} µm, p = 4d = "
           f"{pitch * 1e3:.3f} mm, V = {SPEED * 1e3:g} mm/s; matching drive {q_amp:.3g} N/m = "
           f"{tau_amp * 1e-3:.3g} kPa (limit {display.max_traction_pa * 1e-3:g} kPa, E = {YOUNG * 1e-3:g} kPa)")

    def height(x):
        return AMPLITUDE * np.sin(2 * np.pi * x / pitch)

    period = pitch / SPEED
    times = np.linspace(0.0, period, 64, endpoint=False)
    x = np.linspace(-8e-3, 8e-3, 401)
    # drive checked against the display's traction limit; strain (nt, nx, 6), tensor shear
    drive, rendered = render_virtual_surface(display, height, SPEED, times, x, DEPTH, q_amp / AMPLITUDE, YOUNG)
    real = sliding_sinusoid_strain(x, DEPTH, AMPLITUDE, pitch, SPEED, times)
    # at p = 4d the drive is a standing wave that peaks at t = 0; the real pattern has the same
    # shape a quarter period earlier, i.e. at t = 3/4 of the period
    aligned = real[int(round(0.75 * times.size)) % times.size]
    centre = np.abs(x) <= 2 * d
    shape_err = {}
    rms_ratio = {}
    for name, c in (("eps_xx", 0), ("eps_zx", 4)):
        r = rendered[0, centre, c] / np.sqrt(2)  # the sqrt(2) of the matching formula (RMS match)
        a = aligned[centre, c]
        shape_err[name] = float(np.linalg.norm(r - a) / np.linalg.norm(a))
        rms_ratio[name] = float(_rms(rendered[:, centre, c], None) / _rms(real[:, centre, c], None))
    yield ("match over the central pitch |x| <= 2d: shape error at the peak frame (rendered / sqrt 2 vs "
           f"real) eps_xx {shape_err['eps_xx']:.3f}, eps_zx {shape_err['eps_zx']:.3f}; RMS over a period "
           f"rendered/real eps_xx {rms_ratio['eps_xx']:.3f}, eps_zx {rms_ratio['eps_zx']:.3f} "
           "(closed forms: Flamant strips for the tractors, sliding-sinusoid solution for the grating)")

    # the same drive on a 6 x 10 STReSS2-like array of finite patches, 3-D Cerruti quadrature
    array = DisplayDescription.stress2(pitch_x_m=2 * d, tractor_width_m=d)
    tractions = np.broadcast_to(drive[0] / display.tractor_width_m, (array.rows, array.columns))
    xs3 = x[::8]
    points = np.column_stack([xs3, np.zeros_like(xs3), np.full_like(xs3, DEPTH)])
    starts = range(0, len(points), 10)
    if progress:  # no tqdm object otherwise: even a disabled one starts a monitor thread that outlives it
        starts = tqdm(starts, desc="3-D array", leave=False)
    strain3d = np.concatenate([display_patch_strain_3d(array, points[i:i + 10], tractions, YOUNG) for i in starts])
    plane = rendered[0, ::8]
    diff = float(np.abs(strain3d[:, 4] - plane[:, 4]).max() / np.abs(plane[:, 4]).max())
    yield (f"3-D check: 6 x 10 array (rows {array.tractor_length_m * 1e3:g} mm long, pitch "
           f"{array.pitch_y_m * 1e3:g} mm) vs the plane-strain row model on the centre line: "
           f"max |eps_zx| difference {diff:.3f} of the peak (gaps between rows and finite row length)")

    fig = Figure(figsize=(8, 9.5), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    xmm = x * 1e3
    # the shear convention is named only on the shear panel; legends sit outside the panels
    for ax, (label, c, kind) in zip(axes[:2], (("eps_xx", 0, "strain"), ("eps_zx", 4, "strain, TENSOR shear"))):
        ax.plot(xmm, aligned[:, c], "k-", label="real sliding grating")
        ax.plot(xmm, rendered[0, :, c] / np.sqrt(2), "C0--", label="tractor row / sqrt(2), peak frame")
        ax.plot(xs3 * 1e3, strain3d[:, c] / np.sqrt(2), "C3.", label="6 x 10 array, 3-D / sqrt(2)")
        ax.plot(display.tractor_x_m * 1e3, 0 * display.tractor_x_m, "v", color="0.5", label="tractors")
        ax.set_ylabel(f"{label} ({kind})")
        ax.set_title(f"{label} at depth {DEPTH * 1e3:g} mm ({kind})")
    fig.legend(*axes[0].get_legend_handles_labels(), fontsize=7, ncols=4, loc="outside upper center")
    axes[2].plot(xmm, _rms(real[:, :, 4]), "k-", label="real: RMS eps_zx over a period")
    axes[2].plot(xmm, _rms(rendered[:, :, 4]), "C0--", label="tractor row: RMS eps_zx over a period")
    axes[2].set_xlabel("x (mm)")
    axes[2].set_ylabel("RMS eps_zx (strain, tensor shear)")
    axes[2].set_title("RMS tensor shear strain eps_zx over one drive period")
    fig.legend(*axes[2].get_legend_handles_labels(), fontsize=7, ncols=2, loc="outside lower center")
    png = report_dir / "display_strain.png"
    fig.savefig(png, dpi=110)
    csv = report_dir / "display_strain.csv"
    table = np.column_stack([x, aligned[:, 0], aligned[:, 4], rendered[0, :, 0], rendered[0, :, 4],
                             _rms(real[:, :, 4]), _rms(rendered[:, :, 4])])
    np.savetxt(csv, table, delimiter=",", comments="",
               header="x_m,real_eps_xx,real_eps_zx_tensor,rendered_eps_xx,rendered_eps_zx_tensor,"
                      "real_rms_eps_zx,rendered_rms_eps_zx")
    yield f"wrote {png} (x in mm, strain; tensor shear) and {csv}"

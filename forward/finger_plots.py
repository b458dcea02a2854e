"""Figures of biomimetic-finger scenes: stress/strain maps, receptive fields, time series.

Axes in mm, stress in kPa, strain dimensionless (tensor shear, as the sensors report it).
Figures are ``matplotlib.figure.Figure`` objects saved directly (no pyplot, no backend switch).
"""

from __future__ import annotations

import pathlib
import textwrap

import numpy as np

from tactilab.data_schemas.recording import Recording

from .finger import BiomimeticFinger
from .halfspace import HalfSpace
from .halfspace import SurfaceLoad
from .surfaces import Surface


def _figure(**kwargs):
    """A new ``matplotlib.figure.Figure`` (matplotlib is imported on first use, never pyplot)."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def _unit(quantity: str) -> tuple[float, str]:
    return (1e-3, "kPa") if quantity == "stress" else (1.0, "strain")


def frame_load(finger: BiomimeticFinger, surface: Surface | None, position: float,
               reference_height_m: float = 1.0, half_width: float | None = None) -> SurfaceLoad:
    """The interfacial tractions (Pa) when the contact centre is at world x = position (m), on the
    finger grid padded with zeros to ``half_width`` (m; default: the sensors plus one depth)."""
    h = finger.spacing
    if half_width is None:
        half_width = max(finger.grid()[0][-1], np.abs(finger.sensors.positions_m).max() + finger.depth)
    x = np.arange(-int(np.ceil(half_width / h)), int(np.ceil(half_width / h)) + 1) * h
    X, Y = np.meshgrid(x, x)
    p, q = finger.traction(X, Y, cell=(h, h))
    if surface is not None:
        m = surface.modulation(X + position, Y, reference_height=reference_height_m)
        p, q = p * m, q * m
    return SurfaceLoad(p=p, qx=q, spacing=h)


def plot_field_maps(finger: BiomimeticFinger, path, *, surface: Surface | None = None, position: float = 0.0,
                    reference_height_m: float = 1.0, title: str = "") -> tuple[pathlib.Path, str]:
    """Interfacial pressure and the sensors' quantity (zz and zx) at the sensor depth, as maps.

    Returns the PNG path and the half-space method that computed the maps.
    """
    load = frame_load(finger, surface, position, reference_height_m)
    hs = HalfSpace(finger.contact.young_modulus, finger.contact.poisson_ratio)
    quantity = finger.sensors.quantity
    solve = hs.stress if quantity == "stress" else hs.strain
    result = solve(load, finger.depth, components=("zz", "zx"), tol=1e-4)
    field = result.data[quantity].isel(depth=0)
    scale, unit = _unit(quantity)
    ext = 1e3 * np.array([load.x[0], load.x[-1], load.y[0], load.y[-1]])
    fig = _figure(figsize=(13, 4), layout="constrained")
    axes = fig.subplots(1, 3)
    panels = [(load.components["p"] * 1e-3, "interfacial pressure p (kPa)", "viridis", "p (kPa)")]
    for comp in ("zz", "zx"):
        panels.append((field.sel(component=comp).values * scale,
                       f"{quantity} {comp} at depth {finger.depth * 1e3:.2f} mm ({unit})", "RdBu_r", f"{comp} ({unit})"))
    pos = finger.sensors.positions_m * 1e3
    for ax, (img, label, cmap, bar) in zip(axes, panels):
        lim = np.abs(img).max() or 1.0
        vmin = 0.0 if cmap == "viridis" else -lim
        im = ax.imshow(img, origin="lower", extent=ext, cmap=cmap, vmin=vmin, vmax=lim)
        ax.plot(pos[:, 0], pos[:, 1], "k.", ms=3)
        ax.set(title=label, xlabel="x, finger frame (mm)", ylabel="y (mm)")
        fig.colorbar(im, ax=ax, shrink=0.85, label=bar)
    fig.suptitle(title or f"contact centre at x = {position * 1e3:.2f} mm; maps by {result.method}")
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    return path, result.method


def receptive_field_maps(finger: BiomimeticFinger, sensors, strength: float = 1e-8, n: int = 81):
    """2-D exploratory receptive fields: output of each chosen sensor for a defect of strength
    S_d (m^2) at finger-frame (xi, eta) over the contact, shape (len(sensors), n, n, n_components)."""
    a = finger.contact.contact_radius
    xi = np.linspace(-a, a, int(n))
    XI, ETA = np.meshgrid(xi, xi)
    p, q = finger.traction(XI, ETA)
    resp = finger.point_response(XI, ETA, strength * q, strength * p)  # (n, n, n_sensors, n_comp)
    return xi, np.moveaxis(resp[:, :, list(sensors), :], 2, 0)


def plot_receptive_fields(finger: BiomimeticFinger, path, *, strength: float = 1e-8, max_sensors: int = 4,
                          component: int = 0) -> pathlib.Path:
    """Receptive-field maps of up to ``max_sensors`` sensors spread over the array (PNG)."""
    ns = finger.sensors.n_sensors
    chosen = sorted(set(np.linspace(0, ns - 1, min(max_sensors, ns)).round().astype(int).tolist()))
    xi, rf = receptive_field_maps(finger, chosen, strength)
    scale, unit = _unit(finger.sensors.quantity)
    comp = finger.sensors.components[component]
    fig = _figure(figsize=(3.6 * len(chosen), 3.6), layout="constrained")
    axes = fig.subplots(1, len(chosen), squeeze=False)
    ext = 1e3 * np.array([xi[0], xi[-1], xi[0], xi[-1]])
    for ax, k, img in zip(axes[0], chosen, rf[..., component] * scale):
        lim = np.abs(img).max() or 1.0
        im = ax.imshow(img, origin="lower", extent=ext, cmap="RdBu_r", vmin=-lim, vmax=lim)
        sx, sy = finger.sensors.positions_m[k] * 1e3
        ax.plot([sx], [sy], "k+", ms=10)
        ax.set(title=f"{finger.sensors.ids[k]} {comp} ({unit})", xlabel="defect x, finger frame (mm)",
               ylabel="defect y (mm)")
        fig.colorbar(im, ax=ax, shrink=0.8, label=f"{comp} ({unit})")
    # one line per ~36 characters of panel row: a one-sensor figure wraps its title instead of clipping it
    title = (f"exploratory receptive fields, defect strength S_d = {strength * 1e6:.3g} mm², "
             f"depth {finger.depth * 1e3:.2f} mm (+: sensor)")
    fig.suptitle(textwrap.fill(title, width=int(36 * len(chosen))))
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    return path


def plot_time_series(recording: Recording, path, *, max_lines: int = 8, positions=None) -> pathlib.Path:
    """Sensor time series: a few sensors as lines and, with two sensors or more, all sensors as an
    image (PNG; an image of one sensor would be a one-row heat map of the line above it).

    ``positions`` (m, world x of the contact centre per sample) adds a finger-position axis.
    """
    scale, unit = _unit(recording.quantity)
    t = recording.times_s * 1e3  # drawn in ms
    nc = recording.n_components
    image = recording.n_sensors > 1
    fig = _figure(figsize=(6 * nc, 6.5 if image else 3.6), layout="constrained")
    axes = fig.subplots(2 if image else 1, nc, squeeze=False)
    chosen = np.unique(np.linspace(0, recording.n_sensors - 1, min(max_lines, recording.n_sensors)).round().astype(int))
    for c, comp in enumerate(recording.components):
        values = recording.values[:, :, c] * scale
        for k in chosen:
            # the texture's signal rides on a large static contact stress: show the change
            axes[0, c].plot(t, values[:, k] - np.median(values[:, k]), lw=1,
                            label=f"{recording.sensor_ids[k]} ({np.median(values[:, k]):.3g})")
        axes[0, c].set(title=f"{recording.quantity} {comp} minus its median (in legend) ({unit})",
                       xlabel="time (ms)", ylabel=f"{comp} change ({unit})")
        # beside the panel (the lines fill the axes; a legend inside hides some of them)
        axes[0, c].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
        if positions is not None:
            top = axes[0, c].secondary_xaxis("top", functions=(
                lambda ms, u=positions: 1e3 * np.interp(ms, t, u),
                lambda mm, u=positions: np.interp(np.asarray(mm) * 1e-3, u, t)))
            top.set_xlabel("contact centre x (mm)")
        if not image:
            continue
        change = values - np.median(values, axis=0)
        lim = np.abs(change).max() or 1.0
        im = axes[1, c].imshow(change.T, aspect="auto", origin="lower", cmap="RdBu_r",
                               vmin=-lim, vmax=lim, extent=[t[0], t[-1], -0.5, recording.n_sensors - 0.5])
        axes[1, c].set(title=f"{comp} minus its median, all sensors ({unit})", xlabel="time (ms)",
                       ylabel="sensor index")
        fig.colorbar(im, ax=axes[1, c], label=f"{comp} change ({unit})")
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    return path


def plot_spectrum(recording: Recording, path, *, max_lines: int = 8) -> pathlib.Path:
    """Welch power spectra of a few sensors' outputs, (kPa^2 or strain^2) per Hz vs Hz (PNG)."""
    from scipy import signal

    scale, unit = _unit(recording.quantity)
    nc = recording.n_components
    fig = _figure(figsize=(6 * nc, 4), layout="constrained")
    axes = fig.subplots(1, nc, squeeze=False)
    chosen = np.unique(np.linspace(0, recording.n_sensors - 1, min(max_lines, recording.n_sensors)).round().astype(int))
    nper = max(16, recording.n_times // 4)
    for c, comp in enumerate(recording.components):
        for k in chosen:
            y = recording.values[:, k, c] * scale
            f, p = signal.welch(y - y.mean(), fs=recording.sampling_rate_hz, nperseg=nper)
            axes[0, c].semilogy(f[1:], p[1:], lw=1, label=recording.sensor_ids[k])
        axes[0, c].set(title=f"power spectrum of {comp} ({unit}^2/Hz)", xlabel="frequency (Hz)",
                       ylabel=f"PSD ({unit}^2/Hz)")
        axes[0, c].legend(fontsize=7)
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    return path


def representative_frame(real: np.ndarray) -> int:
    """Index of the frame with the largest RMS of ``real`` over sensors and components (shape (time, sensor, comp)).

    A profile at t = 0 can show an unloaded display; this frame shows the stimulus at its strongest.
    """
    real = np.asarray(real, dtype=float)
    return int(np.argmax(np.sqrt(np.mean(real.reshape(real.shape[0], -1) ** 2, axis=1))))


def plot_rendered_vs_real(sensors, rendered: np.ndarray, real: np.ndarray, path, *,
                          sampling_rate_hz: float | None = None) -> pathlib.Path:
    """Strain profiles at a representative time and the central sensor's time course, display vs real (PNG).

    ``rendered`` and ``real``: tensor strain, shape (time, sensor, component). The profile is drawn at
    :func:`representative_frame` of ``real``; time is in ms when ``sampling_rate_hz`` is given, else in frames.
    """
    x = sensors.positions_m[:, 0] * 1e3
    order = np.argsort(x)
    nc = len(sensors.components)
    frame = representative_frame(real)
    n = np.asarray(rendered).shape[0]
    if sampling_rate_hz:
        t, t_label, at = np.arange(n) * 1e3 / sampling_rate_hz, "time (ms)", f"t = {frame * 1e3 / sampling_rate_hz:.1f} ms"
    else:
        t, t_label, at = np.arange(n), "frame (sampling rate not given)", f"frame {frame}"
    fig = _figure(figsize=(5 * nc, 6.5), layout="constrained")
    axes = fig.subplots(2, nc, squeeze=False)
    centre = int(np.argmin(np.abs(sensors.positions_m[:, 0])))
    for c, comp in enumerate(sensors.components):
        axes[0, c].plot(x[order], rendered[frame, order, c], label="display")
        axes[0, c].plot(x[order], real[frame, order, c], "--", label="real sliding grating")
        axes[0, c].set(title=f"strain {comp} (tensor) at {at} (strongest frame)", xlabel="sensor x (mm)",
                       ylabel=f"{comp} (strain)")
        axes[0, c].legend(fontsize=8)
        axes[1, c].plot(t, rendered[:, centre, c], label="display")
        axes[1, c].plot(t, real[:, centre, c], "--", label="real")
        axes[1, c].axvline(t[frame], color="k", ls=":", lw=1)
        axes[1, c].set(title=f"{comp} at sensor x = {x[centre]:.2f} mm", xlabel=t_label, ylabel=f"{comp} (strain)")
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    return path


def plot_fingerprint_spectra(freqs, ridged, smooth, peak_hz: float, path, *, unit: str = "kPa",
                             scale: float = 1e-3) -> pathlib.Path:
    """PSDs of one sensor scanning a random texture with ridged and smooth skin (PNG)."""
    fig = _figure(figsize=(6.5, 4), layout="constrained")
    ax = fig.subplots()
    ax.semilogy(freqs[1:], ridged[1:] * scale ** 2, label="ridged skin (fingerprint)")
    ax.semilogy(freqs[1:], smooth[1:] * scale ** 2, label="smooth skin")
    ax.axvline(peak_hz, color="k", ls=":", label=f"v / lambda = {peak_hz:g} Hz")
    ax.set(title=f"sigma_zz power spectrum ({unit}^2/Hz)", xlabel="frequency (Hz)", ylabel=f"PSD ({unit}^2/Hz)")
    ax.legend(fontsize=8)
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    return path


def plot_wiener_kernels(x, true_kernel, estimates: dict, path, *, unit: str = "kPa",
                        scale: float = 1e-3) -> pathlib.Path:
    """First-order Wiener kernel estimates (one per record length) against the true kernel (PNG).

    ``x`` in m (finger frame), kernels per bit in Pa (or strain); ``estimates`` maps a label to an array.
    """
    fig = _figure(figsize=(6.5, 4), layout="constrained")
    ax = fig.subplots()
    for label, est in estimates.items():
        ax.plot(x * 1e3, est * scale, lw=1, label=label)
    ax.plot(x * 1e3, true_kernel * scale, "k--", lw=2, label="true kernel p(x) g(x - x0), binned")
    ax.set(title=f"first-order Wiener kernel of a sigma_zz sensor ({unit} per bit)",
           xlabel="x, finger frame (mm)", ylabel=f"kernel ({unit})")
    ax.legend(fontsize=8)
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    return path

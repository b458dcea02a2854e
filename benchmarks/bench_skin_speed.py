"""Scans at different speeds: the gain and phase of a receptor's reading of a grating against temporal frequency.

Run: ``python benchmarks/bench_skin_speed.py [--figure docs/skin_speed.png]`` (a few seconds).

A rigid sinusoidal grating of wavelength ``WAVELENGTH`` slides at speed v in full frictionless contact
over a fingertip; a receptor at depth reads the stress or the strain. Its temporal frequency is
f = v / wavelength; per harmonic the skin answers with the complex moduli E*(2 pi f) of its layers
(``ViscoelasticLayeredHalfSpace.deflection_transfer``, exact per wavenumber). The gain is the reading's
amplitude over the quasi-static one (f -> 0, the relaxed skin), the lead its phase ahead of the
grating's deflection in time. Two skins on bone (moduli illustrative, relaxation times of the pulp
from Pawluk and Howe 1999):

- pulp on bone: 4 mm of one Prony series (E_inf 0.2 MPa; 1.0 MPa at 4 ms, 0.5 MPa at 70 ms,
  0.3 MPa at 1.4 s): one relaxation shape, so the strain is the elastic one at every speed and the
  stress gain is abs(E*) / E_inf (the correspondence principle, docs/theory.md section 7);
- dermis on pulp: 1 mm of a stiffer, faster dermis (E_inf 0.6 MPa; 0.6 MPa at 2 ms) on 3 mm of that
  pulp: the layers relax differently, and the strain depends on speed too.

The agreement column compares the gain from the per-harmonic multiplier with the fundamental of a
full steady-sliding field on a grid (``steady_sliding``, FFT of the sampled field).
"""

from __future__ import annotations

import argparse

import numpy as np

from tactilab.forward import Layer, Prony, ViscoelasticLayeredHalfSpace

WAVELENGTH = 1e-3  # m: the grating's period
HERTZ = np.array([1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0])
PULP = Prony(0.2e6, [(1.0e6, 4e-3), (0.5e6, 0.07), (0.3e6, 1.4)])
DERMIS = Prony(0.6e6, [(0.6e6, 2e-3)])
SKINS = {
    "pulp on bone": ViscoelasticLayeredHalfSpace([Layer(4e-3, PULP, 0.5)]),
    "dermis on pulp": ViscoelasticLayeredHalfSpace([Layer(1e-3, DERMIS, 0.5), Layer(3e-3, PULP, 0.5)]),
}
DEPTHS = (0.75e-3, 2e-3)  # m: in the dermis (Meissner, Merkel) and in the pulp
RIDGE_PERIOD = 0.45e-3  # m: fingerprint ridges
RIDGE_SPEEDS = (0.01, 0.1)  # m/s: usual scanning speeds; the ridges band-pass a texture around v / RIDGE_PERIOD


def response(skin, depth: float, quantity: str, hertz: np.ndarray) -> np.ndarray:
    """Complex gain of the zz reading at ``hertz`` over the quasi-static one (speed v = f * WAVELENGTH)."""
    k = 2 * np.pi / WAVELENGTH
    still = skin.deflection_transfer(k, 0.0, depth, 0.0, quantity)[2]
    return skin.deflection_transfer(k, 0.0, depth, -2 * np.pi * hertz, quantity)[..., 2] / still


def field_gain(skin, depth: float, quantity: str, hertz: float, n: int = 32) -> complex:
    """The same gain from the fundamental of a sampled steady-sliding field (an independent route)."""
    h = WAVELENGTH / n
    grating = 1e-6 * np.cos(2 * np.pi * np.arange(n) / n)
    read = lambda speed: np.fft.rfft(skin.steady_sliding(grating, h, speed, depth, quantity, components=("zz",))  # noqa: E731
                                     .data[quantity].values[0, 0])[1]
    return read(hertz * WAVELENGTH) / read(0.0)


def table() -> dict:
    rows = {}
    print(f"grating {WAVELENGTH * 1e3:g} mm in full contact; columns: temporal frequency f = v / wavelength")
    print(f"{'skin':>15} {'depth':>6} {'reading':>7} {'':>5} " + " ".join(f"{f:>7g}" for f in HERTZ) + "  agreement")
    print(f"{'speed (mm/s)':>37} " + " ".join(f"{f * WAVELENGTH * 1e3:>7g}" for f in HERTZ))
    for name, skin in SKINS.items():
        for depth in DEPTHS:
            for quantity in ("stress", "strain"):
                g = response(skin, depth, quantity, HERTZ)
                rows[(name, depth, quantity)] = g
                agree = max(abs(field_gain(skin, depth, quantity, f) - gi) / abs(gi) for f, gi in zip(HERTZ[::3], g[::3]))
                label = f"{name:>15} {depth * 1e3:>4g}mm {quantity:>7}"
                print(f"{label} {'gain':>5} " + " ".join(f"{abs(x):>7.3f}" for x in g) + f"  {agree:.1e}")
                print(f"{'':>30} {'lead':>5} " + " ".join(f"{-np.degrees(np.angle(x)):>6.1f}d" for x in g))
    print(f"{'abs(E*) / E_inf':>37} " + " ".join(f"{abs(PULP.complex_modulus(2 * np.pi * f)) / PULP.E_inf:>7.3f}"
                                                     for f in HERTZ))
    return rows


def figure(path: str) -> None:
    """Gain (dB) and lead (deg) of stress and strain against frequency (Hz), both skins and depths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    f = np.logspace(0, 3, 121)
    fig, axes = plt.subplots(2, 1, figsize=(7.0, 6.4), sharex=True)
    styles = {"stress": "-", "strain": "--"}
    colours = {("pulp on bone", 0.75e-3): "0.35", ("dermis on pulp", 0.75e-3): "tab:blue",
               ("dermis on pulp", 2e-3): "tab:red"}
    for (name, depth), colour in colours.items():
        for quantity, style in styles.items():
            g = response(SKINS[name], depth, quantity, f)
            where = "any depth" if name == "pulp on bone" else f"{depth * 1e3:g} mm"
            label = f"{quantity}, {name} ({where})"
            axes[0].semilogx(f, 20 * np.log10(np.abs(g)), style, color=colour, label=label)
            axes[1].semilogx(f, -np.degrees(np.angle(g)), style, color=colour)
    axes[0].set_ylabel("gain over quasi-static (dB)")
    axes[1].set_ylabel("lead over the deflection (deg)")
    axes[1].set_xlabel(f"temporal frequency f = v / {WAVELENGTH * 1e3:g} mm (Hz)")
    axes[0].legend(fontsize=7.5, loc="upper left")
    lo, hi = (v / RIDGE_PERIOD for v in RIDGE_SPEEDS)
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.axhline(0.0, color="k", lw=0.6)
        ax.axvspan(lo, hi, color="gold", alpha=0.18, lw=0)
    axes[1].text(np.sqrt(lo * hi), axes[1].get_ylim()[0] + 1.0, f"fingerprint band-pass v / {RIDGE_PERIOD * 1e3:g} mm,\n"
                 f"v = {RIDGE_SPEEDS[0] * 1e3:g} to {RIDGE_SPEEDS[1] * 1e3:g} mm/s", ha="center", fontsize=7.5)
    top = axes[0].secondary_xaxis("top", functions=(lambda x: x * WAVELENGTH * 1e3, lambda v: v / (WAVELENGTH * 1e3)))
    top.set_xlabel("scanning speed v of this grating (mm/s)", fontsize=8.5)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"figure: {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--figure", default=None, help="write the gain/phase figure to this PNG")
    args = parser.parse_args()
    table()
    if args.figure:
        figure(args.figure)


if __name__ == "__main__":
    main()

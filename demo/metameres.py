"""Tactile metameres demo: the paper's sinusoid-vs-tractors pair measured, and what the mechanics adds.

Plane strain, nu = 1/2, skin E = 1.54 MPa, receptors at Z = 1.25 mm (docs/metameres.md).
"""

from __future__ import annotations

import pathlib
import time
from collections.abc import Iterator

import numpy as np

E_SKIN, DEPTH, AMP, PITCH, NOISE = 1.54e6, 1.25e-3, 0.5e-3, 4e-3, 1e-3
TRACTOR_X = np.array([-9, -7, -5, -3, -1, 1, 3, 5, 7, 9]) * 1e-3  # m, the paper's 5 pairs, d = 1 mm


def papers_q(amplitude: float = AMP, pitch: float = PITCH, depth: float = DEPTH, young: float = E_SKIN) -> float:
    """The paper's matching line load Q (N/m), docs/theory.md 4a, with k2' = S_Psi(d) at d = pitch / 4."""
    from tactilab.forward import array_phi_psi

    d = pitch / 4
    k2p = float(array_phi_psi(np.array([d]), d, depth, 5)[1][0])
    return 8 * np.sqrt(2) * np.pi ** 3 * amplitude * depth * young * np.exp(-2 * np.pi * depth / pitch) / (
        3 * k2p * pitch ** 2)


def _paper_section(out: pathlib.Path) -> Iterator[str]:
    from tactilab.inversion import SinusoidFamily, TractorFamily, metamer_pair

    x = np.linspace(-5e-3, 5e-3, 201)
    tractors = TractorFamily(TRACTOR_X, E_SKIN)  # line loads, as in the paper
    hyp = f"xx,zx@{DEPTH * 1e3:g}mm;noise={NOISE:g}"
    yield (f"[metameres] the paper's case: sliding sinusoid A = {AMP * 1e3:g} mm, p = {PITCH * 1e3:g} mm vs 10 line "
           f"tractors at +-1..+-9 mm; E = {E_SKIN / 1e6:g} MPa; receptors {hyp} on [-5, 5] mm (201)")
    t = time.perf_counter()
    good = metamer_pair(SinusoidFamily(PITCH, np.pi / 2).stimulus([AMP]), tractors, hyp, x,
                        scan_phases=np.linspace(0, 2 * np.pi, 64, endpoint=False))
    bad = metamer_pair(SinusoidFamily(PITCH, 0.0).stimulus([AMP]), tractors, hyp, x)
    el = time.perf_counter() - t
    for label, pair in (("favourable phase (tractors at the traction extrema)", good),
                        ("unfavourable phase (tractors at its zeros)", bad)):
        yield (f"  {label}: relative residual {pair.relative_residual:.4f}, d' = {pair.dprime:.4g}; loads (N/mm) "
               + " ".join(f"{q * 1e-3:+.3f}" for q in pair.params))
    q_paper = papers_q()
    yield (f"  travelling scan (64 frames): rms relative residual {good.scan_rms:.4f}; largest favourable load "
           f"{np.abs(good.params).max() * 1e-3:.3f} N/mm vs the paper's Q = {q_paper * 1e-3:.3f} N/mm "
           f"(Q / sqrt 2 = {q_paper / np.sqrt(2) * 1e-3:.3f}); {el * 1e3:.0f} ms")
    good.plot(out / "paper_pair.png")


def _mechanics_section(out: pathlib.Path) -> Iterator[str]:
    from tactilab.inversion import (
        GridLoadFamily,
        IndentationFamily,
        SinusoidFamily,
        metamer_ambiguity,
        metamer_pair,
        resolvable_subspace,
    )

    n, dx = 480, 0.05e-3  # period 24 mm: six 4 mm pitches
    loads = GridLoadFamily((n,), dx, ("p", "qx"), young_modulus=E_SKIN)
    prior, noise = 10e3, 1e-5  # Pa per node, strain per reading
    dims = {}
    t = time.perf_counter()
    for text in ("xx@1.25mm", "xx,zx@1.25mm", "xx@1.25mm,2.5mm", "volumetric@1.25mm,2.5mm"):
        sub = resolvable_subspace(loads, f"{text};noise={noise:g}", prior)
        dims[text] = sub
    el = time.perf_counter() - t
    yield (f"[metameres] resolvable load patterns, periodic grid {n} x {dx * 1e6:g} µm, loads (p, qx), prior "
           f"{prior / 1e3:g} kPa, noise {noise:g} ({el * 1e3:.0f} ms for four spectra, per mode):")
    for text, sub in dims.items():
        edge = sub.wavenumber_edge * 1e-3
        yield (f"  {text:24s} resolved {sub.dimension:4d} of {loads.n_params}, effective dof {sub.effective_dof:7.1f}, "
               f"{sub.information_nats:7.1f} nats, edge {edge:5.2f} rad/mm")
    dims["xx,zx@1.25mm"].plot(out / "spectrum_one_depth.png")
    dims["xx@1.25mm,2.5mm"].plot(out / "spectrum_two_depths.png")
    # exact lateral-traction metamer of an indentation at one depth, and its break at another
    shear = GridLoadFamily((n,), dx, ("qx",), young_modulus=E_SKIN)
    rng = np.random.default_rng(20261122)
    heights = np.convolve(rng.normal(size=n), np.exp(-0.5 * (np.arange(-40, 41) / 10.0) ** 2), "same")
    heights *= 20e-6 / np.abs(heights).max()
    target = IndentationFamily((n,), dx, E_SKIN).stimulus(heights)
    pair = metamer_pair(target, shear, f"xx,zz,zx@{DEPTH * 1e3:g}mm;noise={noise:g}")
    deeper = pair.evaluate(f"xx,zx@{2 * DEPTH * 1e3:g}mm;noise={noise:g}")
    yield (f"  an indentation (random, 20 µm peak) and its pure lateral-traction metamer at {DEPTH * 1e3:g} mm: "
           f"relative residual {pair.relative_residual:.2e}; at {2 * DEPTH * 1e3:g} mm: {deeper.relative_residual:.3f} "
           f"(d' = {deeper.dprime:.3g}; modes near the blind pitch need large tractions)")
    k = 2 * np.pi / PITCH
    sine = metamer_pair(SinusoidFamily(PITCH).stimulus([AMP]), shear, f"xx,zx@{DEPTH * 1e3:g}mm", rcond=1e-6)
    for z2 in (0.75e-3, 2.5e-3):
        got = sine.evaluate(f"xx,zx@{z2 * 1e3:g}mm").relative_residual
        yield (f"  the 4 mm sinusoid's traction metamer read at {z2 * 1e3:g} mm: residual {got:.4f} "
               f"(closed form |Z2 - Z| / (Z2 |1 - kZ|) = {abs(z2 - DEPTH) / (z2 * abs(1 - k * DEPTH)):.4f})")
    yield (f"  blind pitch 2 pi Z = {2 * np.pi * DEPTH * 1e3:.3f} mm: a tangential traction there leaves no strain at "
           f"{DEPTH * 1e3:g} mm; the metamer traction's sign flips across it (kZ / (1 - kZ))")
    amb = metamer_ambiguity(target, shear, f"xx,zx@{DEPTH * 1e3:g}mm;noise={noise:g}", prior)
    yield (f"  ambiguity of lateral tractions given that indentation's readouts: {amb.information_nats:.1f} nats, "
           f"log volume ratio {amb.log_volume_ratio:.1f}, unresolved prior variance {amb.null_energy_fraction:.1%}")


def run_demo(report_dir: pathlib.Path, progress: bool = True) -> Iterator[str]:
    """The paper's metamer pair measured, and the mechanics of metameres (docs/metameres.md).

    Parameters
    ----------
    report_dir : Path
        Folder for ``metameres/`` (PNG plots).
    progress : bool
        Unused (no long loops); kept for the common section signature.
    """
    out = pathlib.Path(report_dir) / "metameres"
    out.mkdir(parents=True, exist_ok=True)
    yield from _paper_section(out)
    yield from _mechanics_section(out)
    yield f"  files in {out}"

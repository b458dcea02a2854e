"""``tactilab synthesis``: optimal tractor spacing for receptors at depth (docs/theory.md 4a)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from .batch_options import add_worker_options, batch_where, wants_batch
from .common import RunReport, add_report_options, make_out
from .material_option import add_material_option, describe_material, read_material_option

NAME = "synthesis"
HELP = ("design a laterotactile display: optimal tractor half spacing d (mm) for receptors at a depth, "
        "matching traction (kPa) and largest renderable amplitude (µm), with sensitivity to width and pairs")

WIDTH_FACTORS = (0.5, 0.8, 1.0, 1.2, 1.5, 2.0)
PAIRS_SENSITIVITY = (1, 2, 3, 4, 5, 6, 7)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--depth", required=True,
                        help="receptor depth Z, a length such as 1.25mm; a comma list (0.5mm,1mm,2mm) gives one row each")
    parser.add_argument("--width", default="10mm", help="comparison window w, a length (default 10mm)")
    parser.add_argument("--pairs", default="5", help="number of tractor pairs, an integer >= 1 (default 5)")
    parser.add_argument("--amplitude", default=None,
                        help="virtual sinusoid amplitude A, a length such as 50um (needs --young-modulus)")
    parser.add_argument("--young-modulus", default=None, help="skin Young's modulus E, a pressure such as 200kPa")
    add_material_option(parser)
    parser.add_argument("--drive-frequency", default=None,
                        help="with a viscoelastic --material: the display's drive frequency, e.g. 100Hz; the traction "
                             "is matched with |E*(2 pi f)| (default: the relaxed modulus, a quasi-static drive)")
    parser.add_argument("--traction-limit", default=None,
                        help="per-tractor traction limit, a pressure such as 5kPa (needs --young-modulus)")
    parser.add_argument("--footprint", default=None,
                        help="tractor contact width along x, a length (default: d, half the tractor pitch 2d)")
    parser.add_argument("--sensitivity-widths", default=None,
                        help="comma list of window widths for the sensitivity rows, lengths "
                             "(default: 0.5, 0.8, 1, 1.2, 1.5, 2 times --width)")
    parser.add_argument("--sensitivity-pairs", default=None,
                        help="comma list of pair counts for the sensitivity rows (default 1,2,3,4,5,6,7)")
    parser.add_argument("--no-sensitivity", action="store_true", help="print only the design rows")
    parser.add_argument("--out", type=Path, default=None,
                        help="with --workers or --scheduler: folder of the batch results, one file per design point "
                             "(default ./synthesis-batch; the same folder resumes)")
    add_report_options(parser, out=False)
    add_worker_options(parser, default_help="no batch; with --workers or --scheduler the table over every depth x "
                                            "sensitivity width x sensitivity pair count runs as a batch, one task "
                                            "per design point")


def _lengths(text: str, name: str) -> list[float]:
    from tactilab.data_schemas.units import to_si

    items = [t for t in str(text).split(",") if t.strip()]
    if not items:
        raise ValueError(f"{name}: give at least one length such as 1.25mm, got {text!r}")
    return [to_si(t.strip(), "length", name=name) for t in items]


def _integers(text: str, name: str) -> list[int]:
    from tactilab.forward.tractors import check_pairs

    out = []
    for item in str(text).split(","):
        try:
            value = int(item.strip())
        except ValueError:
            raise ValueError(f"{name}: expected integers >= 1 (e.g. 5 or 3,5,7), got {text!r}") from None
        if value < 1:
            raise ValueError(f"{name}: the number of tractor pairs must be >= 1, got {value}; e.g. 5")
        out.append(check_pairs(value, name))  # the memory rule, before any array exists
    return out


#: how to fix a length, pressure or width given as <= 0
_FIX = "give a positive value with a unit, e.g. 1.25mm or 200kPa"


class _Options:
    def __init__(self, args: argparse.Namespace) -> None:
        from tactilab.core import rules
        from tactilab.data_schemas.units import to_si

        self.depths = [float(z) for z in rules.depths(_lengths(args.depth, "--depth"), "--depth")]
        self.width = rules.positive(to_si(args.width, "length", name="--width"), "--width", "m", fix=_FIX)
        self.pairs = _integers(args.pairs, "--pairs")
        if len(self.pairs) != 1:
            raise ValueError(f"--pairs: give one number of pairs, got {args.pairs!r}; use --sensitivity-pairs for a list")
        self.pairs = self.pairs[0]
        self.amplitude = None if args.amplitude is None else to_si(args.amplitude, "length", name="--amplitude")
        if self.amplitude is not None and self.amplitude <= 0:
            raise ValueError(f"--amplitude: the sinusoid amplitude must be > 0, got {args.amplitude!r}; "
                             "give its size, e.g. 50um (a sign only shifts the phase)")
        self.young = None if args.young_modulus is None else rules.young_modulus(
            to_si(args.young_modulus, "pressure", name="--young-modulus"), "--young-modulus")
        self.material = read_material_option(args, replaces=("young_modulus",))
        self.skin = None  # the closed-form half-space; a layered material designs on its layers
        self.layers_note = None  # how viscoelastic layers entered the design
        if self.material is not None and self.material.is_layered:
            from tactilab.forward import skin_from_material

            if args.amplitude is not None or args.traction_limit is not None:
                raise ValueError("--material: a layered skin gets its optimal spacing here, not its matching traction "
                                 "(the grating's strain on layers has no closed form); drop --amplitude and "
                                 "--traction-limit")
            self.skin = skin_from_material(self.material)
            if self.material.has_viscoelastic_layers:
                self.skin, self.layers_note = _relaxed_layers(self.skin)
        elif self.material is not None:
            if self.material.poisson_ratio != 0.5:
                raise ValueError(f"--material: the synthesis design assumes nu = 1/2 (plane strain, incompressible), "
                                 f"got poisson_ratio {self.material.poisson_ratio!r}; set it to 0.5")
            self.young = self.material.young_modulus_pa  # viscoelastic: the relaxed modulus (quasi-static)
        self.drive = None if args.drive_frequency is None else to_si(args.drive_frequency, "frequency",
                                                                      name="--drive-frequency")
        if self.drive is not None:
            if self.material is not None and self.material.has_viscoelastic_layers:
                raise ValueError("--drive-frequency: viscoelastic layers get their optimal spacing here, designed on "
                                 "their relaxed moduli (a slow drive), and no matching traction; drop "
                                 "--drive-frequency")
            if self.material is None or not self.material.is_viscoelastic:
                raise ValueError("--drive-frequency: only a viscoelastic --material (model prony or sls) depends on "
                                 "the drive frequency; drop --drive-frequency")
            if not self.drive >= 0:
                raise ValueError(f"--drive-frequency: must be >= 0 Hz, got {args.drive_frequency!r}; e.g. 100Hz")
            from tactilab.forward import skin_from_material

            # under given tractions the strain is J* times the stress: the matching traction scales with |E*|
            self.complex_modulus = complex(skin_from_material(self.material).prony.complex_modulus(
                2 * math.pi * self.drive))
            self.young = abs(self.complex_modulus)
        self.limit = None if args.traction_limit is None else rules.positive(
            to_si(args.traction_limit, "pressure", name="--traction-limit"), "--traction-limit", "Pa", fix=_FIX)
        self.footprint = None if args.footprint is None else rules.positive(
            to_si(args.footprint, "length", name="--footprint"), "--footprint", "m", fix=_FIX)
        if (self.amplitude is not None or self.limit is not None) and self.young is None:
            raise ValueError("--young-modulus: needed with --amplitude or --traction-limit (the traction scales "
                             "with E); give it as a pressure, e.g. 0.2MPa")
        self.widths = ([f * self.width for f in WIDTH_FACTORS] if args.sensitivity_widths is None
                       else [rules.positive(w, "--sensitivity-widths", "m", fix=_FIX)
                             for w in _lengths(args.sensitivity_widths, "--sensitivity-widths")])
        self.pairs_list = (list(PAIRS_SENSITIVITY) if args.sensitivity_pairs is None
                           else _integers(args.sensitivity_pairs, "--sensitivity-pairs"))


def _relaxed_layers(skin):
    """The elastic layers a viscoelastic layered skin is designed on, and the sentence that says why.

    The design is a quasi-static one on the relaxed layers (every E_inf). When every material relaxes
    with one shape (E_j(t) = c_j E(t)) the moduli keep their ratios at every time and frequency, so
    the strain's shape, and the optimum, are the same at any drive rate; otherwise the optimum
    moves with the rate, and the relaxed one is the slow-drive limit."""
    try:
        skin.relaxation_shape()
        rate = "every layer relaxes with one shape, so the optimum holds at any drive rate"
    except ValueError:
        rate = ("the layers relax differently, so this is the slow-drive limit (a fast drive sees the glassy layers, "
                "whose optimum differs)")
    return skin.relaxed, f"viscoelastic layers designed on their relaxed moduli (a quasi-static drive): {rate}"


HEADER = (f"{'depth_mm':>8} {'width_mm':>8} {'pairs':>5} {'d_mm':>8} {'d/Z':>6} {'k2_1/mm':>8} "
          f"{'k2p_1/mm':>8} {'J_1/m':>10} {'rel_res':>8} {'minima':>6}")


def _row(design, opts: _Options) -> str:
    from tactilab.forward import synthesis

    text = (f"{design.depth * 1e3:8.3f} {design.width * 1e3:8.2f} {design.pairs:5d} {design.d * 1e3:8.4f} "
            f"{design.d_over_depth:6.3f} {design.k2 * 1e-3:8.4f} {design.k2_prime * 1e-3:8.4f} "
            f"{design.objective:10.4g} {design.relative_residual:8.4f} {len(design.minima):6d}")
    if opts.amplitude is not None:
        tau = synthesis.matching_traction_amplitude(opts.amplitude, None, None, opts.young, design, opts.footprint)
        q = synthesis.matching_line_load(opts.amplitude, None, None, opts.young, design)
        text += f" {q:10.4g} {tau * 1e-3:10.4g}"
    if opts.limit is not None:
        a_max = synthesis.max_virtual_amplitude(opts.limit, None, None, opts.young, design, opts.footprint)
        text += f" {a_max * 1e6:10.4g}"
    return text


def _header(opts: _Options) -> str:
    text = HEADER
    if opts.amplitude is not None:
        text += f" {'Q_N/m':>10} {'tau_kPa':>10}"
    if opts.limit is not None:
        text += f" {'Amax_µm':>10}"
    return text


def run(args: argparse.Namespace) -> int:
    from tactilab.forward import synthesis

    opts = _Options(args)
    if wants_batch(args):
        return _run_batch(args, opts)
    report = RunReport("synthesis")
    say = (lambda *a: None) if args.json else print
    footprint = "d (half the tractor pitch)" if opts.footprint is None else f"{opts.footprint * 1e3:g} mm"
    say("tactile synthesis design (docs/theory.md 4a; plane strain, nu = 1/2, tractors as line loads)")
    if opts.material is not None:
        skin = describe_material(opts.material)
        if opts.material.is_viscoelastic and opts.drive is None:
            skin += ("; traction and amplitude use the relaxed modulus (quasi-static): under its tractions the "
                     "display's strain lags and creeps (docs/theory.md section 7); --drive-frequency sets the rate")
        elif opts.material.is_viscoelastic:
            lag = math.degrees(math.atan2(opts.complex_modulus.imag, opts.complex_modulus.real))
            skin += (f"; driven at {opts.drive:g} Hz: traction and amplitude use |E*| = {opts.young * 1e-3:.4g} kPa, "
                     f"and the strain lags the traction by {lag:.3g} deg (docs/theory.md section 7)")
        if opts.skin is not None:
            skin += "; the tractors' strain shapes are the layered skin's (docs/layered_skin.md), slower to design"
            if opts.layers_note:
                skin += "; " + opts.layers_note
        say(f"skin from --material: {skin}")
        report.computed.append(f"skin from --material: {skin}")
    say("objective J(d) over x in [-w/2, w/2]; optimum = lowest non-trivial local minimum, d in "
          "[0.2 Z, 5 Z]; k2 = max S_Psi, k2p = S_Psi(d)")
    if opts.amplitude is not None:
        say(f"matching: A = {opts.amplitude * 1e6:g} µm at pitch p = 4d, E = {opts.young * 1e-3:g} kPa; "
              f"Q = line load (N/m), tau = Q / footprint, footprint = {footprint}")
    if opts.limit is not None:
        say(f"max renderable amplitude Amax at traction limit {opts.limit * 1e-3:g} kPa, footprint = {footprint}")
    say()
    say("design")
    say(_header(opts))
    designs = [synthesis.optimal_half_spacing(z, opts.width, opts.pairs, skin=opts.skin) for z in opts.depths]
    for design in designs:
        say(_row(design, opts))
    _summarise(report, designs, opts)
    if args.no_sensitivity:
        report.emit(args.json)
        return 0
    z = opts.depths[0]
    say()
    say(f"sensitivity to the window width (depth {z * 1e3:g} mm, pairs {opts.pairs})")
    say(_header(opts))
    by_width = [synthesis.optimal_half_spacing(z, w, opts.pairs, skin=opts.skin) for w in opts.widths]
    for design in by_width:
        say(_row(design, opts))
    say()
    say(f"sensitivity to the number of pairs (depth {z * 1e3:g} mm, width {opts.width * 1e3:g} mm)")
    say(_header(opts))
    by_pairs = [synthesis.optimal_half_spacing(z, opts.width, n, skin=opts.skin) for n in opts.pairs_list]
    for design in by_pairs:
        say(_row(design, opts))
    for label, group in (("width", by_width), ("pairs", by_pairs)):
        ds = [g.d for g in group]
        say(f"d spread over {label}: {min(ds) * 1e3:.4f} .. {max(ds) * 1e3:.4f} mm "
              f"({(max(ds) - min(ds)) / designs[0].d * 100:.1f} % of the design d)")
    if len(designs) >= 2:
        fit = synthesis.scaling_from_designs(designs)
        say(f"scaling with depth: d = {fit.ratio:.4f} Z (max deviation {fit.max_deviation * 100:.1f} %); "
              f"power law d/mm = {fit.prefactor * 1e3 ** (1 - fit.exponent):.4g} (Z/mm)^{fit.exponent:.3f}")
    report.emit(args.json)
    return 0


def _summarise(report: RunReport, designs, opts: _Options) -> None:
    from tactilab.forward import synthesis

    report.method = ("lowest non-trivial local minimum of J(d) over d in [0.2 Z, 5 Z] (docs/theory.md 4a; plane "
                     "strain, nu = 1/2, tractors as line loads)")
    worst = max(d.relative_residual for d in designs)
    report.error_estimate = (f"relative residual of the matched strain profile over the window, largest "
                             f"{worst:.3g} (0 = exact match)")
    rows = []
    for d in designs:
        row = {"depth_mm": d.depth * 1e3, "width_mm": d.width * 1e3, "pairs": d.pairs, "d_mm": d.d * 1e3,
               "d_over_depth": d.d_over_depth, "relative_residual": d.relative_residual,
               "n_local_minima": len(d.minima)}
        if opts.amplitude is not None:
            tau = synthesis.matching_traction_amplitude(opts.amplitude, None, None, opts.young, d, opts.footprint)
            row["traction_kpa"] = tau * 1e-3
        if opts.limit is not None:
            row["max_amplitude_um"] = 1e6 * synthesis.max_virtual_amplitude(opts.limit, None, None, opts.young, d,
                                                                           opts.footprint)
        rows.append(row)
        report.computed.append(f"optimal half spacing d = {row['d_mm']:.4f} mm (d/Z = {d.d_over_depth:.3f}) for "
                               f"receptors at {row['depth_mm']:g} mm, window {row['width_mm']:g} mm, "
                               f"{d.pairs} pairs")
    report.data["designs"] = rows


def _run_batch(args: argparse.Namespace, opts: _Options) -> int:
    """The design table over depths x widths x pairs as a batch (``tactilab.experiments.design_sweep``)."""
    import numpy as np

    from tactilab.experiments.modelling import design_sweep

    if opts.skin is not None:
        raise ValueError("--workers/--scheduler: the batch design table is for the half-space; run a layered "
                         "--material without --workers")
    if opts.amplitude is not None or opts.limit is not None:
        raise ValueError("--workers/--scheduler: the batch design table has no matching columns; drop --amplitude "
                         "and --traction-limit (run without --workers for them)")
    widths = [opts.width] if args.no_sensitivity else opts.widths
    pairs = [opts.pairs] if args.no_sensitivity else opts.pairs_list
    out = make_out(args.out if args.out is not None else Path("synthesis-batch"))
    say = (lambda *a: None) if args.json else print
    report = RunReport("synthesis")
    report.watch(out)
    table = design_sweep(opts.depths, widths, pairs, out_dir=out, progress=not args.json, echo=say,
                         **batch_where(args))
    report.method = ("lowest non-trivial local minimum of J(d) over d in [0.2 Z, 5 Z] (docs/theory.md 4a; plane "
                     "strain, nu = 1/2, tractors as line loads), one batch task per design point")
    say(f"design table: {len(opts.depths)} depth(s) x {len(widths)} width(s) x {len(pairs)} pair count(s)")
    say(HEADER)
    rows = []
    for z in table["depth"].values:
        for w in table["width"].values:
            for n in table["pairs"].values:
                p = table.sel(depth=z, width=w, pairs=n)
                if np.isnan(float(p["d_m"])):
                    say(f"{z * 1e3:8.3f} {w * 1e3:8.2f} {int(n):5d}   failed (see {out / 'errors.tsv'})")
                    continue
                say(f"{z * 1e3:8.3f} {w * 1e3:8.2f} {int(n):5d} {float(p['d_m']) * 1e3:8.4f} "
                    f"{float(p['d_over_depth']):6.3f} {float(p['k2_per_m']) * 1e-3:8.4f} "
                    f"{float(p['k2_prime_per_m']) * 1e-3:8.4f} {float(p['objective_per_m']):10.4g} "
                    f"{float(p['relative_residual']):8.4f} {int(p['n_minima']):6d}")
                rows.append({"depth_mm": z * 1e3, "width_mm": w * 1e3, "pairs": int(n), "d_mm": float(p["d_m"]) * 1e3,
                             "d_over_depth": float(p["d_over_depth"]),
                             "relative_residual": float(p["relative_residual"]), "n_local_minima": int(p["n_minima"])})
    a = table.attrs
    report.computed.append(f"design table of {len(rows)} point(s): {a['n_run']} run, {a['n_skipped']} skipped (done "
                           f"before), {a['n_failed']} failed")
    worst = max((r["relative_residual"] for r in rows), default=float("nan"))
    report.error_estimate = f"relative residual of the matched strain profile, largest {worst:.3g} (0 = exact match)"
    if a["n_failed"]:
        report.dropped.append(f"{a['n_failed']} design point(s) failed: {a['failed']} (reasons in {out / 'errors.tsv'})")
    report.data["designs"] = rows
    report.emit(args.json)
    return 1 if a["n_failed"] else 0

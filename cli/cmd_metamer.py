"""``tactilab metamer``: the tractor-display metamer of a sliding sinusoid, and how well receptors tell them apart.

With ``--scan-pitch``, ``--scan-phase``, ``--scan-display`` (or ``--workers`` / ``--scheduler``) it
scans every (display, pitch, phase) as a batch through ``tactilab.inversion.metamer_scan``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from .batch_options import add_worker_options, batch_where, wants_batch
from .common import check_hypothesis, choose_out, make_out

NAME = "metamer"
HELP = ("tactile metamer of a sinusoidal surface on a tractor display: residual, d' and tractor loads (N/mm) "
        "for a receptor hypothesis such as xx,zx@1.25mm; PNGs of the strain at depth and the singular spectrum; "
        "--scan-pitch/--scan-phase/--scan-display scan (display, pitch, phase) as a batch (--workers N)")

PRESETS = ("wh2008", "stress2", "braille-row")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--target", required=True,
                        help="target surface: sinusoid:A=LENGTH,p=LENGTH[,phase=RAD], e.g. sinusoid:A=0.5mm,p=4mm "
                             "(frictionless indentation H = A sin(2 pi x / p + phase))")
    parser.add_argument("--display", default="wh2008",
                        help=f"tractor display: a preset ({', '.join(PRESETS)}) or a .json description file "
                             "(SI: m, Pa); its first row is used, loads bounded by traction limit x tractor width")
    parser.add_argument("--hypothesis", default="xx,zx@1.25mm",
                        help="receptor readouts components@depths[:tensor|engineering], depths with units, "
                             "e.g. xx,zx@1.25mm or max_shear@1mm,2mm:engineering (default xx,zx@1.25mm)")
    parser.add_argument("--noise", default="1e-3", help="noise std of one reading, strain (dimensionless), > 0 (default 1e-3)")
    parser.add_argument("--young-modulus", default="1.54MPa", help="skin Young's modulus E, a pressure (default 1.54MPa)")
    parser.add_argument("--window", default="10mm", help="receptors span [-w/2, w/2], a length (default 10mm)")
    parser.add_argument("--receptors", default="201", help="number of receptors in the window, an integer >= 2 (default 201)")
    parser.add_argument("--scan", default="32", help="frames of a travelling scan over one pitch, an integer >= 1 (default 32)")
    parser.add_argument("--unbounded", action="store_true", help="ignore the display's load limits")
    parser.add_argument("--out", type=Path, default=None,
                        help="folder for the PNGs (default: a new folder metamer-<display>, then -2, -3, ...); an "
                             "existing non-empty one needs --force; with --scan-* the batch folder (default "
                             "metamer-scan; the same folder resumes)")
    parser.add_argument("--force", action="store_true",
                        help="write into an existing, non-empty --out folder (files of the same name are replaced)")
    parser.add_argument("--json", action="store_true", help="print one JSON object (SI units) instead of text")
    scan = add_worker_options(parser, default_help="serial in-process")
    scan.add_argument("--scan-pitch", default=None, metavar="LIST",
                      help="scan: grating pitches, comma-separated lengths (e.g. 2mm,4mm,8mm; default: the target's)")
    scan.add_argument("--scan-phase", default=None, metavar="LIST",
                      help="scan: grating phases, comma-separated, rad (e.g. 0,0.785,1.571; default: the target's)")
    scan.add_argument("--scan-display", default=None, metavar="LIST",
                      help="scan: displays, comma-separated presets or .json files (default: --display)")


def _target(spec: str) -> dict:
    from tactilab.data_schemas.units import to_si

    kind, sep, body = spec.partition(":")
    if kind.strip() != "sinusoid" or not sep:
        raise ValueError(f"--target: expected sinusoid:A=LENGTH,p=LENGTH[,phase=RAD], got {spec!r}; e.g. sinusoid:A=0.5mm,p=4mm")
    fields = {}
    for item in body.split(","):
        key, eq, value = item.partition("=")
        if not eq or key.strip() not in ("A", "p", "phase") or key.strip() in fields:
            raise ValueError(f"--target: unknown or repeated field {item!r} in {spec!r}; use A=, p= and optionally phase=")
        fields[key.strip()] = value.strip()
    if "A" not in fields or "p" not in fields:
        raise ValueError(f"--target: give both A= and p= (lengths), got {spec!r}; e.g. sinusoid:A=0.5mm,p=4mm")
    pitch = to_si(fields["p"], "length", name="--target p")
    if pitch <= 0:
        raise ValueError(f"--target p: the pitch must be > 0, got {fields['p']!r}; e.g. p=4mm")
    return dict(amplitude=to_si(fields["A"], "length", name="--target A"), pitch=pitch,
                phase=to_si(fields.get("phase", "0"), "dimensionless", name="--target phase"))


def _display(spec: str):
    from tactilab.data_schemas import DisplayDescription

    if spec in PRESETS:
        return getattr(DisplayDescription, spec.replace("-", "_"))()
    path = Path(spec)
    if path.suffix.lower() == ".json" and path.is_file():
        return DisplayDescription.load(path)
    raise ValueError(f"--display: must be one of {', '.join(PRESETS)} or an existing .json display description, got {spec!r}")


#: bytes per frame of a travelling scan: its phase and its relative residual (float64 each)
SCAN_FRAME_BYTES = 16


def _receptors(args, n_tractors: int, hypothesis) -> "np.ndarray":
    """The receptor x positions (m), after the memory rule (before the array exists)."""
    import numpy as np

    from tactilab.inversion import check_receptor_memory

    window = _quantity(args.window, "length", "--window")
    n = check_receptor_memory(_count(args.receptors, "--receptors", 2), n_tractors, hypothesis.n_depths, "--receptors")
    return np.linspace(-window / 2, window / 2, n)


def _scan_frames(args) -> int:
    from tactilab.core.memory import check_count

    return check_count(_count(args.scan, "--scan", 1), SCAN_FRAME_BYTES, "--scan",
                       "frames (a phase and a residual each)")


def _count(text: str, name: str, minimum: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {text!r}") from None
    if value < minimum:
        raise ValueError(f"{name}: must be >= {minimum}, got {value}")
    return value


def _quantity(text: str, dimension: str, name: str) -> float:
    """``text`` with its unit, in SI, checked by the positive rule (:func:`tactilab.core.rules.positive`)."""
    from tactilab.core import rules
    from tactilab.data_schemas.units import SI_UNIT, to_si

    return rules.positive(to_si(text, dimension, name=name), name, SI_UNIT[dimension],
                          fix="give a positive value" + ("" if dimension == "dimensionless" else " with a unit"))


def _young_modulus(text: str) -> float:
    from tactilab.core import rules
    from tactilab.data_schemas.units import to_si

    return rules.young_modulus(to_si(text, "pressure", name="--young-modulus"), "--young-modulus")


def _scan(args: argparse.Namespace) -> int:
    """``--scan-*`` / ``--workers``: the metamer of every (display, pitch, phase) as a batch (no PNGs)."""
    import numpy as np

    from tactilab.data_schemas.units import to_si
    from tactilab.inversion import metamer_scan

    target = _target(args.target)
    pitches = ([_quantity(t.strip(), "length", "--scan-pitch") for t in args.scan_pitch.split(",") if t.strip()]
               if args.scan_pitch is not None else [target["pitch"]])
    phases = ([to_si(t.strip(), "dimensionless", name="--scan-phase") for t in args.scan_phase.split(",") if t.strip()]
              if args.scan_phase is not None else [target["phase"]])
    displays = [_display(t.strip()) for t in (args.scan_display or args.display).split(",") if t.strip()]
    hypothesis = check_hypothesis(args.hypothesis, "--hypothesis").with_noise(_quantity(args.noise, "dimensionless", "--noise"))
    x = _receptors(args, max(np.size(d.tractor_x_m) for d in displays), hypothesis)
    frames = _scan_frames(args)
    out = make_out(args.out if args.out is not None else Path("metamer-scan"))
    scan = metamer_scan(pitches, phases, displays, hypothesis, amplitude=target["amplitude"],
                        young_modulus=_young_modulus(args.young_modulus), receptors=x,
                        out_dir=out, bounds=None if args.unbounded else "family",
                        scan_frames=frames, progress=not args.json,
                        echo=(lambda _: None) if args.json else print, **batch_where(args))
    a = scan.attrs
    points = []
    for d in scan["display"].values:
        for p in scan["pitch"].values:
            for ph in scan["phase"].values:
                v = scan.sel(display=d, pitch=p, phase=ph)
                ok = bool(v["finished"])
                points.append(dict(display=str(d), pitch_m=float(p), phase_rad=float(ph), finished=ok,
                                   **{k: (float(v[k]) if ok else None) for k in
                                      ("relative_residual", "dprime", "p_correct_2ifc", "scan_rms")},
                                   metameric=bool(v["metameric"]) if ok else None,
                                   n_at_limit=int(v["n_at_limit"]) if ok else None))
    if args.json:
        print(json.dumps(dict(hypothesis=str(hypothesis), amplitude_m=target["amplitude"], points=points,
                              n_run=a["n_run"], n_skipped=a["n_skipped"], n_failed=a["n_failed"],
                              failed=[k for k in a["failed"].split(";") if k], out=str(out))))
        return 1 if a["n_failed"] else 0
    print(f"metamer scan: sinusoid A = {target['amplitude'] * 1e3:g} mm; hypothesis {hypothesis}; {x.size} receptors")
    print(f"{'display':12s} {'pitch_mm':>8s} {'phase_rad':>9s} {'rel_res':>8s} {'dprime':>9s} {'P_2ifc':>7s} "
          f"{'scan_rms':>8s} {'at_limit':>8s}  metameric")
    for r in points:
        head = f"{r['display']:12s} {r['pitch_m'] * 1e3:8.3g} {r['phase_rad']:9.4g}"
        if not r["finished"]:
            print(f"{head}   failed (see {out / 'errors.tsv'})")
            continue
        print(f"{head} {r['relative_residual']:8.4f} {r['dprime']:9.4g} {r['p_correct_2ifc']:7.4f} "
              f"{r['scan_rms']:8.4f} {r['n_at_limit']:8d}  {r['metameric']}")
    print(f"batch: {a['n_run']} point(s) run, {a['n_skipped']} skipped (done before), {a['n_failed']} failed; "
          f"files: {out / 'results'} (one per point, with the tractor loads in N/m), {out / 'metamer_scan.nc'}")
    return 1 if a["n_failed"] else 0


def run(args: argparse.Namespace) -> int:
    if wants_batch(args) or any(v is not None for v in (args.scan_pitch, args.scan_phase, args.scan_display)):
        return _scan(args)
    import numpy as np

    from tactilab.inversion import SinusoidFamily, TractorFamily, metamer_pair, resolvable_subspace

    target_spec = _target(args.target)
    description = _display(args.display)
    noise = _quantity(args.noise, "dimensionless", "--noise")
    hypothesis = check_hypothesis(args.hypothesis, "--hypothesis").with_noise(noise)
    young = _young_modulus(args.young_modulus)
    x = _receptors(args, np.size(description.tractor_x_m), hypothesis)
    window = float(x[-1] - x[0])
    frames = _scan_frames(args)
    out = choose_out(args.out, Path(f"metamer-{description.display_id}"), args.force)

    tractors = TractorFamily.from_display(description, young)
    grating = SinusoidFamily(target_spec["pitch"], target_spec["phase"])
    phases = target_spec["phase"] + np.linspace(0, 2 * np.pi, frames, endpoint=False)
    pair = metamer_pair(grating.stimulus([target_spec["amplitude"]]), tractors, hypothesis, x,
                        bounds=None if args.unbounded else "family", scan_phases=phases)
    prior = tractors.limit if tractors.limit is not None else 1e3  # N/m
    subspace = resolvable_subspace(tractors, hypothesis, prior, x)
    pair.plot(out / "metamer_strain.png")
    subspace.plot(out / "metamer_spectrum.png")
    result = dict(hypothesis=str(hypothesis), display=description.display_id, relative_residual=pair.relative_residual,
                  dprime=pair.dprime, p_correct_2ifc=pair.p_correct_2ifc, metameric=pair.metameric,
                  scan_rms=pair.scan_rms, scan_frames=frames, tractor_x_m=tractors.tractor_x.tolist(),
                  loads_n_per_m=pair.params.tolist(), load_limit_n_per_m=None if args.unbounded else tractors.limit,
                  per_component=pair.per_component, resolvable_dimension=subspace.dimension, prior_std_n_per_m=prior,
                  files=[str(out / "metamer_strain.png"), str(out / "metamer_spectrum.png")])
    if args.json:
        print(json.dumps(result))
        return 0
    limit = "none" if args.unbounded or tractors.limit is None else f"{tractors.limit * 1e-3:.4g} N/mm"
    print(f"target: sinusoid A = {target_spec['amplitude'] * 1e3:g} mm, p = {target_spec['pitch'] * 1e3:g} mm, "
          f"phase {target_spec['phase']:g} rad; display {description.display_id} ({tractors.n_params} tractors, "
          f"load limit {limit}); E = {young * 1e-6:g} MPa; {x.size} receptors on [{-window / 2 * 1e3:g}, {window / 2 * 1e3:g}] mm")
    print(f"hypothesis {hypothesis} ({hypothesis.shear} shear)")
    print(f"relative residual {pair.relative_residual:.4g} (||diff|| / ||target readout||, not squared); "
          f"d' = {pair.dprime:.4g}; P(correct, 2IFC) = {pair.p_correct_2ifc:.4f}; metameric: {pair.metameric}")
    print(f"travelling scan ({frames} frames over one pitch): rms relative residual {pair.scan_rms:.4g}")
    print("per component: " + ", ".join(f"{k} {v:.4g}" for k, v in pair.per_component.items()))
    print("tractor loads (N/mm): " + ", ".join(f"{xi * 1e3:+g} mm: {q * 1e-3:+.4f}"
                                               for xi, q in zip(tractors.tractor_x, pair.params)))
    if not args.unbounded and tractors.limit is not None:
        at_limit = int(np.sum(np.abs(pair.params) >= tractors.limit * (1 - 1e-9)))
        if at_limit:
            print(f"note: {at_limit} of {tractors.n_params} tractors sit at their load limit "
                  f"({tractors.limit * 1e-3:.4g} N/mm); --unbounded shows the unconstrained metamer")
    print(f"resolvable load patterns (s > 1, prior std {prior * 1e-3:.4g} N/mm): {subspace.dimension} of {tractors.n_params}")
    print(f"wrote {out / 'metamer_strain.png'} and {out / 'metamer_spectrum.png'}")
    return 0

"""``tactilab metamer``: the tractor-display metamer of a sliding sinusoid, and how well receptors tell them apart."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from .common import make_out

NAME = "metamer"
HELP = ("tactile metamer of a sinusoidal surface on a tractor display: residual, d' and tractor loads (N/mm) "
        "for a receptor hypothesis such as xx,zx@1.25mm; PNGs of the strain at depth and the singular spectrum")

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
    parser.add_argument("--out", type=Path, default=None, help="folder for the PNGs (default: metamer-<display>)")
    parser.add_argument("--json", action="store_true", help="print one JSON object (SI units) instead of text")


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


def _count(text: str, name: str, minimum: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {text!r}") from None
    if value < minimum:
        raise ValueError(f"{name}: must be >= {minimum}, got {value}")
    return value


def _positive(text: str, dimension: str, name: str) -> float:
    from tactilab.data_schemas.units import to_si

    value = to_si(text, dimension, name=name)
    if value <= 0:
        raise ValueError(f"{name}: must be > 0, got {text!r}")
    return value


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from tactilab.forward import ReceptorHypothesis
    from tactilab.inversion import SinusoidFamily, TractorFamily, metamer_pair, resolvable_subspace

    target_spec = _target(args.target)
    description = _display(args.display)
    noise = _positive(args.noise, "dimensionless", "--noise")
    hypothesis = ReceptorHypothesis.parse(args.hypothesis).with_noise(noise)
    young = _positive(args.young_modulus, "pressure", "--young-modulus")
    window = _positive(args.window, "length", "--window")
    x = np.linspace(-window / 2, window / 2, _count(args.receptors, "--receptors", 2))
    frames = _count(args.scan, "--scan", 1)
    out = make_out(args.out if args.out is not None else Path(f"metamer-{description.display_id}"))

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

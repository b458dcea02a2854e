"""``tactilab contact SURFACE``: solve the skin's contact with a rigid surface; write the solution and maps."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from .common import RunReport, add_report_options, choose_out, staged_outputs
from .material_option import RELAXED, add_material_option, describe_material, read_material_option, read_time_option

NAME = "contact"
HELP = ("solve the frictional contact of the skin with a rigid surface (height map, scene or built-in): "
        "contact area, peak pressure (kPa), stick zone; writes contact.nc (SI) and PNGs (mm, kPa, strain)")

#: the normal-contact methods of solve_contact (tactilab.forward.contact.METHODS, and "auto")
NORMAL_METHODS = ("auto", "preconditioned_cg", "polonsky_keer")

GRID_RULE = ("Built-ins and scenes are sampled on --grid nodes (default 256 per axis) at --grid-spacing; "
             "without --grid-spacing a finger's grid spans 3 Hertz contact diameters of the requested load, "
             "a sinusoid's periodic cell is one period, a rough periodic cell has 20 um nodes. "
             "Height-map files keep their own grid.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = f"{HELP}. {GRID_RULE}"
    parser.add_argument("surface", help="a height map (.npy with --spacing and --height-unit, .csv, .nc with x/y "
                                        "coordinates and units), a scene (.toml, .json), or a built-in: "
                                        "sphere:R=10mm, sinusoid:A=5um,p=1mm, rough:rms=2um,hurst=0.8,seed=1 "
                                        "(or slope=0.1 instead of rms; long=, short= cut-off wavelengths; "
                                        "hurst 0.8 and seed 0 by default)")
    load = parser.add_argument_group("load (exactly one; a scene gives its normal force)")
    load.add_argument("--normal-force", help="total normal force with unit, e.g. 0.8N (N/m with --plane-strain)")
    load.add_argument("--mean-pressure", help="mean pressure over a periodic cell with unit, e.g. 10kPa")
    load.add_argument("--approach", help="rigid-body approach with unit, e.g. 5um")
    fr = parser.add_argument_group("friction")
    fr.add_argument("--friction", type=float, default=None,
                    help="Coulomb coefficient mu >= 0, dimensionless (default: the scene's, else 0)")
    fr.add_argument("--condition", choices=("frictionless", "sliding", "partial", "stuck"), default=None,
                    help="interface condition (default: sliding when mu > 0, else frictionless)")
    fr.add_argument("--tangential-force", help="total tangential force on the skin for partial and stuck, with "
                                               "unit: 0.2N (along x) or 0.2N,0.1N (x, y); N/m with --plane-strain")
    fr.add_argument("--slide-direction", default="1,0",
                    help="for sliding: direction of the traction on the skin, dimensionless DX,DY (default 1,0)")
    sk = parser.add_argument_group("skin and grid")
    sk.add_argument("--young-modulus", help="skin Young's modulus with unit (default: the scene's, else 1MPa)")
    sk.add_argument("--nu", type=float, default=None,
                    help="Poisson's ratio in (-1, 0.5], dimensionless (default: the scene's, else 0.5)")
    add_material_option(sk)
    sk.add_argument("--time", default=None,
                    help="with a viscoelastic --material: how long the load is held, with unit, e.g. 200ms (default "
                         "0: the instantaneous contact), or 'relaxed' (the relaxed elastic contact, frictionless); a "
                         "viscoelastic half-space is solved in time steps, frictionless; viscoelastic layers at 0 "
                         "(their glassy elastic layers, any friction condition) or relaxed only")
    sk.add_argument("--finger-radius", help="press a surface with a finger of this radius, e.g. 10mm "
                                            "(isolated contact); without it a surface is a periodic cell")
    sk.add_argument("--periodic", action="store_true", help="the grid is one period of an endless surface")
    sk.add_argument("--plane-strain", action="store_true",
                    help="a profile along x (built-ins become profiles; forces in N/m)")
    sk.add_argument("--grid", help="nodes per axis for built-ins and scenes: N or NX,NY (default 256)")
    sk.add_argument("--grid-spacing", help="node spacing with unit for built-ins and scenes, e.g. 20um")
    sk.add_argument("--spacing", help="node spacing of a .npy or plain-matrix .csv height map, with unit: "
                                      "20um or 20um,10um (x, y)")
    sk.add_argument("--height-unit", help="unit of the heights in a .npy or plain-matrix .csv, e.g. um")
    parser.add_argument("--method", choices=NORMAL_METHODS, default="auto",
                        help="normal-contact method (default auto: preconditioned_cg)")
    parser.add_argument("--tol", type=float, default=1e-8,
                        help="solver tolerance: the largest gap residual over the gap's range (max - min), "
                             "dimensionless (default 1e-8)")
    parser.add_argument("--depth", action="append", default=[],
                        help="receptor depth(s) for the strain map, with unit: 1mm, or 1mm,2mm; repeatable")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder for contact.nc (SI), pressure.png (mm, kPa), stick_slip.png and "
                             "strain.nc/.png; default: a new folder <surface>-contact (then -2, -3, ...); an "
                             "existing non-empty one needs --force")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    add_report_options(parser)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from .contact_inputs import build_problem, parse_options

    report = RunReport("contact")
    material = read_material_option(args)
    held_s = read_time_option(args.time)  # its unit is checked with the other options, before the problem is built
    opts = parse_options(args)
    if material is not None:  # its modulus sizes the default grid (the relaxed one: the largest contact)
        opts["young_modulus"], args.nu = material.young_modulus_pa, material.poisson_ratio
    problem, settings = build_problem(args, opts)
    if material is None and problem.scene is not None and (problem.scene.material.is_viscoelastic
                                                            or problem.scene.material.is_layered):
        if args.young_modulus is not None or args.nu is not None:
            raise ValueError("--young-modulus, --nu: the scene's material is viscoelastic or layered, which they "
                             "cannot describe; drop them, or give an elastic --material")
        material = problem.scene.material  # as --material
    held = _held_time(held_s, material)
    from tactilab.forward import HalfSpace, skin_from_material, solve_contact
    from tactilab.forward.contact_files import write_contact

    depths = opts["depths"]
    skin = HalfSpace(E=settings["young_modulus"], nu=settings["nu"]) if material is None else skin_from_material(material)
    held_note = None
    if material is not None and (material.has_viscoelastic_layers or held == math.inf):  # refusals before any folder
        skin, settings, held_note = _held_elastic(args, report, skin, settings, held)
    created = args.out is None or not args.out.exists()
    out = report.watch(choose_out(args.out, Path(f"{problem.label}-contact"), args.force))
    if material is not None and material.is_viscoelastic and held != math.inf:
        return _viscoelastic(args, report, problem, settings, skin, held, depths, out, material, created)
    shape = " x ".join(str(n) for n in problem.gap.shape[::-1])
    if not (args.quiet or args.json):
        print(f"tactilab contact: solving on {shape} nodes ({settings['memory_bytes'] / 2**20:.0f} MiB estimated)",
              file=sys.stderr, flush=True)
    # staged: a refusal, or a warning that --strict makes an error, leaves no partial output
    with report.collecting_warnings(), staged_outputs(out, created) as stage:
        t0 = time.perf_counter()
        try:
            sol = solve_contact(skin, problem.gap, problem.spacing, periodic=problem.periodic,
                                friction=settings["friction"], condition=settings["condition"],
                                tangential_force=opts["tangential_force"], slide_direction=opts["slide_direction"],
                                method=args.method, tol=args.tol, **settings["load"])
        except ValueError as exc:
            raise ValueError(as_option(str(exc))) from None
        elapsed = time.perf_counter() - t0
        write_contact(sol, stage, skin=skin, depths=depths, friction=settings["friction"], title=problem.label)
    _summarise(report, sol, problem, settings, elapsed, depths)
    if material is not None:
        report.computed.append(describe_material(material) + (held_note or ""))
    report.data["time_s"] = float(np.round(elapsed, 6))
    report.emit(args.json)
    return 0


def _held_time(held: float | None, material) -> float | None:
    """``--time`` in s (>= 0, inf for relaxed), only with a viscoelastic material or viscoelastic layers."""
    if held is None:
        return None
    if material is None or not (material.is_viscoelastic or material.has_viscoelastic_layers):
        raise ValueError("--time: only a viscoelastic --material (model prony or sls, or layers with Prony terms) "
                         "depends on time; drop --time")
    return held


def _held_elastic(args, report, skin, settings, held):
    """The elastic skin of an exact limit of a held load: the glassy layers at t = 0+ (any friction
    condition: the skin answers elastically with E(0)), or the relaxed skin, the limit of the
    frictionless time-stepped contact under a load held for ever. Returns the skin, the settings
    and the note for the report."""
    held = held or 0.0
    if held == 0.0:
        report.data["held_state"] = "instantaneous"
        return skin.instantaneous, _top(settings, skin.instantaneous), (
            "; the load applied at t = 0: the instantaneous contact, on the glassy elastic layers (every E(0))")
    if held != math.inf:
        raise ValueError(f"--time: the contact of viscoelastic layers is computed at its two exact limits, 0ms (the "
                         f"instantaneous contact, on the glassy layers) and {RELAXED} (the load held until the layers "
                         f"have relaxed), got {args.time!r}; give --time 0ms or --time {RELAXED} (a time-stepped "
                         "contact is for a viscoelastic half-space, model prony or sls)")
    if settings["condition"] != "frictionless" and (args.condition is not None or args.friction is not None):
        raise ValueError(f"--time {RELAXED}: the relaxed contact is the limit of the frictionless time-stepped "
                         f"contact (with friction the stick zone depends on how the skin relaxed), got "
                         f"{'--condition ' + args.condition if args.condition else '--friction ' + str(args.friction)}; "
                         "drop --condition and --friction")
    if settings["condition"] != "frictionless":
        report.dropped.append(f"friction (mu = {settings['friction']:g}, the scene's): the relaxed contact is "
                              "solved frictionless")
    settings = {**settings, "condition": "frictionless", "friction": 0.0}
    report.data["held_state"] = RELAXED
    return skin.relaxed, _top(settings, skin.relaxed), ("; the load held until the skin has relaxed: the relaxed "
                                                        "elastic contact (every E_inf), frictionless")


def _top(settings: dict, skin) -> dict:
    """The settings with the modulus (Pa) of the elastic skin solved (its top layer's when layered)."""
    return {**settings, "young_modulus": skin.layers[0].E if hasattr(skin, "layers") else skin.E}


def _viscoelastic(args, report, problem, settings, skin, held, depths, out, material, created) -> int:
    """The load applied at t = 0 and held for ``--time``: a time-stepped viscoelastic contact
    (frictionless), written as the last step's solution and the strain of its pseudo-pressure."""
    import numpy as np

    from tactilab.forward import solve_viscoelastic_contact, write_field
    from tactilab.forward.contact_files import write_contact

    if settings["condition"] != "frictionless" and args.condition is not None:
        raise ValueError(f"--condition: a viscoelastic --material is solved frictionless, got --condition "
                         f"{args.condition}; drop --condition (or use --condition frictionless)")
    held = held or 0.0
    fastest = float(skin.prony.taus.min())
    times = np.array([0.0]) if held == 0 else np.unique(np.concatenate(
        [[0.0], np.geomspace(min(held, fastest / 10), held, 40)]))
    with report.collecting_warnings(), staged_outputs(out, created) as stage:  # no partial output on a refusal
        t0 = time.perf_counter()
        try:
            history = solve_viscoelastic_contact(skin, problem.gap, problem.spacing, times, periodic=problem.periodic,
                                                 tol=args.tol, keep_every=None, **settings["load"])
        except ValueError as exc:
            raise ValueError(as_option(str(exc))) from None
        elapsed = time.perf_counter() - t0
        sol = history.last
        write_contact(sol, stage, title=problem.label)
        if depths:
            write_field(history.strain(skin, list(depths), tol=max(1e-6, float(sol.error_estimate))), stage,
                        stem="strain")
    if settings["condition"] != "frictionless":
        report.dropped.append(f"friction (mu = {settings['friction']:g}, the scene's): a viscoelastic contact is "
                              "solved frictionless")
    settings = {**settings, "condition": "frictionless", "friction": 0.0}
    _summarise(report, sol, problem, settings, elapsed, depths)
    report.computed[0] = report.computed[0].replace("; E = ", "; relaxed E = ", 1)
    unit, scale = ("mm", 1e3) if problem.gap.ndim == 1 else ("mm^2", 1e6)
    report.computed.append(f"{describe_material(material)}; load held for {held * 1e3:g} ms in {len(times)} time "
                           f"steps: contact area {history.area[0] * scale:.4g} -> {history.area[-1] * scale:.4g} {unit}")
    report.method = ("solve_viscoelastic_contact: one elastic contact per time step, the relaxation history in the "
                     "gap (generalised Maxwell, exact for piecewise linear histories); " + report.method)
    report.data["time_s"] = float(np.round(elapsed, 6))
    report.data["held_s"] = held
    report.emit(args.json)
    return 0


#: solve_contact's argument names -> the options that set them (its errors are reworded with these)
OPTION_OF = {"method": "--method", "tangential_force": "--tangential-force", "friction": "--friction", "condition": "--condition",
             "normal_force": "--normal-force", "mean_pressure": "--mean-pressure", "approach": "--approach",
             "slide_direction": "--slide-direction", "tol": "--tol", "gap": "--grid", "spacing": "--grid-spacing",
             "periodic": "--periodic"}


def as_option(message: str) -> str:
    """A solver error ``"arg: text"`` as ``"--option (arg): text"``, so the user sees the option to change."""
    arg, sep, rest = message.partition(":")
    option = OPTION_OF.get(arg.strip())
    return f"{option} ({arg.strip()}):{rest}" if sep and option else message


def _summarise(report: RunReport, sol, problem, settings, elapsed: float, depths) -> None:
    import numpy as np

    ps = problem.plane_strain
    area_unit, force_unit = ("mm", "N/m") if ps else ("mm^2", "N")
    area = float(sol.area) * (1e3 if ps else 1e6)
    peak = float(np.max(sol.pressure))
    dx = problem.spacing if np.ndim(problem.spacing) == 0 else problem.spacing[0]
    report.computed.append(f"{problem.label}: {' x '.join(str(n) for n in problem.gap.shape[::-1])} nodes at "
                           f"{dx * 1e6:g} um, {'periodic' if problem.periodic else 'isolated'}; E = "
                           f"{settings['young_modulus'] / 1e3:g} kPa, nu = {settings['nu']:g}")
    report.computed += problem.notes
    report.computed.append(f"contact area {area:.4g} {area_unit} (fraction {float(sol.contact_fraction):.4g}), "
                           f"normal force {float(sol.normal_force):.4g} {force_unit}, approach "
                           f"{float(sol.approach) * 1e6:.4g} um, peak pressure {peak / 1e3:.4g} kPa")
    stick = None
    if settings["condition"] in ("partial", "stuck"):
        stick = stick_radius(sol.stick, problem.spacing)
        what = "half-width (half its total length)" if ps else "radius (of the disc of equal area)"
        report.computed.append(f"stick zone {what} {stick * 1e3:.4g} mm ({settings['condition']}, mu = "
                               f"{settings['friction']:g})")
    report.computed.append(f"{int(sol.iterations)} iterations ({'converged' if sol.converged else 'NOT converged'})"
                           f" in {elapsed:.3g} s")
    grid = "periodic" if problem.periodic else "isolated, zero-padded"
    report.method = (f"solve_contact, normal method {sol.method}: conjugate gradients on the FFT compliance "
                     f"({grid}); {settings['condition']}" + (
                         ": tangential tractions by projected gradient and semismooth Newton"
                         if settings["condition"] in ("partial", "stuck") else ""))
    parts = ", ".join(f"{k} {float(v):.1e}" for k, v in dict(sol.error_parts).items())
    report.error_estimate = (f"max |pressure error| <= {float(sol.error_estimate):.1e} of the peak pressure "
                             f"({parts}); requested --tol {settings['tol']:g}")
    report.dropped += problem.dropped
    if not depths:
        report.dropped.append("strain at depth: no --depth given")
    if settings["condition"] not in ("partial", "stuck") and settings["friction"] == 0:
        report.dropped.append("stick/slip map: frictionless contact")
    report.data.update(
        surface=problem.label, shape=list(problem.gap.shape), periodic=problem.periodic,
        contact_area_mm2=None if ps else area, contact_length_mm=area if ps else None,
        contact_fraction=float(sol.contact_fraction), peak_pressure_kpa=peak / 1e3,
        normal_force_n=None if ps else float(sol.normal_force), normal_force_n_per_m=float(sol.normal_force) if ps
        else None, approach_um=float(sol.approach) * 1e6, stick_radius_mm=None if stick is None else stick * 1e3,
        iterations=int(sol.iterations), converged=bool(sol.converged),
        error_estimate_of_peak_pressure=float(sol.error_estimate),
        error_parts={k: float(v) for k, v in dict(sol.error_parts).items()}, condition=settings["condition"],
        friction=settings["friction"], depths_mm=[z * 1e3 for z in depths])


def stick_radius(stick, spacing) -> float:
    """Size of a stick zone (m): the radius of the disc of equal area, or the half-width of a profile's."""
    import numpy as np

    stick = np.asarray(stick, dtype=bool)
    if stick.ndim == 1:
        dx = spacing if np.ndim(spacing) == 0 else spacing[0]
        return float(stick.sum() * dx / 2)
    dx, dy = (spacing, spacing) if np.ndim(spacing) == 0 else spacing
    return float(np.sqrt(stick.sum() * dx * dy / np.pi))

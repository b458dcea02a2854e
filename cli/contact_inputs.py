"""Inputs of ``tactilab contact``: the surface argument and the grid options turned into a gap (edge only).

The SURFACE argument is a height-map file (``.npy``, ``.csv``, ``.nc``; read by
``tactilab.data_schemas.read_height_map``), a scene file (``.toml``/``.json``) or a built-in:

- ``sphere:R=10mm``: a smooth finger of radius R on a flat surface (a cylinder with --plane-strain);
- ``sinusoid:A=5um,p=1mm``: h = A cos(2 pi x / p), ridges along y;
- ``rough:rms=2um,hurst=0.8,seed=1``: a self-affine random surface (``slope=0.1`` instead of ``rms``;
  ``long=``, ``short=``: its cut-off wavelengths with units).

The gap at zero approach is r^2 / (2 R) - h(x, y) with a finger of radius R (the sphere, the scene's
finger, or --finger-radius), and -h(x, y) without one (a nominally flat skin: a periodic cell only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

BUILTINS = {"sphere": {"R"}, "sinusoid": {"A", "p"}, "rough": {"rms", "slope", "hurst", "seed", "long", "short"}}
DEFAULT_GRID = 256
SPAN_CONTACT_DIAMETERS = 3.0  # a finger's default grid spans 3 Hertz contact diameters
DEFAULT_ROUGH_SPACING = 20e-6  # m, a periodic rough cell without a finger


@dataclass
class Problem:
    """A contact problem built from the command line (SI units)."""

    gap: np.ndarray
    spacing: float | tuple[float, float]
    periodic: bool
    label: str
    finger_radius: float | None = None
    scene: object = None
    notes: list[str] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)

    @property
    def plane_strain(self) -> bool:
        """True for a profile (shape (nx,))."""
        return self.gap.ndim == 1


def parse_builtin(text: str) -> tuple[str, dict[str, str]] | None:
    """``"sphere:R=10mm"`` -> ``("sphere", {"R": "10mm"})``; None when ``text`` is not a built-in."""
    kind, sep, rest = text.partition(":")
    if not sep or kind not in BUILTINS:
        return None
    params = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, value = item.partition("=")
        if not eq or key.strip() not in BUILTINS[kind]:
            raise ValueError(f"SURFACE {text!r}: {item!r} is not a parameter of {kind}; use "
                             f"{', '.join(sorted(BUILTINS[kind]))} as KEY=VALUE with units")
        params[key.strip()] = value.strip()
    return kind, params


def parse_grid(text: str | None, plane_strain: bool) -> tuple[int, ...]:
    """``--grid``: ``N`` (N x N, or N nodes with --plane-strain) or ``NX,NY``; returned as the array shape."""
    if text is None:
        return (DEFAULT_GRID,) if plane_strain else (DEFAULT_GRID, DEFAULT_GRID)
    try:
        sizes = [int(s) for s in text.replace("x", ",").split(",")]
    except ValueError:
        raise ValueError(f"--grid: expected N or NX,NY (node counts), got {text!r}; e.g. --grid 256") from None
    if len(sizes) not in (1, 2) or min(sizes) < 8 or (plane_strain and len(sizes) == 2):
        raise ValueError(f"--grid: expected N or NX,NY with at least 8 nodes per axis (one N with --plane-strain), "
                         f"got {text!r}; e.g. --grid 256")
    if plane_strain:
        return (sizes[0],)
    nx, ny = (sizes[0], sizes[0]) if len(sizes) == 1 else sizes
    return (ny, nx)


def check_memory(shape: tuple[int, ...], periodic: bool, condition: str, limit: int | None = None) -> int:
    """Refuse a grid whose solve needs more than ``limit`` bytes, naming the largest square grid that fits.

    The estimate and the limit (half the available memory) are the solver's own
    (``tactilab.forward.contact.memory_estimate`` / ``memory_limit``); checked here before the surface is
    built, so that a refused grid costs nothing.
    """
    from tactilab.forward.contact import memory_estimate, memory_limit

    limit = memory_limit() if limit is None else limit
    need = memory_estimate(shape, periodic, condition)
    if need > limit:
        side = 1
        while memory_estimate((2 * side,) * len(shape), periodic, condition) <= limit:
            side *= 2
        kind = "periodic" if periodic else "isolated (zero-padded to twice the grid)"
        raise ValueError(f"--grid: a {kind} contact on {' x '.join(map(str, shape[::-1]))} nodes needs about "
                         f"{need / 2**30:.1f} GiB, above the limit {limit / 2**30:.1f} GiB (half the available "
                         f"memory); use at most {side} nodes per axis, or a coarser --grid-spacing")
    return need


def hertz_radius(radius: float, e_star: float, plane_strain: bool, force: float | None,
                 approach: float | None) -> float:
    """Hertz contact radius (m) of a finger of ``radius`` under ``force`` (N, or N/m) or ``approach`` (m)."""
    if force is not None:
        if plane_strain:
            return math.sqrt(4 * force * radius / (math.pi * e_star))
        return (3 * force * radius / (4 * e_star)) ** (1 / 3)
    return math.sqrt((2 if plane_strain else 1) * radius * approach)


def node_coordinates(shape: tuple[int, ...], spacing) -> tuple[np.ndarray, np.ndarray | None]:
    """Node coordinates (m) as SurfaceLoad puts them, x first and centred: ``(x, y)`` broadcast to ``shape``."""
    dx = spacing if np.ndim(spacing) == 0 else spacing[0]
    x = (np.arange(shape[-1]) - shape[-1] // 2) * dx
    if len(shape) == 1:
        return x, None
    dy = spacing if np.ndim(spacing) == 0 else spacing[1]
    y = (np.arange(shape[0]) - shape[0] // 2) * dy
    yy, xx = np.meshgrid(y, x, indexing="ij")
    return xx, yy


def finger_gap(radius: float | None, x: np.ndarray, y: np.ndarray | None) -> np.ndarray:
    """r^2 / (2 R) of a finger of radius R (0 without a finger), m."""
    if radius is None:
        return np.zeros_like(x)
    r2 = x**2 if y is None else x**2 + y**2
    return r2 / (2 * radius)


def _positive_option(value: float, option: str, text: str, example: str) -> float:
    """The core rule for a positive quantity, its message naming the option and an example with a unit."""
    from tactilab.core import rules

    unit = {"N": "N", "a": "Pa"}.get(example[-1], "m")
    return rules.positive(value, option, unit, fix=f"give e.g. {example} (got {text!r})")


def _quantities(text: str, dimension: str, option: str, count: tuple[int, ...] = (1, 2)) -> list[float]:
    """A comma-separated list of quantities with units (SI floats); ``count`` is the allowed lengths."""
    from tactilab.data_schemas.units import to_si

    parts = [s for s in text.split(",") if s.strip()]
    if len(parts) not in count:
        raise ValueError(f"{option}: expected {' or '.join(map(str, count))} comma-separated value(s), got {text!r}")
    return [to_si(s, dimension, name=option) for s in parts]


def parse_options(args) -> dict:
    """Every option with a unit converted to SI up front, so a wrong unit fails before any work."""
    from tactilab.core import rules

    plane = bool(args.plane_strain)
    loads = {k: getattr(args, k) for k in ("normal_force", "mean_pressure", "approach") if getattr(args, k)}
    values = {key: _quantities(text, {"normal_force": "line_load" if plane else "force", "mean_pressure": "pressure",
                                      "approach": "length"}[key], "--" + key.replace("_", "-"), (1,))[0]
              for key, text in loads.items()}
    if len(values) > 1:
        raise ValueError(f"--normal-force, --mean-pressure, --approach: give exactly one, got "
                         f"{', '.join('--' + k.replace('_', '-') for k in values)}")
    for key, value in values.items():
        if key != "approach":
            _positive_option(value, "--" + key.replace("_", "-"), loads[key], "0.8N" if key == "normal_force" else "10kPa")
    out = {"load": values, "grid": parse_grid(args.grid, plane)}
    out["young_modulus"] = (rules.young_modulus(_quantities(args.young_modulus, "pressure", "--young-modulus",
                                                            (1,))[0], "--young-modulus")
                            if args.young_modulus else None)
    out["finger_radius"] = (_positive_option(_quantities(args.finger_radius, "length", "--finger-radius", (1,))[0],
                                      "--finger-radius", args.finger_radius, "10mm") if args.finger_radius else None)
    out["grid_spacing"] = (_positive_option(_quantities(args.grid_spacing, "length", "--grid-spacing", (1,))[0],
                                     "--grid-spacing", args.grid_spacing, "20um") if args.grid_spacing else None)
    out["spacing"] = None
    if args.spacing:
        spacing = [_positive_option(v, "--spacing", args.spacing, "20um") for v in _quantities(args.spacing, "length",
                                                                                         "--spacing")]
        out["spacing"] = spacing[0] if len(spacing) == 1 else tuple(spacing)
    out["tangential_force"] = None
    if args.tangential_force:
        pair = _quantities(args.tangential_force, "line_load" if plane else "force", "--tangential-force",
                           (1,) if plane else (1, 2))
        out["tangential_force"] = pair[0] if plane else (pair[0], pair[1] if len(pair) == 2 else 0.0)
    direction = _quantities(args.slide_direction, "dimensionless", "--slide-direction", (2,))
    if not np.hypot(*direction) > 0:
        raise ValueError(f"--slide-direction: must not be zero, got {args.slide_direction!r}; e.g. 1,0")
    out["slide_direction"] = tuple(direction)
    depths = [z for text in args.depth for z in _quantities(text, "length", "--depth", tuple(range(1, 65)))]
    out["depths"] = [_positive_option(z, "--depth", ",".join(args.depth), "1mm") for z in depths]
    if args.nu is not None:
        rules.poisson_ratio(args.nu, "--nu")
    if args.friction is not None and not args.friction >= 0:
        raise ValueError(f"--friction: the Coulomb coefficient must be >= 0, got {args.friction!r}; e.g. 0.5")
    if not 0 < args.tol < 1:
        raise ValueError(f"--tol: must be in (0, 1), got {args.tol!r}; e.g. 1e-8")
    return out


def _scene_or_map(path: Path, args, spacing):
    """A scene record or a HeightMap from a file, by suffix."""
    suffix = path.suffix.lower()
    if suffix in (".toml", ".json"):
        from tactilab.data_schemas.files import load_scene

        scene = load_scene(path)
        if scene.contact is None:
            raise ValueError(f"{path}: the scene has no finger contact (a display drives the skin); give a scene "
                             "with a [contact] table")
        if scene.contact.periodic:
            raise ValueError(f"{path}: the scene is a periodic cell (mean_pressure) without a finger; simulate it with "
                             "tactilab simulate, or press its surface here as a built-in (e.g. sinusoid:A=2um,p=1mm "
                             "--periodic --plane-strain --mean-pressure 3kPa)")
        return scene, None
    from tactilab.data_schemas.height_map import read_height_map

    return None, read_height_map(path, spacing=spacing, height_unit=args.height_unit)


def _load_settings(load: dict[str, float], periodic: bool, scene) -> dict[str, float]:
    """The solver's load keyword (SI): the one given option, or the scene's normal force."""
    if not load:
        if scene is None:
            raise ValueError("--normal-force, --mean-pressure, --approach: give one (e.g. --normal-force 0.8N)")
        return {"normal_force": float(scene.contact.normal_force_n)}
    if "mean_pressure" in load and not periodic:
        raise ValueError(f"--mean-pressure: a mean pressure needs a periodic cell (--periodic), got "
                         f"{load['mean_pressure']:g} Pa on an isolated contact; give --normal-force, or add --periodic")
    return dict(load)


def build_problem(args, opts: dict) -> tuple[Problem, dict]:
    """The gap, grid and settings of ``tactilab contact`` from its arguments and ``parse_options(args)`` (SI)."""
    from tactilab.data_schemas.units import to_si

    builtin = parse_builtin(args.surface)
    scene = hmap = None
    path = Path(args.surface)
    if builtin is None:
        if not path.is_file():
            raise ValueError(f"SURFACE: {args.surface!r} is neither a file nor a built-in; give a height map "
                             "(.npy, .csv, .nc), a scene (.toml) or sphere:R=10mm, sinusoid:A=5um,p=1mm, "
                             "rough:rms=2um,hurst=0.8,seed=1")
        scene, hmap = _scene_or_map(path, args, opts["spacing"])
    elif args.spacing is not None or args.height_unit is not None:
        raise ValueError("--spacing, --height-unit: they describe a .npy or .csv height map, not a built-in; use "
                         "--grid-spacing for a built-in's nodes")
    if hmap is not None and (args.grid is not None or args.grid_spacing is not None):
        raise ValueError("--grid, --grid-spacing: a height-map file keeps its own grid; drop them (or resample "
                         "the file)")
    plane_strain = args.plane_strain or (hmap is not None and hmap.heights_m.ndim == 1)
    if scene is not None and plane_strain:
        raise ValueError("--plane-strain: a scene's finger is a sphere (3-D); drop --plane-strain")
    young = opts["young_modulus"] if opts["young_modulus"] is not None else (
        scene.material.young_modulus_pa if scene is not None else 1e6)
    nu = args.nu if args.nu is not None else (scene.material.poisson_ratio if scene is not None else 0.5)
    radius = opts["finger_radius"]
    kind, params = builtin if builtin is not None else (None, {})
    if kind == "sphere":
        if "R" not in params or radius is not None:
            raise ValueError("SURFACE sphere: give its radius once, as sphere:R=10mm (not --finger-radius)")
        radius = to_si(params["R"], "length", name="sphere R")
        if radius <= 0:
            raise ValueError(f"SURFACE sphere: R must be > 0, got {params['R']!r}")
    elif scene is not None:
        radius = radius if radius is not None else float(scene.contact.finger_radius_m)
    if radius is None and not args.periodic:
        raise ValueError("--periodic: a surface without a finger is a nominally flat contact, which needs a periodic "
                         "cell; add --periodic, or press it with --finger-radius 10mm")
    friction = args.friction if args.friction is not None else (
        float(scene.contact.friction_coefficient) if scene is not None else 0.0)
    if args.condition == "stuck" and args.friction is None:
        friction = math.inf  # stuck: no slip whatever the load, the limit mu -> inf
    condition = args.condition or ("sliding" if friction > 0 else "frictionless")
    load = _load_settings(opts["load"], args.periodic, scene)
    e_star = young / (1 - nu**2)
    notes: list[str] = []
    dropped: list[str] = []
    if hmap is not None:
        shape, spacing = hmap.heights_m.shape, (hmap.spacing_x_m if plane_strain
                                                 else (hmap.spacing_x_m, hmap.spacing_y_m))
    else:
        shape = opts["grid"]
        spacing = _grid_spacing(opts["grid_spacing"], kind, params, shape, radius, e_star, plane_strain, load)
    need = check_memory(shape, args.periodic, condition)
    x, y = node_coordinates(shape, spacing)
    if hmap is not None:
        heights = hmap.heights_m
        label = path.stem
    elif scene is not None:
        x0 = float(scene.scan.start_position_m)
        heights = scene.surface.height_at(x + x0, y)
        label = scene.name or path.stem
        notes.append(f"scene {label}: finger R = {radius * 1e3:g} mm at world x = {x0 * 1e3:g} mm")
        if scene.contact.fingerprint_period_m is not None:
            dropped.append("the scene's fingerprint ridges: the skin is solved smooth")
        if scene.contact.adhesion > 0:
            dropped.append(f"the scene's adhesion blend ({scene.contact.adhesion:g}): adhesion is out of scope here")
    else:
        heights = _builtin_heights(kind, params, x, shape, spacing, args.periodic, notes)
        label = "cylinder" if kind == "sphere" and plane_strain else kind
    gap = finger_gap(radius, x, y) - heights
    problem = Problem(gap=np.asarray(gap, dtype=float), spacing=spacing, periodic=args.periodic, label=label,
                      finger_radius=radius, scene=scene, notes=notes, dropped=dropped)
    settings = {"young_modulus": young, "nu": nu, "friction": friction, "condition": condition, "load": load,
                "memory_bytes": need, "tol": args.tol}
    return problem, settings


def _grid_spacing(given, kind, params, shape, radius, e_star, plane_strain, load) -> float:
    """--grid-spacing (``given``, m), or the default rule of the module docstring (m)."""
    if given is not None:
        return given
    n = shape[-1]
    if radius is not None and "mean_pressure" not in load:
        if load.get("approach", 1.0) <= 0:
            raise ValueError(f"--approach: {load['approach']:g} m leaves the finger out of contact, so it cannot size "
                             "the grid; give a positive approach, or --grid-spacing")
        a = hertz_radius(radius, e_star, plane_strain, load.get("normal_force"), load.get("approach"))
        return 2 * SPAN_CONTACT_DIAMETERS * a / n
    if kind == "sinusoid":
        return _sinusoid(params)[1] / n
    return DEFAULT_ROUGH_SPACING


def _sinusoid(params: dict[str, str]) -> tuple[float, float]:
    """Amplitude and period (m) of ``sinusoid:A=..,p=..``."""
    from tactilab.data_schemas.units import to_si

    missing = {"A", "p"} - set(params)
    if missing:
        raise ValueError(f"SURFACE sinusoid: {', '.join(sorted(missing))} missing; e.g. sinusoid:A=5um,p=1mm")
    amplitude = to_si(params["A"], "length", name="sinusoid A")
    period = to_si(params["p"], "length", name="sinusoid p")
    if amplitude <= 0 or period <= 0:
        raise ValueError(f"SURFACE sinusoid: A and p must be > 0, got A={params['A']!r}, p={params['p']!r}")
    return amplitude, period


def _builtin_heights(kind, params, x, shape, spacing, periodic, notes) -> np.ndarray:
    """Heights (m) of the sinusoid and rough built-ins on the grid (0 for the sphere's flat)."""
    from tactilab.data_schemas.surface import random_rough_surface
    from tactilab.data_schemas.units import to_si

    if kind == "sphere":
        return np.zeros(shape)
    if kind == "sinusoid":
        amplitude, period = _sinusoid(params)
        width = shape[-1] * (spacing if np.ndim(spacing) == 0 else spacing[0])
        periods = width / period
        if periodic and abs(periods - round(periods)) > 1e-9 * max(periods, 1):
            raise ValueError(f"SURFACE sinusoid: a periodic grid must hold whole periods, got {periods:.6g} periods "
                             f"of {period * 1e3:g} mm in {width * 1e3:g} mm; set --grid-spacing to p / N")
        notes.append(f"sinusoid: A = {amplitude * 1e6:g} um, period {period * 1e3:g} mm, ridges along y")
        return amplitude * np.cos(2 * np.pi * x / period)
    rough = dict(params)
    if ("rms" in rough) == ("slope" in rough):
        raise ValueError("SURFACE rough: give exactly one of rms= (a length) and slope= (dimensionless); "
                         "e.g. rough:rms=2um,hurst=0.8,seed=1")
    try:
        seed = int(rough.get("seed", "0"))
        hurst = float(rough.get("hurst", "0.8"))
    except ValueError:
        raise ValueError(f"SURFACE rough: seed must be an integer and hurst a number, got {params}") from None
    kwargs = {"hurst": hurst, "rng": np.random.default_rng(seed)}
    if "rms" in rough:
        kwargs["rms_height"] = to_si(rough["rms"], "length", name="rough rms")
    else:
        kwargs["rms_slope"] = to_si(rough["slope"], "dimensionless", name="rough slope")
    for key, name in (("long", "long_cutoff"), ("short", "short_cutoff")):
        if key in rough:
            kwargs[name] = to_si(rough[key], "length", name=f"rough {key}")
    spacing_xy = spacing if np.ndim(spacing) == 0 else tuple(spacing)
    heights = random_rough_surface(shape, spacing_xy, **kwargs)
    notes.append(f"rough: rms height {np.sqrt(np.mean(heights**2)) * 1e6:.3g} um, Hurst {hurst:g}, seed {seed}")
    return heights

"""Tactile synthesis design: the tractor spacing that best renders a sliding grating at depth.

docs/theory.md section 4a. An array of ``pairs`` tractor pairs (half spacing d, pair centres
``4 n d``) driven with alternating tangential line loads produces at depth Z the strain
``eps_xx = 3 q S_Phi / (pi E)`` and ``gamma_zx = 3 q S_Psi / (pi E)`` (ENGINEERING shear). A
sinusoidal surface of pitch ``p = 4 d`` sliding over the finger produces ``eps_xx`` and
``gamma_zx`` with amplitude ratio 1 : 2. The design objective compares the two shapes over a
window ``x in [-w/2, w/2]``:

    J(d) = int [S_Phi + (k2/2) cos(2 pi x / (4d))]^2 dx + int [S_Psi - k2 sin(2 pi x / (4d))]^2 dx,

with ``k2 = max S_Psi`` over ``[-4d, 4d]`` (the sign and k2 corrections of docs/theory.md are
applied). J -> 0 trivially as d -> 0 and has spurious minima at very small d, so the optimum is
the lowest non-trivial local minimum: J is scanned on a geometric grid of d over a bracket
starting at 0.2 Z, every interior local minimum is refined with a bounded scalar minimiser,
and, among those that are non-trivial (relative residual J / int target^2 < 1: the array fits
the target better than no strain at all), the one with the lowest J is returned. All minima
are reported.

Quadrature: composite 8-point Gauss-Legendre on panels no wider than ``min(Z, d) / 2`` (the
integrand varies on the scales Z and d): relative error below 1e-10 (tests check it against
a 4x finer rule and scipy.integrate.quad). ``k2`` is located on a grid of spacing
``min(Z, d) / 25`` and refined with a bounded minimiser to 1e-10 Z.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from .halfspace import HalfSpace
from .halfspace import positive as _positive
from .skin import LayeredHalfSpace, tractor_phi_psi
from .tractors import array_centres, array_phi_psi, check_pairs

_GAUSS = np.polynomial.legendre.leggauss(8)
#: the skin of the closed-form design
HALF_SPACE = "half-space (closed form, nu = 1/2)"


def _check_skin(skin):
    """None for the closed-form half-space (``None`` or ``HalfSpace(E, 0.5)``), else a layered skin."""
    if skin is None or (isinstance(skin, HalfSpace) and skin.nu == 0.5):
        return None
    if isinstance(skin, LayeredHalfSpace):
        return skin
    raise ValueError(f"skin: the design takes None or HalfSpace(E, 0.5) (the closed form) or a LayeredHalfSpace, "
                     f"got {skin!r}; for another Poisson's ratio give LayeredHalfSpace([Layer(h, E, nu)], "
                     "base=HalfSpace(E, nu))")


def _phi_psi(x: np.ndarray, d: float, z: float, n: int, skin) -> tuple[np.ndarray, np.ndarray]:
    """S_Phi, S_Psi of the array (1/m): the closed form, or the layered skin's (docs/theory.md 6)."""
    if skin is None:
        return array_phi_psi(x, d, z, n)
    centres, sign = array_centres(d, n)
    sources = np.concatenate([centres - d, centres + d])
    weights = np.concatenate([-sign * np.ones(n), sign * np.ones(n)])  # each pair: -delta(x + d) + delta(x - d)
    return tractor_phi_psi(skin, x, sources, weights, z)


@dataclass(frozen=True)
class SpacingDesign:
    """The optimal half spacing of a tractor array for receptors at one depth.

    Attributes
    ----------
    depth, width : float
        Receptor depth Z and comparison window w, m.
    pairs : int
        Number of tractor pairs.
    d : float
        Optimal half spacing, m (tractor pitch ``2 d``, rendered grating pitch ``4 d``).
    k2 : float
        Amplitude factor, max of S_Psi over [-4d, 4d], 1/m.
    k2_prime : float
        S_Psi(x = d), 1/m: enters the matching traction.
    objective : float
        J at the optimum, 1/m.
    relative_residual : float
        J divided by the integral of the squared target (dimensionless; 0 is a perfect match).
    bracket : (float, float)
        The half spacings searched, m.
    minima : tuple of (float, float, float)
        Every interior local minimum found, as (d in m, J in 1/m, relative residual), in
        increasing d. Those with relative residual >= 1 (no better than zero strain) are trivial.
    grid_points : int
        Size of the scan grid.
    skin : str
        The skin the design was made for: the closed-form half-space at nu = 1/2, or a layered
        skin's repr.
    """

    depth: float
    width: float
    pairs: int
    d: float
    k2: float
    k2_prime: float
    objective: float
    relative_residual: float
    bracket: tuple[float, float]
    minima: tuple[tuple[float, float, float], ...]
    grid_points: int
    skin: str = HALF_SPACE

    @property
    def pitch(self) -> float:
        """Pitch of the rendered grating, ``4 d``, m."""
        return 4.0 * self.d

    @property
    def d_over_depth(self) -> float:
        """Optimal d in units of the depth Z."""
        return self.d / self.depth

    def to_dict(self) -> dict:
        """Plain dict (SI units), e.g. for JSON or a table row."""
        out = asdict(self)
        out["pitch"] = self.pitch
        out["d_over_depth"] = self.d_over_depth
        return out


def _check_inputs(depth, width, pairs) -> tuple[float, float, int]:
    return (_positive(depth, "depth", fix="receptors sit inside the skin: give Z > 0 in m"),
            _positive(width, "width", fix="give the comparison window w > 0 in m"),
            check_pairs(pairs))


def _quadrature(width: float, panel: float) -> tuple[np.ndarray, np.ndarray]:
    t, wt = _GAUSS
    n_panels = max(1, int(math.ceil(width / panel)))
    edges = np.linspace(-0.5 * width, 0.5 * width, n_panels + 1)
    mid = 0.5 * (edges[1:] + edges[:-1])
    half = 0.5 * (edges[1] - edges[0])
    return (mid[:, None] + half * t[None, :]).ravel(), np.tile(wt * half, n_panels)


def amplitude_factor(half_spacing: float, depth: float, pairs: int = 5, skin=None) -> tuple[float, float]:
    """k2 = max of S_Psi over [-4d, 4d] (1/m), and where it is reached (m); ``skin`` as in
    :func:`optimal_half_spacing`."""
    d = _positive(half_spacing, "half_spacing", fix="the tractor spacing must be > 0 (give d in m)")
    z, _, n = _check_inputs(depth, 1.0, pairs)
    skin = _check_skin(skin)
    step = min(z, d) / 25.0
    xs = np.linspace(-4 * d, 4 * d, int(math.ceil(8 * d / step)) + 1)
    psi = _phi_psi(xs, d, z, n, skin)[1]
    i = int(np.argmax(psi))
    lo, hi = xs[max(i - 1, 0)], xs[min(i + 1, xs.size - 1)]
    res = minimize_scalar(lambda x: -_phi_psi(np.array(x), d, z, n, skin)[1], bounds=(lo, hi),
                          method="bounded", options={"xatol": 1e-10 * z})
    if -res.fun >= psi[i]:
        return float(-res.fun), float(res.x)
    return float(psi[i]), float(xs[i])


def spacing_objective(half_spacing: float, depth: float, width: float = 10e-3, pairs: int = 5,
                      panel_fraction: float = 0.5, skin=None) -> dict:
    """The design objective J(d) of docs/theory.md 4a and its parts.

    Parameters
    ----------
    half_spacing : float
        d, m, > 0.
    depth : float
        Z, m, > 0.
    width : float
        Window w, m; x runs over [-w/2, w/2].
    pairs : int
        Number of tractor pairs (>= 1).
    panel_fraction : float
        Quadrature panel width in units of ``min(Z, d)`` (default 0.5; smaller is finer).
    skin : None, HalfSpace or LayeredHalfSpace
        As in :func:`optimal_half_spacing`.

    Returns
    -------
    dict
        ``objective`` (J, 1/m), ``k2`` (1/m), ``target_norm`` (integral of the squared
        target, 1/m) and ``relative_residual`` (J / target_norm).
    """
    d = _positive(half_spacing, "half_spacing", fix="the tractor spacing must be > 0 (give d in m)")
    z, w, n = _check_inputs(depth, width, pairs)
    frac = _positive(panel_fraction, "panel_fraction", "1")
    skin = _check_skin(skin)
    k2, _ = amplitude_factor(d, z, n, skin)
    xs, wq = _quadrature(w, frac * min(z, d))
    s_phi, s_psi = _phi_psi(xs, d, z, n, skin)
    phase = np.pi * xs / (2.0 * d)
    target_phi = -0.5 * k2 * np.cos(phase)
    target_psi = k2 * np.sin(phase)
    j = float(np.sum(wq * ((s_phi - target_phi) ** 2 + (s_psi - target_psi) ** 2)))
    norm = float(np.sum(wq * (target_phi**2 + target_psi**2)))
    return {"objective": j, "k2": k2, "target_norm": norm,
            "relative_residual": j / norm if norm > 0 else math.inf}


def optimal_half_spacing(depth: float, width: float = 10e-3, pairs: int = 5, *,
                         bracket: tuple[float, float] | None = None,
                         grid_points: int = 200, skin=None) -> SpacingDesign:
    """The optimal half spacing d of a tractor array for receptors at depth Z.

    Parameters
    ----------
    depth : float
        Receptor depth Z, m.
    width : float
        Comparison window w, m (default 10 mm).
    pairs : int
        Number of tractor pairs (default 5).
    bracket : (float, float), optional
        Half spacings searched, m; default ``(0.2 Z, 5 Z)``, which excludes the trivial
        d -> 0 behaviour and the spurious minima below about 0.2 Z.
    grid_points : int
        Points of the geometric scan grid (>= 20).
    skin : None, HalfSpace or LayeredHalfSpace
        None or ``HalfSpace(E, 0.5)`` (default): the closed-form half-space at nu = 1/2. A
        ``LayeredHalfSpace``: its exact plane-strain strain of the array (docs/theory.md 6,
        :mod:`tactilab.forward.skin.line_loads`), normalised by the ``E`` of the layer at Z as the
        closed form is by the half-space's (the optimum does not depend on that scale).

    Returns
    -------
    SpacingDesign

    Raises
    ------
    ValueError
        For a bad input, or when J has no interior local minimum in the bracket.
    """
    z, w, n = _check_inputs(depth, width, pairs)
    skin = _check_skin(skin)
    if bracket is None:
        lo, hi = 0.2 * z, 5.0 * z
    else:
        try:
            lo, hi = (float(v) for v in bracket)
        except (TypeError, ValueError):
            raise ValueError(f"bracket: expected two half spacings (low, high) in m, got {bracket!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
            raise ValueError(f"bracket: need finite 0 < low < high in m, got {bracket!r}; e.g. (0.2 Z, 5 Z)")
    if isinstance(grid_points, bool) or not isinstance(grid_points, (int, np.integer)) or grid_points < 20:
        raise ValueError(f"grid_points: need an integer >= 20 to locate the minima, got {grid_points!r}")
    grid = np.geomspace(lo, hi, int(grid_points))
    values = np.array([spacing_objective(d, z, w, n, skin=skin)["objective"] for d in grid])
    minima = []
    for i in range(1, grid.size - 1):
        if values[i] <= values[i - 1] and values[i] < values[i + 1]:
            res = minimize_scalar(lambda d: spacing_objective(d, z, w, n, skin=skin)["objective"],
                                  bounds=(grid[i - 1], grid[i + 1]), method="bounded",
                                  options={"xatol": 1e-7 * z})
            d_best = float(res.x) if res.fun <= values[i] else float(grid[i])
            parts = spacing_objective(d_best, z, w, n, skin=skin)
            minima.append((d_best, parts["objective"], parts["relative_residual"]))
    # a minimum whose array fits the target no better than zero strain (relative residual >= 1)
    # is trivial: J is small there only because k2, and with it the target, is small
    useful = [m for m in minima if m[2] < 1.0]
    if not useful:
        found = ", ".join(f"d = {m[0]:.4g} m (relative residual {m[2]:.3g})" for m in minima) or "none"
        raise ValueError(
            f"bracket: J(d) has no non-trivial interior local minimum in [{lo:.4g}, {hi:.4g}] m for depth "
            f"{z:.4g} m, width {w:.4g} m, pairs {n} (local minima: {found}); widen the bracket or change "
            "the width or the number of pairs"
        )
    d_opt = min(useful, key=lambda m: m[1])[0]
    parts = spacing_objective(d_opt, z, w, n, skin=skin)
    centres = _phi_psi(np.array([d_opt]), d_opt, z, n, skin)[1]
    return SpacingDesign(depth=z, width=w, pairs=n, d=d_opt, k2=parts["k2"], k2_prime=float(centres[0]),
                         objective=parts["objective"], relative_residual=parts["relative_residual"],
                         bracket=(lo, hi), minima=tuple(minima), grid_points=int(grid_points),
                         skin=HALF_SPACE if skin is None else repr(skin))


def _design_pitch_depth(design: SpacingDesign, pitch, depth) -> tuple[float, float]:
    if not isinstance(design, SpacingDesign):
        raise ValueError(f"design: expected a SpacingDesign from optimal_half_spacing, got {type(design).__name__}")
    p = design.pitch if pitch is None else _positive(pitch, "pitch", fix="give the grating pitch p > 0 in m")
    z = design.depth if depth is None else _positive(depth, "depth")
    if not math.isclose(z, design.depth, rel_tol=1e-9):
        raise ValueError(f"depth: {z!r} m differs from the depth the design was made for ({design.depth!r} m); "
                         "call optimal_half_spacing at this depth")
    return p, z


def matching_line_load(amplitude: float, pitch: float | None, depth: float | None, young_modulus: float,
                       design: SpacingDesign) -> float:
    """Line load Q (N/m) whose tractor drive matches a sliding sinusoid of amplitude A and pitch p.

    ``Q = 8 sqrt(2) pi^3 A Z E exp(-2 pi Z / p) / (3 k2' p^2)`` (docs/theory.md 4a). Without the
    sqrt(2) it equates the peak engineering shear of the array, ``3 Q k2' / (pi E)``, with the
    grating's ``8 pi^2 A Z e^{-2 pi Z/p} / p^2``; at p = 4d the tractors sample the travelling
    wave at two points per period, so the drive is a standing wave whose mean square over
    space and time is half that of a travelling wave: the sqrt(2) equates the two RMS strains.

    Parameters
    ----------
    amplitude : float
        A, m (its sign is kept).
    pitch : float or None
        p, m; None for the design's ``4 d``.
    depth : float or None
        Z, m; None for the design's depth (another depth raises ValueError).
    young_modulus : float
        E, Pa.
    design : SpacingDesign
    """
    p, z = _design_pitch_depth(design, pitch, depth)
    a = float(amplitude)
    if not math.isfinite(a):
        raise ValueError(f"amplitude: must be finite, in m, got {amplitude!r}")
    e = _positive(young_modulus, "young_modulus", "Pa")
    return 8.0 * math.sqrt(2.0) * math.pi**3 * a * z * e * math.exp(-2 * math.pi * z / p) / (
        3.0 * design.k2_prime * p * p)


def matching_traction_amplitude(amplitude: float, pitch: float | None, depth: float | None,
                                young_modulus: float, design: SpacingDesign,
                                footprint: float | None = None) -> float:
    """Traction amplitude (Pa) on each tractor that renders a sinusoid of amplitude A, pitch p.

    The matching line load of :func:`matching_line_load` spread over a tractor of contact
    width ``footprint`` (m; default ``design.d``, tractors half as wide as their pitch 2d).
    """
    q = matching_line_load(amplitude, pitch, depth, young_modulus, design)
    c = design.d if footprint is None else _positive(footprint, "footprint", fix="give the tractor width in m")
    return q / c


def max_virtual_amplitude(traction_limit: float, pitch: float | None, depth: float | None,
                          young_modulus: float, design: SpacingDesign,
                          footprint: float | None = None) -> float:
    """Largest sinusoid amplitude A (m) a display with a per-tractor traction limit can render.

    Inverts :func:`matching_traction_amplitude`: ``A_max = limit * footprint / Q(A = 1)``.

    Parameters
    ----------
    traction_limit : float
        Largest tangential traction of one tractor, Pa (``DisplayDescription.max_traction_pa``).
    pitch, depth, young_modulus, design, footprint
        As in :func:`matching_traction_amplitude`.
    """
    limit = _positive(traction_limit, "traction_limit", "Pa")
    per_metre = matching_traction_amplitude(1.0, pitch, depth, young_modulus, design, footprint)
    return limit / per_metre


@dataclass(frozen=True)
class DepthScaling:
    """How the optimal half spacing scales with depth.

    Attributes
    ----------
    designs : tuple of SpacingDesign
        One per depth.
    ratios : ndarray
        d / Z per depth.
    ratio : float
        Least-squares slope of d = c Z (through the origin).
    prefactor, exponent : float
        Power-law fit d = prefactor * Z**exponent (d, Z in m), least squares in log-log.
    max_deviation : float
        Largest relative deviation of the designs from d = ratio * Z.
    """

    designs: tuple[SpacingDesign, ...]
    ratios: np.ndarray
    ratio: float
    prefactor: float
    exponent: float
    max_deviation: float


def _check_list(values, name: str, unit: str, minimum: int = 1) -> list[float]:
    items = list(np.atleast_1d(np.asarray(values, dtype=float)))
    if len(items) < minimum:
        need = "at least one value" if minimum == 1 else f"at least {minimum} values"
        raise ValueError(f"{name}: give {need} in {unit}, got {values!r}")
    return [_positive(v, name, unit) for v in items]


def depth_scaling(depths, width: float | None = 10e-3, pairs: int = 5, *,
                  width_over_depth: float | None = None) -> DepthScaling:
    """Optimise the spacing at several depths and fit how d scales with Z.

    Parameters
    ----------
    depths : sequence of float
        Receptor depths, m (at least two).
    width : float or None
        Fixed comparison window, m. Give None together with ``width_over_depth``.
    pairs : int
        Number of tractor pairs.
    width_over_depth : float, optional
        Use a window proportional to depth, ``w = width_over_depth * Z``; then d / Z is
        exactly constant (the problem has no other length scale), which tests the optimiser.
    """
    zs = _check_list(depths, "depths", "m", minimum=2)
    if (width is None) == (width_over_depth is None):
        raise ValueError("width, width_over_depth: give width or width_over_depth (exactly one), got "
                         f"width={width!r}, width_over_depth={width_over_depth!r}")
    if width_over_depth is not None:
        r = _positive(width_over_depth, "width_over_depth", "1")
        designs = tuple(optimal_half_spacing(z, r * z, pairs) for z in zs)
    else:
        designs = tuple(optimal_half_spacing(z, width, pairs) for z in zs)
    return scaling_from_designs(designs)


def scaling_from_designs(designs) -> DepthScaling:
    """Fit d = c Z and d = a Z**b to designs made at two or more depths (see :func:`depth_scaling`)."""
    designs = tuple(designs)
    if len(designs) < 2 or not all(isinstance(dsg, SpacingDesign) for dsg in designs):
        raise ValueError(f"designs: need at least two SpacingDesign objects at different depths, got {len(designs)}")
    z = np.array([dsg.depth for dsg in designs])
    d = np.array([dsg.d for dsg in designs])
    if np.unique(z).size < 2:
        raise ValueError("designs: all made at one depth; a scaling fit needs two depths or more")
    ratio = float(np.dot(z, d) / np.dot(z, z))
    exponent, log_prefactor = np.polyfit(np.log(z), np.log(d), 1)
    return DepthScaling(designs=designs, ratios=d / z, ratio=ratio, prefactor=float(np.exp(log_prefactor)),
                        exponent=float(exponent), max_deviation=float(np.max(np.abs(d / (ratio * z) - 1))))


def design_table(depths, widths, pairs_list):
    """Optimal designs for every combination of depth, window width and number of pairs.

    Parameters
    ----------
    depths, widths : sequence of float
        m.
    pairs_list : sequence of int

    Returns
    -------
    pandas.DataFrame
        One row per design: ``depth_m, width_m, pairs, d_m, d_over_depth, pitch_m, k2_per_m,
        k2_prime_per_m, objective_per_m, relative_residual, n_minima``.
    """
    import pandas as pd

    zs = _check_list(depths, "depths", "m")
    ws = _check_list(widths, "widths", "m")
    ns = [check_pairs(n) for n in (pairs_list if np.ndim(pairs_list) else [pairs_list])]
    if not ns:
        raise ValueError(f"pairs_list: give at least one number of pairs, got {pairs_list!r}")
    rows = []
    for z in zs:
        for w in ws:
            for n in ns:
                dsg = optimal_half_spacing(z, w, n)
                rows.append(dict(depth_m=z, width_m=w, pairs=n, d_m=dsg.d, d_over_depth=dsg.d_over_depth,
                                 pitch_m=dsg.pitch, k2_per_m=dsg.k2, k2_prime_per_m=dsg.k2_prime,
                                 objective_per_m=dsg.objective, relative_residual=dsg.relative_residual,
                                 n_minima=len(dsg.minima)))
    return pd.DataFrame(rows)

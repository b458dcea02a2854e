"""Loads given as continuous objects, and the error of representing them on a grid.

A :class:`SurfaceLoad` is nodal values: the solver's error estimate covers its method for those
values as given. A *continuous* load (a Hertz contact with its friction condition, a callable
p(x, y), the pressure of a prescribed deflection) is what the user actually asks about; sampling it
on a grid adds an error of its own (the edge of a Hertz contact, a profile finer than the grid).
The protocol is small:

- :class:`ContinuousLoad` has a default grid (``shape``, ``spacing``), says whether it is
  ``periodic``, and samples itself on any grid: ``sample(shape, spacing) -> SurfaceLoad``.

:meth:`HalfSpace.stress` / ``strain`` accept one in place of a ``SurfaceLoad``. The sampling error
is bounded twice, and the smaller bound is reported (both are upper bounds, so is their minimum)
unless :func:`alias_check` finds content beyond the grid's Nyquist wavenumber: that content
aliases alike on every nested grid, the Richardson bound cannot see it, and the spectral bound
alone is reported:

- :func:`sampling_error`, Richardson: solves on the grids of spacing 2h and 4h (nodes shared with
  the fine grid), d1 = |F_h - F_2h| and d2 = |F_2h - F_4h| (max over the shared nodes or sensor
  points); with the observed ratio rho = d2/d1 = 2^p the error of F_h is d1/(rho - 1), returned
  twice (a safety factor), with rho clipped to [1.5, 4]: faster than second order is not trusted
  (a Hertz contact's square-root edge shows an apparent order near 4 on coarse grids while its
  asymptotic order is about 1.8). Tight for rough loads; for smooth loads it errs large (by 5x to
  1e6x for a Gaussian 1.5 spacings wide), and the coarse solves carry the method's own error at 2h
  and 4h.
- :func:`spectral_sampling_error`, aliasing: the load sampled on a grid 2x (2-D) or 4x (1-D)
  finer, minus the load the method sees on the h grid (nodal forces, or the trigonometric
  interpolant for the spectral method), pushed through the exact transfer at each depth (the
  attenuation exp(-k z) weights the content near and beyond the grid scale), relative to the
  field's peak. Only function evaluations and FFTs on the fine grid, no method error; tight for
  smooth loads (3x to 4.3x the true error for that Gaussian) and within 2.2x for the rough ones.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable

import numpy as np

from tactilab.core import rules as check
from .loads import LOAD_COMPONENTS, SurfaceLoad
from .spectral import pressure_from_deflection

__all__ = ["ContinuousLoad", "TractionField", "DeflectionLoad", "refined_grid", "coarse_grid", "shared_nodes",
           "sampling_error", "spectral_sampling_error", "alias_check"]

SAFETY = 2.0


def _shape(value, ndim: int | None = None) -> tuple[int, ...]:
    shape = (int(value),) if np.ndim(value) == 0 else tuple(int(v) for v in value)
    if len(shape) not in (1, 2) or (ndim is not None and len(shape) != ndim) or min(shape) < 1:
        raise ValueError(f"shape: expected (nx,) or (ny, nx) of positive node counts, got {value!r}")
    return shape


class ContinuousLoad(abc.ABC):
    """A surface load defined everywhere, with a default grid to sample it on.

    Subclasses set ``shape`` ((nx,) or (ny, nx)), ``spacing`` (m, (dx,) or (dx, dy)) and
    ``periodic``, and implement :meth:`sample`. Grid nodes follow :class:`SurfaceLoad`
    (index n // 2 is the origin); a periodic load repeats with period ``n h`` per axis.
    """

    shape: tuple[int, ...]
    spacing: tuple[float, ...]
    periodic: bool = False

    @property
    def ndim(self) -> int:
        """1 for a plane-strain load, 2 for a surface load."""
        return len(self.shape)

    @abc.abstractmethod
    def sample(self, shape, spacing) -> SurfaceLoad:
        """The tractions (Pa) at the nodes of the grid ``shape`` x ``spacing`` (m)."""

    def nodal(self) -> SurfaceLoad:
        """The load sampled on its own grid."""
        return self.sample(self.shape, self.spacing)


def _grid(shape, spacing, periodic: bool) -> tuple[tuple[int, ...], tuple[float, ...]]:
    shape = _shape(shape)
    spacing = check.spacing(spacing, len(shape))
    if periodic and any(n % 4 for n in shape):
        raise ValueError(f"shape: a periodic continuous load needs node counts divisible by 4 (the error estimate "
                         f"samples it at 2h and 4h over the same period), got {shape}")
    return shape, spacing


def _coords(shape, spacing):
    axes = [(np.arange(n) - n // 2) * h for n, h in zip(shape[::-1], spacing)]  # x first
    if len(shape) == 1:
        return (axes[0],)
    xx, yy = np.meshgrid(axes[0], axes[1])
    return xx, yy


class TractionField(ContinuousLoad):
    """Tractions given as functions of position, sampled at the grid nodes.

    Parameters
    ----------
    p, qx, qy : callable or None
        ``f(x)`` (1-D, plane strain) or ``f(x, y)`` (2-D), positions in m, returning the traction
        in Pa (p pushes into the skin; qx, qy along +x, +y). ``None`` means zero.
    shape : int or (ny, nx)
        Default grid: ``nx`` (1-D) or ``(ny, nx)`` nodes.
    spacing : float or (dx, dy)
        Default grid spacing in m.
    periodic : bool
        True when the functions repeat with period ``n h`` (node counts divisible by 4).
    """

    def __init__(self, p: Callable | None = None, qx: Callable | None = None, qy: Callable | None = None, *,
                 shape, spacing, periodic: bool = False):
        self.functions = {k: f for k, f in zip(LOAD_COMPONENTS, (p, qx, qy)) if f is not None}
        if not self.functions:
            raise ValueError("TractionField: give at least one of p, qx, qy (functions of position returning Pa)")
        for name, f in self.functions.items():
            if not callable(f):
                raise ValueError(f"{name}: expected a function of position (m) returning Pa, got {type(f).__name__}")
        self.periodic = bool(periodic)
        self.shape, self.spacing = _grid(shape, spacing, self.periodic)

    def __repr__(self) -> str:
        return f"TractionField({', '.join(self.functions)}; shape={self.shape}, spacing={self.spacing})"

    def sample(self, shape, spacing) -> SurfaceLoad:
        shape = _shape(shape, self.ndim)
        spacing = check.spacing(spacing, self.ndim)
        xy = _coords(shape, spacing)
        values = {}
        for name, f in self.functions.items():
            v = np.broadcast_to(np.asarray(f(*xy), dtype=float), shape)
            values[name] = v
        return SurfaceLoad(**values, spacing=spacing, periodic=self.periodic)


class DeflectionLoad(ContinuousLoad):
    """The pressure that imposes a prescribed normal deflection (a rigid profile in full, frictionless
    contact), periodic: ``P~ = E rho H~ / (2 (1 - nu^2))`` of the deflection sampled on the grid
    (docs/theory.md section 2).

    Parameters
    ----------
    height : callable
        Deflection into the skin in m, ``h(x)`` (1-D) or ``h(x, y)`` (2-D), positions in m,
        periodic with period ``n h`` per axis (a ``Surface.height`` qualifies).
    young_modulus : float
        E in Pa.
    nu : float
        Poisson's ratio.
    shape, spacing
        Default grid, as :class:`TractionField` (node counts divisible by 4).
    """

    periodic = True

    def __init__(self, height: Callable, young_modulus: float, nu: float, *, shape, spacing):
        if not callable(height):
            raise ValueError(f"height: expected a function of position (m) returning m, got {type(height).__name__}")
        self.height = height
        self.young_modulus = check.young_modulus(young_modulus)
        self.nu = check.poisson_ratio(nu)
        self.shape, self.spacing = _grid(shape, spacing, True)

    def __repr__(self) -> str:
        return f"DeflectionLoad(shape={self.shape}, spacing={self.spacing}, E={self.young_modulus}, nu={self.nu})"

    def sample(self, shape, spacing) -> SurfaceLoad:
        shape = _shape(shape, self.ndim)
        spacing = check.spacing(spacing, self.ndim)
        h = np.broadcast_to(np.asarray(self.height(*_coords(shape, spacing)), dtype=float), shape)
        return pressure_from_deflection(np.array(h), spacing, self.young_modulus, self.nu)


# ------------------------------------------------------------------------------------------ grids
def refined_grid(shape, spacing, periodic: bool, halvings: int = 1):
    """The grid of spacing h / 2^k over the same domain; every old node is a new node."""
    for _ in range(halvings):
        shape = tuple(2 * n if (periodic or n % 2 == 0) else 2 * n - 1 for n in shape)
        spacing = tuple(h / 2 for h in spacing)
    return shape, spacing


def coarse_grid(shape, spacing, periodic: bool):
    """The grid of spacing 2h over (about) the same domain, or None when it would have < 3 nodes."""
    if periodic:
        if any(n % 2 for n in shape):
            return None
        new = tuple(n // 2 for n in shape)
    else:
        new = tuple((n + 1) // 2 for n in shape)
    if min(new) < 3:
        return None
    return new, tuple(2 * h for h in spacing)


def shared_nodes(fine_shape, coarse_shape) -> tuple[tuple[slice, ...], tuple[slice, ...]]:
    """Index slices (fine, coarse) of the nodes the 2h grid shares with the h grid."""
    fine, coarse = [], []
    for n, m in zip(fine_shape, coarse_shape):
        off = n // 2 - 2 * (m // 2)  # fine index of coarse node i is 2 i + off
        i0 = max(0, math.ceil(-off / 2))
        i1 = min(m, (n - 1 - off) // 2 + 1)
        coarse.append(slice(i0, i1))
        fine.append(slice(2 * i0 + off, 2 * (i1 - 1) + off + 1, 2))
    return tuple(fine), tuple(coarse)


def sampling_error(levels: list[np.ndarray], shapes: list[tuple[int, ...]] | None) -> tuple[float, float]:
    """Richardson bound on the sampling error of ``levels[0]`` (the module docstring).

    Parameters
    ----------
    levels : list of ndarray
        Outputs on the h, 2h (and 4h) grids, each ``(n_depth, n_out, *grid)``; or, with
        ``shapes=None``, at the same sensor points ``(n_depth, n_out, n_points)``.
    shapes : list of tuple or None
        The grids' shapes (None for sensor points).

    Returns
    -------
    estimate : float
        Bound on max |F_h - F| relative to max |F_h|; ``inf`` with fewer than two levels.
    order : float
        Observed convergence order p = log2(rho) (nan when unknown).
    """
    peak = float(np.abs(levels[0]).max())
    if len(levels) < 2 or peak == 0.0:
        return (math.inf if len(levels) < 2 else 0.0), math.nan

    def diff(i: int) -> float:
        if shapes is None:
            return float(np.abs(levels[i] - levels[i + 1]).max())
        f, c = shared_nodes(shapes[i], shapes[i + 1])
        return float(np.abs(levels[i][(..., *f)] - levels[i + 1][(..., *c)]).max())

    d1 = diff(0)
    if len(levels) < 3 or d1 == 0.0:
        return SAFETY * d1 / 0.5 / peak, math.nan
    rho = diff(1) / d1
    estimate = SAFETY * d1 / (min(max(rho, 1.5), 4.0) - 1.0)
    return estimate / peak, math.log2(rho) if rho > 0 else math.nan


# ------------------------------------------------------------------- spectral (aliasing) estimate
#: refinement of the grid the load is sampled on for the spectral estimate, per dimension count
SPECTRAL_REFINEMENT = {1: 4, 2: 2}


def _coarse_index(coarse_shape, periodic: bool, halvings: int) -> tuple[np.ndarray, ...]:
    """Per axis, the index on the grid ``halvings`` times finer (:func:`refined_grid`) of every
    node of the grid ``coarse_shape``."""
    out = []
    for n in coarse_shape:
        idx = np.arange(n)
        for _ in range(halvings):
            (nn,), _h = refined_grid((n,), (1.0,), periodic)
            f, c = shared_nodes((nn,), (n,))
            full = np.full(n, -1)
            full[np.arange(n)[c[0]]] = np.arange(nn)[f[0]]
            idx, n = full[idx], nn
        if (idx < 0).any():
            raise AssertionError("refined_grid keeps every node")  # pragma: no cover - an invariant
        out.append(idx)
    return tuple(out)


#: content beyond the grid's Nyquist box, relative to all the load's content, above which the grid aliases
ALIAS_THRESHOLD = 1e-10


def alias_check(load: ContinuousLoad, coarse: SurfaceLoad) -> tuple[float, int | None, SurfaceLoad]:
    """Content of the load beyond the grid's Nyquist wavenumbers, seen on one finer sampling.

    The load is sampled once on the grid r times finer (r = 4 in 1-D, 2 in 2-D, as the spectral
    estimate, which reuses these samples). Content beyond the h grid's Nyquist box is aliased onto
    a coarse mode by every nested grid (h, 2h, 4h alike), so the Richardson bound cannot see it;
    any such content above :data:`ALIAS_THRESHOLD` makes the spectral estimate the reported one.
    The rule: the check sees content up to the fine grid's Nyquist wavenumber (r pi / h); content
    finer still aliases on the fine grid too and is not seen by any sampling.

    Returns
    -------
    fraction : float
        sum |F_k| beyond the h grid's Nyquist box over sum |F_k| (largest over the components),
        in [0, 1]; 0 for a zero load.
    halvings : int or None
        Fewest halvings of the spacing whose Nyquist box holds all but :data:`ALIAS_THRESHOLD`
        of the content (0 when the h grid does); log2(r), the fine grid, when no coarser one does
        and the fine samples hold nothing beyond 3/4 of their own Nyquist wavenumbers (a margin: a
        load with content up to the fine grid's edge may have more beyond it); None otherwise.
    fine : SurfaceLoad
        The fine samples.
    """
    r = SPECTRAL_REFINEMENT[coarse.ndim]
    steps = int(round(math.log2(r)))
    fshape, fspacing = refined_grid(coarse.shape, coarse.spacing, load.periodic, steps)
    fine = load.sample(fshape, fspacing)
    boxes = [refined_grid(coarse.shape, coarse.spacing, load.periodic, j)[0] for j in range(steps)]
    boxes.append(tuple(0.75 * n for n in fshape))  # the fine grid, with a margin below its Nyquist
    # the real FFT's half spectrum, each column weighted by how often it stands in the full one
    nx = fshape[-1]
    half = np.full(nx // 2 + 1, 2.0)
    half[0] = 1.0
    if nx % 2 == 0:
        half[-1] = 1.0
    fractions = [0.0] * (steps + 1)  # content beyond each box, relative to all of it
    for values in fine.components.values():
        scale = float(np.abs(values).max())
        if scale == 0.0:
            continue
        spectrum = np.abs(np.fft.rfftn(values / scale)) * half  # scaled first: no overflow at 1e300 Pa
        total = float(spectrum.sum())
        for j, box in enumerate(boxes):
            beyond = spectrum * (1.0 - _box(fshape, box)[..., : nx // 2 + 1])
            fractions[j] = max(fractions[j], float(beyond.sum()) / total)
    halvings = next((j for j, f in enumerate(fractions) if f <= ALIAS_THRESHOLD), None)
    return fractions[0], halvings, fine


def spectral_sampling_error(load: ContinuousLoad, coarse: SurfaceLoad, depths, nu: float, weights: np.ndarray,
                            band_limited: bool, peak: float, fine: SurfaceLoad | None = None) -> float:
    """Estimate of the sampling error from the load's content near and beyond the grid scale.

    The load is sampled again on a grid r times finer (r = 4 in 1-D, 2 in 2-D; function
    evaluations only). The error of the h grid's representation is the difference between the
    load the method sees and the finely sampled load: nodal forces (``band_limited=False``, the
    closed forms and DC-FFT: the h samples times r^d at the shared nodes, zero elsewhere, whose
    spectrum is the h spectrum repeated beyond the h Nyquist wavenumber) or the trigonometric
    interpolant (``band_limited=True``, the spectral method: the h spectrum, zero beyond its
    Nyquist wavenumber), minus the fine samples. That difference load is pushed through the exact
    half-space transfer at each depth (the attenuation exp(-k z) weights it) with one periodic FFT
    solve on the fine grid (zero-padded 2x per axis for an isolated load) and compared with the
    field's peak: no solve on the h grid, no method error in it. The fine grid's own error is a
    fraction r^-p of the h grid's for a load converging at order p, so the difference is at least
    (1 - 1/r) of the h grid's error when p >= 1; the estimate is ``1.5 / (1 - 1/r)`` times
    ``max |error field| / peak`` (2 in 1-D, 3 in 2-D).

    Parameters
    ----------
    load : ContinuousLoad
    coarse : SurfaceLoad
        The load sampled on the h grid (what the method solved).
    depths : ndarray, shape (n_depth,)
        Depths in m.
    nu : float
        Poisson's ratio.
    weights : ndarray, shape (n_out, 6)
        Output rows (stress or strain) as the solve used them.
    band_limited : bool
        True when the method reads the nodes as a trigonometric interpolant.
    peak : float
        max |field| of the h solve, in the output's units.
    fine : SurfaceLoad or None
        The load already sampled on the fine grid (:func:`alias_check`); sampled here when None.

    Returns
    -------
    float
        Relative estimate (``inf`` when ``peak`` is zero and the error is not).
    """
    from .spectral import periodic_stress

    r = SPECTRAL_REFINEMENT[coarse.ndim]
    halvings = int(round(math.log2(r)))
    fshape, fspacing = refined_grid(coarse.shape, coarse.spacing, load.periodic, halvings)
    fine = load.sample(fshape, fspacing) if fine is None else fine
    index = np.ix_(*_coarse_index(coarse.shape, load.periodic, halvings))
    diffs = {}
    for name, fvals in fine.components.items():
        cvals = coarse.components.get(name)
        cvals = np.zeros(coarse.shape) if cvals is None else np.asarray(cvals, dtype=float)
        fvals = np.asarray(fvals, dtype=float)
        seen = np.zeros(fshape)
        seen[index] = cvals * r**coarse.ndim  # nodal forces: the h spectrum, repeated
        if band_limited:  # the trigonometric interpolant: the h spectrum inside its Nyquist box only
            seen = np.fft.ifftn(np.fft.fftn(seen) * _box(fshape, coarse.shape)).real
        diffs[name] = seen - fvals
    if not load.periodic:
        diffs = {k: np.pad(v, [(0, n) for n in v.shape]) for k, v in diffs.items()}
    diff_load = SurfaceLoad(**diffs, spacing=fspacing, periodic=True)
    err = float(np.abs(periodic_stress(diff_load, depths, nu, weights)).max())
    if peak == 0.0:
        return 0.0 if err == 0.0 else math.inf
    return 1.5 / (1.0 - 1.0 / r) * err / peak


def _box(fshape, cshape) -> np.ndarray:
    """Weights on the fine grid's wavenumbers: 1 inside the coarse grid's Nyquist box, 1/2 on its
    edge (the Nyquist mode of an even grid, split between +k and -k), 0 beyond."""
    masks = []
    for n, m in zip(fshape, cshape):
        f = np.abs(np.fft.fftfreq(n, 1.0 / n))
        masks.append(np.where(f < m / 2, 1.0, np.where(f == m / 2, 0.5, 0.0)))
    return masks[0] if len(masks) == 1 else masks[0][:, None] * masks[1][None, :]

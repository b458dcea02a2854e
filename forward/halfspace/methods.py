"""The method registry behind :meth:`HalfSpace.stress`: one class per method, each with its
own applicability rule, error estimate and cost model (the ``solve_ivp`` pattern).

``METHODS = {"closed_form": ClosedForm, "spectral": Spectral, "dcfft": DCFFT}``.
A user can pass a name or a :class:`Method` subclass to ``method=``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from .loads import SurfaceLoad
from .spectral import VOIGT, periodic_stress


@dataclass(frozen=True)
class Problem:
    """What one evaluation needs: the load, the depths, what to output and where."""

    load: SurfaceLoad
    depths: np.ndarray          # (n_depth,), m
    nu: float
    weights: np.ndarray         # (n_out, 6): outputs = weights @ Voigt stress
    points: np.ndarray | None   # (n, 2) x, y in m (1-D loads: y ignored), or None for the grid
    dtype: np.dtype

    @property
    def n_eval(self) -> int:
        return int(np.prod(self.load.shape)) if self.points is None else len(self.points)

    @property
    def stress_rows(self) -> list[int]:
        """Voigt stress components the outputs depend on."""
        return [j for j in range(6) if np.any(self.weights[:, j] != 0)]


def _fft_cost(n: float) -> float:
    return 2.5 * n * np.log2(max(n, 2.0))


def _grid_index(problem: Problem):
    """Indices of points that sit on grid nodes, or None when any point is off-grid."""
    load, pts = problem.load, problem.points
    ix = pts[:, 0] / load.dx + load.shape[-1] // 2
    idx = [ix]
    if load.ndim == 2:
        idx.insert(0, pts[:, 1] / load.dy + load.shape[0] // 2)
    idx = np.array(idx)
    rounded = np.rint(idx)
    upper = np.array(load.shape)[:, None] - 1
    if np.all(np.abs(idx - rounded) < 1e-9) and np.all(rounded >= 0) and np.all(rounded <= upper):
        return tuple(rounded.astype(int))
    return None


class Method(ABC):
    """Base class (template method): the public methods guard and dispatch; subclasses
    supply ``_error``, ``_cost`` and ``_grid_field`` (the field on the load grid)."""

    name = "base"
    exact_for = ""

    def applicable(self, problem: Problem) -> str | None:
        """None if the method can run, else the reason it cannot."""
        return None

    def error_estimate(self, problem: Problem) -> float:
        """Estimated max error relative to the field's peak magnitude."""
        err = self._error(problem)
        if problem.dtype == np.float32:
            err += 5e-7 * np.log2(max(problem.n_eval, 2))
        return float(err)

    def cost(self, problem: Problem) -> float:
        """A flop-count model used only to rank methods."""
        return float(self._cost(problem))

    def compute(self, problem: Problem) -> np.ndarray:
        """Outputs, shape (n_depth, n_out, *grid) or (n_depth, n_out, n_points)."""
        field = self._grid_field(problem)
        if problem.points is None:
            return field
        idx = _grid_index(problem)
        if idx is None:
            raise ValueError(f"points: method {self.name!r} evaluates on grid nodes only; use 'closed_form' or 'spectral'")
        return field[(slice(None), slice(None), *idx)]

    @abstractmethod
    def _error(self, problem: Problem) -> float:
        """Relative error estimate of the method itself."""

    @abstractmethod
    def _cost(self, problem: Problem) -> float:
        """Flop model."""

    @abstractmethod
    def _grid_field(self, problem: Problem) -> np.ndarray:
        """Outputs on the load grid, shape (n_depth, n_out, *grid)."""


class Spectral(Method):
    """Periodic FFT solution (docs/theory.md s2): exact for periodic loads; for an isolated load
    its periodic images add an error ~ (Z/L)^2 in 2-D and ~ Z/L in 1-D."""

    name = "spectral"
    exact_for = "periodic loads"

    def _error(self, problem: Problem) -> float:
        rounding = 1e-14 if problem.dtype == np.float64 else 0.0
        if problem.load.periodic:
            return rounding
        return rounding + image_error(problem.load, problem.depths)

    def _cost(self, problem: Problem) -> float:
        n = np.prod(problem.load.shape)
        outs = len(problem.depths) * len(problem.weights)
        n_fft = len(problem.load.components) + (outs if self._off_grid(problem) is None else 0)
        cost = n_fft * _fft_cost(n) + 40 * n * outs
        if self._off_grid(problem) is not None:
            cost += 8 * n * len(problem.points) * outs  # exact trigonometric sums
        return cost

    @staticmethod
    def _off_grid(problem: Problem):
        if problem.points is None or _grid_index(problem) is not None:
            return None
        return problem.points

    def compute(self, problem: Problem) -> np.ndarray:
        pts = self._off_grid(problem)
        if pts is None:
            return super().compute(problem)
        return periodic_stress(problem.load, problem.depths, problem.nu, problem.weights, dtype=problem.dtype,
                               points=pts)

    def _grid_field(self, problem: Problem) -> np.ndarray:
        return periodic_stress(problem.load, problem.depths, problem.nu, problem.weights, dtype=problem.dtype)


def image_error(load: SurfaceLoad, depths: np.ndarray) -> float:
    """Relative error of treating an isolated load as periodic (an upper estimate).

    The nearest periodic image sits about L/2 beyond the grid edge. Its far field decays
    like the slowest kernel component: 1/r^2 in 3-D (Cerruti's in-plane stress) and 1/r in
    plane strain (the Hilbert tail of Flamant's tangential solution), against a peak of
    order F/a^2 (F/a in 1-D) with a = max(depth, load extent). Hence
    ~ C (2a/L)^2 in 2-D and C (2a/L) in 1-D, with C (8 and 4) measured on Gaussian
    tangential loads (tests/test_forward_halfspace.py); normal loads decay faster, so the
    estimate is conservative for them.
    """
    if load.is_zero():
        return 0.0
    a = max(float(np.max(depths)), load.extent)
    L = min(n * h for n, h in zip(load.shape[::-1], load.spacing))
    if load.ndim == 1:
        return float(4.0 * 2 * a / L)
    return float(8.0 * (2 * a / L) ** 2)


class DCFFT(Method):
    """Zero-padded convolution with the point (line) kernel sampled at depth: no periodic
    images; exact for the load as a set of nodal forces."""

    name = "dcfft"
    exact_for = "isolated loads (zero outside the grid)"

    def applicable(self, problem: Problem) -> str | None:
        if problem.load.periodic:
            return "the load is periodic; DC-FFT assumes zero load outside the grid"
        if problem.points is not None and _grid_index(problem) is None:
            return "sensors lie off the grid nodes; the closed form evaluates them exactly"
        return None

    def _error(self, problem: Problem) -> float:
        from .dcfft import dcfft_error_estimate

        return max(dcfft_error_estimate(problem.load.spacing, float(z), dtype=problem.dtype)
                   for z in problem.depths)

    def _cost(self, problem: Problem) -> float:
        n = np.prod([2 * s for s in problem.load.shape])
        n_fft = len(problem.load.components) + 2 * len(problem.depths) * len(problem.stress_rows)
        return n_fft * _fft_cost(n)

    def _grid_field(self, problem: Problem) -> np.ndarray:
        from .dcfft import dcfft_stress

        rows = problem.stress_rows
        stress = dcfft_stress(problem.load, problem.depths, problem.nu, [VOIGT[j] for j in rows],
                              dtype=problem.dtype)
        return np.einsum("oj,dj...->do...", problem.weights[:, rows], stress)


class ClosedForm(Method):
    """Direct sum of Boussinesq/Cerruti (Flamant in 1-D) kernels over the loaded nodes:
    exact for nodal forces, cost (loaded nodes) x (points); best for few of each."""

    name = "closed_form"
    exact_for = "few loads and few sensors"

    def applicable(self, problem: Problem) -> str | None:
        if problem.load.periodic:
            return "the load is periodic; the closed forms are for isolated loads"
        return None

    def _error(self, problem: Problem) -> float:
        from .dcfft import dcfft_error_estimate

        return max(dcfft_error_estimate(problem.load.spacing, float(z), dtype=problem.dtype)
                   for z in problem.depths)

    def _cost(self, problem: Problem) -> float:
        loaded = sum(np.count_nonzero(v) for v in problem.load.components.values())
        return 60.0 * loaded * problem.n_eval * len(problem.depths) * len(problem.stress_rows)

    def _grid_field(self, problem: Problem) -> np.ndarray:
        return self.compute(problem)

    def compute(self, problem: Problem) -> np.ndarray:
        from .kernels import direct_stress

        load = problem.load
        if problem.points is None:
            if load.ndim == 1:
                pts = load.x[:, None]
            else:
                yy, xx = np.meshgrid(load.y, load.x, indexing="ij")
                pts = np.column_stack([xx.ravel(), yy.ravel()])
        else:
            pts = problem.points
        rows = problem.stress_rows
        comps = [VOIGT[j] for j in rows]
        out = []
        for z in problem.depths:
            if load.ndim == 1:
                xyz = np.column_stack([pts[:, 0], np.full(len(pts), z)])
            else:
                xyz = np.column_stack([pts[:, 0], pts[:, 1], np.full(len(pts), z)])
            stress = direct_stress(load, xyz, problem.nu, comps)  # (n, n_comp)
            out.append(stress @ problem.weights[:, rows].T)
        values = np.asarray(out).transpose(0, 2, 1)  # (n_depth, n_out, n)
        if problem.points is None:
            values = values.reshape(values.shape[:2] + load.shape)
        return values


#: Method registry: name -> Method subclass; HalfSpace.stress/strain look ``method`` up here
METHODS: dict[str, type[Method]] = {"closed_form": ClosedForm, "spectral": Spectral, "dcfft": DCFFT}

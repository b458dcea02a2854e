"""The method registry behind :meth:`HalfSpace.stress`: one class per method, each with its
own applicability rule, error estimate, error scale and cost model (the ``solve_ivp`` pattern).

``METHODS = {"closed_form": ClosedForm, "spectral": Spectral, "dcfft": DCFFT}``, and beside it
:func:`select_method`, the choice: a forced method, or the cheapest one whose error estimate
meets ``tol``. A user can pass a name or a :class:`Method` subclass to ``method=``.

:class:`Method` is a template: its public methods (:meth:`~Method.compute`,
:meth:`~Method.error_estimate`, :meth:`~Method.cost`, :meth:`~Method.field_error`) guard and
dispatch; subclasses implement only ``_compute``, ``_error`` and ``_cost`` and declare
``error_scale``.
"""

from __future__ import annotations

import functools
import math
import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from .dcfft import alias_error, nodal_dcfft_stress
from .kernels import nodal_stress
from .loads import SurfaceLoad
from .spectral import VOIGT, angular_wavenumbers, periodic_stress


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

    @functools.cached_property
    def load_width(self) -> float:
        """Length in m over which the load varies: :func:`load_width` of the load (cached)."""
        return load_width(self.load)

    @functools.cached_property
    def estimates(self) -> dict:
        """Memo of :meth:`Method.error_estimate` per method instance (the problem is immutable)."""
        return {}

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


def user_stacklevel() -> int:
    """``stacklevel`` for ``warnings.warn`` called here that points at the first caller outside the
    solver package (the user's line, however deep the facade's call chain is)."""
    import os
    import sys

    here = os.path.dirname(os.path.abspath(__file__))
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.dirname(os.path.abspath(frame.f_code.co_filename)) == here:
        frame, level = frame.f_back, level + 1
    return level


class AccuracyWarning(UserWarning):
    """No method meets the requested tolerance; the result says how far off it may be."""


class Method(ABC):
    """Base class (template method): the public methods guard and dispatch; subclasses
    supply ``_compute``, ``_error`` and ``_cost``, and say in ``error_scale`` what their
    ``_error`` is relative to.

    Attributes
    ----------
    name : str
        Registry name (a key of :data:`METHODS`).
    exact_for : str
        The problems the method solves exactly.
    error_scale : {"field", "traction"}
        What ``_error`` is relative to: the peak of the computed field (``"field"``) or the
        peak nodal traction ``|p| + |qx| + |qy|`` (``"traction"``, the nodal-force methods).
        :meth:`field_error` turns either into an error relative to the field's peak.
    """

    name = "base"
    exact_for = ""
    error_scale = "field"

    def applicable(self, problem: Problem) -> str | None:
        """None if the method can run, else the reason it cannot."""
        return None

    def error_estimate(self, problem: Problem) -> float:
        """Estimated max error (computed once per problem): the method's own, relative to
        ``error_scale``, plus float32 rounding (:meth:`rounding_error`, relative to the field's peak)."""
        memo = problem.estimates
        if self not in memo:
            memo[self] = float(self._error(problem)) + self.rounding_error(problem)
        return memo[self]

    @staticmethod
    def rounding_error(problem: Problem) -> float:
        """float32 rounding, relative to the field's peak: about eps32 = 1.2e-7 per FFT pass, growing like
        log2(N) (measured 1e-7 to 3e-7 on 64 x 64 nodes at every magnitude, once the solver scales the
        load to a unit peak); 0 in float64, where each method's own estimate holds its rounding."""
        return 5e-7 * math.log2(max(problem.n_eval, 2)) if problem.dtype == np.float32 else 0.0

    def cost(self, problem: Problem) -> float:
        """A flop-count model used only to rank methods."""
        return float(self._cost(problem))

    def compute(self, problem: Problem) -> np.ndarray:
        """Outputs, shape (n_depth, n_out, *grid) or (n_depth, n_out, n_points).

        Raises
        ------
        ValueError
            When the method cannot run on this problem (:meth:`applicable`).
        """
        why = self.applicable(problem)
        if why is not None:
            raise ValueError(f"method: {self.name!r} cannot run here: {why}")
        return self._compute(problem)

    def field_error(self, problem: Problem, values: np.ndarray, stress_scale: float = 1.0) -> float:
        """The error estimate relative to the peak of the computed ``values``.

        A ``"traction"``-scaled estimate is multiplied by peak traction / peak field
        (``stress_scale`` turns the field into a stress scale: E for strain, about 2x the true
        stress); a ``"field"``-scaled one is returned as it is.
        """
        estimate = self.error_estimate(problem)
        if self.error_scale == "field":
            return estimate
        rounding = self.rounding_error(problem)  # already relative to the field's peak: never rescaled
        load = problem.load
        peak_traction = float(sum(np.abs(a) for a in load.components.values()).max())
        peak_field = float(np.abs(values).max()) * stress_scale
        if peak_traction == 0.0 or peak_field == 0.0:
            return estimate
        return (estimate - rounding) * peak_traction / peak_field + rounding

    @staticmethod
    def _at_points(problem: Problem, field: np.ndarray) -> np.ndarray:
        """The grid field at the problem's points (which sit on grid nodes), or all of it."""
        if problem.points is None:
            return field
        return field[(slice(None), slice(None), *_grid_index(problem))]

    @abstractmethod
    def _compute(self, problem: Problem) -> np.ndarray:
        """Outputs for an applicable problem, shape as :meth:`compute`."""

    @abstractmethod
    def _error(self, problem: Problem) -> float:
        """Relative error estimate of the method itself (relative to ``error_scale``)."""

    @abstractmethod
    def _cost(self, problem: Problem) -> float:
        """Flop model."""


_EPS64 = float(np.finfo(np.float64).eps)


class Spectral(Method):
    """Periodic FFT solution (docs/theory.md s2): exact for periodic loads; for an isolated load
    its periodic images add an error ~ (Z/L)^2 in 2-D and ~ Z/L in 1-D."""

    name = "spectral"
    exact_for = "periodic loads"

    def _error(self, problem: Problem) -> float:
        # the FFTs' rounding grows like log2(N) (measured 1.8e-14 on 128 nodes): 30 eps log2(N)
        n = math.prod(problem.load.shape)
        rounding = 30.0 * _EPS64 * math.log2(max(n, 2)) if problem.dtype == np.float64 else 0.0
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

    def _compute(self, problem: Problem) -> np.ndarray:
        pts = self._off_grid(problem)
        if pts is not None:  # the exact trigonometric interpolant at the points
            return periodic_stress(problem.load, problem.depths, problem.nu, problem.weights, dtype=problem.dtype,
                                   points=pts)
        field = periodic_stress(problem.load, problem.depths, problem.nu, problem.weights, dtype=problem.dtype)
        return self._at_points(problem, field)


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


def load_width(load: SurfaceLoad) -> float:
    """The length in m over which a load varies, from its spectrum (the narrowest component).

    For each component, ``w = sqrt(ndim / (2 <|k|^2>))`` with ``<|k|^2>`` the power-weighted
    mean squared angular wavenumber of the grid values, zero-padded (the load is zero outside
    the grid, so a load cut off by the grid edge shows its edge): exactly the standard deviation of a
    Gaussian bump (measured within 1 % from 1 grid spacing up, 0.47 spacings for one of 0.5).
    Sharp edges and sub-grid detail raise ``<|k|^2>``, so the width errs small (the estimate
    that uses it errs large). ``inf`` for a uniform or zero load.
    """
    widths = [np.inf]
    padded = tuple(2 * n for n in load.shape)  # zero outside the grid: a cut-off load has edges
    ks = angular_wavenumbers(padded, load.spacing)
    k2 = sum(k**2 for k in ks)
    for values in load.components.values():
        scale = float(np.abs(values).max())
        if scale == 0.0:
            continue
        # scaled to a peak of 1 first: squared FFT magnitudes overflow from ~1e150 Pa, underflow below ~1e-160
        power = np.abs(np.fft.fftn(values / scale, s=padded, axes=tuple(range(load.ndim)))) ** 2
        total = float(power.sum())
        mean_k2 = float((k2 * power).sum()) / total if total > 0 else 0.0
        if mean_k2 > 0:
            widths.append(float(np.sqrt(load.ndim / (2.0 * mean_k2))))
    return min(widths)


def _sampling_error(problem: Problem) -> float:
    """Kernel-sampling (alias) error of the nodal-force methods, at every depth, for the load's
    own width (never wider than the depth: the estimator's calibrated default)."""
    w = problem.load_width
    # float64's rounding floor only: float32 rounding is relative to the field's peak (Method.rounding_error),
    # and a traction-scaled float32 floor overstated it by peak traction / peak field (1e3x at 3 mm depth)
    return max(alias_error(problem.load.spacing, float(z), np.dtype(np.float64), min(float(z), w))
               for z in problem.depths)


class DCFFT(Method):
    """Zero-padded convolution with the point (line) kernel sampled at depth: no periodic
    images; exact for the load as a set of nodal forces."""

    name = "dcfft"
    exact_for = "isolated loads (zero outside the grid)"
    error_scale = "traction"

    def applicable(self, problem: Problem) -> str | None:
        if problem.load.periodic:
            return "the load is periodic; DC-FFT assumes zero load outside the grid"
        if problem.points is not None and _grid_index(problem) is None:
            return "sensors lie off the grid nodes; the closed form evaluates them exactly"
        return None

    def _error(self, problem: Problem) -> float:
        return _sampling_error(problem)

    def _cost(self, problem: Problem) -> float:
        n = np.prod([2 * s for s in problem.load.shape])
        n_fft = len(problem.load.components) + 2 * len(problem.depths) * len(problem.stress_rows)
        return n_fft * _fft_cost(n)

    def _compute(self, problem: Problem) -> np.ndarray:
        rows = problem.stress_rows
        stress = nodal_dcfft_stress(problem.load, problem.depths, problem.nu, tuple(VOIGT[j] for j in rows),
                                    problem.dtype)
        return self._at_points(problem, np.einsum("oj,dj...->do...", problem.weights[:, rows], stress))


class ClosedForm(Method):
    """Direct sum of Boussinesq/Cerruti (Flamant in 1-D) kernels over the loaded nodes:
    exact for nodal forces, cost (loaded nodes) x (points); best for few of each."""

    name = "closed_form"
    exact_for = "few loads and few sensors"
    error_scale = "traction"

    def applicable(self, problem: Problem) -> str | None:
        if problem.load.periodic:
            return "the load is periodic; the closed forms are for isolated loads"
        return None

    def _error(self, problem: Problem) -> float:
        return _sampling_error(problem)

    def _cost(self, problem: Problem) -> float:
        loaded = sum(np.count_nonzero(v) for v in problem.load.components.values())
        return 60.0 * loaded * problem.n_eval * len(problem.depths) * len(problem.stress_rows)

    def _compute(self, problem: Problem) -> np.ndarray:
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
            stress = nodal_stress(load, xyz, problem.nu, tuple(comps))  # (n, n_comp)
            out.append(stress @ problem.weights[:, rows].T)
        values = np.asarray(out).transpose(0, 2, 1)  # (n_depth, n_out, n)
        if problem.points is None:
            values = values.reshape(values.shape[:2] + load.shape)
        return values


#: Method registry: name -> Method subclass; HalfSpace.stress/strain look ``method`` up here
METHODS: dict[str, type[Method]] = {"closed_form": ClosedForm, "spectral": Spectral, "dcfft": DCFFT}


def _instance(method) -> Method:
    if isinstance(method, str):
        if method not in METHODS:
            raise ValueError(f"method: unknown method {method!r}; use 'auto' or one of {sorted(METHODS)}")
        return METHODS[method]()
    if isinstance(method, type) and issubclass(method, Method):
        return method()
    if isinstance(method, Method):
        return method
    raise ValueError(f"method: expected 'auto', a method name or a Method subclass, got {method!r}")


def _rank(problem: Problem) -> tuple[dict, list]:
    """Every registered method's (estimate, cost), or the reason it cannot run."""
    candidates: dict = {}
    runnable = []
    for name, cls in METHODS.items():
        m = cls()
        why = m.applicable(problem)
        if why is not None:
            candidates[name] = why
            continue
        err, cost = m.error_estimate(problem), m.cost(problem)
        candidates[name] = (err, cost)
        runnable.append((m, err, cost))
    return candidates, runnable


def _warn_forced(chosen: Method, err: float, tol: float, runnable: list) -> None:
    """A forced method whose own estimate exceeds tol: say so, and name the better method."""
    others = [r for r in runnable if r[0].name != chosen.name]
    meeting = [r for r in others if r[1] <= tol]
    if meeting:
        better, better_err, _ = min(meeting, key=lambda r: r[2])
        advice = f"{better.name!r} meets it (estimate {better_err:.1e}): use method={better.name!r}"
    elif others and min(r[1] for r in others) < err:
        better, better_err, _ = min(others, key=lambda r: r[1])
        advice = (f"no method meets it; {better.name!r} is more accurate (estimate {better_err:.1e}): use "
                  f"method={better.name!r}, refine the grid spacing below the depth, or loosen tol")
    else:
        advice = "no registered method does better: refine the grid spacing below the depth, or loosen tol"
    warnings.warn(f"method {chosen.name!r} was forced, but its error estimate {err:.1e} exceeds tol={tol:.0e}; "
                  f"{advice}", AccuracyWarning, stacklevel=user_stacklevel())


def select_method(problem: Problem, tol: float, method="auto") -> tuple[Method, str, dict]:
    """The method to run: the one forced by the caller, or the cheapest whose estimate meets tol.

    Parameters
    ----------
    problem : Problem
        The evaluation.
    tol : float
        Requested error, relative to the field's peak.
    method : "auto", str, Method subclass or instance
        ``"auto"`` chooses among :data:`METHODS`; anything else forces that method.

    Returns
    -------
    method : Method
        The method to run.
    reason : str
        Why it was chosen.
    candidates : dict
        Per method name: ``(error_estimate, cost)`` or the reason it cannot run (auto only).

    Warns
    -----
    AccuracyWarning
        When no method meets ``tol`` (the most accurate one is used), or when a forced method's
        own estimate exceeds ``tol`` (the warning names the better method, if there is one).
    """
    if not (isinstance(method, str) and method == "auto"):
        chosen = _instance(method)
        why = chosen.applicable(problem)
        if why is not None:
            raise ValueError(f"method: {chosen.name!r} cannot run here: {why}")
        err = chosen.error_estimate(problem)
        if err > tol:
            _warn_forced(chosen, err, tol, _rank(problem)[1])
        return chosen, "forced by the caller", {}
    candidates, runnable = _rank(problem)
    good = [r for r in runnable if r[1] <= tol]
    if good:
        m, err, _ = min(good, key=lambda r: r[2])
        return m, f"cheapest method with error estimate {err:.1e} <= tol {tol:.0e}", candidates
    m, err, _ = min(runnable, key=lambda r: r[1])
    warnings.warn(
        f"no method meets tol={tol:.0e}; using {m.name!r} with estimated relative error {err:.1e} "
        "(refine the grid spacing below the depth, enlarge the grid, or loosen tol)",
        AccuracyWarning, stacklevel=user_stacklevel())
    return m, f"most accurate method available (error estimate {err:.1e} > tol {tol:.0e})", candidates

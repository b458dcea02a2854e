"""One entry point for linear regularised inversion: :func:`invert_linear`.

Solves ``min_m ||A m - d||^2 + lam ||L m||^2`` (Tikhonov, penalties in
:mod:`tactilab.inversion.penalties`) or ``min_m 1/2 ||A m - d||^2 + lam ||D m||_1`` (total
variation, :mod:`tactilab.inversion.tv`). Like ``scipy.integrate.solve_ivp`` it looks the path up
in a registry, :data:`METHODS`, and says which it used in the result:

- ``"fft"``: the operator is a :class:`~tactilab.inversion.operators.FourierDiagonal`
  (a sensor at every node of a periodic grid, translation invariant): O(n log n) and the
  regularisation criteria in closed form, O(n) per lam.
- ``"dense"``: an explicit matrix (or any operator with n <= ``DENSE_MAX``): generalised SVD
  through a Cholesky factor of ``L^T L + eps I``; criteria in closed form.
- ``"iterative"``: any ``scipy.sparse.linalg.LinearOperator`` (irregular sensors, padded
  grids): matrix-free conjugate gradients on the normal equations, preconditioned by the
  circulant ``(c + lam |L(k)|^2)^-1`` with ``c`` a probe estimate of ``mean diag(A^T A)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.linalg as sla
from scipy.sparse.linalg import aslinearoperator

from tactilab.core import rules

from .criteria import CRITERIA, CriteriaResult, SpectralForm, choose_lambda
from .iterative_criteria import IterativeCriteria, NormalSolver, choose_lambda_iterative
from .linear_common import LinearInversionResult, check_data
from .operators import FourierDiagonal, model_layout
from .paths import choose_path
from .penalties import PENALTIES, check_penalty, penalty_matrix, penalty_symbol
from .tv import invert_tv

__all__ = ["invert_linear", "LinearInversionResult", "Factorisation", "METHODS", "fft_form", "dense_form",
           "check_data"]


def _data_scale(data: np.ndarray) -> float:
    """Largest data magnitude (1 for all-zero data): the unit the spectral sums run in."""
    peak = float(np.max(np.abs(data))) if data.size else 0.0
    return peak if peak > 0 else 1.0


def _rescaled(crit: CriteriaResult, scale: float, n_data: int) -> CriteriaResult:
    """Criteria computed on data / scale, back in data units (curves may reach inf past 1e308)."""
    if scale == 1.0:
        return crit
    with np.errstate(over="ignore"):
        s2 = np.float64(scale) ** 2
        for key in ("residual2", "seminorm2", "gcv"):
            if key in crit.curves:
                crit.curves[key] = crit.curves[key] * s2
        if "gcv" in crit.errors:
            crit.errors["gcv"] = crit.errors["gcv"] * s2
    if "log_evidence" in crit.curves:
        crit.curves["log_evidence"] = crit.curves["log_evidence"] - n_data * np.log(scale)
    crit.noise_std = crit.noise_std * scale
    return crit


def fft_form(op: FourierDiagonal, data: np.ndarray, penalty: str):
    """SpectralForm of a FourierDiagonal problem, plus (D, H, L2) on the rfft half grid."""
    axes = tuple(range(len(op.dims)))
    n = data.size
    scale = _data_scale(data)
    d_hat = np.fft.rfftn(data.reshape(op.dims) / scale, axes=axes)
    h = op.half_multiplier
    l2 = penalty_symbol(penalty, op.dims, op.spacing)[..., : op.dims[-1] // 2 + 1]
    h2 = np.abs(h) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(l2 > 0, h2 / np.where(l2 > 0, l2, 1.0), np.where(h2 > 0, np.inf, 0.0))
    form = SpectralForm(ratio=ratio.ravel(), coef2=(np.abs(d_hat) ** 2 / n).ravel(),
                        weights=op.weights.ravel(), n_data=n, data_scale=scale)
    return form, d_hat * scale, h, l2


def _solve_fft(op, data, penalty, lam, aux):
    d_hat, h, l2 = aux
    den = np.abs(h) ** 2 + lam * l2
    with np.errstate(divide="ignore", invalid="ignore"):
        m_hat = np.where(den > 0, np.conj(h) * d_hat / np.where(den > 0, den, 1.0), 0.0)
    return np.fft.irfftn(m_hat, s=op.dims, axes=tuple(range(len(op.dims)))), 0, True


def dense_form(a: np.ndarray, data: np.ndarray, lmat: np.ndarray):
    """SpectralForm of a dense problem via ``R^T R = L^T L + eps I`` and the SVD of ``A R^-1``."""
    ltl = lmat.T @ lmat
    eps = 1e-12 * max(float(np.trace(ltl)) / ltl.shape[0], 1e-300)
    r = sla.cholesky(ltl + eps * np.eye(ltl.shape[0]), lower=False)
    b = sla.solve_triangular(r, a.T, trans="T", lower=False).T  # A R^-1
    u, s, vt = np.linalg.svd(b, full_matrices=False)
    scale = _data_scale(data)
    c = u.T @ (data / scale)
    resid0 = max(float((data / scale) @ (data / scale) - c @ c), 0.0)
    form = SpectralForm(ratio=s**2, coef2=c**2, weights=np.ones_like(s), n_data=data.size, resid0=resid0,
                        data_scale=scale)
    return form, (r, s, vt, c * scale)


def _solve_dense(op, data, penalty, lam, aux):
    r, s, vt, c = aux
    y = vt.T @ (s / (s**2 + lam) * c)
    return sla.solve_triangular(r, y, lower=False), 0, True


def _solve_iterative(op, data, penalty, lam, aux):
    solver, x0 = aux
    return solver.solve(lam, op.rmatvec(data), x0)


#: path name -> callable(op, data, penalty, lam, aux) -> (model_flat, iterations, converged)
METHODS: dict[str, Callable] = {"fft": _solve_fft, "dense": _solve_dense, "iterative": _solve_iterative}


@dataclass(frozen=True)
class Factorisation:
    """What :func:`invert_linear` factorised, returned for reuse: :meth:`solve` gives the model at
    another ``lam`` for the cost of a back-substitution (fft: one inverse FFT; dense: products with
    the kept SVD factors; iterative: one CG solve with the kept preconditioner).

    Attributes
    ----------
    path : str
        ``"fft"``, ``"dense"`` or ``"iterative"``.
    penalty : str
        The Tikhonov penalty.
    model_shape : tuple of int
        Shape of the models :meth:`solve` returns.
    parts : tuple
        fft: ``(D, H, |L|^2)`` on the rfft half grid; dense: ``(R, s, V^T, U^T d)`` with
        ``R^T R = L^T L + eps I`` and ``A R^-1 = U diag(s) V^T``; iterative: the normal-equations
        solver (preconditioner and probes) and the data scale.
    """

    path: str
    penalty: str
    model_shape: tuple
    parts: tuple = field(repr=False)
    operator: object = field(repr=False)
    data: np.ndarray = field(repr=False)

    def solve(self, lam: float) -> np.ndarray:
        """The Tikhonov model at ``lam`` (finite, > 0), in the operator's model units, shape ``model_shape``."""
        if not (np.isfinite(lam) and lam > 0):
            raise ValueError(f"lam: regularisation strength must be finite and > 0, got {lam!r}")
        if self.path == "iterative":
            solver, scale = self.parts
            x, _, _ = _solve_iterative(self.operator, self.data, self.penalty, float(lam), (solver, None))
            return (x * scale).reshape(self.model_shape)
        model, _, _ = METHODS[self.path](self.operator, self.data, self.penalty, float(lam), self.parts)
        return np.asarray(model).reshape(self.model_shape)


def invert_linear(
    operator,
    data,
    *,
    penalty: str = "gradient",
    lam: float | None = None,
    criterion: str = "gcv",
    noise_std: float | None = None,
    method: str = "auto",
    spacing=None,
    tol: float | None = None,
    max_iter: int | None = None,
    rng: np.random.Generator | None = None,
    n_probes: int = 8,
) -> LinearInversionResult:
    """Regularised linear inversion ``d = A m + noise`` through one of the registered paths.

    Parameters
    ----------
    operator : FourierDiagonal, LinearOperator or ndarray, shape (n_data, n_model)
        Forward map. Its ``dims`` (the grid shape) are used by the penalties when present; with
        a ``loads`` attribute the model is load-major and the penalty acts per load component.
        A circulant forward operator (periodic, a sensor at every node, one load and one
        component) is converted to its FourierDiagonal form and takes the fft path.
    data : array_like, n_data values
        Observations, finite (data units: Pa for stress, or strain).
    penalty : {"identity", "gradient", "curvature", "tv"}
        Tikhonov penalty, or total variation (edges, isolated defects).
    lam : float or None
        Regularisation strength. ``None``: chosen by ``criterion``.
    criterion : {"gcv", "lcurve", "discrepancy", "evidence"}
        Used when ``lam`` is None. All four are computed and reported (and a warning is issued
        when they disagree by more than 10x): in closed form on the fft and dense paths; on the
        iterative path from warm-started CG solves, with GCV's trace by Hutchinson and the
        evidence's log det by stochastic Lanczos quadrature (``criteria.estimator`` states the
        estimators and their standard errors; see :mod:`tactilab.inversion.iterative_criteria`).
    noise_std : float or None
        Noise standard deviation in data units (needed by the discrepancy principle; else
        estimated by the evidence).
    method : {"auto", "fft", "dense", "iterative"}
        Path; ``auto`` picks fft for FourierDiagonal, dense for n_model <= 1024, else iterative.
    spacing : float or tuple, optional
        Grid spacing in m for the penalties (default: the operator's, else 1).
    tol, max_iter : float, int, optional
        Relative tolerance and iteration limit: CG (default 1e-8, 2000) or ADMM for TV
        (default 1e-4, 3000).
    rng : numpy.random.Generator, optional
        For the probe vectors of the iterative path: preconditioner scale and the stochastic
        criteria (default seed 0).
    n_probes : int
        Rademacher probes of the iterative path's GCV and evidence estimators (>= 2).

    Returns
    -------
    LinearInversionResult
        With its :class:`Factorisation` (Tikhonov penalties) for re-solving at another lam.
    """
    if penalty == "tv":
        if model_layout(operator)[1] > 1:
            raise ValueError(f"penalty: 'tv' acts on one load component, the operator has {len(operator.loads)} "
                             f"({', '.join(operator.loads)}); use a Tikhonov penalty or one load per operator")

        return invert_tv(operator, data, lam=lam, noise_std=noise_std, method=method, spacing=spacing,
                         tol=tol, max_iter=3000 if max_iter is None else max_iter, rng=rng)
    if penalty not in PENALTIES:
        raise ValueError(f"penalty: unknown penalty {penalty!r}; use one of {', '.join(PENALTIES)} or 'tv'")
    check_penalty(penalty)
    if criterion not in CRITERIA:
        raise ValueError(f"criterion: unknown {criterion!r}; use one of {', '.join(CRITERIA)}")
    if lam is not None and not (np.isfinite(lam) and lam > 0):
        raise ValueError(f"lam: regularisation strength must be finite and > 0, got {lam!r}; or None to choose it")
    operator, path = choose_path(operator, method)
    keep = isinstance(operator, FourierDiagonal) or (isinstance(operator, np.ndarray) and path == "dense")
    op = operator if keep else aslinearoperator(operator)
    d = check_data(data, operator.shape[0], shape=getattr(operator, "dimsd", None))
    dims, n_fields = model_layout(operator)  # grid shape; loads stacked load-major
    model_shape = dims if n_fields == 1 else (n_fields, *dims)
    if spacing is not None:
        rules.spacing(spacing, len(dims))
    spacing = spacing if spacing is not None else getattr(operator, "spacing", 1.0)
    crit = None
    penalises_nothing = ValueError(f"penalty: {penalty!r} penalises nothing on a model grid of shape {dims} "
                                   "(every model is in its null space); use penalty='identity' or a larger grid")
    if path == "fft":
        form, *aux = fft_form(op, d, penalty)
        if not np.any(aux[-1]):
            raise penalises_nothing
    elif path == "dense":
        a = op if isinstance(op, np.ndarray) else op.matmat(np.eye(op.shape[1]))
        lmat = penalty_matrix(penalty, dims, spacing, periodic=False, n_fields=n_fields).toarray()
        if not np.any(lmat):
            raise penalises_nothing
        form, aux = dense_form(np.asarray(a, dtype=float), d, lmat)
    if path in ("fft", "dense"):
        if lam is None:
            crit = choose_lambda(form, noise_std=noise_std)
            lam_used, source = crit.lam[criterion], criterion
            if not np.isfinite(lam_used):
                raise ValueError(f"criterion: {criterion!r} cannot choose lam for this problem "
                                 f"({crit.notes.get(criterion, 'no optimum')}); choose another criterion "
                                 f"(choices: {', '.join(f'{k}={v:.3g}' for k, v in crit.lam.items())}) or give lam")
        else:
            lam_used, source = float(lam), "given"
        model, iters, ok = METHODS[path](op, d, penalty, lam_used, aux)
        model = np.asarray(model).reshape(model_shape)
        resid = form.residual_norm(lam_used)
        kept = Factorisation(path, penalty, model_shape, tuple(aux), op, d)
    else:
        rng = rng if rng is not None else np.random.default_rng(0)
        tol = 1e-8 if tol is None else tol
        max_iter = 2000 if max_iter is None else max_iter
        if int(n_probes) != n_probes or n_probes < 2:
            raise ValueError(f"n_probes: need an integer >= 2 probes for a standard error, got {n_probes!r}; e.g. 8")
        solver = NormalSolver(op, penalty, dims, spacing, rng, tol, max_iter, n_fields=n_fields)
        x0 = None
        # CG and the criteria run on data / max|data| (no overflow of squared norms at 1e200)
        scale = _data_scale(d)
        d_s = d / scale
        if lam is None:
            noise_s = None if noise_std is None else noise_std / scale
            if noise_s is not None and 0 < noise_s < 1e-100:
                raise ValueError(f"noise_std: {noise_std!r} is {noise_s:.3g} x the data's magnitude ({scale:.3g}), far "
                                 "below the float rounding of the data (2.2e-16 relative); no criterion can use it: "
                                 "give the real noise level, or None to estimate it")
            icrit = IterativeCriteria(solver, d_s, rng, n_probes=n_probes)
            crit = _rescaled(choose_lambda_iterative(icrit, noise_std=noise_s), scale, d.size)
            lam_used, source = crit.lam[criterion], criterion
            x0 = icrit.norms(lam_used)["x"] if lam_used in icrit._cache else None
        else:
            lam_used, source = float(lam), "given"
        x, iters, ok = _solve_iterative(op, d_s, penalty, lam_used, (solver, x0))
        resid = scale * float(np.linalg.norm(op.matvec(x) - d_s))
        model = (x * scale).reshape(model_shape)
        kept = Factorisation(path, penalty, model_shape, (solver, scale), op, d_s)
    msg = (f"path={path}, penalty={penalty}, lam={lam_used:.4g} ({source}), residual={resid:.4g}"
           + (f", {iters} CG iterations{'' if ok else ' (NOT converged)'}" if path == "iterative" else "")
           + (f"; criteria: {crit.estimator}" if crit is not None and crit.errors else ""))
    return LinearInversionResult(model=model, method=path, penalty=penalty, lam=lam_used, lam_source=source,
                                 criteria=crit, residual_norm=resid, iterations=iters, converged=ok, message=msg,
                                 factorisation=kept)

"""All four regularisation criteria on the matrix-free (iterative) path.

For ``min ||A m - d||^2 + lam ||L m||^2`` with only ``A`` as a LinearOperator, write the normal
operator ``N(lam) = A^T A + lam L^T L`` (SPD; ``L^T L`` carries the same ``eps I`` as the dense
path, see :func:`tactilab.inversion.linear.dense_form`, so that values agree) and ``x(lam)`` its
preconditioned-CG solution. Per lam on a descending log grid, warm-started from the previous lam:

- residual ``rho = ||A x - d||^2`` and seminorm ``eta = ||L x||^2`` (one CG solve);
- L-curve curvature of ``(log rho, log eta)`` in closed form from ``rho, eta`` and
  ``eta' = -2 (L^T L x)^T N^-1 (L^T L x)`` (one more CG solve; ``rho' = -lam eta'``, and the second
  derivatives cancel, as in Hansen's formula);
- GCV ``n rho / (n - T)^2`` with ``T = tr(A N^-1 A^T) = tr(N^-1 A^T A)`` estimated by Hutchinson:
  ``T ~ mean_j z_j^T N^-1 A^T A z_j`` over Rademacher probes ``z_j`` (one CG solve per probe;
  the probes live in data space, ``z^T A N^-1 A^T z``, when there are fewer data than unknowns),
  standard error ``std_j / sqrt(p)``, carried to GCV by the delta method;
- the evidence ``-1/2 [quad/sigma^2 + logdet(lam) + n log(2 pi sigma^2)]`` with the exact
  ``quad = rho + lam eta`` and ``logdet(lam) = log det N(lam) - n_model log lam - log det(L^T L)``:
  ``log det N`` by stochastic Lanczos quadrature (Ubaru, Chen and Saad 2017): per probe, Lanczos
  with full reorthogonalisation on ``N`` started at ``z/||z||`` until the Gauss-quadrature value of
  ``z^T log(N) z`` changes by < ``1e-6 n``; ``log det(L^T L + eps I)`` is exact (sparse LU).
  The same probes serve every lam (common random numbers), so the estimated curves are smooth in
  lam and their minimisers are well defined.

The grid walks down from a lam where the penalty dominates and stops once every requested
criterion is bracketed (three grid points past its optimum), so that ill-conditioned small lam are
never solved for; each choice is then refined by bounded Brent on log lam (discrepancy: brentq).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.linalg import eigh_tridiagonal
from scipy.optimize import brentq, minimize_scalar
from scipy.sparse.linalg import LinearOperator, cg, splu

from .criteria import CRITERIA, CriteriaResult, spread_warning
from .penalties import penalty_matrix, penalty_symbol

__all__ = ["NormalSolver", "IterativeCriteria", "choose_lambda_iterative"]


class NormalSolver:
    """Preconditioned CG on ``(A^T A + lam L^T L) x = b`` for one operator and penalty.

    The preconditioner is the circulant ``(c + lam |L(k)|^2)^-1`` with ``c`` a Hutchinson estimate
    of ``mean diag(A^T A)`` (8 Rademacher probes from ``rng``).
    """

    def __init__(self, op: LinearOperator, penalty: str, dims, spacing, rng: np.random.Generator,
                 tol: float, max_iter: int):
        self.op, self.dims, self.tol, self.max_iter = op, tuple(dims), float(tol), int(max_iter)
        self.n = op.shape[1]
        lmat = penalty_matrix(penalty, self.dims, spacing, periodic=False)
        self.lmat = lmat.tocsr()
        self.ltl = (lmat.T @ lmat).tocsc()
        # the dense path's eps I, so that log det and the null-space modes match it
        self.eps = 1e-12 * max(float(self.ltl.diagonal().sum()) / self.n, 1e-300)
        z = rng.choice([-1.0, 1.0], size=(self.n, 8))
        az = np.column_stack([op.matvec(z[:, j]) for j in range(8)])
        self.c = float(np.sum(az * az) / (self.n * 8))
        self.l2 = penalty_symbol(penalty, self.dims, spacing)[..., : self.dims[-1] // 2 + 1]
        self.axes = tuple(range(len(self.dims)))
        self.iterations = 0

    def normal(self, lam: float) -> LinearOperator:
        return LinearOperator((self.n, self.n), dtype=float,
                              matvec=lambda x: self.op.rmatvec(self.op.matvec(x)) + lam * (self.ltl @ x + self.eps * x))

    def solve(self, lam: float, rhs: np.ndarray, x0: np.ndarray | None = None) -> tuple[np.ndarray, int, bool]:
        den = self.c + lam * self.l2

        def precondition(v):
            spec = np.fft.rfftn(np.asarray(v).reshape(self.dims), axes=self.axes) / den
            return np.fft.irfftn(spec, s=self.dims, axes=self.axes).ravel()

        count = [0]

        def callback(_):
            count[0] += 1

        x, info = cg(self.normal(lam), rhs, x0=x0, rtol=self.tol, maxiter=self.max_iter,
                     M=LinearOperator((self.n, self.n), matvec=precondition, dtype=float), callback=callback)
        self.iterations += count[0]
        return x, count[0], info == 0

    def logdet_penalty(self) -> float:
        """``log det(L^T L + eps I)`` exactly, by sparse LU (the matrix is SPD)."""
        lu = splu((self.ltl + self.eps * sp.identity(self.n, format="csc")).tocsc())
        return float(np.sum(np.log(np.abs(lu.U.diagonal()))) + np.sum(np.log(np.abs(lu.L.diagonal()))))


def slq_logdet(matvec, n: int, probes: np.ndarray, max_steps: int = 200, rtol: float = 1e-6) -> np.ndarray:
    """Stochastic Lanczos quadrature: per probe ``z``, the estimate ``z^T log(M) z`` of ``log det M``.

    Parameters
    ----------
    matvec : callable
        SPD operator ``M``.
    n : int
        Its size.
    probes : ndarray, shape (n, p)
        Rademacher probes (so that ``E[z^T log(M) z] = tr log M``).
    max_steps : int
        Lanczos steps at most per probe (full reorthogonalisation).
    rtol : float
        Stop a probe once its quadrature value changes by less than ``rtol * n``.

    Returns
    -------
    ndarray, shape (p,)
        One unbiased-up-to-quadrature estimate per probe; their mean is the log det.
    """
    out = np.empty(probes.shape[1])
    for j in range(probes.shape[1]):
        z = probes[:, j]
        norm2 = float(z @ z)
        q = z / np.sqrt(norm2)
        basis = [q]
        alpha: list[float] = []
        beta: list[float] = []
        prev = np.inf
        est = 0.0
        for _ in range(min(max_steps, n)):
            w = matvec(q)
            a = float(q @ w)
            alpha.append(a)
            qs = np.array(basis)
            w = w - qs.T @ (qs @ w)
            w = w - qs.T @ (qs @ w)  # twice is enough (Kahan/Parlett)
            theta, vecs = eigh_tridiagonal(np.array(alpha), np.array(beta)) if beta else (np.array([a]), np.ones((1, 1)))
            est = norm2 * float(np.sum(vecs[0] ** 2 * np.log(np.maximum(theta, np.finfo(float).tiny))))
            b = float(np.linalg.norm(w))
            if abs(est - prev) < rtol * n or b <= 1e-12 * abs(a):
                break
            prev = est
            beta.append(b)
            q = w / b
            basis.append(q)
        out[j] = est
    return out


class IterativeCriteria:
    """Criteria values at any lam with CG solves, cached and warm-started (see module docstring)."""

    def __init__(self, solver: NormalSolver, data: np.ndarray, rng: np.random.Generator, n_probes: int = 8):
        self.s, self.d = solver, data
        self.n_data, self.n = data.size, solver.n
        self.atd = solver.op.rmatvec(data)
        self.probes = rng.choice([-1.0, 1.0], size=(self.n, int(n_probes)))
        self._rng = rng
        self._atap: np.ndarray | None = None
        self._logdet_l: float | None = None
        self._cache: dict = {}
        self._warm: dict = {}

    def _warm_start(self, key: str, lam: float):
        if not self._warm.get(key):
            return None
        lams = np.array(list(self._warm[key]))
        return self._warm[key][float(lams[np.argmin(np.abs(np.log(lams / lam)))])]

    def _solve(self, key: str, lam: float, rhs: np.ndarray) -> np.ndarray:
        x, _, ok = self.s.solve(lam, rhs, self._warm_start(key, lam))
        self._warm.setdefault(key, {})[lam] = x
        self.converged = getattr(self, "converged", True) and ok
        return x

    def norms(self, lam: float) -> dict:
        """Residual^2, seminorm^2, the solution and ``eta'`` (two CG solves)."""
        lam = float(lam)
        hit = self._cache.setdefault(lam, {})
        if "rho" not in hit:
            x = self._solve("x", lam, self.atd)
            r = self.s.op.matvec(x) - self.d
            lx = self.s.lmat @ x
            hit.update(x=x, rho=float(r @ r), eta=float(lx @ lx))
        return hit

    def curvature(self, lam: float) -> float:
        """Signed curvature of ``(log rho, log eta)`` (closed form, see module docstring)."""
        h = self.norms(lam)
        if "curv" not in h:
            g = self.s.ltl @ h["x"] + self.s.eps * h["x"]
            deta = -2.0 * float(g @ self._solve("deta", lam, g))
            rho, eta = h["rho"], h["eta"]
            if rho <= 0 or eta <= 0 or deta >= 0:
                h["curv"] = 0.0
            else:
                h["curv"] = float(-rho * eta * (rho * eta + lam * deta * rho + lam**2 * deta * eta)
                                  / (deta * (lam**2 * eta**2 + rho**2) ** 1.5))
        return h["curv"]

    def dof(self, lam: float) -> tuple[float, float]:
        """Hutchinson estimate of ``tr(influence matrix)`` and its standard error."""
        h = self._cache.setdefault(float(lam), {})
        if "dof" not in h:
            op = self.s.op
            if self._atap is None:
                # probe the smaller side: tr(A N^-1 A^T) in data space, tr(N^-1 A^T A) in model space
                if self.n_data < self.n:
                    self._tprobes = self._rng.choice([-1.0, 1.0], size=(self.n_data, self.probes.shape[1]))
                    self._atap = np.column_stack([op.rmatvec(z) for z in self._tprobes.T])
                else:
                    self._tprobes = self.probes
                    self._atap = np.column_stack([op.rmatvec(op.matvec(z)) for z in self.probes.T])
            ys = [self._solve(f"p{j}", float(lam), self._atap[:, j]) for j in range(self._atap.shape[1])]
            if self.n_data < self.n:
                t = np.array([self._tprobes[:, j] @ op.matvec(y) for j, y in enumerate(ys)])
            else:
                t = np.array([self._tprobes[:, j] @ y for j, y in enumerate(ys)])
            h["dof"], h["dof_se"] = float(t.mean()), float(t.std(ddof=1) / np.sqrt(t.size))
        return h["dof"], h["dof_se"]

    def gcv(self, lam: float) -> tuple[float, float]:
        rho = self.norms(lam)["rho"]
        t, se = self.dof(lam)
        left = self.n_data - t
        if left <= 0:  # the estimate says every datum is fitted: GCV is undefined there
            return np.inf, np.inf
        return self.n_data * rho / left**2, 2.0 * self.n_data * rho / left**3 * se

    def logdet(self, lam: float) -> tuple[float, float]:
        """``log det(I + B B^T / lam)`` of the dense path's evidence, by SLQ, and its standard error."""
        h = self._cache.setdefault(float(lam), {})
        if "logdet" not in h:
            if self._logdet_l is None:
                self._logdet_l = self.s.logdet_penalty()
            est = slq_logdet(self.s.normal(float(lam)).matvec, self.n, self.probes)
            h["logdet"] = float(est.mean()) - self.n * np.log(lam) - self._logdet_l
            h["logdet_se"] = float(est.std(ddof=1) / np.sqrt(est.size))
        return h["logdet"], h["logdet_se"]

    def log_evidence(self, lam: float, noise_std: float | None) -> tuple[float, float, float]:
        """Log evidence, its standard error and the noise std used (given, or profiled out)."""
        h = self.norms(lam)
        quad = h["rho"] + lam * h["eta"]
        ld, se = self.logdet(lam)
        var = max(quad / self.n_data, np.finfo(float).tiny) if noise_std is None else noise_std**2
        ll = -0.5 * (quad / var + ld + self.n_data * np.log(2 * np.pi * var))
        return ll, 0.5 * se, float(np.sqrt(var))


def _past_optimum(values: list, k: int = 3) -> bool:
    """True once the last k values all lie above the running minimum reached before them."""
    if len(values) < k + 2:
        return False
    best = int(np.nanargmin(values))
    return 0 < best <= len(values) - 1 - k


def _refine(fun, grid: np.ndarray, values: np.ndarray) -> float:
    i = int(np.nanargmin(values))
    lo, hi = np.log(grid[max(i - 1, 0)]), np.log(grid[min(i + 1, grid.size - 1)])
    if hi <= lo:
        return float(grid[i])
    lo, hi = min(lo, hi), max(lo, hi)
    res = minimize_scalar(fun, bounds=(lo, hi), method="bounded", options={"xatol": 0.02})
    return float(np.exp(res.x)) if res.fun <= values[i] else float(grid[i])


def choose_lambda_iterative(crit: IterativeCriteria, noise_std: float | None = None, criteria=("gcv", "lcurve",
                            "discrepancy", "evidence"), per_decade: int = 3, max_decades: float = 16.0,
                            tau: float = 1.0, warn_factor: float = 10.0) -> CriteriaResult:
    """Choose lam by each criterion on the matrix-free path (stochastic GCV and evidence).

    Parameters as :func:`tactilab.inversion.criteria.choose_lambda`; ``per_decade`` grid points per
    decade of lam, at most ``max_decades`` below the start ``100 c / max|L(k)|^2``.
    The result's ``estimator`` names the stochastic estimators and ``errors`` holds the standard
    errors of the GCV and log-evidence curves (``"gcv"``, ``"log_evidence"``, ``"dof"``).
    """
    criteria = tuple(criteria)
    unknown = [c for c in criteria if c not in CRITERIA]
    if unknown or not criteria:
        raise ValueError(f"criteria: unknown or empty {criteria!r}; use a subset of {', '.join(CRITERIA)}")
    if noise_std is not None and not (np.isfinite(noise_std) and noise_std > 0):
        raise ValueError(f"noise_std: must be finite and > 0 (data units), got {noise_std!r}; or pass None to estimate it")
    s = crit.s
    need_ev = "evidence" in criteria or ("discrepancy" in criteria and noise_std is None)
    l2max = float(np.max(s.l2)) if np.max(s.l2) > 0 else 1.0
    lam_hi = 100.0 * s.c / l2max
    step = 10.0 ** (1.0 / per_decade)
    grid: list[float] = []
    cur = {k: [] for k in ("residual2", "seminorm2", "gcv", "gcv_se", "dof", "dof_se", "curvature",
                           "log_evidence", "log_evidence_se")}
    lam = lam_hi
    while len(grid) < max_decades * per_decade + 1:
        grid.append(lam)
        h = crit.norms(lam)
        cur["residual2"].append(h["rho"])
        cur["seminorm2"].append(h["eta"])
        done = []
        if "gcv" in criteria:
            g, gse = crit.gcv(lam)
            t, tse = crit.dof(lam)
            cur["gcv"].append(g), cur["gcv_se"].append(gse), cur["dof"].append(t), cur["dof_se"].append(tse)
            done.append(_past_optimum(cur["gcv"]))
        if "lcurve" in criteria:
            cur["curvature"].append(crit.curvature(lam))
            done.append(_past_optimum([-v for v in cur["curvature"]]) and max(cur["curvature"]) > 0)
        if need_ev:
            ll, llse, sig = crit.log_evidence(lam, noise_std)
            cur["log_evidence"].append(ll), cur["log_evidence_se"].append(llse)
            done.append(_past_optimum([-v for v in cur["log_evidence"]]))
        if "discrepancy" in criteria:
            sigma_now = noise_std if noise_std is not None else sig
            done.append(h["rho"] < tau**2 * crit.n_data * sigma_now**2)
        if all(done):
            break
        lam /= step
    g = np.array(grid)
    curves = {k: np.array(v) for k, v in cur.items() if v}
    chosen: dict = {}
    notes: dict = {}
    if "gcv" in criteria:
        chosen["gcv"] = _refine(lambda t: crit.gcv(np.exp(t))[0], g, curves["gcv"])
    if need_ev:
        lam_ev = _refine(lambda t: -crit.log_evidence(np.exp(t), noise_std)[0], g, -curves["log_evidence"])
        if "evidence" in criteria:
            chosen["evidence"] = lam_ev
            if noise_std is None:
                notes["evidence"] = "noise std profiled out (generalised maximum likelihood)"
    sigma = noise_std if noise_std is not None else crit.log_evidence(lam_ev, None)[2]
    if "lcurve" in criteria:
        inner = curves["curvature"].copy()
        inner[[0, -1]] = -np.inf
        chosen["lcurve"] = _refine(lambda t: -crit.curvature(np.exp(t)), g, -inner)
    if "discrepancy" in criteria:
        target = tau**2 * crit.n_data * sigma**2
        f = lambda t: crit.norms(np.exp(t))["rho"] - target  # noqa: E731 (monotone in t)
        below = np.flatnonzero(curves["residual2"] < target)
        if below.size == 0:
            chosen["discrepancy"] = float(g[-1])
            notes["discrepancy"] = "residual exceeds the noise level even for the smallest lam tried"
        elif below[0] == 0:
            chosen["discrepancy"] = float(g[0])
            notes["discrepancy"] = "residual stays below the noise level: data carry no signal above noise"
        else:
            j = int(below[0])
            chosen["discrepancy"] = float(np.exp(brentq(f, np.log(g[j]), np.log(g[j - 1]), xtol=1e-3)))
        if noise_std is None:
            notes["discrepancy"] = notes.get("discrepancy", "") + f" (noise std estimated by the evidence: {sigma:.3g})"
    p = crit.probes.shape[1]
    parts = []
    if "gcv" in criteria:
        t, tse = crit.dof(chosen["gcv"])
        parts.append(f"GCV trace by Hutchinson ({p} Rademacher probes, one CG solve each): "
                     f"dof {t:.4g} +- {tse:.2g} (1 s.e.) at the GCV choice")
    if need_ev:
        ll, llse, _ = crit.log_evidence(lam_ev, noise_std)
        parts.append(f"evidence log det by stochastic Lanczos quadrature ({p} probes): "
                     f"log evidence {ll:.6g} +- {llse:.2g} (1 s.e.) at its choice")
    parts.append("L-curve and discrepancy from CG norms (deterministic to the CG tolerance)")
    errors = {k: curves[k + "_se"] for k in ("gcv", "dof", "log_evidence") if k + "_se" in curves}
    result = CriteriaResult(lam=chosen, grid=g, curves={k: v for k, v in curves.items() if not k.endswith("_se")},
                            noise_std=float(sigma), notes=notes, spread=float("nan"),
                            estimator="; ".join(parts), errors=errors)
    result.spread = spread_warning(chosen, warn_factor, stacklevel=3)
    return result

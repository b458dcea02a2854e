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
  ``quad = rho + lam (eta + eps ||x||^2)`` and ``logdet(lam) = log det(I + M^-1 A^T A / lam)``, ``M = L^T L + eps I``
  (``= log det N(lam) - n log lam - log det M``) = ``tr log(I + R^-T A^T A R^-1 / lam)`` with
  ``R^T R = M`` (sparse LDL^T), by stochastic Lanczos quadrature (Ubaru, Chen and Saad 2017), see
  :func:`slq_log1p_trace`: per Rademacher probe, Lanczos with full reorthogonalisation until the
  quadrature value changes by < 1e-6 relative. The eigenvalues ``r_i / lam`` decay like the
  forward map's spectrum, so few steps suffice (``log det N`` itself would span many more decades).
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
import scipy.linalg as sla
from scipy.sparse.linalg import LinearOperator, cg, splu, spsolve_triangular

from tactilab.core import rules

from .criteria import CRITERIA, CriteriaResult, spread_warning
from .penalties import penalty_matrix, penalty_symbol

__all__ = ["NormalSolver", "IterativeCriteria", "choose_lambda_iterative", "slq_log1p_trace"]


class NormalSolver:
    """Preconditioned CG on ``(A^T A + lam L^T L) x = b`` for one operator and penalty.

    The preconditioner is the circulant ``(c + lam |L(k)|^2)^-1`` with ``c`` a Hutchinson estimate
    of ``mean diag(A^T A)`` (8 Rademacher probes from ``rng``).
    """

    def __init__(self, op: LinearOperator, penalty: str, dims, spacing, rng: np.random.Generator,
                 tol: float, max_iter: int, n_fields: int = 1):
        self.op, self.dims, self.tol, self.max_iter = op, tuple(dims), float(tol), int(max_iter)
        self.n = op.shape[1]
        self.model_shape = (int(n_fields), *self.dims)  # load-major: one grid per load component
        lmat = penalty_matrix(penalty, self.dims, spacing, periodic=False, n_fields=n_fields)
        self.lmat = lmat.tocsr()
        self.ltl = (lmat.T @ lmat).tocsc()
        # the dense path's eps I, so that log det and the null-space modes match it
        self.eps = 1e-12 * max(float(self.ltl.diagonal().sum()) / self.n, 1e-300)
        z = rng.choice([-1.0, 1.0], size=(self.n, 8))
        az = np.column_stack([op.matvec(z[:, j]) for j in range(8)])
        self.c = float(np.sum(az * az) / (self.n * 8))
        self.l2 = penalty_symbol(penalty, self.dims, spacing)[..., : self.dims[-1] // 2 + 1]
        self.axes = tuple(range(1, len(self.dims) + 1))
        self.iterations = 0

    def normal(self, lam: float) -> LinearOperator:
        return LinearOperator((self.n, self.n), dtype=float,
                              matvec=lambda x: self.op.rmatvec(self.op.matvec(x)) + lam * (self.ltl @ x + self.eps * x))

    def solve(self, lam: float, rhs: np.ndarray, x0: np.ndarray | None = None) -> tuple[np.ndarray, int, bool]:
        den = self.c + lam * self.l2

        def precondition(v):
            spec = np.fft.rfftn(np.asarray(v).reshape(self.model_shape), axes=self.axes) / den
            return np.fft.irfftn(spec, s=self.dims, axes=self.axes).ravel()

        count = [0]

        def callback(_):
            count[0] += 1

        x, info = cg(self.normal(lam), rhs, x0=x0, rtol=self.tol, maxiter=self.max_iter,
                     M=LinearOperator((self.n, self.n), matvec=precondition, dtype=float), callback=callback)
        self.iterations += count[0]
        return x, count[0], info == 0

    def penalty_factor(self):
        """``(v -> R^-1 v, v -> R^-T v)`` with ``R^T R = L^T L + eps I``: ``R = D^1/2 L^T`` from an
        LDL^T factorisation (sparse LU without pivoting, exact for this SPD matrix)."""
        m = (self.ltl + self.eps * sp.identity(self.n, format="csc")).tocsc()
        lu = splu(m, permc_spec="NATURAL", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
        if not (np.array_equal(lu.perm_r, np.arange(self.n)) and np.array_equal(lu.perm_c, np.arange(self.n))):
            # SuperLU pivoted after all: fall back to a dense Cholesky factor (small n only)
            r = np.linalg.cholesky(m.toarray()).T
            return (lambda v: sla.solve_triangular(r, v, lower=False),
                    lambda v: sla.solve_triangular(r, v, lower=False, trans="T"))
        low = lu.L.tocsr()
        up = low.T.tocsr()
        d_isqrt = 1.0 / np.sqrt(lu.U.diagonal())
        return (lambda v: spsolve_triangular(up, d_isqrt * v, lower=False, unit_diagonal=True),
                lambda v: d_isqrt * spsolve_triangular(low, v, lower=True, unit_diagonal=True))


def slq_log1p_trace(apply_s, probes: np.ndarray, max_steps: int = 300, rtol: float = 1e-6) -> np.ndarray:
    """Stochastic Lanczos quadrature of ``tr log(I + S)`` for symmetric positive semidefinite ``S``.

    Per Rademacher probe ``z``: Lanczos (full reorthogonalisation) started at ``z/||z||`` gives a
    tridiagonal ``T`` with eigenpairs ``(theta_k, v_k)``; ``||z||^2 sum_k v_k[0]^2 log(1 + theta_k)``
    is the Gauss quadrature of ``z^T log(I + S) z`` (Ubaru, Chen and Saad 2017), and the mean over
    probes estimates the trace.

    Parameters
    ----------
    apply_s : callable
        ``v -> S v``.
    probes : ndarray, shape (n, p)
        Rademacher probes.
    max_steps : int
        Lanczos steps at most per probe.
    rtol : float
        Stop a probe once its quadrature value changes by less than ``rtol * max(1, |value|)``.

    Returns
    -------
    ndarray, shape (p,)
        One estimate per probe.
    """
    n, p = probes.shape
    out = np.empty(p)
    for j in range(p):
        z = probes[:, j]
        norm2 = float(z @ z)
        q = z / np.sqrt(norm2)
        basis = [q]
        alpha: list[float] = []
        beta: list[float] = []
        prev, est = np.inf, 0.0
        for _ in range(min(max_steps, n)):
            w = apply_s(q)
            a = float(q @ w)
            alpha.append(a)
            qs = np.array(basis)
            for _ in range(2):  # twice is enough (Parlett)
                w = w - qs.T @ (qs @ w)
            theta, vecs = (eigh_tridiagonal(np.array(alpha), np.array(beta)) if beta
                           else (np.array([a]), np.ones((1, 1))))
            est = norm2 * float(np.sum(vecs[0] ** 2 * np.log1p(np.maximum(theta, 0.0))))
            b = float(np.linalg.norm(w))
            if abs(est - prev) < rtol * max(1.0, abs(est)) or b <= 1e-12 * max(abs(a), 1e-300):
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
        self._rinv = None
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
        self.failed = getattr(self, "failed", set())
        if not ok:
            self.failed.add(lam)
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
            h["dof_probes"] = t
        return h["dof"], h["dof_se"]

    def gcv(self, lam: float) -> tuple[float, float]:
        rho = self.norms(lam)["rho"]
        t, se = self.dof(lam)
        left = self.n_data - t
        if left <= 0:  # the estimate says every datum is fitted: GCV is undefined there
            return np.inf, np.inf
        return self.n_data * rho / left**2, 2.0 * self.n_data * rho / left**3 * se

    def probe_values(self, name: str, lam: float, noise_std: float | None = None) -> np.ndarray:
        """Per-probe values of ``"gcv"`` or ``"neg_log_evidence"`` at lam (their mean ~ the estimate).

        With common probes, differences between lam are far more precise than each value: these
        give the standard error of a difference (see :func:`_plausible`).
        """
        h = self.norms(lam)
        if name == "gcv":
            self.dof(lam)
            left = np.maximum(self.n_data - h["dof_probes"], 1e-300)
            return self.n_data * h["rho"] / left**2
        self.logdet(lam)
        ll = self.log_evidence(lam, noise_std)[0]
        return -ll + 0.5 * (h["logdet_probes"] - h["logdet"])

    def logdet(self, lam: float) -> tuple[float, float]:
        """``log det(I + B B^T / lam)`` of the dense path's evidence, by SLQ, and its standard error.

        ``B = A R^-1`` with ``R^T R = L^T L + eps I``: ``tr log(I + B^T B / lam)`` by SLQ.
        """
        h = self._cache.setdefault(float(lam), {})
        if "logdet" not in h:
            if self._rinv is None:
                self._rinv, self._rinv_t = self.s.penalty_factor()
            op, rinv, rinv_t = self.s.op, self._rinv, self._rinv_t

            def apply_s(v):
                av = op.matvec(rinv(v))
                return rinv_t(op.rmatvec(av)) / lam

            est = slq_log1p_trace(apply_s, self.probes)
            h["logdet"] = float(est.mean())
            h["logdet_probes"] = est
            h["logdet_se"] = float(est.std(ddof=1) / np.sqrt(est.size))
        return h["logdet"], h["logdet_se"]

    def log_evidence(self, lam: float, noise_std: float | None) -> tuple[float, float, float]:
        """Log evidence, its standard error and the noise std used (given, or profiled out)."""
        h = self.norms(lam)
        # d^T (I + B B^T / lam)^-1 d = rho + lam x^T (L^T L + eps I) x: the eps I term is the dense
        # path's (proper, very wide) prior on the null space of L, kept so that values agree
        quad = h["rho"] + lam * (h["eta"] + self.s.eps * float(h["x"] @ h["x"]))
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


def _plausible(grid: np.ndarray, samples: np.ndarray) -> tuple[float, float]:
    """Range of grid lam whose criterion (to minimise) is within 2 s.e. of the best grid value.

    ``samples`` has shape (n_grid, n_probes): per-probe values with probes shared across lam, so
    the s.e. of each difference is ``std_j(s_ij - s_bj) / sqrt(p)``: the choice's uncertainty
    from the estimator (wide where the curve is flat against its noise).
    """
    mean = samples.mean(axis=1)
    b = int(np.nanargmin(mean))
    diff = samples - samples[b]
    se = diff.std(axis=1, ddof=1) / np.sqrt(samples.shape[1])
    ok = mean - mean[b] <= 2.0 * se
    return float(grid[ok].min()), float(grid[ok].max())


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
    decade of lam, at most ``max_decades`` below the start (two decades above the lam where the
    residual has fallen by 10% from its penalty-dominated value).
    The result's ``estimator`` names the stochastic estimators and ``errors`` holds the standard
    errors of the GCV and log-evidence curves (``"gcv"``, ``"log_evidence"``, ``"dof"``) and, as
    ``"gcv_lam_range"`` / ``"evidence_lam_range"``, the grid lam whose criterion is within 2 s.e.
    (of the difference, probes being shared) of the best: the choice's stochastic uncertainty.
    """
    criteria = tuple(criteria)
    unknown = [c for c in criteria if c not in CRITERIA]
    if unknown or not criteria:
        raise ValueError(f"criteria: unknown or empty {criteria!r}; use a subset of {', '.join(CRITERIA)}")
    if noise_std is not None:
        rules.positive(noise_std, "noise_std", "data units", "or pass None to estimate it")
    s = crit.s
    need_ev = "evidence" in criteria or ("discrepancy" in criteria and noise_std is None)
    pos = s.l2[s.l2 > 0]
    # above lam_top the penalty outweighs A^T A on every penalised mode; walk down by decades
    # (one CG solve each, cheap there) until the residual starts to fall, and start the fine grid
    # two decades above that: higher up every criterion is flat or monotone
    lam = 100.0 * s.c / (float(pos.min()) if pos.size else 1.0)
    rho_top = crit.norms(lam)["rho"]
    for _ in range(40):
        if crit.norms(lam / 10.0)["rho"] < 0.9 * rho_top:
            break
        lam /= 10.0
    lam_hi = lam * 10.0
    step = 10.0 ** (1.0 / per_decade)
    grid: list[float] = []
    cur = {k: [] for k in ("residual2", "seminorm2", "gcv", "gcv_se", "dof", "dof_se", "curvature",
                           "log_evidence", "log_evidence_se")}
    notes: dict = {}
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
        if lam in getattr(crit, "failed", set()):
            # smaller lam are worse conditioned still: stop here rather than report unconverged values
            notes["grid"] = (f"CG did not converge at lam = {lam:.3g} (max_iter {s.max_iter}); the grid stops there, "
                             "so a criterion whose optimum lies lower is reported at the grid's end")
            break
        lam /= step
    g = np.array(grid)
    curves = {k: np.array(v) for k, v in cur.items() if v}
    chosen: dict = {}
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
    ranges: dict = {}
    if "gcv" in criteria:
        t, tse = crit.dof(chosen["gcv"])
        lo, hi = _plausible(g, np.array([crit.probe_values("gcv", x) for x in g]))
        parts.append(f"GCV trace by Hutchinson ({p} Rademacher probes, one CG solve each): "
                     f"dof {t:.4g} +- {tse:.2g} (1 s.e.) at the GCV choice; grid lam within 2 s.e. "
                     f"(of the difference) of the GCV minimum: {lo:.3g} .. {hi:.3g}")
        ranges["gcv_lam_range"] = np.array([lo, hi])
    if need_ev:
        ll, llse, _ = crit.log_evidence(lam_ev, noise_std)
        lo, hi = _plausible(g, np.array([crit.probe_values("neg_log_evidence", x, noise_std) for x in g]))
        parts.append(f"evidence log det by stochastic Lanczos quadrature ({p} probes): "
                     f"log evidence {ll:.6g} +- {llse:.2g} (1 s.e.) at its choice; grid lam within 2 s.e. (of the "
                     f"difference) of the maximum: {lo:.3g} .. {hi:.3g}")
        ranges["evidence_lam_range"] = np.array([lo, hi])
    parts.append("L-curve and discrepancy from CG norms (deterministic to the CG tolerance)")
    errors = {k: curves[k + "_se"] for k in ("gcv", "dof", "log_evidence") if k + "_se" in curves}
    errors.update(ranges)
    result = CriteriaResult(lam=chosen, grid=g, curves={k: v for k, v in curves.items() if not k.endswith("_se")},
                            noise_std=float(sigma), notes=notes, spread=float("nan"),
                            estimator="; ".join(parts), errors=errors)
    result.spread = spread_warning(chosen, warn_factor, stacklevel=3)
    return result

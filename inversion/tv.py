"""Total-variation inversion by ADMM: ``min_m 1/2 ||A m - d||^2 + lam ||D m||_1``.

``D`` is the forward difference (periodic on the fft path, free ends otherwise; in 2-D the
anisotropic sum of |d/dx| and |d/dy|), divided by the grid spacing, so ``lam`` is in data
units squared times metres. TV keeps edges and isolated defects that Tikhonov smears.

Splitting ``z = D m`` with scaled dual ``u`` (Boyd et al. 2011, "Distributed optimization and
statistical learning via ADMM", section 3.1 and 6.4.1):

    m <- argmin 1/2 ||A m - d||^2 + rho/2 ||D m - z + u||^2     (linear solve)
    z <- soft(D m + u, lam / rho)
    u <- u + D m - z

Stopping rule (their eq. 3.12): primal residual ``||D m - z|| <= sqrt(p) eps_abs + eps_rel
max(||D m||, ||z||)`` and dual residual ``rho ||D^T (z - z_old)|| <= sqrt(n) eps_abs + eps_rel
||rho D^T u||``, or ``max_iter`` (then ``converged=False``). Over-relaxation alpha = 1.8
(their section 3.4.3); ``rho`` starts at 1e-4 ``||A||^2 / |D(k_min)|^2`` and is rebalanced (x2 or
/2) every 20 iterations when the scaled primal and dual residuals differ tenfold (section 3.4.1;
rebalancing every iteration was tried and stalls on these exponentially ill-posed operators).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
from scipy.optimize import brentq
from scipy.sparse.linalg import LinearOperator, aslinearoperator, cg

from .linear_common import LinearInversionResult, check_data
from .operators import FourierDiagonal
from .paths import choose_path
from .penalties import penalty_matrix, penalty_symbol

__all__ = ["invert_tv", "admm_tv"]


def _soft(x, t):
    return np.sign(x) * np.maximum(np.abs(x) - t, 0.0)


def admm_tv(op, d, lam, dims, spacing, path, rho=None, eps_abs=1e-6, eps_rel=1e-4, max_iter=3000, alpha=1.8,
            adapt_every=20, warm: dict | None = None):
    """Run ADMM for one lam. Returns (model_flat, iterations, converged).

    ``warm``: a dict updated in place with the final ``m, z, u, rho``; when it holds them, ADMM
    starts there (the discrepancy search re-solves for nearby lam).
    """
    n = int(np.prod(dims))
    dmat = penalty_matrix("gradient", dims, spacing, periodic=(path == "fft"))
    dtd = (dmat.T @ dmat).tocsr()
    atd = op.rmatvec(d) if not isinstance(op, np.ndarray) else op.T @ d
    if path == "fft":
        h2 = np.abs(op.half_multiplier) ** 2
        l2 = penalty_symbol("gradient", dims, spacing)[..., : dims[-1] // 2 + 1]
        axes = tuple(range(len(dims)))
        scale = float(h2.max())
    elif path == "dense":
        a = op if isinstance(op, np.ndarray) else op.matmat(np.eye(n))
        ata = a.T @ a
        scale = float(np.linalg.eigvalsh(ata)[-1])
    else:
        v = np.ones(n) / np.sqrt(n)
        for _ in range(30):  # power iteration for ||A||^2
            w = op.rmatvec(op.matvec(v))
            scale = float(np.linalg.norm(w))
            v = w / max(scale, 1e-300)
    if rho is None:
        # rho = 1e-4 x the largest ratio |H|^2 / |D|^2 (at the longest grid wavelength): tuned on
        # exponentially ill-posed kernels, where rho near ||A||^2 / ||D||^2 stalls ADMM
        extent = max(np.asarray(dims) * np.broadcast_to(np.asarray(spacing, dtype=float), (len(dims),))[::-1])
        rho = 1e-4 * max(scale, 1e-300) / (2 * np.pi / extent) ** 2
    rho = float(rho)
    m = np.zeros(n)
    z = dmat @ m
    u = np.zeros_like(z)
    if warm and "m" in warm:
        m, z, u, rho = warm["m"].copy(), warm["z"].copy(), warm["u"] * (warm["rho"] / rho), rho
    cache = {}

    def keep(it, ok):
        if warm is not None:
            warm.update(m=m, z=z, u=u, rho=rho)
        return m, it, ok

    def solve(rhs, rho_):
        if path == "fft":
            spec = np.fft.rfftn(rhs.reshape(dims), axes=axes)
            den = h2 + rho_ * l2
            spec = np.where(den > 0, spec / np.where(den > 0, den, 1.0), 0.0)
            return np.fft.irfftn(spec, s=dims, axes=axes).ravel()
        if path == "dense":
            if cache.get("rho") != rho_:
                cache["rho"] = rho_
                cache["chol"] = sla.cho_factor(ata + rho_ * dtd.toarray() + 1e-14 * scale * np.eye(n))
            return sla.cho_solve(cache["chol"], rhs)
        normal = LinearOperator((n, n), matvec=lambda x: op.rmatvec(op.matvec(x)) + rho_ * (dtd @ x), dtype=float)
        x, _ = cg(normal, rhs, x0=cache.get("x0"), rtol=1e-8, maxiter=1000)
        cache["x0"] = x
        return x

    p = z.size
    for it in range(1, max_iter + 1):
        m = solve(atd + rho * (dmat.T @ (z - u)), rho)
        dm = dmat @ m
        z_old = z
        relaxed = alpha * dm + (1.0 - alpha) * z_old  # over-relaxation, Boyd section 3.4.3
        z = _soft(relaxed + u, lam / rho)
        u = u + relaxed - z
        r_norm = np.linalg.norm(dm - z)
        s_norm = rho * np.linalg.norm(dmat.T @ (z - z_old))
        eps_pri = np.sqrt(p) * eps_abs + eps_rel * max(np.linalg.norm(dm), np.linalg.norm(z))
        eps_dual = np.sqrt(n) * eps_abs + eps_rel * rho * np.linalg.norm(dmat.T @ u)
        if r_norm <= eps_pri and s_norm <= eps_dual:
            return keep(it, True)
        if adapt_every and it % adapt_every == 0:
            # residual balancing (Boyd 3.4.1) applied sparingly: ADMM needs a steady rho between changes
            ratio = (r_norm / eps_pri) / max(s_norm / eps_dual, 1e-300)
            if ratio > 10:
                rho *= 2.0
                u /= 2.0
            elif ratio < 0.1:
                rho /= 2.0
                u *= 2.0
    return keep(max_iter, False)


def invert_tv(operator, data, *, lam=None, noise_std=None, method="auto", spacing=None, tol=None,
              max_iter=3000, rng=None) -> LinearInversionResult:
    """Total-variation inversion; see :func:`tactilab.inversion.linear.invert_linear` (``penalty="tv"``).

    ``lam=None`` chooses lam by the discrepancy principle (needs ``noise_std``): a root search
    on log lam, one ADMM solve per trial. ``tol`` is ADMM's relative tolerance ``eps_rel``
    (default 1e-4).
    """
    del rng  # ADMM is deterministic
    operator, method = choose_path(operator, method)
    is_matrix = isinstance(operator, np.ndarray)
    if is_matrix and method == "iterative":
        operator, is_matrix = aslinearoperator(operator), False
    op = operator if isinstance(operator, (FourierDiagonal, np.ndarray)) else aslinearoperator(operator)
    d = check_data(data, operator.shape[0], shape=getattr(operator, "dimsd", None))
    dims = (operator.shape[1],) if is_matrix else tuple(getattr(operator, "dims", (operator.shape[1],)))
    spacing = spacing if spacing is not None else getattr(operator, "spacing", 1.0)
    eps_rel = 1e-4 if tol is None else float(tol)
    if not (0 < eps_rel < 1):
        raise ValueError(f"tol: ADMM relative tolerance must be in (0, 1), got {tol!r}")
    eps_abs = 1e-3 * eps_rel * float(np.linalg.norm(d)) / np.sqrt(d.size)

    def fwd(x):
        return op @ x if is_matrix else op.matvec(x)

    warm: dict = {}

    def run(lam_):
        return admm_tv(op, d, lam_, dims, spacing, method, eps_abs=eps_abs, eps_rel=eps_rel, max_iter=max_iter,
                       warm=warm)

    if lam is None:
        if noise_std is None or not (np.isfinite(noise_std) and noise_std > 0):
            raise ValueError(f"noise_std: TV with lam=None chooses lam by the discrepancy principle and needs "
                             f"noise_std > 0 (data units), got {noise_std!r}; or pass lam")
        target = np.sqrt(d.size) * noise_std
        gmax = float(np.max(np.abs(fwd_adjoint(op, d, is_matrix)))) * float(np.mean(spacing))
        lo, hi = np.log(gmax * 1e-8), np.log(max(gmax, 1e-300) * 10)

        def g(t):
            return np.linalg.norm(fwd(run(np.exp(t))[0]) - d) - target

        if g(hi) <= 0:
            lam_used, source = float(np.exp(hi)), "discrepancy (bracket top: data within noise)"
        elif g(lo) >= 0:
            lam_used, source = float(np.exp(lo)), "discrepancy (bracket bottom: residual above noise)"
        else:
            lam_used, source = float(np.exp(brentq(g, lo, hi, xtol=0.05))), "discrepancy"
    else:
        if not (np.isfinite(lam) and lam > 0):
            raise ValueError(f"lam: TV strength must be finite and > 0, got {lam!r}")
        lam_used, source = float(lam), "given"
    m, iters, ok = run(lam_used)
    resid = float(np.linalg.norm(fwd(m) - d))
    msg = (f"path={method}, penalty=tv (ADMM), lam={lam_used:.4g} ({source}), residual={resid:.4g}, "
           f"{iters} ADMM iterations{'' if ok else ' (NOT converged: max_iter reached)'}")
    return LinearInversionResult(model=m.reshape(dims), method=method, penalty="tv", lam=lam_used, lam_source=source,
                                 criteria=None, residual_norm=resid, iterations=iters, converged=ok, message=msg)


def fwd_adjoint(op, d, is_matrix):
    """``A^T d`` for a matrix or an operator."""
    return op.T @ d if is_matrix else op.rmatvec(d)

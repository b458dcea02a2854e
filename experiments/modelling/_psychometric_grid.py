"""The posterior of a psychometric function: psignifit 4's priors, bounds and two-pass adaptive grid.

Reproduced from psignifit 4 (python-psignifit 4.3: ``_priors.py``, ``_parameter.py``,
``_posterior.py``, ``psignifit.py::_fit_parameters``): the default bounds, the coarse grid
whose cells holding at least 1e-5 of the posterior mass set tighter bounds (one cell of margin),
the fine grid on those, trapezoid cell weights, the posterior mean on the fine grid and the MAP
by a simplex search from the best grid point. Differences: the likelihood is evaluated for all
grid points at once per level block (the speed), and intervals and medians interpolate the
marginal's cumulative mass at cell edges (psignifit interpolates it at cell centres, which
shifts each end by up to half a cell).
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from scipy import optimize
from scipy.special import gammaln, ndtri, xlogy


class ParamSummary(NamedTuple):
    """Posterior summary of one parameter: MAP, mean, median and central 95 % / 68 % intervals."""

    map: float
    mean: float
    median: float
    ci95: tuple[float, float]
    ci68: tuple[float, float]


AXES = ("guess", "lapse", "eta", "threshold", "width")
_COARSE = {"nafc": dict(threshold=30, width=40, lapse=10, guess=1, eta=20),
           "yes_no": dict(threshold=25, width=30, lapse=10, guess=10, eta=15)}
_FINE = {"nafc": dict(threshold=40, width=40, lapse=20, guess=1, eta=20),
         "yes_no": dict(threshold=40, width=40, lapse=20, guess=20, eta=20)}
_MASS_TOL = 1e-5
_THREADS = max(1, min(4, os.cpu_count() or 1))


def _threshold_prior(x, s0, s1):
    """Flat on the stimulus range, cosine fall-off to 0 over half the range on each side."""
    sp = s1 - s0
    p = np.where((s0 < x) & (x < s1), 1.0, 0.0)
    left = ((s0 - sp / 2) <= x) & (x <= s0)
    right = (s1 <= x) & (x <= (s1 + sp / 2))
    p = np.where(left, (1 + np.cos(2 * np.pi * (s0 - x) / sp)) / 2, p)
    return np.where(right, (1 + np.cos(2 * np.pi * (x - s1) / sp)) / 2, p)


def _width_prior(x, alpha, wmin, wmax):
    """Flat from 2 wmin to wmax (alpha-rescaled), cosine fall-offs to 0 at wmin and 3 wmax."""
    y = x * (ndtri(0.95) - ndtri(0.05)) / (ndtri(1 - alpha) - ndtri(alpha))
    p = np.where(((2 * wmin) < y) & (y < wmax), 1.0, 0.0)
    p = np.where((wmin <= y) & (y <= 2 * wmin), (1 - np.cos(np.pi * (y - wmin) / wmin)) / 2, p)
    return np.where((wmax <= y) & (y <= 3 * wmax), (1 + np.cos(np.pi / 2 * (y - wmax) / wmax)) / 2, p)


def _beta_1_10(x):
    """Beta(1, 10) density."""
    x = np.asarray(x, dtype=float)
    return np.where((x >= 0) & (x <= 1), 10 * np.clip(1 - x, 0, 1) ** 9, 0.0)


def _log(p):
    with np.errstate(divide="ignore"):
        return np.log(p)


@dataclass
class GridPosterior:
    """Posterior of (guess, lapse, eta, threshold, width) on psignifit's adaptive grid (fit scale u)."""

    u: np.ndarray
    k: np.ndarray
    n: np.ndarray
    core: object
    kind: str
    fixed: dict
    custom: dict | None
    threshold_pc: float
    width_alpha: float
    grid: dict = field(default_factory=dict)
    mass: np.ndarray | None = None
    map: dict = field(default_factory=dict)

    def __post_init__(self):
        s0, s1 = float(self.u.min()), float(self.u.max())
        sp = s1 - s0
        wmin = float(np.diff(np.unique(self.u)).min())
        self.c = float(self.core.ppf(1 - self.width_alpha) - self.core.ppf(self.width_alpha))
        self.z_pc = float(self.core.ppf(self.threshold_pc))
        a = self.width_alpha
        width_spread = sp / ((ndtri(0.95) - ndtri(0.05)) / (ndtri(1 - a) - ndtri(a)))
        self.bounds = {"threshold": (s0 - sp / 2, s1 + sp / 2), "width": (wmin, 3 * width_spread),
                       "lapse": (0.0, 0.5), "guess": (0.0, 0.5), "eta": (0.0, 1 - 1e-10)}
        self.tied = self.kind == "equal_asymptote"
        if self.tied:
            self.fixed.pop("guess", None)
        for key, value in self.fixed.items():
            self.bounds[key] = (value, value)
        self.priors = {"threshold": lambda x: _threshold_prior(x, s0, s1),
                       "width": lambda x: _width_prior(x, a, wmin, sp),
                       "lapse": _beta_1_10, "guess": _beta_1_10, "eta": _beta_1_10}
        self.priors.update(self.custom or {})
        self.free = [ax for ax in AXES if self.bounds[ax][0] != self.bounds[ax][1] and not (self.tied and ax == "guess")]

    def log_post(self, g, lam, e, t, w):
        """Log posterior (unnormalised) at broadcastable parameter arrays; -inf outside the support."""
        if self.tied:
            g = lam
        scale = self.c / w
        eta = np.asarray(e, dtype=float) ** 2
        beta_binomial = bool(np.any(eta > 1e-9))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            eta_p = np.where(eta > 1e-9, 1 / np.maximum(eta, 1e-300) - 1, np.inf)
            if math.prod(np.broadcast_shapes(*(np.shape(a) for a in (g, lam, e, t, w)))) > 4096:
                span = 1 - g - lam  # big grids: one level block at a time (memory of one grid per thread)

                def part(blocks):
                    acc = 0.0
                    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # per thread
                        for ui, ki, ni in blocks:
                            psi = g + span * self.core.cdf(self.z_pc + (ui - t) * scale)
                            acc = acc + self._ll(psi, ki, ni, eta, eta_p, beta_binomial)
                    return acc

                blocks = list(zip(self.u, self.k, self.n))
                n_threads = min(_THREADS, len(blocks))
                with ThreadPoolExecutor(n_threads) as pool:  # numpy's ufuncs release the GIL
                    total = sum(pool.map(part, [blocks[i::n_threads] for i in range(n_threads)]))
            else:  # a few points (the MAP search, emcee): all blocks at once on a trailing axis
                ex = (lambda a: np.asarray(a, dtype=float)[..., None])
                psi = ex(g) + (1 - ex(g) - ex(lam)) * self.core.cdf(self.z_pc + (self.u - ex(t)) * ex(scale))
                total = np.sum(self._ll(psi, self.k, self.n, ex(eta), ex(eta_p), beta_binomial), axis=-1)
            prior = (_log(self.priors["threshold"](t)) + _log(self.priors["width"](w))
                     + _log(self.priors["lapse"](lam)) + _log(self.priors["guess"](g)) + _log(self.priors["eta"](e)))
            out = total + prior
        return np.where(np.isnan(out), -np.inf, out)

    @staticmethod
    def _ll(psi, k, n, eta, eta_p, beta_binomial):
        """Binomial (or psignifit's beta-binomial where eta > 1e-9) log-likelihood, no binomial coefficient."""
        if np.ndim(k) == 0:  # one block (grid pass): skip empty terms, np.log is much faster than xlogy
            ll = (k * np.log(psi) if k > 0 else 0.0) + ((n - k) * np.log1p(-psi) if n > k else 0.0)
        else:
            ll = xlogy(k, psi) + xlogy(n - k, 1 - psi)
        if beta_binomial:
            ap, bp = psi * eta_p, (1 - psi) * eta_p
            bb = gammaln(k + ap) + gammaln(n - k + bp) - gammaln(n + eta_p) - gammaln(ap) - gammaln(bp) + gammaln(eta_p)
            ll = np.where(eta > 1e-9, bb, ll)
        return ll

    def _grid_eval(self, bounds, steps):
        grid = {ax: (np.array([bounds[ax][0]]) if np.isclose(*bounds[ax]) or (self.tied and ax == "guess")
                     else np.linspace(*bounds[ax], steps[ax])) for ax in AXES}
        mesh = np.meshgrid(*(grid[ax] for ax in AXES), indexing="ij", sparse=True)
        logp = self.log_post(*mesh)
        logp = np.broadcast_to(logp, tuple(len(grid[ax]) for ax in AXES))
        best = np.unravel_index(int(np.argmax(logp)), logp.shape)
        p = np.exp(logp - logp[best])
        for i, ax in enumerate(AXES):
            x = grid[ax]
            if len(x) > 1:
                d = np.empty_like(x)
                d[1:] = np.diff(x)
                d[0] = d[1] / 2
                d[-1] = d[-1] / 2
                p = p * d.reshape([-1 if j == i else 1 for j in range(len(AXES))])
        return grid, p / p.sum(), {ax: float(grid[ax][best[i]]) for i, ax in enumerate(AXES)}

    def fit(self):
        """Run the two passes and the MAP search; returns self."""
        steps = "yes_no" if self.kind == "yes_no" else "nafc"
        grid, mass, _ = self._grid_eval(self.bounds, _COARSE[steps])
        idx = np.nonzero(mass >= _MASS_TOL)
        tight = {}
        for i, ax in enumerate(AXES):
            x, lo, hi = grid[ax], 0, len(grid[ax]) - 1
            if idx[i].size:
                lo, hi = max(lo, int(idx[i].min()) - 1), min(hi, int(idx[i].max()) + 1)
            tight[ax] = (float(x[lo]), float(x[hi]))
        self.grid, self.mass, start = self._grid_eval(tight, _FINE[steps])
        self.map = self._maximise(start)
        return self

    def _maximise(self, start):
        point = dict(start)
        if not self.free:
            return point
        lo = np.array([self.bounds[ax][0] for ax in self.free])
        hi = np.array([self.bounds[ax][1] for ax in self.free])

        def objective(v):
            q = {**point, **dict(zip(self.free, v))}
            value = float(self.log_post(*(q[ax] for ax in AXES)))
            return -value if math.isfinite(value) else 1e300

        x0 = np.array([start[ax] for ax in self.free])
        res = optimize.minimize(objective, x0, method="Nelder-Mead", bounds=list(zip(lo, hi)),
                                options=dict(xatol=1e-7 * (1 + np.abs(x0).max()), fatol=1e-10, maxiter=4000))
        best = res.x if res.fun <= objective(x0) else x0
        point.update(zip(self.free, map(float, best)))
        if self.tied:
            point["guess"] = point["lapse"]
        return point

    def _edges(self, ax):
        x = self.grid[ax]
        return np.concatenate([[x[0]], (x[1:] + x[:-1]) / 2, [x[-1]]])

    def marginal(self, ax):
        """Marginal mass per grid point of one axis, shape (n_ax,)."""
        i = AXES.index(ax)
        return self.mass.sum(axis=tuple(j for j in range(len(AXES)) if j != i))

    def quantiles(self, ax, q):
        """Quantiles of one axis's marginal, linear within cells (cell edges from the trapezoid rule)."""
        cum = np.concatenate([[0.0], np.cumsum(self.marginal(ax))])
        return np.interp(q, cum / cum[-1], self._edges(ax))

    def draws(self, n_draws, rng):
        """Posterior draws: grid cells by mass, uniform within each cell; dict of (n_draws,) arrays."""
        cum = np.cumsum(self.mass.ravel())
        flat = np.minimum(np.searchsorted(cum, rng.random(n_draws) * cum[-1], side="right"), cum.size - 1)
        ids = np.unravel_index(flat, self.mass.shape)
        out = {}
        for i, ax in enumerate(AXES):
            if len(self.grid[ax]) == 1:
                out[ax] = np.full(n_draws, self.grid[ax][0])
            else:
                e = self._edges(ax)
                out[ax] = e[ids[i]] + rng.random(n_draws) * (e[ids[i] + 1] - e[ids[i]])
        if self.tied:
            out["guess"] = out["lapse"].copy()
        return out

    def psi(self, theta, u=None):
        """psi at the levels for parameter dicts of arrays: shape (..., n_levels)."""
        u = self.u if u is None else u
        t, w = (np.asarray(theta[k], dtype=float)[..., None] for k in ("threshold", "width"))
        g, lam = (np.asarray(theta[k], dtype=float)[..., None] for k in ("guess", "lapse"))
        return g + (1 - g - lam) * self.core.cdf(self.z_pc + (u - t) * self.c / w)

    def goodness(self, draws, rng, n_rep: int = 1000):
        """(deviance at the MAP, posterior-predictive p of the deviance)."""
        def dev(k, psi):
            with np.errstate(divide="ignore", invalid="ignore"):
                d = 2 * (xlogy(k, k / (self.n * psi)) + xlogy(self.n - k, (self.n - k) / (self.n * (1 - psi))))
            return np.sum(np.nan_to_num(d, nan=0.0, posinf=1e300), axis=-1)

        deviance = float(dev(self.k, self.psi(self.map)))
        take = {key: np.asarray(v)[:n_rep] for key, v in draws.items()}
        psi = self.psi(take)
        eta = np.asarray(take["eta"])[:, None] ** 2
        p = psi
        if np.any(eta > 1e-9):  # beta-binomial: the success probability itself varies per block
            e = np.clip(eta, 1e-9, 1 - 1e-9)
            p = np.where(eta > 1e-9, rng.beta(psi * (1 / e - 1), (1 - psi) * (1 / e - 1)), psi)
        k_rep = rng.binomial(self.n.astype(np.int64), np.clip(p, 0, 1))
        return deviance, float(np.mean(dev(k_rep, psi) >= dev(self.k, psi)))

    def summaries(self, draws, method):
        """ParamSummary per parameter (grid: mean on the grid, quantiles of the marginal)."""
        out = {}
        for ax in AXES:
            if ax == "eta" and "eta" in self.fixed and self.fixed["eta"] == 0.0:
                continue
            src = "lapse" if (self.tied and ax == "guess") else ax
            if len(self.grid[src]) == 1:
                v = float(self.grid[src][0])
                out[ax] = ParamSummary(v, v, v, (v, v), (v, v))
                continue
            if method == "grid":
                mean = float(np.sum(self.marginal(src) * self.grid[src]))
                med, a, b, c, d = self.quantiles(src, [0.5, 0.025, 0.975, 0.16, 0.84])
            else:
                x = np.asarray(draws[src])
                mean = float(x.mean())
                med, a, b, c, d = np.quantile(x, [0.5, 0.025, 0.975, 0.16, 0.84])
            out[ax] = ParamSummary(float(self.map[src]), mean, float(med), (float(a), float(b)),
                                          (float(c), float(d)))
        return out


def grid_posterior(u, k, n, core, kind, fixed, custom, threshold_pc, width_alpha) -> GridPosterior:
    """Build and run the adaptive grid posterior."""
    return GridPosterior(u, k, n, core, kind, dict(fixed), custom, threshold_pc, width_alpha).fit()


class _PosteriorModel:
    """The grid's posterior as a model of :func:`tactilab.inversion.sample_posterior` (vectorised):
    the free parameters inside the grid's bounds, psignifit's priors, one likelihood term per block."""

    vectorized = True

    def __init__(self, post: GridPosterior):
        self.post = post
        self.param_names = tuple(post.free)
        self.lo = np.array([post.bounds[ax][0] for ax in post.free])
        self.hi = np.array([post.bounds[ax][1] for ax in post.free])
        # the sd of each marginal (the sampler's scale for its MAP polish and start ball)
        self.scale = np.array([max(np.diff(post.quantiles(ax, [0.16, 0.84]))[0], 1e-6) for ax in post.free])
        self.observed = post.k
        # priors of the fixed parameters are constant: evaluated once (a tied guess follows the lapse)
        self.varying = [ax for ax in AXES if ax in post.free or (post.tied and ax == "guess")]
        with np.errstate(divide="ignore"):
            self.fixed_log_prior = float(sum(_log(post.priors[ax](post.map[ax])) for ax in AXES
                                             if ax not in self.varying))

    def _params(self, theta):
        """Parameter values: the free ones per walker (W,), the fixed ones as scalars."""
        theta = np.atleast_2d(theta)
        q = {ax: self.post.map[ax] for ax in AXES}
        q.update({ax: theta[:, i] for i, ax in enumerate(self.param_names)})
        if self.post.tied:
            q["guess"] = q["lapse"]
        return q, theta

    def log_prior(self, theta):
        q, theta = self._params(theta)
        inside = np.all((theta >= self.lo) & (theta <= self.hi), axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            lp = self.fixed_log_prior + sum(_log(self.post.priors[ax](q[ax])) for ax in self.varying)
        return np.where(inside & ~np.isnan(lp), lp, -np.inf)

    def log_likelihood(self, theta):
        """Binomial (or beta-binomial) term of every block, shape (W, n_blocks)."""
        q, theta = self._params(theta)
        eta = np.asarray(q["eta"], dtype=float)[..., None] ** 2
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            eta_p = np.where(eta > 1e-9, 1 / np.maximum(eta, 1e-300) - 1, np.inf)
            psi = np.broadcast_to(self.post.psi(q), (theta.shape[0], self.post.k.size))
            ll = self.post._ll(psi, self.post.k, self.post.n, eta, eta_p, bool(np.any(eta > 1e-9)))
        return np.where(np.isnan(ll), -np.inf, ll)


def sample_emcee(post: GridPosterior, rng, max_steps: int = 5000, max_draws: int = 32000):
    """Draws of the same posterior by the project's MCMC engine, :func:`tactilab.inversion.sample_posterior`:
    four emcee ensembles started at the grid's MAP, run until R-hat, ESS and the autocorrelation
    checks pass (or ``max_steps``; then a UserWarning says which checks failed)."""
    from tactilab.inversion import sample_posterior

    if not post.free:
        raise ValueError("method: 'emcee' needs at least one free parameter, but every one is fixed; "
                         "use method='grid'")
    model = _PosteriorModel(post)
    start = np.array([post.map[ax] for ax in post.free])
    # tau_factor 20: the kept chain spans 20 autocorrelation times (the fixed run this replaced kept
    # about 21); R-hat and ESS >= 400 are checked as for every posterior
    tree = sample_posterior(model, rng, start=start, max_steps=max_steps, check_every=500, tau_factor=20.0,
                            max_draws=max_draws, info_tol=None)
    if not tree.attrs["converged"]:
        import warnings

        warnings.warn(f"emcee: {tree.attrs['message']}", UserWarning, stacklevel=3)
    posterior = tree["posterior"]
    n_draws = posterior[post.free[0]].values.size
    out = {ax: np.full(n_draws, post.map[ax]) for ax in AXES}
    out.update({ax: posterior[ax].values.ravel() for ax in post.free})
    if post.tied:
        out["guess"] = out["lapse"].copy()
    return out

"""What surface did the finger touch? The surface posterior from a scan, through the solved contact.

:func:`invert_surface` (scene + recording) and :func:`invert_scan` (a prepared
:class:`~tactilab.inversion.surface_scan.ContactScan` and its data) return a
:class:`~tactilab.inversion.surface_posterior.SurfacePosterior`:

1. ``method="laplace"``: the MAP by Gauss-Newton with a line search
   (:mod:`~tactilab.inversion.surface_laplace`), the free context parameters part of the state;
   the Gaussian (Laplace) posterior around it, the context marginalised as the heights' block of
   the joint covariance.
2. ``method="mcmc"``: the same MAP, then emcee (:mod:`~tactilab.inversion.sampler`) on the exact
   non-linear posterior in a reduced basis (:mod:`~tactilab.inversion.surface_mcmc`): a check of
   the Laplace answer on small problems.
3. The untouched nodes: the prior conditioned on each draw's touched nodes and on the skin's upper
   bound (:mod:`~tactilab.inversion.surface_bound`), drawn; their mean, sd and band come from the draws.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.linalg import solve_triangular

from .gaussian import StationaryPrior
from .priors import LogNormal, Normal, Uniform
from .surface_bound import TruncatedConditional, bound_rows
from .surface_laplace import ContextTransform, gauss_newton, prior_root
from .surface_mcmc import sample_surface
from .surface_posterior import CONTEXT_UNITS, SurfacePosterior
from .surface_scan import CONTEXT_NAMES

__all__ = ["invert_scan", "parse_context", "METHODS"]

#: posterior methods
METHODS = ("laplace", "mcmc")


def parse_context(scan, context: dict) -> tuple[list[ContextTransform], dict]:
    """Split ``context`` into free parameters (priors) and fixed values; check the scan has each one."""
    if not isinstance(context, dict):
        raise ValueError(f"context: expected a dict name -> float or prior, got {type(context).__name__}")
    free, fixed = [], {}
    for name, value in context.items():
        if name not in CONTEXT_NAMES:
            raise ValueError(f"context: unknown parameter {name!r}; the scene's context parameters are "
                             f"{', '.join(CONTEXT_NAMES)}")
        if name == "normal_force" and scan.mean_pressure is not None:
            raise ValueError("context: the scene is a periodic cell loaded by its mean pressure; it has no "
                             "normal_force to fix or free (drop it)")
        if isinstance(value, (Uniform, Normal, LogNormal)):
            free.append(ContextTransform(name, value))
        elif isinstance(value, (int, float)) and np.isfinite(value) and \
                (value >= 0 if name == "friction" else value > 0):
            fixed[name] = float(value)
        else:
            raise ValueError(f"context: {name} must be a finite float (> 0; friction >= 0) or a Uniform, Normal or "
                             f"LogNormal prior, got {value!r}")
    return free, fixed


def invert_scan(scan, data, noise_std: float, *, prior: StationaryPrior | None = None, context: dict | None = None,
                method: str = "laplace", rng: np.random.Generator, n_draws: int = 400, truth=None,
                max_iter: int = 30, continuation: bool = True, mcmc_options: dict | None = None,
                jacobian_every: int = 1, jacobian_tol: float = 1e-8, workers: int = 1,
                gradient_tol: float = 1e-8, solve_dtype=np.float64, map_tol: float = 1e-6) -> SurfacePosterior:
    """The surface posterior of a prepared scan (see the module docstring).

    Parameters
    ----------
    scan : ContactScan
    data : ndarray, shape (n_frames, n_out)
        Sensor outputs, Pa (stress) or tensor strain.
    noise_std : float
        The data's noise sd (> 0), data units.
    prior : StationaryPrior or None
        Prior of the heights on the profile grid (m^2 variance, m correlation length); None: flat,
        the touched heights are then a relief of mean 0 (a uniform shift changes no datum at a given
        force) and the untouched nodes have no posterior (NaN mean and sd, their bound in ``upper_bound``).
    context : dict, optional
        ``normal_force``, ``friction``, ``young_modulus`` -> a float (fixed, SI) or a prior (free).
    method : {"laplace", "mcmc"}
    rng : numpy.random.Generator
        Every draw (posterior draws, the sampler).
    n_draws : int
        Posterior draws kept (the untouched nodes' statistics come from them).
    truth : ndarray, optional
        The true heights (m), for the figure and the files.
    max_iter : int
        Gauss-Newton iteration limit (per continuation stage).
    continuation : bool
        Lower the noise sd tenfold per stage from the initial misfit (default); False with
        ``max_iter=1`` is the linearised inversion (one Gauss-Newton step from the prior mean).
    mcmc_options : dict, optional
        Passed to :func:`~tactilab.inversion.surface_mcmc.sample_surface` (``method="mcmc"``).
    jacobian_every : int
        Gauss-Newton iterations per explicit Jacobian (1: every one; above 1, with a prior, the
        steps in between use the last one with the exact gradient: the same MAP, fewer solves; see
        :func:`~tactilab.inversion.surface_laplace.gauss_newton`).
    jacobian_tol : float
        Relative residual of the Jacobian's restricted solves (default 1e-8; 1e-6 left the rows of a
        fingertip scan's Jacobian within 6e-6 of the exact ones, in 11 instead of 15 iterations).
        It sets the Hessian only (the steps' model and the Laplace covariance; with
        ``jacobian_every`` > 1 the MAP is the exact gradient's zero): 1e-4 moved a 60-frame
        fingertip scan's posterior sds by at most 5e-5 of the largest.
    workers : int
        Threads (default 1): over chunks of the Jacobian's and the gradients' restricted solves
        (:class:`tactilab.forward.ContactLinearisation`), and over blocks of frames of the scan
        solves (:meth:`ContactScan.solve`).
    gradient_tol : float
        Relative residual of the exact gradients' restricted solves (default 1e-8; with
        ``jacobian_every`` > 1): see :func:`~tactilab.inversion.surface_laplace.gauss_newton`.
    solve_dtype : float64 or float32
        Precision of the iterations of those restricted solves (default float64); float32 halves
        their FFT work and is refined until the float64 residual meets both tolerances.
    map_tol : float
        Nats (> 0, default 1e-6): the Gauss-Newton decrement at which the MAP search stops
        (:func:`~tactilab.inversion.surface_laplace.gauss_newton`'s ``tol``; the objective's stall
        test, 1e-3 nats over two iterations, usually stops it first). 5e-3 left the issue's fingertip
        scan's MAP within 0.014 posterior sd of the default's at every touched node, two scan solves
        sooner.

    Returns
    -------
    SurfacePosterior
    """
    if method not in METHODS:
        raise ValueError(f"method: must be one of {METHODS}, got {method!r}")
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng: expected a numpy Generator (np.random.default_rng(seed)), got {rng!r}")
    if method == "mcmc" and prior is None:
        raise ValueError("prior: method='mcmc' samples a reduced basis of the prior-whitened heights; give a "
                         "StationaryPrior (or use method='laplace' without a prior)")
    if prior is not None and not isinstance(prior, StationaryPrior):
        raise ValueError(f"prior: expected a StationaryPrior (or None for a flat prior), got {type(prior).__name__}")
    if not (np.isfinite(map_tol) and map_tol > 0):
        raise ValueError(f"map_tol: the Gauss-Newton decrement at which the search stops must be > 0 nats, got "
                         f"{map_tol!r}; e.g. 1e-6")
    if not (np.isfinite(noise_std) and noise_std > 0):
        raise ValueError(f"noise_std: the likelihood needs the data's noise sd > 0, got {noise_std!r}")
    d = np.asarray(data, dtype=float)
    if d.shape != (scan.n_frames, scan.n_out) or not np.all(np.isfinite(d)):
        raise ValueError(f"data: expected finite values of shape ({scan.n_frames}, {scan.n_out}) (frames, outputs), "
                         f"got {d.shape}")
    transforms, fixed = parse_context(scan, dict(context or {}))
    shape, spacing = scan.profile.shape, scan.profile.spacing
    spacing_xy = spacing if scan.profile.y is None else (spacing, float(scan.profile.y[1] - scan.profile.y[0]))
    root = None if prior is None else prior_root(prior, shape, spacing_xy)
    mean0 = 0.0 if prior is None else prior.mean
    lap = gauss_newton(scan, d, float(noise_std), root, mean0, transforms, fixed, max_iter=max_iter, tol=map_tol,
                       continuation=continuation, jacobian_every=jacobian_every,
                       jacobian_tol=jacobian_tol, workers=workers, gradient_tol=gradient_tol,
                       solve_dtype=solve_dtype)
    n, names = scan.profile.size, [t.name for t in transforms]
    if lap.chi2 > d.size + 4 * np.sqrt(2 * d.size):  # the residual is 4 sd above its expectation
        warnings.warn(f"chi2: the MAP leaves chi2 = {lap.chi2:.4g} for {d.size} data (expected {d.size} +- "
                      f"{np.sqrt(2 * d.size):.2g}): a local optimum of the non-convex partial-contact objective, or a "
                      "model or noise level that does not fit the data; the posterior is centred there",
                      UserWarning, stacklevel=2)
    touched = lap.touched
    rows = bound_rows(scan, lap.state, touched)
    cond = None if prior is None else TruncatedConditional(root @ root, mean0, touched, rows, lap.heights)

    def gaussian_draws(k, gen):
        """Laplace draws: heights (all nodes; untouched from the unconstrained conditional) and context."""
        eps = gen.standard_normal((lap.unknowns.size, k))
        z = np.tile(lap.z[:, None], (1, k))
        z[lap.unknowns] += solve_triangular(lap.hessian_factor[0], eps, lower=lap.hessian_factor[1])
        h = (z[:n].T if root is None else mean0 + (root @ z[:n]).T)
        if root is None:
            h[:, ~touched] = np.nan
        ctx = {t.name: t.value(z[n + i]) for i, t in enumerate(transforms)}
        return h, ctx

    note, chain = "", None
    if method == "mcmc":
        chain = sample_surface(scan, d, float(noise_std), lap, root, mean0, transforms, fixed, rng=rng,
                               **(mcmc_options or {}))
        note = chain["message"]

    def sampler(k, gen):
        if chain is not None:  # the sampler's draws, resampled
            pick = gen.integers(0, chain["heights"].shape[0], k)
            h, ctx = chain["heights"][pick].copy(), {q: v[pick] for q, v in chain["context"].items()}
        else:
            h, ctx = gaussian_draws(k, gen)
        if cond is not None:
            h = cond.draw(h, gen)
        return h.reshape(k, *shape), ctx

    draws, ctx_draws_kept = sampler(int(n_draws), rng)
    cov_h = _height_covariance(lap, root, n)
    mean, std = _moments(lap, draws, cov_h, touched, method, shape)
    upper = np.full(n, np.nan)
    if (~touched).any():
        upper[~touched] = rows.node_bound(lap.heights, np.flatnonzero(~touched))
    map_h = lap.heights.copy()
    if prior is None:  # no prior: the level is not measured; the touched heights are a relief of mean 0
        level = float(map_h.reshape(-1)[touched].mean())
        mean, map_h, draws, upper = mean - level, map_h - level, draws - level, upper - level
    ctx_summary = {}
    for i, t in enumerate(transforms):
        vals = np.asarray(ctx_draws_kept[t.name], dtype=float)
        ctx_summary[t.name] = {"mean": float(vals.mean()), "sd": float(vals.std(ddof=1)),
                               "q05": float(np.quantile(vals, 0.05)), "q95": float(np.quantile(vals, 0.95)),
                               "map": float(lap.context[t.name]), "units": CONTEXT_UNITS[t.name][0]}
    gibbs = 0 if cond is None else cond.gibbs_draws
    message = (f"{lap.message}; {lap.iterations} Gauss-Newton iterations; chi2 {lap.chi2:.4g} for {d.size} data; "
               f"{int(touched.sum())} of {n} nodes touched; untouched nodes: "
               + ("no prior, no posterior (NaN)" if prior is None else
                  f"prior conditioned on the touched nodes and the skin's bound ({rows.n_rows} bounds; "
                  f"{gibbs} of the draws needed Gibbs sweeps)") + (f"; {note}" if note else ""))
    return SurfacePosterior(x=scan.profile.x.copy(), y=None if scan.profile.y is None else scan.profile.y.copy(),
                            mean=mean, std=std, map=map_h, touched=touched.reshape(shape),
                            upper_bound=upper.reshape(shape), context=ctx_summary,
                            resolvable_band=_resolvable_band(cov_h, prior, lap, shape, spacing_xy, touched),
                            noise_std=float(noise_std), chi2=lap.chi2, n_data=d.size, method=method, message=message,
                            draws=draws, context_draws={k: np.asarray(v) for k, v in ctx_draws_kept.items()},
                            truth=None if truth is None else np.asarray(truth, dtype=float).reshape(shape),
                            _sampler=sampler)


def _height_covariance(lap, root, n) -> np.ndarray:
    """The Laplace covariance of the heights (context marginalised), (n, n), m^2 (NaN rows: no prior, untouched)."""
    cov_z = lap.covariance_z()
    full = np.zeros((lap.z.size, lap.z.size))
    full[np.ix_(lap.unknowns, lap.unknowns)] = cov_z
    if root is None:
        cov = full[:n, :n]
        cov[~lap.touched, :] = np.nan
        cov[:, ~lap.touched] = np.nan
        return cov
    return root @ full[:n, :n] @ root


def _moments(lap, draws, cov_h, touched, method, shape):
    """Mean and sd: touched nodes from the Laplace Gaussian (or the sampler's draws), the others from draws."""
    flat = draws.reshape(draws.shape[0], -1)
    with np.errstate(invalid="ignore"):
        mean, std = flat.mean(axis=0), flat.std(axis=0, ddof=1)
    if method == "laplace":
        mean[touched] = lap.heights.reshape(-1)[touched]
        std[touched] = np.sqrt(np.diag(cov_h)[touched])
    return mean.reshape(shape), std.reshape(shape)


def _resolvable_band(cov_h, prior, lap, shape, spacing, touched) -> dict:
    """Fourier modes of the profile whose posterior variance is below half the prior's (see SurfacePosterior)."""
    n = int(np.prod(shape))
    if prior is not None:
        ref = prior.spectrum(tuple(shape), spacing).reshape(-1)
        cov = cov_h
    else:  # no prior: a white reference with the MAP's variance, on the touched nodes (others left out)
        var = float(np.var(lap.heights.reshape(-1)[touched])) if touched.sum() > 1 else 0.0
        ref = np.full(n, var if var > 0 else 1.0)
        cov = np.where(np.isnan(cov_h), 0.0, cov_h)
    c = cov.reshape(*shape, *shape)
    axes_a, axes_b = tuple(range(len(shape))), tuple(range(len(shape), 2 * len(shape)))
    spec = np.fft.fftn(np.fft.ifftn(c, axes=axes_b), axes=axes_a).reshape(n, n)
    ratio = np.real(np.diag(spec)) / ref
    ks = np.meshgrid(*[2 * np.pi * np.fft.fftfreq(m, d) for m, d in
                       zip(shape, (spacing,) if np.ndim(spacing) == 0 else spacing[::-1])], indexing="ij")
    kabs = np.sqrt(sum(k**2 for k in ks)).reshape(-1)
    resolved = (ratio < 0.5) & (kabs > 0)
    k_max = float(kabs[resolved].max()) if resolved.any() else 0.0
    return {"k_max": k_max, "wavelength_min": 2 * np.pi / k_max if k_max > 0 else float("inf"),
            "fraction": float(resolved.mean())}

"""Exact linear-Gaussian posterior: prior ``m ~ N(m0, C)``, data ``d = A m + e``, ``e ~ N(0, sigma^2 I)``.

The prior is stationary on the periodic model grid: its covariance ``C`` is circulant with
eigenvalues ``lambda_k`` (the prior spectrum, in model units squared), built from a spectral density
(:class:`StationaryPrior`) or given directly (e.g. the Tikhonov prior
``lambda_k = sigma^2 / (lam |L(k)|^2)``, see :func:`tikhonov_prior_spectrum`).

Paths (as in :mod:`tactilab.inversion.linear`):
- ``"fft"`` (FourierDiagonal operator): everything is per mode, O(n log n):
  posterior variance ``v_k = lambda_k sigma^2 / (sigma^2 + |H_k|^2 lambda_k)``, mean
  ``m0 + lambda_k conj(H_k) (D_k - H_k M0_k) / (|H_k|^2 lambda_k + sigma^2)``, pointwise variance
  ``mean_k v_k`` (the same at every node), log evidence a sum over modes.
- ``"dense"``: square-root form, a QR of the stacked system ``[A Q / sigma; diag(lambda^-1/2)]``
  in the prior's real Fourier eigenbasis ``Q`` (no inverse of C, no Cholesky, no subtraction):
  mean and pointwise std keep their relative accuracy at any signal-to-noise.
- ``"iterative"``: prior-whitened conjugate gradients ``m = m0 + C^{1/2} z`` for the mean;
  pointwise std from exact posterior samples by perturbation-optimisation (Monte Carlo).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse.linalg import LinearOperator, aslinearoperator, cg

from tactilab.core import rules

from .gaussian_dense import _dense_posterior
from .linear_common import DENSE_MAX, check_data
from .operators import FourierDiagonal, angular_wavenumbers
from .paths import choose_path
from .penalties import penalty_symbol

KINDS = ("matern32", "matern52", "squared_exponential", "white", "self_affine")

__all__ = ["StationaryPrior", "GaussianPosterior", "gaussian_posterior", "tikhonov_prior_spectrum", "KINDS"]


@dataclass(frozen=True)
class StationaryPrior:
    """Stationary Gaussian prior on a periodic grid, defined by its spectral density.

    Parameters
    ----------
    variance : float
        Pointwise prior variance, model units squared (Pa^2 for a pressure).
    correlation_length : float
        Correlation length ell in m (ignored for ``"white"``).
    kind : {"matern32", "matern52", "squared_exponential", "white", "self_affine"}
        Spectral density shape: Matern ``(2 nu / ell^2 + k^2)^-(nu + d/2)``, squared exponential
        ``exp(-k^2 ell^2 / 2)``, flat, or self-affine ``(1 + k^2 ell^2)^-(H + d/2)``: a rough
        surface's power law ``k^-(1 + 2 H)`` (a profile; ``k^-2 (1 + H)`` in 2-D) rolled off below
        ``k = 1 / ell`` (ell the correlation length, H the Hurst exponent).
    mean : float
        Prior mean (uniform), model units.
    hurst : float
        Hurst exponent H in (0, 1] of ``"self_affine"`` (ignored by the other kinds).
    """

    variance: float
    correlation_length: float = 1e-3
    kind: str = "matern32"
    mean: float = 0.0
    hurst: float = 0.8

    def __post_init__(self) -> None:
        rules.positive(self.variance, "variance", "model units squared", "give the pointwise prior variance")
        rules.positive(self.correlation_length, "correlation_length", "m")
        if self.kind not in KINDS:
            raise ValueError(f"kind: unknown prior kind {self.kind!r}; use one of {', '.join(KINDS)}")
        if not np.isfinite(self.mean):
            raise ValueError(f"mean: prior mean must be finite, got {self.mean!r}")
        if not (0 < self.hurst <= 1):
            raise ValueError(f"hurst: the Hurst exponent must lie in (0, 1], got {self.hurst!r}; 0.8 is typical")

    def spectrum(self, shape: tuple[int, ...], spacing) -> np.ndarray:
        """Eigenvalues of the circulant prior covariance, full grid, ``fftfreq`` order.

        Normalised so that the pointwise variance ``mean(lambda_k)`` equals ``variance``.
        """
        ks = angular_wavenumbers(tuple(shape), spacing)
        k2 = sum(k**2 for k in ks) * np.ones(shape)
        ell, d = self.correlation_length, len(shape)
        if self.kind == "white":
            dens = np.ones(shape)
        elif self.kind == "squared_exponential":
            dens = np.exp(-0.5 * k2 * ell**2)
        elif self.kind == "self_affine":
            dens = (1.0 + k2 * ell**2) ** (-(self.hurst + d / 2))
        else:
            nu = 1.5 if self.kind == "matern32" else 2.5
            dens = (2 * nu / ell**2 + k2) ** (-(nu + d / 2)) * (2 * nu / ell**2) ** (nu + d / 2)
        return self.variance * dens.size * dens / dens.sum()


def tikhonov_prior_spectrum(lam: float, penalty: str, noise_std: float, shape, spacing) -> np.ndarray:
    """Prior spectrum equivalent to Tikhonov ``lam ||L m||^2``: ``sigma^2 / (lam |L(k)|^2)``.

    Modes in the null space of ``L`` get ``inf`` (a flat, improper prior).
    """
    l2 = penalty_symbol(penalty, shape, spacing)
    with np.errstate(divide="ignore"):
        return np.where(l2 > 0, noise_std**2 / (lam * np.where(l2 > 0, l2, 1.0)), np.inf)


@dataclass
class GaussianPosterior:
    """Posterior of a linear-Gaussian problem (see module docstring).

    Attributes
    ----------
    mean, std : ndarray, shape ``dims``
        Posterior mean and pointwise standard deviation (model units).
    log_evidence : float
        ``log p(d)``; NaN when the prior is improper (some ``lambda_k = inf``).
    method : str
        ``"fft"``, ``"dense"`` or ``"iterative"``.
    noise_std : float
        Noise standard deviation used (data units).
    note : str
        How the std was obtained (exact, or Monte Carlo with its sample count).
    """

    mean: np.ndarray
    std: np.ndarray
    log_evidence: float
    method: str
    noise_std: float
    note: str
    dims: tuple
    spacing: object
    _aux: dict = field(repr=False, default_factory=dict)

    def __repr__(self) -> str:
        """Method, shape, error estimate (pointwise std) and evidence; never the arrays."""
        std = np.asarray(self.std, dtype=float)
        return (f"GaussianPosterior(method={self.method!r}, mean shape {tuple(np.shape(self.mean))} (model units), "
                f"pointwise std median {np.median(std):.3g} [{np.min(std):.3g}, {np.max(std):.3g}], "
                f"log evidence {self.log_evidence:.6g}, noise_std {self.noise_std:.3g} data units)")

    def _repr_html_(self) -> str:
        """The short repr for notebooks (escaped, monospace)."""
        import html

        return "<pre>" + html.escape(repr(self)) + "</pre>"

    def sample(self, n_samples: int, rng: np.random.Generator) -> np.ndarray:
        """Exact posterior draws, shape ``(n_samples, *dims)``."""
        if int(n_samples) < 1:
            raise ValueError(f"n_samples: need at least 1 sample, got {n_samples!r}")
        n_samples = int(n_samples)
        if self.method == "fft":
            axes = tuple(range(1, len(self.dims) + 1))
            w = rng.standard_normal((n_samples, *self.dims))
            spec = np.fft.rfftn(w, axes=axes) * np.sqrt(self._aux["post_var"])
            return self.mean + np.fft.irfftn(spec, s=self.dims, axes=axes)
        if self.method == "dense":
            root = self._aux["cov_root"]
            return self.mean + (root @ rng.standard_normal((root.shape[1], n_samples))).T.reshape(n_samples, *self.dims)
        return self._aux["sampler"](n_samples, rng)

    def covariance(self) -> np.ndarray:
        """Dense posterior covariance (n, n); dense path, or fft path with n <= DENSE_MAX."""
        if self.method == "dense":
            return self._aux["cov"]
        n = int(np.prod(self.dims))
        if self.method == "fft" and n <= DENSE_MAX:
            axes = tuple(range(1, len(self.dims) + 1))
            eye = np.eye(n).reshape(n, *self.dims)
            out = np.fft.irfftn(np.fft.rfftn(eye, axes=axes) * self._aux["post_var"], s=self.dims, axes=axes)
            return out.reshape(n, n)
        raise ValueError(f"covariance: a dense covariance needs the dense path or n <= {DENSE_MAX}, got n={n} "
                         f"on the {self.method} path; use std or sample() instead")

    def variance_ratio(self) -> tuple[np.ndarray, np.ndarray]:
        """Posterior / prior variance per Fourier mode against |k| (rad/m), fft path (or dense 1-D)."""
        ks = angular_wavenumbers(self.dims, self.spacing)
        kabs = np.sqrt(sum(k**2 for k in ks) * np.ones(self.dims))
        if self.method == "fft":
            half = kabs[..., : self.dims[-1] // 2 + 1]
            ratio = self._aux["post_var"] / self._aux["prior_half"]
            return half.ravel(), ratio.ravel()
        if self.method == "dense" and len(self.dims) == 1:
            cov = self._aux["cov"]
            post = np.real(np.diag(np.fft.ifft(np.fft.fft(cov, axis=0), axis=1)))
            return kabs, post / self._aux["prior_full"]
        raise ValueError("variance_ratio: needs the fft path or a 1-D dense problem; "
                         f"this posterior used the {self.method} path")

    def _prior_pointwise_var(self) -> float:
        if "prior_pointwise_var" in self._aux:
            return self._aux["prior_pointwise_var"]
        a = self._aux
        return float(np.sum(a["w"] * np.where(a["finite"], a["prior_half"], 0)) / a["n"])

    def _gain(self) -> float:
        return self._aux["gain"] if "gain" in self._aux else float(np.max(np.abs(self._aux["h"])))

    def resolvable_band(self, threshold: float = 0.5, depth: float | None = None) -> dict:
        """Wavenumbers where the posterior variance is below ``threshold`` x prior variance.

        Parameters
        ----------
        threshold : float in (0, 1)
            Variance-reduction level that counts as resolved.
        depth : float, optional
            Sensor depth Z in m, for the rough estimate ``k_c ~ ln(SNR) / Z`` with
            ``SNR = prior std x max|H| / noise std`` (max|H|: the operator's largest gain).
            (For a white prior and the normal-pressure kernel the exact edge solves
            ``k Z - ln(1 + k Z) = ln(SNR)``, so ``k_c`` underestimates it.)

        Returns
        -------
        dict
            ``k_max`` (rad/m, largest resolved |k|, 0 if none), ``wavelength_min`` (m),
            ``fraction`` (share of modes resolved), ``k_c_estimate`` (rad/m or None).
        """
        if not (0 < threshold < 1):
            raise ValueError(f"threshold: must be in (0, 1), got {threshold!r}")
        kabs, ratio = self.variance_ratio()
        resolved = ratio < threshold
        k_max = float(kabs[resolved].max()) if resolved.any() else 0.0
        out = {"k_max": k_max, "wavelength_min": 2 * np.pi / k_max if k_max > 0 else np.inf,
               "fraction": float(resolved.mean()), "k_c_estimate": None}
        if depth is not None:
            depth = rules.depth(depth)
            snr = np.sqrt(self._prior_pointwise_var()) * self._gain() / self.noise_std
            out["k_c_estimate"] = float(np.log(snr) / depth) if snr > 1 else 0.0
        return out

    def resolution_kernel(self, index) -> np.ndarray:
        """Posterior-mean response to a unit impulse at grid node ``index`` (a column of R).

        ``R = C A^T (A C A^T + sigma^2 I)^-1 A``; a perfect resolution gives a delta.
        """
        flat = int(np.ravel_multi_index(np.atleast_1d(index), self.dims))
        if self.method == "fft":
            e = np.zeros(self.dims)
            e.flat[flat] = 1.0
            axes = tuple(range(len(self.dims)))
            filt = self._aux["filter"]
            if filt is None:
                filt = 1.0 - self._aux["post_var"] / self._aux["prior_half"]
            return np.fft.irfftn(np.fft.rfftn(e, axes=axes) * filt, s=self.dims, axes=axes)
        if self.method == "dense":
            return self._aux["resolution"][:, flat].reshape(self.dims)
        raise ValueError("resolution_kernel: needs the fft or dense path; the iterative path has no explicit R")


def _prior_spectrum(prior, dims, spacing) -> np.ndarray:
    if isinstance(prior, StationaryPrior):
        return prior.spectrum(dims, spacing)
    lam = np.asarray(prior, dtype=float)
    if lam.shape != tuple(dims):
        raise ValueError(f"prior: spectrum shape {lam.shape} does not match the model grid {tuple(dims)}")
    if not (lam > 0).all():  # NaN fails too
        raise ValueError("prior: spectrum eigenvalues must be > 0 (inf allowed for flat modes), no NaN")
    return lam


def _fft_posterior(op: FourierDiagonal, d, lam_full, m0, sigma):
    dims = op.dims
    n = d.size
    if len(dims) == 1:  # plain 1-D transforms: less overhead on small grids
        fwd = np.fft.rfft
        inv = lambda spec: np.fft.irfft(spec, n)  # noqa: E731
    else:
        axes = tuple(range(len(dims)))
        fwd = lambda x: np.fft.rfftn(x, axes=axes)  # noqa: E731
        inv = lambda spec: np.fft.irfftn(spec, s=dims, axes=axes)  # noqa: E731
    half = lam_full[..., : dims[-1] // 2 + 1]
    h = op.half_multiplier
    h2 = h.real**2 + h.imag**2
    s2 = sigma**2
    finite = np.isfinite(half)
    proper = bool(finite.all())
    if proper:
        v = h2 * half + s2  # data variance per mode
        inv_v = 1.0 / v
        post_var = (s2 * half) * inv_v
        gain = (half * inv_v) * np.conj(h)  # Kalman gain per mode
        filt = None  # the resolution filter 1 - post_var / prior is built on demand
    else:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            post_var = np.where(finite, half * s2 / (s2 + h2 * half), s2 / h2)
            gain = np.where(finite, half * np.conj(h) / (h2 * half + s2), 1.0 / h)
            filt = np.where(finite, h2 * half / (h2 * half + s2), 1.0)
        if not np.all(np.isfinite(post_var)):
            raise ValueError("prior: a flat (infinite-variance) mode is not seen by the operator (H = 0 there); "
                             "give it a finite prior variance")
    d_grid = d.reshape(dims)
    resid_hat = fwd(d_grid - op.matvec(np.full(n, m0)).reshape(dims) if m0 != 0 else d_grid)
    mean = m0 + inv(gain * resid_hat)
    w = op.weights
    pointwise = float((w * post_var).sum() / n)
    if proper:
        r2 = resid_hat.real**2 + resid_hat.imag**2
        log_ev = -0.5 * float((w * (r2 * inv_v / n + np.log(2 * np.pi * v))).sum())
    else:
        log_ev = float("nan")
    aux = {"post_var": post_var, "filter": filt, "prior_half": half, "w": w, "n": n, "finite": finite,
           "h": h}
    return mean, np.full(dims, np.sqrt(pointwise)), log_ev, aux, "exact (closed form per Fourier mode)"


def _circulant(lam_full, dims) -> np.ndarray:
    n = int(np.prod(dims))
    axes = tuple(range(1, len(dims) + 1))
    eye = np.eye(n).reshape(n, *dims)
    return np.fft.ifftn(np.fft.fftn(eye, axes=axes) * lam_full, axes=axes).real.reshape(n, n)


def _iterative_posterior(op, d, lam_full, m0, sigma, dims, rng, n_samples, tol, max_iter):
    if not np.all(np.isfinite(lam_full)):
        raise ValueError("prior: the iterative path needs a proper prior (finite spectrum)")
    n = op.shape[1]
    axes = tuple(range(len(dims)))
    root_half = np.sqrt(lam_full[..., : dims[-1] // 2 + 1])

    def c_half(x):  # C^{1/2} x by FFT (symmetric)
        return np.fft.irfftn(np.fft.rfftn(x.reshape(dims), axes=axes) * root_half, s=dims, axes=axes).ravel()

    def normal(z):
        return c_half(op.rmatvec(op.matvec(c_half(z)))) / sigma**2 + z

    sys_op = LinearOperator((n, n), matvec=normal, dtype=float)
    r0 = d - op.matvec(np.full(n, m0))
    def solve(rhs):
        z, info = cg(sys_op, rhs, rtol=tol, maxiter=max_iter)
        if info != 0:
            raise ValueError(f"max_iter: CG did not converge in {max_iter} iterations; raise max_iter or use the fft path")
        return m0 + c_half(z)

    mean = solve(c_half(op.rmatvec(r0)) / sigma**2)

    def sampler(k, rng_):
        out = np.empty((k, n))
        for i in range(k):
            eps = sigma * rng_.standard_normal(d.size)
            xi = rng_.standard_normal(n)
            out[i] = solve(c_half(op.rmatvec(r0 + eps)) / sigma**2 + xi)
        return out.reshape(k, *dims)

    draws = sampler(n_samples, rng)
    std = draws.std(axis=0, ddof=1)
    aux = {"sampler": sampler, "prior_pointwise_var": float(np.mean(lam_full))}
    note = f"std by Monte Carlo from {n_samples} perturbation-optimisation samples (relative error ~{1 / np.sqrt(2 * (n_samples - 1)):.2g})"
    return mean.reshape(dims), std, float("nan"), aux, note


def gaussian_posterior(
    operator,
    data,
    prior,
    noise_std: float,
    *,
    method: str = "auto",
    spacing=None,
    rng: np.random.Generator | None = None,
    n_samples: int = 64,
    tol: float = 1e-10,
    max_iter: int = 5000,
) -> GaussianPosterior:
    """Exact Gaussian posterior of ``d = A m + e``.

    Parameters
    ----------
    operator : FourierDiagonal, LinearOperator or ndarray (n_data, n_model)
        Forward map; ``dims`` (model grid) taken from it when present.
    data : array_like, n_data values
        Finite observations (data units).
    prior : StationaryPrior or ndarray, shape ``dims``
        Prior, or the circulant prior spectrum (eigenvalues, ``inf`` = flat mode; fft path only).
    noise_std : float
        Noise standard deviation, data units, > 0.
    method : {"auto", "fft", "dense", "iterative"}
        Path, chosen as for :func:`~tactilab.inversion.invert_linear` by
        :func:`~tactilab.inversion.paths.choose_path` (a circulant forward operator takes the fft path).
    spacing : float or tuple, optional
        Grid spacing in m (default: the operator's, else 1).
    rng : numpy.random.Generator, optional
        Needed by the iterative path (Monte Carlo std).
    n_samples : int
        Samples for the iterative path's std.

    Returns
    -------
    GaussianPosterior
    """
    rules.positive(noise_std, "noise_std", "data units", "give the noise standard deviation of the data")
    operator, method = choose_path(operator, method)  # the same path as invert_linear for this operator
    is_matrix = isinstance(operator, np.ndarray)
    dims = (operator.shape[1],) if is_matrix else tuple(getattr(operator, "dims", (operator.shape[1],)))
    spacing = spacing if spacing is not None else getattr(operator, "spacing", 1.0)
    d = check_data(data, operator.shape[0], shape=getattr(operator, "dimsd", None))
    lam_full = _prior_spectrum(prior, dims, spacing)
    m0 = prior.mean if isinstance(prior, StationaryPrior) else 0.0
    if method == "fft":
        out = _fft_posterior(operator, d, lam_full, m0, noise_std)
    elif method == "dense":
        a = operator if is_matrix else aslinearoperator(operator).matmat(np.eye(operator.shape[1]))
        out = _dense_posterior(np.asarray(a, dtype=float), d, lam_full, m0, noise_std, dims)
    else:
        if rng is None:
            raise ValueError("rng: the iterative path draws samples for the std; pass rng=np.random.default_rng(seed)")
        op = aslinearoperator(operator) if not is_matrix else aslinearoperator(operator)
        out = _iterative_posterior(op, d, lam_full, m0, noise_std, dims, rng, int(n_samples), tol, max_iter)
    mean, std, log_ev, aux, note = out
    return GaussianPosterior(mean=mean, std=std, log_evidence=log_ev, method=method, noise_std=float(noise_std),
                             note=note, dims=dims, spacing=spacing, _aux=aux)

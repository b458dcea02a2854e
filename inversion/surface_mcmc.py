"""The surface posterior by MCMC in a reduced basis: a check of the Laplace answer on small problems.

The basis is the likelihood-informed subspace at the MAP (Cui, Martin, Marzouk, Solonen and
Spantini, Inverse Problems 30, 2014): in the whitened heights ``z`` (prior ``N(0, I)``), the right
singular vectors ``U`` of the whitened Jacobian with the ``n_basis`` largest singular values.
The sampled parameters are their coefficients ``a`` (``z = U a + (I - U U^T) eps``) and the free
context parameters; the likelihood is the exact non-linear one (every frame's contact solved);
the complement ``(I - U U^T) eps``, ``eps ~ N(0, I)``, is the prior's (the data do not see it,
to first order) and is drawn exactly; the likelihood holds it at the MAP's (zero when the basis
spans the Jacobian's row space: the MAP's gradient condition puts ``z_map`` there). emcee runs
through :func:`~tactilab.inversion.sample_posterior`
(four ensembles, R-hat, ESS and autocorrelation stopping).
"""

from __future__ import annotations

import math

import numpy as np

from .sampler import sample_posterior

__all__ = ["SurfaceSubspacePosterior", "sample_surface"]


class SurfaceSubspacePosterior:
    """The surface posterior in the reduced basis, as a :class:`~tactilab.inversion.sampler.PosteriorModel`.

    Parameters
    ----------
    scan : ContactScan
    data : ndarray, shape (n_frames, n_out)
    noise_std : float
    basis : ndarray, shape (n, K)
        Orthonormal columns in the whitened heights.
    root : ndarray, shape (n, n)
        The prior covariance root (m).
    mean : float
        Prior mean height, m.
    z_map : ndarray, shape (n,)
        The whitened MAP heights (their component along the basis is the origin of ``a``).
    transforms : list of ContextTransform
    fixed : dict
    """

    def __init__(self, scan, data, noise_std, basis, root, mean, z_map, transforms, fixed):
        self.scan, self.data, self.noise_std = scan, np.asarray(data, dtype=float), float(noise_std)
        self.basis, self.root, self.mean = basis, root, float(mean)
        self.offset = z_map - basis @ (basis.T @ z_map)  # the MAP's part outside the basis, kept fixed
        self.start = np.concatenate([basis.T @ z_map, np.zeros(len(transforms))])
        self.transforms, self.fixed = list(transforms), dict(fixed)
        k = basis.shape[1]
        self.param_names = tuple(f"a{i}" for i in range(k)) + tuple(f"z_{t.name}" for t in self.transforms)
        self.observed = self.data.ravel()
        self.units = "a*, z_*: whitened (prior sd 1) coefficients of the reduced basis and the context"

    def _split(self, theta):
        k = self.basis.shape[1]
        return np.asarray(theta[:k], dtype=float), np.asarray(theta[k:], dtype=float)

    def heights(self, theta) -> np.ndarray:
        a, _ = self._split(theta)
        return self.mean + self.root @ (self.offset + self.basis @ a)

    def context(self, theta) -> dict | None:
        _, zc = self._split(theta)
        ctx = dict(self.fixed)
        for z, tr in zip(zc, self.transforms):
            v = float(tr.value(z))
            if not math.isfinite(v) or v < 0 or (tr.name != "friction" and v == 0):
                return None
            if not tr.gaussian and abs(z) > 1:
                return None
            ctx[tr.name] = v
        return ctx

    def log_prior(self, theta) -> float:
        a, zc = self._split(theta)
        if self.context(theta) is None:
            return -math.inf
        gauss = np.array([t.gaussian for t in self.transforms], dtype=bool)
        return -0.5 * float(a @ a) - 0.5 * float(np.sum(zc[gauss] ** 2))

    def log_likelihood(self, theta) -> np.ndarray:
        ctx = self.context(theta)
        if ctx is None:
            return np.full(self.data.size, -math.inf)
        out = self.scan.solve(self.heights(theta).reshape(self.scan.profile.shape), ctx).outputs
        r = (self.data - out).ravel() / self.noise_std
        return -0.5 * r * r - math.log(self.noise_std * math.sqrt(2 * math.pi))

    def initial(self, rng, n):
        """Candidates around the Laplace MAP (its coordinates, a spread of a tenth of the Laplace sd)."""
        scale = getattr(self, "scale", np.ones(self.start.size))
        return self.start + 0.1 * scale * rng.standard_normal((n, self.start.size))


def sample_surface(scan, data, noise_std, lap, root, mean, transforms, fixed, *, rng, n_basis: int = 8,
                   max_steps: int = 4000, check_every: int = 250, n_walkers: int | None = None, min_ess: float = 400.0,
                   tau_factor: float = 30.0, n_start: int = 16, max_draws: int = 4000) -> dict:
    """emcee on the reduced basis (module docstring); returns ``heights`` (N, n), ``context`` and a ``message``.

    ``max_draws`` caps the draws kept (each costs one more likelihood evaluation, for the tree's
    pointwise log-likelihood); the other options are :func:`~tactilab.inversion.sample_posterior`'s.
    """
    n = scan.profile.size
    k_ctx = len(transforms)
    J = lap.jacobian
    whitened = (J[:, :n] @ root) / noise_std
    _, s, vt = np.linalg.svd(whitened, full_matrices=False)
    keep = int(min(int(n_basis), int(np.sum(s > 1e-8 * s[0])) if s.size else 0))
    if keep < 1:
        raise ValueError("n_basis: the data inform no direction of the heights (a zero Jacobian); nothing to sample")
    basis = vt[:keep].T
    z_h = lap.z[:n]
    model = SurfaceSubspacePosterior(scan, data, noise_std, basis, root, mean, z_h, transforms, fixed)
    model.start = np.concatenate([basis.T @ z_h, lap.z[n:]])
    scale = np.concatenate([1.0 / np.sqrt(1.0 + s[:keep] ** 2), np.ones(k_ctx)])
    model.scale = scale
    tree = sample_posterior(model, rng, n_walkers=n_walkers, max_steps=max_steps, check_every=check_every,
                            min_ess=min_ess, tau_factor=tau_factor, n_start=n_start, info_tol=None,
                            max_draws=max_draws)
    post = tree["posterior"]
    theta = np.column_stack([np.asarray(post[q].values).reshape(-1) for q in model.param_names])
    a, zc = theta[:, :keep], theta[:, keep:]
    eps = rng.standard_normal((theta.shape[0], n))
    complement = eps - (eps @ basis) @ basis.T  # the prior's draws outside the basis
    z = a @ basis.T + complement
    heights = mean + z @ root.T
    context = {t.name: np.asarray(t.value(zc[:, i]), dtype=float) for i, t in enumerate(transforms)}
    return {"heights": heights, "context": context,
            "message": f"MCMC on a {keep}-vector likelihood-informed basis: {tree.attrs['message'].splitlines()[0]}",
            "tree": tree}

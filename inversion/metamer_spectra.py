"""What a stimulus family can and cannot resolve: singular spectra and Gaussian ambiguity.

The whitened readout map of a family is ``B = A * prior_std / noise_std`` (prior: independent
N(0, prior_std^2) parameters; noise: independent N(0, noise_std^2) readings). Its singular
values ``s`` say everything: a direction with ``s > 1`` is resolved (its signal beats the
noise), ``sum s^2 / (1 + s^2)`` is the effective number of resolved parameters, and
``1/2 sum log(1 + s^2)`` nats is the information the readouts carry about the parameters.

Periodic grid families read at every node are block-diagonal per Fourier mode: the spectrum is
assembled from one small SVD per mode (``GridLoadFamily.modes``), O(n log n) overall.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft
from numpy.typing import ArrayLike

from tactilab.forward import ReceptorHypothesis

from .metamer_families import FamilyStimulus, StimulusFamily, _check_hypothesis, require_linear, resolve_receptors
from .metamer_grids import GridLoadFamily
from .metamer_plots import plot_spectrum


def _mode_singular_values(m: np.ndarray) -> np.ndarray:
    """Singular values per mode, (n_modes, n_load) descending, zero-padded; closed forms for 1 or 2 loads."""
    n_modes, n_dc, n_load = m.shape
    if n_load == 1:
        return np.sqrt(np.einsum("mdl,mdl->ml", m.real, m.real) + np.einsum("mdl,mdl->ml", m.imag, m.imag))
    if n_load == 2:  # Gram eigenvalues; s1 s2 from the Lagrange identity (no cancellation)
        a = np.sum(np.abs(m[:, :, 0]) ** 2, axis=1)
        c = np.sum(np.abs(m[:, :, 1]) ** 2, axis=1)
        b = np.abs(np.sum(m[:, :, 0].conj() * m[:, :, 1], axis=1)) ** 2
        half, diff = 0.5 * (a + c), 0.5 * (a - c)
        big = half + np.sqrt(diff * diff + b)
        i, j = np.triu_indices(n_dc, 1)
        wedge = np.sum(np.abs(m[:, i, 0] * m[:, j, 1] - m[:, j, 0] * m[:, i, 1]) ** 2, axis=1)  # = s1^2 s2^2
        small = np.sqrt(wedge) / np.maximum(np.sqrt(big), np.finfo(float).tiny)
        return np.column_stack([np.sqrt(big), small])
    s = np.linalg.svd(m, compute_uv=False)
    return np.pad(s, ((0, 0), (0, n_load - s.shape[1])))


class _Whitened:
    """The whitened readout map of a family, per mode (periodic, all nodes) or dense."""

    def __init__(self, family, hypothesis, prior_std, receptors, what: str):
        h = _check_hypothesis(hypothesis)
        require_linear(h, what)
        if h.noise_std is None:
            raise ValueError(f"hypothesis: {what} needs noise_std (what counts as resolved is set by the noise); "
                             "give e.g. ReceptorHypothesis.parse('xx,zx@1.25mm;noise=1e-3')")
        try:
            tau = float(prior_std)
        except (TypeError, ValueError):
            raise ValueError(f"prior_std: expected one number in the family's parameter units, got {prior_std!r}") from None
        if not np.isfinite(tau) or tau <= 0:
            raise ValueError(f"prior_std: must be finite and > 0 (family parameter units), got {prior_std!r}")
        self.family, self.h, self.tau, self.scale = family, h, tau, tau / h.noise_std
        self.n_params = family.n_params
        self.receptors = receptors
        self.periodic = isinstance(family, GridLoadFamily) and family.periodic and family.all_nodes(receptors)
        if self.periodic:
            m, self.weight, self.rho = family.modes(h)
            self.m = m * self.scale
            self.s = _mode_singular_values(self.m)  # (n_modes, n_load)
            self.values = np.repeat(self.s.ravel(), np.repeat(self.weight.astype(int), self.s.shape[1]))
        else:
            self.a = family.matrix(h, receptors) * self.scale
            s = np.linalg.svd(self.a, compute_uv=False)
            self.values = np.pad(s, (0, self.n_params - s.size))
        self.values = np.sort(self.values)[::-1]

    def svd(self):
        """Full per-mode (or dense) SVD: u, s (zero-padded to n_load / n_params), vh."""
        if self.periodic:
            u, s, vh = np.linalg.svd(self.m, full_matrices=True)
            return u, np.pad(s, ((0, 0), (0, vh.shape[-1] - s.shape[1]))), vh
        u, s, vh = np.linalg.svd(self.a, full_matrices=True)
        return u, np.pad(s, (0, vh.shape[0] - s.size)), vh

    def vectors(self, select) -> np.ndarray:
        """Real right singular vectors (whitened = physical up to prior_std) where select(s) holds."""
        _, s, vh = self.svd()
        if not self.periodic:
            return vh[select(s)].T
        fam = self.family
        half = (*fam.shape[:-1], fam.shape[-1] // 2 + 1)
        picks = np.argwhere(select(s) & (self.weight[:, None] > 0))
        out = []
        for mode, j in picks:
            v = vh[mode, j].conj()
            v = v * np.exp(-1j * np.angle(v[np.argmax(np.abs(v))]))  # a real vector for self-conjugate modes
            parts = (v, 1j * v) if self.weight[mode] == 2 else (v,)
            for part in parts:
                spec = np.zeros((len(fam.loads), int(np.prod(half))), complex)
                spec[:, mode] = part
                x = sfft.irfftn(spec.reshape(len(fam.loads), *half), s=fam.shape,
                                axes=tuple(range(1, 1 + len(fam.shape)))).reshape(-1)
                out.append(x / np.linalg.norm(x))
        return np.array(out).T.reshape(self.n_params, len(out))

    def stats(self) -> dict:
        s2 = self.values ** 2
        return dict(information_nats=float(0.5 * np.sum(np.log1p(s2))),
                    null_energy_fraction=float(np.mean(1.0 / (1.0 + s2))))


@dataclass
class Subspace:
    """The resolvable and null subspaces of a family under a receptor hypothesis.

    Attributes
    ----------
    singular_values : ndarray, shape (n_params,)
        Of the whitened map ``A prior_std / noise_std``, descending, zero-padded.
    dimension : int
        Number of resolved directions (``s > 1``).
    effective_dof : float
        ``sum s^2 / (1 + s^2)``.
    information_nats : float
        ``1/2 sum log(1 + s^2)``.
    null_dimension : int
        Directions the readouts cannot see at all (``s <= rtol * s_max``).
    null_energy_fraction : float
        ``mean 1 / (1 + s^2)``: the fraction of the prior's variance the readouts leave
        unresolved (posterior trace / prior trace), counting exact null directions fully.
    wavenumber_edge : float or None
        Largest wavenumber (rad/m) with a resolved direction (periodic families; 0 if none).
    """

    singular_values: np.ndarray
    dimension: int
    effective_dof: float
    information_nats: float
    null_dimension: int
    null_energy_fraction: float
    wavenumber_edge: float | None
    rtol: float
    _whitened: _Whitened

    def basis(self, which: str = "resolvable") -> np.ndarray:
        """Orthonormal real basis, (n_params, k): "resolvable" (s > 1) or "null" (s <= rtol s_max)."""
        smax = self.singular_values[0] if self.singular_values.size else 0.0
        if which == "resolvable":
            return self._whitened.vectors(lambda s: s > 1.0)
        if which == "null":
            return self._whitened.vectors(lambda s: s <= self.rtol * smax)
        raise ValueError(f"which: must be 'resolvable' or 'null', got {which!r}")

    def plot(self, path) -> None:
        """The singular spectrum against the noise floor (s = 1)."""
        w = self._whitened
        plot_spectrum(self.singular_values, path, rho=w.rho if w.periodic else None,
                      mode_s=w.s if w.periodic else None,
                      title=f"{w.h}; prior std {w.tau:.3g} {w.family.param_units[0]} per parameter")


def resolvable_subspace(family: StimulusFamily, hypothesis: ReceptorHypothesis | str, prior_std: float,
                        receptors: ArrayLike | None = None, *, rtol: float = 1e-12) -> Subspace:
    """Singular spectrum of a family's whitened readout map, and what it resolves.

    Parameters
    ----------
    family : StimulusFamily
    hypothesis : ReceptorHypothesis or str
        Linear readouts with ``noise_std`` (nonlinear invariants are refused).
    prior_std : float
        Prior standard deviation of each parameter (the family's parameter units).
    receptors : array_like, optional
        Receptor positions (m); None: the family's grid nodes.
    rtol : float
        Singular values ``<= rtol * s_max`` count as exact nulls.

    Returns
    -------
    Subspace
        Periodic families read at every node are analysed per Fourier mode (O(n log n));
        other families through a dense SVD of their readout matrix.
    """
    w = _Whitened(family, hypothesis, prior_std, receptors, "resolvable_subspace")
    s = w.values
    smax = s[0] if s.size else 0.0
    edge = None
    if w.periodic:
        hit = (w.s > 1.0).any(axis=1) & (w.weight > 0)
        edge = float(w.rho[hit].max()) if hit.any() else 0.0
    stats = w.stats()
    return Subspace(s, int(np.sum(s > 1.0)), float(np.sum(s * s / (1.0 + s * s))), stats["information_nats"],
                    int(np.sum(s <= rtol * smax)), stats["null_energy_fraction"], edge, float(rtol), w)


@dataclass
class MetamerPosterior:
    """Gaussian posterior of a family's parameters: ``mean`` and marginal ``std`` (n_params,)."""

    mean: np.ndarray
    std: np.ndarray


@dataclass
class Ambiguity:
    """How many stimuli of a family are consistent with a target's readouts.

    ``information_nats`` (``1/2 sum log(1 + s^2)``), ``log_volume_ratio`` (log of posterior over
    prior volume, ``= -information_nats``), ``null_energy_fraction`` (posterior / prior variance
    trace), ``posterior`` (mean and std, parameter units); ``sample(n, rng)`` draws stimuli.
    """

    information_nats: float
    log_volume_ratio: float
    null_energy_fraction: float
    posterior: MetamerPosterior
    _whitened: _Whitened
    _z_mean: np.ndarray

    def sample(self, n: int, rng: np.random.Generator) -> list[FamilyStimulus]:
        """``n`` stimuli drawn from the posterior (each reads out like the target, within the noise)."""
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"n: number of samples must be an integer >= 1, got {n!r}")
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng: expected a numpy Generator (np.random.default_rng(seed)), got {type(rng).__name__}")
        w = self._whitened
        _, s, vh = w.svd()
        white = rng.standard_normal((n, w.n_params))
        if w.periodic:
            fam = w.family
            axes = tuple(range(2, 2 + len(fam.shape)))
            spec = sfft.rfftn(white.reshape(n, len(fam.loads), *fam.shape), axes=axes)
            spec = spec.reshape(n, len(fam.loads), -1).transpose(0, 2, 1)  # (n, modes, n_load)
            coef = np.einsum("mkl,nml->nmk", vh, spec) / np.sqrt(1.0 + s * s)
            spec = np.einsum("mkl,nmk->nml", vh.conj(), coef).transpose(0, 2, 1)
            half = (*fam.shape[:-1], fam.shape[-1] // 2 + 1)
            z = sfft.irfftn(spec.reshape(n, len(fam.loads), *half), s=fam.shape, axes=axes).reshape(n, -1)
        else:
            z = ((white @ vh.T) / np.sqrt(1.0 + s * s)) @ vh
        return [w.family.stimulus(w.tau * (self._z_mean + zi)) for zi in z]


def metamer_ambiguity(target: FamilyStimulus, family: StimulusFamily, hypothesis: ReceptorHypothesis | str,
                      prior_std: float, receptors: ArrayLike | None = None) -> Ambiguity:
    """The Gaussian posterior over ``family`` given the target's (noise-free) readouts.

    Parameters
    ----------
    target : FamilyStimulus
        The stimulus whose readouts are observed (any family).
    family : StimulusFamily
        The family the posterior is over.
    hypothesis : ReceptorHypothesis or str
        Linear readouts with ``noise_std``.
    prior_std : float
        Prior standard deviation of each parameter (family units).
    receptors : array_like, optional
        Receptor positions (m); None: the family's (else the target's) grid nodes.

    Returns
    -------
    Ambiguity
        Prior: independent N(0, prior_std^2) parameters; likelihood: independent readings with
        ``noise_std``; the posterior mean and marginal std are in the family's units.
    """
    if not isinstance(target, FamilyStimulus):
        raise ValueError(f"target: expected a FamilyStimulus, got {type(target).__name__}")
    receptors = resolve_receptors(receptors, family, target.family)
    w = _Whitened(family, hypothesis, prior_std, receptors, "metamer_ambiguity")
    y = target.readout(w.h, receptors) / w.h.noise_std
    u, s, vh = w.svd()
    if w.periodic:
        fam = family
        axes = tuple(range(1, 1 + len(fam.shape)))
        n_dc = w.m.shape[1]
        spec = sfft.rfftn(y.reshape(n_dc, *fam.shape), axes=axes).reshape(n_dc, -1).T
        k = min(n_dc, vh.shape[-1])
        coef = np.einsum("mdk,md->mk", u.conj()[:, :, :k], spec) * (s[:, :k] / (1 + s[:, :k] ** 2))
        zs = np.einsum("mkl,mk->ml", vh.conj()[:, :k], coef).T
        half = (*fam.shape[:-1], fam.shape[-1] // 2 + 1)
        z = sfft.irfftn(zs.reshape(len(fam.loads), *half), s=fam.shape, axes=axes).reshape(-1)
        var_mode = np.einsum("mkl,mk->ml", np.abs(vh) ** 2, 1.0 / (1.0 + s * s))  # (modes, n_load)
        var = (w.weight[:, None] * var_mode).sum(axis=0) / int(np.prod(fam.shape))
        std = w.tau * np.repeat(np.sqrt(var), int(np.prod(fam.shape)))
    else:
        k = min(u.shape[0], vh.shape[0])
        z = vh[:k].T @ ((s[:k] / (1 + s[:k] ** 2)) * (u[:, :k].T @ y))
        std = w.tau * np.sqrt(np.einsum("kp,k->p", vh ** 2, 1.0 / (1.0 + s * s)))
    stats = w.stats()
    return Ambiguity(stats["information_nats"], -stats["information_nats"], stats["null_energy_fraction"],
                     MetamerPosterior(w.tau * z, std), w, z)

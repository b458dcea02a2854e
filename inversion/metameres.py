"""Tactile metameres: stimuli that receptors cannot tell apart, measured (docs/metameres.md).

Given a receptor hypothesis (which strain readouts, at which depths, with which noise), two
stimuli are metameres when their readout vectors differ by less than the noise can resolve:
``dprime = ||r_a - r_b|| / noise_std < criterion``. Functions here find the best match of a
target within a family of stimuli (:func:`metamer_pair`), score pairs (:func:`compare_stimuli`),
group stimuli into classes (:func:`metamer_classes`), and measure what a family can and cannot
resolve (:func:`resolvable_subspace`, :func:`metamer_ambiguity`). Residuals are NOT squared:
``relative_residual = ||r_match - r_target|| / ||r_target||``. Readouts are ordered (depth,
component, receptor); strain shear is tensor unless the hypothesis says engineering.

Periodic grid families read at every node are block-diagonal per Fourier mode: their analysis
is one FFT of ``n_load`` impulse responses plus one small SVD per mode (never a dense SVD).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.fft as sfft
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.linalg import qr
from scipy.optimize import least_squares, lsq_linear
from scipy.spatial.distance import squareform
from scipy.special import ndtr

from numpy.typing import ArrayLike

from tactilab.forward import ReceptorHypothesis

from .metamer_families import (
    VOIGT,
    FamilyStimulus,
    SinusoidFamily,
    StimulusFamily,
    _check_hypothesis,
    check_families_memory,
    resolve_receptors,
)
from .metamer_grids import GridLoadFamily
from .metamer_plots import plot_pair
from .metamer_spectra import Ambiguity, Subspace, metamer_ambiguity, resolvable_subspace


# ----- scores ------------------------------------------------------------------------------
@dataclass(frozen=True)
class PairScore:
    """How well receptors tell two stimuli apart (dimensionless; None without a noise model)."""

    relative_residual: float
    dprime: float | None
    p_correct_2ifc: float | None
    metameric: bool | None


def _score(ra: np.ndarray, rb: np.ndarray, hypothesis: ReceptorHypothesis, criterion: float) -> PairScore:
    diff = float(np.linalg.norm(ra - rb))
    ref = float(np.linalg.norm(ra))
    rel = diff / ref if ref > 0 else (0.0 if diff == 0 else np.inf)
    if hypothesis.noise_std is None:
        return PairScore(rel, None, None, None)
    d = diff / hypothesis.noise_std
    return PairScore(rel, d, float(ndtr(d / np.sqrt(2.0))), bool(d < criterion))


def _check_stimulus(value, name: str) -> FamilyStimulus:
    if not isinstance(value, FamilyStimulus):
        raise ValueError(f"{name}: expected a FamilyStimulus (family.stimulus(params)), got {type(value).__name__}")
    return value


def compare_stimuli(a: FamilyStimulus, b: FamilyStimulus, hypothesis: ReceptorHypothesis | str,
                    receptors: ArrayLike | None, criterion: float = 1.0) -> PairScore:
    """Score two stimuli under a hypothesis.

    Parameters
    ----------
    a, b : FamilyStimulus
        The two stimuli (any families).
    hypothesis : ReceptorHypothesis or str
        Readouts; d' needs ``noise_std``.
    receptors : array_like or None
        Receptor positions, m, shape (n,) (plane families) or (n, 2); None: a grid family's nodes.
    criterion : float
        d' below which the pair is called metameric.

    Returns
    -------
    PairScore
        ``relative_residual`` is relative to ``a``'s readout norm (not squared).
    """
    h = _check_hypothesis(hypothesis)
    a, b = _check_stimulus(a, "a"), _check_stimulus(b, "b")
    r = resolve_receptors(receptors, a.family, b.family)
    return _score(a.readout(h, r), b.readout(h, r), h, criterion)


# ----- metamer pairs ------------------------------------------------------------------------
@dataclass
class MetamerPair:
    """The best match of a target within a family, and how far receptors can tell them apart.

    Attributes
    ----------
    target, match : FamilyStimulus
    params : ndarray, shape (n_params,)
        The match's parameters (``match.family.param_units``).
    relative_residual : float
        ``||r_match - r_target|| / ||r_target||`` (not squared).
    explained : float
        ``1 - relative_residual**2``: the fraction of the target readout's energy matched.
    dprime, p_correct_2ifc, chi2, metameric
        ``||diff|| / noise_std``, ``Phi(dprime / sqrt 2)``, ``dprime**2``, ``dprime < criterion``
        (None without a noise model).
    dof : int
        ``n_readouts - rank`` of the family's readout matrix (degrees of freedom of ``chi2``).
    per_component : dict
        Relative residual of each component's readouts (all depths and receptors).
    scan_rms : float or None
        Rms of the relative residual over the frames of a travelling scan (``scan_phases``).
    """

    target: FamilyStimulus
    match: FamilyStimulus
    params: np.ndarray
    relative_residual: float
    explained: float
    dprime: float | None
    p_correct_2ifc: float | None
    chi2: float | None
    dof: int
    metameric: bool | None
    per_component: dict
    scan_rms: float | None
    receptors: np.ndarray
    hypothesis: ReceptorHypothesis
    criterion: float = 1.0
    scan_residuals: np.ndarray | None = None
    target_readout: np.ndarray = field(default=None, repr=False)
    match_readout: np.ndarray = field(default=None, repr=False)

    def evaluate(self, other_hypothesis) -> PairScore:
        """Score the same two stimuli under another hypothesis (same receptors)."""
        return compare_stimuli(self.target, self.match, other_hypothesis, self.receptors, self.criterion)

    def to_dataset(self):
        """Readouts of target and match as an ``xarray.Dataset`` (depth, component, receptor)."""
        import xarray as xr

        h = self.hypothesis
        shape = (h.n_depths, h.n_components, -1)
        coords = {"depth": ("depth", np.array(h.depths), {"units": "m", "positive": "down"}),
                  "component": list(h.components)}
        rec = np.asarray(self.receptors)
        if rec.ndim == 1:
            coords["x"] = ("receptor", rec, {"units": "m", "long_name": "receptor position x"})
        dims = ("depth", "component", "receptor")
        attrs = {"units": "1", "shear_convention": h.shear}
        ds = xr.Dataset({"target": (dims, self.target_readout.reshape(shape),
                                    {**attrs, "long_name": "readout of the target stimulus"}),
                         "match": (dims, self.match_readout.reshape(shape),
                                   {**attrs, "long_name": "readout of the matching stimulus"}),
                         "params": ("param", self.params, {"units": ",".join(sorted(set(self.match.family.param_units)))})},
                        coords=coords)
        ds.attrs.update(hypothesis=str(h), relative_residual=self.relative_residual,
                        dprime=np.nan if self.dprime is None else self.dprime)
        return ds

    def plot(self, path) -> None:
        """Target vs match readouts against receptor position (mm), one panel per depth."""
        plot_pair(self, path)


def _solve(family, h, receptors, b, bounds, rcond):
    """Match parameters (linear hypothesis), the rank of the readout map, and its matrix (None per mode)."""
    periodic = getattr(family, "periodic", False) and isinstance(family, GridLoadFamily)
    if periodic and bounds is None and family.all_nodes(receptors):
        m, weight, _ = family.modes(h)
        u, s, vh = np.linalg.svd(m, full_matrices=False)
        keep = s > rcond * s.max() if s.size and s.max() > 0 else np.zeros_like(s, bool)
        axes = tuple(range(1, 1 + len(family.shape)))
        n_dc = m.shape[1]
        spec = sfft.rfftn(b.reshape(n_dc, *family.shape), axes=axes).reshape(n_dc, -1).T  # (modes, n_dc)
        coef = np.einsum("mdk,md->mk", u.conj(), spec)
        coef = np.where(keep, coef / np.where(keep, s, 1.0), 0.0)
        p = np.einsum("mkl,mk->ml", vh.conj(), coef).T.reshape(len(family.loads), *family.shape[:-1], -1)
        params = sfft.irfftn(p, s=family.shape, axes=axes).reshape(-1)
        return params, int((keep * weight[:, None]).sum()), None
    a = family.matrix(h, receptors)
    if bounds is None:
        params, _, rank, _ = np.linalg.lstsq(a, b, rcond=rcond)
        return params, int(rank), a
    # ||A x - b|| = ||R x - Q^T b|| + const: the bounded solve works on the small triangular factor
    q, r = qr(a, mode="economic") if a.shape[0] > a.shape[1] else (np.eye(a.shape[0]), a)
    res = lsq_linear(r, q.T @ b, bounds=bounds, method="trf", tol=1e-12)
    s = np.linalg.svd(r, compute_uv=False)
    return res.x, int(np.sum(s > rcond * s[0])) if s.size and s[0] > 0 else 0, a


def _bounds(bounds, family):
    if bounds == "family":
        return getattr(family, "bounds", None)
    if bounds is None:
        return None
    lo, hi = (np.broadcast_to(np.asarray(v, float), (family.n_params,)) for v in bounds)
    if np.any(lo > hi) or np.isnan(lo).any() or np.isnan(hi).any():
        raise ValueError(f"bounds: need lower <= upper (no NaN) for each of the {family.n_params} parameters")
    return lo, hi


def metamer_pair(target: FamilyStimulus, family: StimulusFamily, hypothesis: ReceptorHypothesis | str,
                 receptors: ArrayLike | None = None, *, bounds="family", rcond: float = 1e-10,
                 criterion: float = 1.0, scan_phases: ArrayLike | None = None) -> MetamerPair:
    """The stimulus of ``family`` whose readouts come closest to the target's.

    Parameters
    ----------
    target : FamilyStimulus
        The stimulus to match (any family).
    family : StimulusFamily
        Where the match is sought.
    hypothesis : ReceptorHypothesis or str
        Readouts; nonlinear invariants allowed (the linear full-strain match is refined with
        ``scipy.optimize.least_squares``).
    receptors : array_like, optional
        Receptor positions, m; None: the family's (else the target's) grid nodes.
    bounds : "family", None or (lower, upper)
        "family": the family's own bounds (e.g. a tractor's load limit); with bounds the match
        is a bounded least-squares solve (``lsq_linear``), without, a minimum-norm solve that
        drops singular values below ``rcond * s_max``.
    criterion : float
        d' below which the pair is called metameric.
    scan_phases : array_like, optional
        Spatial phases (rad) of a travelling target grating (``SinusoidFamily`` targets): each
        is an independent quasi-static frame, matched on its own; ``scan_rms`` is the rms of
        the frames' relative residuals.

    Returns
    -------
    MetamerPair
    """
    h = _check_hypothesis(hypothesis)
    target = _check_stimulus(target, "target")
    crit = float(criterion)
    if not np.isfinite(crit) or crit <= 0:
        raise ValueError(f"criterion: the d' threshold must be finite and > 0, got {criterion!r}")
    rc = float(rcond)
    if not 0 <= rc < 1:
        raise ValueError(f"rcond: must be in [0, 1), got {rcond!r}")
    r = resolve_receptors(receptors, family, target.family)
    check_families_memory(r, h, family, target.family)  # the memory rule, for the largest of them
    bnds = _bounds(bounds, family)
    b = target.readout(h, r)
    if not np.any(b):  # 0/0: every stimulus would "match", and the residual would read 0
        raise ValueError(f"hypothesis: {h} reads exactly 0 of the target at every receptor (volumetric strain in "
                         "an incompressible skin, nu = 0.5, is 0 for every surface traction), so any stimulus "
                         "matches it and there is no metamer to find; pick a hypothesis that reads the target, "
                         "e.g. deviatoric_norm or xx,zx")
    if h.linear:
        params, rank, a = _solve(family, h, r, b, bnds, rc)
    else:
        if family.n_params > 2000:
            raise ValueError(f"hypothesis: nonlinear invariants need a small family (n_params <= 2000), the "
                             f"{family.name} family has {family.n_params}; use linear components")
        full = ReceptorHypothesis(VOIGT, h.depths, h.noise_std)
        x0, _, a = _solve(family, full, r, target.readout(full, r), bnds, rc)
        a = None
        lo, hi = bnds if bnds is not None else (-np.inf, np.inf)
        x0 = np.clip(x0, lo, hi)
        scale = max(float(np.linalg.norm(b)), np.finfo(float).tiny)
        fit = least_squares(lambda p: (family.stimulus(p).readout(h, r) - b) / scale, x0, bounds=(lo, hi),
                            xtol=1e-12, ftol=1e-12, gtol=1e-12)
        params, rank = fit.x, min(family.n_params, b.size)
    match = family.stimulus(params)
    rm = a @ params if a is not None else match.readout(h, r)
    score = _score(b, rm, h, crit)
    per = {}
    nb, nm = b.reshape(h.n_depths, h.n_components, -1), rm.reshape(h.n_depths, h.n_components, -1)
    for c, name in enumerate(h.components):
        ref = np.linalg.norm(nb[:, c])
        per[name] = float(np.linalg.norm(nm[:, c] - nb[:, c]) / ref) if ref > 0 else float(np.linalg.norm(nm[:, c]))
    scan = None
    if scan_phases is not None:
        if not isinstance(target.family, SinusoidFamily):
            raise ValueError(f"scan_phases: a travelling scan needs a SinusoidFamily target, got the "
                             f"{target.family.name} family")
        phases = np.atleast_1d(np.asarray(scan_phases, dtype=float))
        if phases.size == 0 or not np.isfinite(phases).all():
            raise ValueError("scan_phases: give finite phases in rad, e.g. np.linspace(0, 2*np.pi, 32, endpoint=False)")
        scan = np.array([metamer_pair(target.family.with_phase(ph).stimulus(target.params), family, h, r,
                                      bounds=bounds, rcond=rc, criterion=crit).relative_residual for ph in phases])
    d = score.dprime
    return MetamerPair(target, match, params, score.relative_residual, 1.0 - score.relative_residual ** 2, d,
                       score.p_correct_2ifc, None if d is None else d * d, int(b.size - rank), score.metameric,
                       per, None if scan is None else float(np.sqrt(np.mean(scan ** 2))), np.asarray(r), h, crit,
                       scan, b, rm)


# ----- classes -------------------------------------------------------------------------------
@dataclass(frozen=True)
class MetamerClasses:
    """Labels (0, 1, ...) of metamer classes and the pairwise d' matrix (n, n)."""

    labels: np.ndarray
    dprime: np.ndarray


def metamer_classes(stimuli: list[FamilyStimulus], hypothesis: ReceptorHypothesis | str,
                    receptors: ArrayLike | None, criterion: float = 1.0) -> MetamerClasses:
    """Group stimuli so that every pair within a class has d' <= criterion (complete linkage).

    Parameters
    ----------
    stimuli : list of FamilyStimulus
        At least two stimuli.
    hypothesis : ReceptorHypothesis or str
        Readouts with ``noise_std`` (d' = readout distance / noise_std).
    receptors : array_like or None
        Receptor positions, m; None: the first grid family's nodes.
    criterion : float
        Largest d' allowed inside a class.

    Returns
    -------
    MetamerClasses
        ``labels`` (n,) int from 0, and the pairwise d' matrix (n, n).
    """
    h = _check_hypothesis(hypothesis)
    if h.noise_std is None:
        raise ValueError("hypothesis: metamer classes need noise_std (d' = ||diff|| / noise_std); "
                         "give e.g. ReceptorHypothesis(..., noise_std=1e-3)")
    stimuli = [_check_stimulus(s, f"stimuli[{i}]") for i, s in enumerate(stimuli)]
    if len(stimuli) < 2:
        raise ValueError(f"stimuli: give at least two stimuli to group, got {len(stimuli)}")
    r = resolve_receptors(receptors, *(s.family for s in stimuli))
    reads = np.array([s.readout(h, r) for s in stimuli])
    sq = np.sum(reads ** 2, axis=1)
    dist = np.sqrt(np.maximum(sq[:, None] + sq[None, :] - 2 * reads @ reads.T, 0.0)) / h.noise_std
    np.fill_diagonal(dist, 0.0)
    dist = 0.5 * (dist + dist.T)
    labels = fcluster(linkage(squareform(dist, checks=False), method="complete"), t=float(criterion),
                      criterion="distance")
    _, labels = np.unique(labels, return_inverse=True)
    return MetamerClasses(labels, dist)



__all__ = ["Ambiguity", "MetamerClasses", "MetamerPair", "PairScore", "Subspace", "compare_stimuli",
           "metamer_ambiguity", "metamer_classes", "metamer_pair", "resolvable_subspace"]

"""Choice of the Tikhonov strength by GCV, L-curve corner, discrepancy principle and evidence.

Every linear Tikhonov problem ``min ||A m - d||^2 + lam ||L m||^2`` is reduced once to its
spectral (generalised-singular-value) form :class:`SpectralForm`: per mode a ratio
``r = s^2`` (``|H(k)|^2 / |L(k)|^2`` in the FFT-diagonal case), the squared data coefficient
``c^2`` and a multiplicity ``w``. With filter factors ``f = r / (r + lam)`` every criterion is
a closed-form sum over the modes, O(n) per ``lam``:

- residual ``||A m - d||^2 = sum w (lam / (r + lam))^2 c^2 + resid0``,
- seminorm ``||L m||^2 = sum w r c^2 / (r + lam)^2``,
- GCV ``n ||A m - d||^2 / (n - sum w f)^2`` (Golub, Heath and Wahba 1979),
- discrepancy: ``||A m - d||^2 = tau^2 n sigma^2`` (Morozov),
- L-curve: corner = maximum curvature of ``(log residual, log seminorm)`` (Hansen 1992),
- evidence: the marginal likelihood of ``d`` under the Gaussian prior ``L m ~ N(0, sigma^2/lam)``,
  with ``sigma`` given or profiled out (Wahba's generalised maximum likelihood); modes in the
  null space of ``L`` carry an improper prior and are left out (restricted likelihood).
Modes with ``r = inf`` (null space of L, seen by A) are unregularised: ``f = 1``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from tactilab.core import rules

CRITERIA = ("gcv", "lcurve", "discrepancy", "evidence")

def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """Plain sum of products; einsum avoids BLAS threads, which stall on a busy machine."""
    return float(np.einsum("i,i->", a, b))


__all__ = ["CRITERIA", "SpectralForm", "CriteriaResult", "choose_lambda", "plot_criteria", "spread_warning"]


@dataclass
class SpectralForm:
    """Tikhonov problem in its diagonal form (see module docstring).

    Parameters
    ----------
    ratio : ndarray, shape (n_modes,)
        Squared generalised singular values ``r >= 0`` (``inf`` for modes free of penalty).
    coef2 : ndarray, shape (n_modes,)
        Squared data coefficients ``c^2``, in units of ``data_scale^2``.
    weights : ndarray, shape (n_modes,)
        Multiplicity of each mode (2 for a complex rfft mode standing for its mirror).
    n_data : int
        Number of data values.
    resid0 : float
        Squared norm of the data outside the range of A (never fitted), units of ``data_scale^2``.
    data_scale : float
        The data unit the coefficients are measured in (data units; default 1): the builders in
        :mod:`tactilab.inversion.linear` divide the data by its largest magnitude before squaring,
        so that data of 1e-300 or 1e200 neither underflow nor overflow. Every public method takes
        and returns data units; the sums run in the scaled units.

    Notes
    -----
    Every sum is written with the bounded factors ``t = lam / (r + lam)`` and ``r / (r + lam)``
    (both in [0, 1]) and the log determinant with ``logaddexp``, so no lam in (0, 1e308) overflows.
    """

    ratio: np.ndarray
    coef2: np.ndarray
    weights: np.ndarray
    n_data: int
    resid0: float = 0.0
    data_scale: float = 1.0
    _finite: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.data_scale) and self.data_scale > 0):
            raise ValueError(f"data_scale: must be finite and > 0 (data units), got {self.data_scale!r}")
        self.ratio = np.nan_to_num(np.asarray(self.ratio, dtype=float), nan=0.0, posinf=np.inf)
        self.coef2 = np.asarray(self.coef2, dtype=float)
        self.weights = np.asarray(self.weights, dtype=float)
        self._finite = np.isfinite(self.ratio)
        inf_w = self.weights[~self._finite]
        self.n_free = float(inf_w.sum())
        self._r = self.ratio[self._finite]
        with np.errstate(divide="ignore"):
            self._logr = np.log(self._r)
        self._c2 = self.coef2[self._finite]
        self._w = self.weights[self._finite]
        self._wc2 = self._w * self._c2
        self._cache: dict = {}
        # data outside the penalised modes that no lam can fit: the range complement
        self._resid_fixed = float(self.resid0)
        self.n_outside = float(self.n_data - self.weights.sum())
        with np.errstate(over="ignore"):
            self._scale2 = np.float64(self.data_scale) ** 2  # inf beyond 1e154: only the data-unit curves

    def lam_range(self) -> tuple[float, float]:
        """A bracket ``(lo, hi)`` of lam spanning all the informative ratios."""
        pos = self._r[self._r > 0]
        if pos.size == 0:
            return 1e-12, 1.0
        # ratios below 1e-20 of the largest are lost to rounding in the filter factors anyway
        lo = max(float(pos.min()), float(pos.max()) * 1e-20)
        return max(lo * 1e-4, 1e-300), min(float(pos.max()) * 1e4, 1e300)

    def _sums(self, lam: float) -> dict:
        """Every spectral sum the criteria need at one lam, in one fused pass (cached).

        With ``inv = 1 / (r + lam)``, ``t = lam inv`` and ``q = r inv`` (t + q = 1): residual
        ``sum wc2 t^2``, seminorm ``sum wc2 q inv``, dof ``sum w q``, evidence quadratic form
        ``sum wc2 t``, and the L-curve sums ``A_k = sum wc2 q t^k`` (k = 1, 2, 3) and
        ``B2 = sum wc2 q^2 t^2`` (scaled units).
        """
        hit = self._cache.get(float(lam))
        if hit is not None:
            return hit
        inv = 1.0 / (self._r + lam)
        t = lam * inv
        q = self._r * inv
        wq = self._wc2 * q
        t2 = t * t
        out = {
            "res": _dot(self._wc2, t2), "semi": _dot(wq, inv), "dof": _dot(self._w, q), "quad": _dot(self._wc2, t),
            "a1": _dot(wq, t), "a2": _dot(wq, t2), "a3": _dot(wq, t2 * t), "b2": _dot(wq * q, t2),
        }
        # log(1 + r/lam) = logaddexp(log r, log lam) - log lam: no overflow at any r or lam
        loglam = np.log(lam)
        out["logdet"] = _dot(self._w, np.logaddexp(self._logr, loglam)) - float(self._w.sum()) * loglam
        if len(self._cache) > 4096:
            self._cache.clear()
        self._cache[float(lam)] = out
        return out

    def _residual2_scaled(self, lam: float) -> float:
        return self._sums(lam)["res"] + self._resid_fixed

    def residual2(self, lam: float) -> float:
        """``||A m - d||^2`` in data units squared (inf beyond the float range; see residual_norm)."""
        with np.errstate(over="ignore"):
            return self._residual2_scaled(lam) * self._scale2

    def residual_norm(self, lam: float) -> float:
        """``||A m - d||`` in data units (finite wherever the data are)."""
        return float(self.data_scale * np.sqrt(self._residual2_scaled(lam)))

    def seminorm2(self, lam: float) -> float:
        with np.errstate(over="ignore"):
            return self._sums(lam)["semi"] * self._scale2

    def dof(self, lam: float) -> float:
        """Effective number of fitted parameters ``trace(influence matrix)``."""
        return self._sums(lam)["dof"] + self.n_free

    def _gcv_scaled(self, lam: float) -> float:
        free = max(self.n_data - self.dof(lam), 1e-150)
        return self.n_data * self._residual2_scaled(lam) / free / free

    def gcv(self, lam: float) -> float:
        with np.errstate(over="ignore"):
            return self._gcv_scaled(lam) * self._scale2

    def _n_eff(self) -> float:
        return float(self._w.sum()) + self.n_outside

    def _log_evidence_scaled(self, lam: float, noise_scaled: float | None) -> tuple[float, float]:
        sums = self._sums(lam)
        quad = sums["quad"] + self._resid_fixed
        n_eff = self._n_eff()
        if noise_scaled is None:
            noise_scaled = float(np.sqrt(max(quad / n_eff, np.finfo(float).tiny)))
        # quad / sigma^2 and log sigma^2 without forming sigma^2 (no under/overflow)
        ll = -0.5 * ((quad / noise_scaled) / noise_scaled + sums["logdet"]
                     + n_eff * (np.log(2 * np.pi) + 2 * np.log(noise_scaled)))
        return float(ll), noise_scaled

    def log_evidence(self, lam: float, noise_std: float | None = None) -> tuple[float, float]:
        """Log marginal likelihood (data units) and the noise std used (given or profiled).

        Only penalised modes and the range complement enter (restricted likelihood).
        Per mode the data variance is ``sigma^2 v`` with ``v = 1 + r / lam``.
        """
        scaled = None if noise_std is None else noise_std / self.data_scale
        ll, sig = self._log_evidence_scaled(lam, scaled)
        return ll - self._n_eff() * float(np.log(self.data_scale)), sig * self.data_scale

    def lcurve_curvature(self, lam: float) -> float:
        """Signed curvature of ``(log residual, log seminorm)`` against ``log lam``."""
        sums = self._sums(lam)
        rho = self._residual2_scaled(lam)
        if rho <= 0 or sums["a1"] <= 0:
            return 0.0
        u1 = 2.0 * sums["a2"] / rho
        v1 = -2.0 * sums["a2"] / sums["a1"]
        u2 = u1 + 2.0 * (sums["b2"] - 2.0 * sums["a3"]) / rho - u1 * u1
        v2 = v1 + 6.0 * sums["a3"] / sums["a1"] - v1 * v1
        return float((u1 * v2 - u2 * v1) / max((u1 * u1 + v1 * v1) ** 1.5, 1e-300))


@dataclass
class CriteriaResult:
    """The lam chosen by each criterion, with the curves for plotting.

    Attributes
    ----------
    lam : dict
        Criterion name -> chosen lam (NaN where it could not be applied, see ``notes``).
    grid : ndarray
        Lam grid of the curves.
    curves : dict
        ``"gcv"``, ``"residual2"``, ``"seminorm2"``, ``"curvature"``, ``"log_evidence"`` on ``grid``.
    noise_std : float
        Noise std used by the discrepancy principle (given, or estimated by the evidence).
    notes : dict
        Criterion -> remark (bracket hit, noise estimated, ...).
    spread : float
        max/min ratio of the finite choices.
    estimator : str
        How the curves were computed (closed-form spectral sums, or the stochastic estimators of
        the iterative path with their accuracy).
    errors : dict
        Standard errors of stochastic curves on ``grid`` (``"gcv"``, ``"dof"``, ``"log_evidence"``)
        and the lam ranges within 2 s.e. of each stochastic optimum (``"gcv_lam_range"``,
        ``"evidence_lam_range"``); empty for closed forms.
    """

    lam: dict
    grid: np.ndarray
    curves: dict
    noise_std: float
    notes: dict
    spread: float
    estimator: str = "closed-form spectral sums (exact)"
    errors: dict = field(default_factory=dict)


def spread_warning(chosen: dict, warn_factor: float, stacklevel: int = 3) -> float:
    """max/min of the finite choices; warn (UserWarning) when it exceeds ``warn_factor``."""
    vals = np.array([v for v in chosen.values() if np.isfinite(v) and v > 0])
    spread = float(vals.max() / vals.min()) if vals.size else float("nan")
    if vals.size > 1 and spread > warn_factor:
        listing = ", ".join(f"{k}={v:.3g}" for k, v in chosen.items())
        warnings.warn(
            f"regularisation criteria disagree by a factor {spread:.3g} (> {warn_factor:g}): {listing}; "
            "inspect the criteria plot and check the noise level",
            UserWarning,
            stacklevel=stacklevel,
        )
    return spread


def _refine(fun, grid: np.ndarray, values: np.ndarray) -> float:
    """Minimise ``fun(log lam)`` near the best grid point."""
    i = int(np.nanargmin(values))
    lo = np.log(grid[max(i - 1, 0)])
    hi = np.log(grid[min(i + 1, grid.size - 1)])
    if hi <= lo:
        return float(grid[i])
    res = minimize_scalar(fun, bounds=(lo, hi), method="bounded", options={"xatol": 1e-2})
    best = res.x if res.fun <= values[i] else np.log(grid[i])
    return float(np.exp(best))


def choose_lambda(
    form: SpectralForm,
    noise_std: float | None = None,
    criteria=CRITERIA,
    n_grid: int = 32,
    tau: float = 1.0,
    warn_factor: float = 10.0,
) -> CriteriaResult:
    """Choose the Tikhonov strength by each criterion (closed-form sums, O(n) per lam).

    Parameters
    ----------
    form : SpectralForm
        The problem in diagonal form (from :mod:`tactilab.inversion.linear`).
    noise_std : float or None
        Noise standard deviation in data units. ``None``: the evidence profiles it out and
        the discrepancy principle uses that estimate (said in ``notes``).
    criteria : iterable of str
        Subset of ``("gcv", "lcurve", "discrepancy", "evidence")``.
    n_grid : int
        Number of log-spaced lam values for the curves (each choice is then refined).
    tau : float
        Safety factor of the discrepancy principle, ``||r|| = tau sqrt(n) sigma``.
    warn_factor : float
        Warn (``UserWarning``) when the choices spread by more than this factor.

    Returns
    -------
    CriteriaResult
    """
    criteria = tuple(criteria)
    unknown = [c for c in criteria if c not in CRITERIA]
    if unknown or not criteria:
        raise ValueError(f"criteria: unknown or empty {criteria!r}; use a subset of {', '.join(CRITERIA)}")
    if noise_std is not None:
        rules.positive(noise_std, "noise_std", "data units", "or pass None to estimate it")
    scale = form.data_scale
    noise_s = None if noise_std is None else noise_std / scale  # in the form's scaled units
    if noise_s is not None and 0 < noise_s < 1e-100:
        raise ValueError(f"noise_std: {noise_std!r} is {noise_s:.3g} x the data's magnitude ({scale:.3g}), far below "
                         "the float rounding of the data (2.2e-16 relative); no criterion can use it: give the "
                         "real noise level, or None to estimate it")
    lo, hi = form.lam_range()
    grid = np.geomspace(lo, hi, n_grid)
    curves = {
        "residual2": np.array([form.residual2(x) for x in grid]),
        "seminorm2": np.array([form.seminorm2(x) for x in grid]),
    }
    chosen: dict = {}
    notes: dict = {}
    if "gcv" in criteria:
        gcv_s = np.array([form._gcv_scaled(x) for x in grid])
        with np.errstate(over="ignore"):
            curves["gcv"] = gcv_s * np.float64(scale) ** 2
        res_s = np.array([form._residual2_scaled(x) for x in grid])
        if np.ptp(gcv_s) <= 1e-9 * np.max(np.abs(gcv_s)) and np.ptp(res_s) <= 1e-12 * np.max(np.abs(res_s)):
            chosen["gcv"] = float(np.sqrt(lo * hi))
            notes["gcv"] = "lam has no effect on the fit here (no penalised mode is seen by the data); any lam does"
        elif np.ptp(gcv_s) <= 1e-9 * np.max(np.abs(gcv_s)):
            chosen["gcv"] = float("nan")
            notes["gcv"] = "GCV is flat in lam (e.g. a single datum: the residual and n - dof shrink together)"
        else:
            chosen["gcv"] = _refine(lambda t: form._gcv_scaled(np.exp(t)), grid, gcv_s)
    need_ev = "evidence" in criteria or ("discrepancy" in criteria and noise_std is None)
    if need_ev:
        ev_s = np.array([form._log_evidence_scaled(x, noise_s)[0] for x in grid])
        curves["log_evidence"] = ev_s - form._n_eff() * np.log(scale)
        lam_ev = _refine(lambda t: -form._log_evidence_scaled(np.exp(t), noise_s)[0], grid, -ev_s)
        if "evidence" in criteria:
            chosen["evidence"] = lam_ev
            if noise_std is None:
                notes["evidence"] = "noise std profiled out (generalised maximum likelihood)"
    sigma_s = noise_s if noise_s is not None else form._log_evidence_scaled(lam_ev, None)[1]
    sigma = sigma_s * scale
    if "lcurve" in criteria:
        curves["curvature"] = np.array([form.lcurve_curvature(x) for x in grid])
        inner = curves["curvature"].copy()
        inner[[0, -1]] = -np.inf  # a corner at the bracket's end is no corner
        if grid.size < 3 or not np.any(inner > 0):
            chosen["lcurve"] = float("nan")
            notes["lcurve"] = "no corner: the L-curve has no positive curvature inside the lam bracket"
        else:
            chosen["lcurve"] = _refine(lambda t: -form.lcurve_curvature(np.exp(t)), grid, -inner)
    if "discrepancy" in criteria:
        target = tau**2 * form.n_data * sigma_s**2
        f = lambda t: form._residual2_scaled(np.exp(t)) - target  # noqa: E731 (monotone in t)
        a, b = np.log(lo), np.log(hi)
        if f(a) >= 0:
            chosen["discrepancy"] = float(lo)
            notes["discrepancy"] = "residual exceeds the noise level even for the smallest lam"
        elif f(b) <= 0:
            chosen["discrepancy"] = float(hi)
            notes["discrepancy"] = "residual stays below the noise level: data carry no signal above noise"
        else:
            chosen["discrepancy"] = float(np.exp(brentq(f, a, b, xtol=1e-4)))
        if noise_std is None:
            notes["discrepancy"] = notes.get("discrepancy", "") + f" (noise std estimated by the evidence: {sigma:.3g})"
    spread = spread_warning(chosen, warn_factor, stacklevel=3)
    return CriteriaResult(lam=chosen, grid=grid, curves=curves, noise_std=float(sigma), notes=notes, spread=spread)


def plot_criteria(result: CriteriaResult, path, title: str = "Regularisation criteria", *,
                  data_unit: str = "data units") -> None:
    """Plot GCV, L-curve, discrepancy residual and evidence with each choice marked (PNG).

    ``data_unit`` names the unit of the data and residuals (e.g. "Pa", "strain"); the penalty norm is in
    the model's units times the penalty operator's.
    """
    from matplotlib.figure import Figure
    from matplotlib.ticker import LogLocator, NullFormatter

    fig = Figure(figsize=(9, 7))
    axes = fig.subplots(2, 2)
    g = result.grid
    colours = {"gcv": "C0", "lcurve": "C1", "discrepancy": "C2", "evidence": "C3"}

    def mark(ax, names):
        for name in names:
            if name in result.lam:
                ax.axvline(result.lam[name], color=colours[name], ls="--", label=f"{name}: {result.lam[name]:.3g}")

    ax = axes[0, 0]
    if "gcv" in result.curves:
        ax.loglog(g, result.curves["gcv"], "k-")
        if "gcv" in result.errors:  # stochastic estimate: +-2 s.e. band
            ax.fill_between(g, result.curves["gcv"] - 2 * result.errors["gcv"],
                            result.curves["gcv"] + 2 * result.errors["gcv"], color="0.8", label="+-2 s.e.")
    ax.set(xlabel="lambda (penalty weight)", ylabel=f"GCV ({data_unit}^2)", title="Generalised cross-validation")
    mark(ax, ["gcv"])
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    ax.loglog(np.sqrt(result.curves["residual2"]), np.sqrt(result.curves["seminorm2"]), "k.-", ms=3)
    ax.set(xlabel=f"residual norm ||Am-d|| ({data_unit})", ylabel="penalty norm ||Lm||", title="L-curve")
    for axis in (ax.xaxis, ax.yaxis):  # at most ~5 labelled decades, no labelled minor ticks: no overlap
        axis.set_major_locator(LogLocator(numticks=5))
        axis.set_minor_formatter(NullFormatter())
    if "lcurve" in result.lam:
        i = int(np.argmin(np.abs(np.log(g / result.lam["lcurve"]))))
        ax.plot(np.sqrt(result.curves["residual2"][i]), np.sqrt(result.curves["seminorm2"][i]), "o", color="C1",
                label="corner")
        ax.legend(fontsize=7)
    ax = axes[1, 0]
    ax.loglog(g, np.sqrt(result.curves["residual2"]), "k-")
    ax.set(xlabel="lambda", ylabel=f"residual norm ({data_unit})", title=f"Discrepancy (sigma={result.noise_std:.3g})")
    mark(ax, ["discrepancy"])
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    if "log_evidence" in result.curves:
        # relative to its maximum on a symlog axis: the evidence falls by ~1e6 nats at large lambda, which
        # would flatten the peak on a linear axis; within 1 nat of the top the axis is linear
        ev = result.curves["log_evidence"]
        top = float(np.nanmax(ev))
        ax.semilogx(g, ev - top, "k-")
        ax.set_yscale("symlog", linthresh=1.0)
        if "log_evidence" in result.errors:
            se = result.errors["log_evidence"]
            ax.fill_between(g, ev - top - 2 * se, ev - top + 2 * se, color="0.8", label="+-2 s.e.")
    ax.set(xlabel="lambda", ylabel="log evidence - its maximum (nats, symlog)", title="Marginal likelihood")
    mark(ax, ["evidence"])
    ax.legend(fontsize=7)
    fig.suptitle(title if not result.errors else f"{title} (stochastic estimates, iterative path)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)

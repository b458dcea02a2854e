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
        Squared data coefficients ``c^2`` (data units squared).
    weights : ndarray, shape (n_modes,)
        Multiplicity of each mode (2 for a complex rfft mode standing for its mirror).
    n_data : int
        Number of data values.
    resid0 : float
        Squared norm of the data outside the range of A (never fitted).
    """

    ratio: np.ndarray
    coef2: np.ndarray
    weights: np.ndarray
    n_data: int
    resid0: float = 0.0
    _finite: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.ratio = np.nan_to_num(np.asarray(self.ratio, dtype=float), nan=0.0, posinf=np.inf)
        self.coef2 = np.asarray(self.coef2, dtype=float)
        self.weights = np.asarray(self.weights, dtype=float)
        self._finite = np.isfinite(self.ratio)
        inf_w = self.weights[~self._finite]
        self.n_free = float(inf_w.sum())
        self._r = self.ratio[self._finite]
        self._c2 = self.coef2[self._finite]
        self._w = self.weights[self._finite]
        self._wc2 = self._w * self._c2
        self._wc2r = self._wc2 * self._r
        self._wc2rr = self._wc2r * self._r
        self._wr = self._w * self._r
        self._cache: dict = {}
        # data outside the penalised modes that no lam can fit: the range complement
        self._resid_fixed = float(self.resid0)
        self.n_outside = float(self.n_data - self.weights.sum())

    def lam_range(self) -> tuple[float, float]:
        """A bracket ``(lo, hi)`` of lam spanning all the informative ratios."""
        pos = self._r[self._r > 0]
        if pos.size == 0:
            return 1e-12, 1.0
        # ratios below 1e-20 of the largest are lost to rounding in the filter factors anyway
        lo = max(float(pos.min()), float(pos.max()) * 1e-20)
        return lo * 1e-4, float(pos.max()) * 1e4

    def _sums(self, lam: float) -> dict:
        """Every spectral sum the criteria need at one lam, in one fused pass (cached).

        With ``inv = 1 / (r + lam)``: residual ``lam^2 sum wc2 inv^2``, seminorm
        ``sum wc2 r inv^2``, dof ``sum w r inv``, evidence quadratic form ``lam sum wc2 inv``, and
        the L-curve derivatives ``sum wc2 r inv^3``, ``sum wc2 r inv^4``, ``sum wc2 r^2 inv^4``.
        """
        hit = self._cache.get(float(lam))
        if hit is not None:
            return hit
        den = self._r + lam
        inv = 1.0 / den
        inv2 = inv * inv
        inv4 = inv2 * inv2
        out = {
            "c_inv": float(_dot(self._wc2, inv)), "c_inv2": float(_dot(self._wc2, inv2)),
            "cr_inv2": float(_dot(self._wc2r, inv2)), "r_inv": float(_dot(self._wr, inv)),
            "cr_inv3": float(_dot(self._wc2r, inv2 * inv)), "cr_inv4": float(_dot(self._wc2r, inv4)),
            "crr_inv4": float(_dot(self._wc2rr, inv4)),
        }
        # log(1 + r/lam) = log(r + lam) - log(lam): one log per mode, always computed so that
        # every criterion at this lam is served by this single pass
        out["logdet"] = float(_dot(self._w, np.log(den))) - float(self._w.sum()) * np.log(lam)
        if len(self._cache) > 4096:
            self._cache.clear()
        self._cache[float(lam)] = out
        return out

    def residual2(self, lam: float) -> float:
        return lam * lam * self._sums(lam)["c_inv2"] + self._resid_fixed

    def seminorm2(self, lam: float) -> float:
        return self._sums(lam)["cr_inv2"]

    def dof(self, lam: float) -> float:
        """Effective number of fitted parameters ``trace(influence matrix)``."""
        return self._sums(lam)["r_inv"] + self.n_free

    def gcv(self, lam: float) -> float:
        return self.n_data * self.residual2(lam) / max(self.n_data - self.dof(lam), 1e-300) ** 2

    def log_evidence(self, lam: float, noise_std: float | None = None) -> tuple[float, float]:
        """Log marginal likelihood and the noise std used (given or profiled).

        Only penalised modes and the range complement enter (restricted likelihood).
        Per mode the data variance is ``sigma^2 v`` with ``v = 1 + r / lam``.
        """
        sums = self._sums(lam)
        quad = lam * sums["c_inv"] + self._resid_fixed
        n_eff = float(self._w.sum()) + self.n_outside
        if noise_std is None:
            var = max(quad / n_eff, np.finfo(float).tiny)
        else:
            var = noise_std**2
        ll = -0.5 * (quad / var + sums["logdet"] + n_eff * np.log(2 * np.pi * var))
        return ll, float(np.sqrt(var))

    def lcurve_curvature(self, lam: float) -> float:
        """Signed curvature of ``(log residual, log seminorm)`` against ``log lam``."""
        sums = self._sums(lam)
        rho = self.residual2(lam)
        eta = sums["cr_inv2"]
        if rho <= 0 or eta <= 0:
            return 0.0
        eta_l = -2.0 * sums["cr_inv3"]
        eta_ll = 6.0 * sums["cr_inv4"]
        rho_l = -lam * eta_l
        rho_ll = 2.0 * (sums["crr_inv4"] - 2 * lam * sums["cr_inv4"])
        u1 = lam * rho_l / rho
        v1 = lam * eta_l / eta
        u2 = u1 + lam * lam * rho_ll / rho - u1 * u1
        v2 = v1 + lam * lam * eta_ll / eta - v1 * v1
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
    if noise_std is not None and not (np.isfinite(noise_std) and noise_std > 0):
        raise ValueError(f"noise_std: must be finite and > 0 (data units), got {noise_std!r}; or pass None to estimate it")
    lo, hi = form.lam_range()
    grid = np.geomspace(lo, hi, n_grid)
    curves = {
        "residual2": np.array([form.residual2(x) for x in grid]),
        "seminorm2": np.array([form.seminorm2(x) for x in grid]),
    }
    chosen: dict = {}
    notes: dict = {}
    if "gcv" in criteria:
        curves["gcv"] = np.array([form.gcv(x) for x in grid])
        chosen["gcv"] = _refine(lambda t: form.gcv(np.exp(t)), grid, curves["gcv"])
    need_ev = "evidence" in criteria or ("discrepancy" in criteria and noise_std is None)
    if need_ev:
        curves["log_evidence"] = np.array([form.log_evidence(x, noise_std)[0] for x in grid])
        lam_ev = _refine(lambda t: -form.log_evidence(np.exp(t), noise_std)[0], grid, -curves["log_evidence"])
        if "evidence" in criteria:
            chosen["evidence"] = lam_ev
            if noise_std is None:
                notes["evidence"] = "noise std profiled out (generalised maximum likelihood)"
    sigma = noise_std if noise_std is not None else form.log_evidence(lam_ev, None)[1]
    if "lcurve" in criteria:
        curves["curvature"] = np.array([form.lcurve_curvature(x) for x in grid])
        inner = curves["curvature"].copy()
        inner[[0, -1]] = -np.inf  # a corner at the bracket's end is no corner
        chosen["lcurve"] = _refine(lambda t: -form.lcurve_curvature(np.exp(t)), grid, -inner)
    if "discrepancy" in criteria:
        target = tau**2 * form.n_data * sigma**2
        f = lambda t: form.residual2(np.exp(t)) - target  # noqa: E731 (monotone in t)
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


def plot_criteria(result: CriteriaResult, path, title: str = "Regularisation criteria") -> None:
    """Plot GCV, L-curve, discrepancy residual and evidence with each choice marked (PNG)."""
    from matplotlib.figure import Figure

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
    ax.set(xlabel="lambda (penalty weight)", ylabel="GCV (data units^2)", title="Generalised cross-validation")
    mark(ax, ["gcv"])
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    ax.loglog(np.sqrt(result.curves["residual2"]), np.sqrt(result.curves["seminorm2"]), "k.-", ms=3)
    ax.set(xlabel="residual norm ||Am-d|| (data units)", ylabel="penalty norm ||Lm||", title="L-curve")
    if "lcurve" in result.lam:
        i = int(np.argmin(np.abs(np.log(g / result.lam["lcurve"]))))
        ax.plot(np.sqrt(result.curves["residual2"][i]), np.sqrt(result.curves["seminorm2"][i]), "o", color="C1",
                label="corner")
        ax.legend(fontsize=7)
    ax = axes[1, 0]
    ax.loglog(g, np.sqrt(result.curves["residual2"]), "k-")
    ax.set(xlabel="lambda", ylabel="residual norm (data units)", title=f"Discrepancy (sigma={result.noise_std:.3g})")
    mark(ax, ["discrepancy"])
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    if "log_evidence" in result.curves:
        ax.semilogx(g, result.curves["log_evidence"], "k-")
        if "log_evidence" in result.errors:
            ev, se = result.curves["log_evidence"], result.errors["log_evidence"]
            ax.fill_between(g, ev - 2 * se, ev + 2 * se, color="0.8", label="+-2 s.e.")
    ax.set(xlabel="lambda", ylabel="log evidence", title="Marginal likelihood")
    mark(ax, ["evidence"])
    ax.legend(fontsize=7)
    fig.suptitle(title if not result.errors else f"{title} (stochastic estimates, iterative path)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)

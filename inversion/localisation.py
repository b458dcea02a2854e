"""Defect localisation accuracy vs number of sensors and stress components (docs/theory.md 4b).

For the point-defect scan model (:class:`DefectScanModel`) with Gaussian noise, the Fisher
information of ``theta = (x0, y0, S_d)`` is ``I = J^T J / sigma^2`` with ``J`` the Jacobian of the
noise-free signal ``S_d g(x0, y0)`` (central differences for x0, y0; exact ``g`` for S_d). The
Cramer-Rao bound ``sd(x0) >= sqrt((I^-1)_00)`` is reported with the defect area as a nuisance
parameter, next to the posterior sd from emcee (flat priors) when asked.
"""

from __future__ import annotations

import numpy as np

from tactilab.core import rules

from .mcmc import sample_scene_posterior
from .scene_params import NONLINEAR, DefectScanModel, Normal, Uniform

__all__ = ["cramer_rao", "square_sensors", "localisation_study", "plot_localisation", "DEFAULT_SCENE"]

DEFAULT_SCENE = dict(x0=0.3e-3, y0=0.2e-3, friction=0.5, depth=3e-3, young_modulus=1e6, normal_force=0.8)


def square_sensors(n_side: int, spacing: float = 1e-3) -> np.ndarray:
    """``n_side x n_side`` sensor grid (finger frame) centred on the contact, shape (n_side**2, 2), m."""
    if int(n_side) < 1:
        raise ValueError(f"n_side: need at least 1 sensor per side, got {n_side!r}")
    c = (np.arange(int(n_side)) - (int(n_side) - 1) / 2) * spacing
    xx, yy = np.meshgrid(c, c)
    return np.column_stack([xx.ravel(), yy.ravel()])


def cramer_rao(model: DefectScanModel, params: dict, area: float, noise_std: float, step: float = 1e-7) -> dict:
    """Cramer-Rao lower bounds on sd(x0), sd(y0) (m) with the defect area as nuisance.

    Returns
    -------
    dict
        ``sd_x0``, ``sd_y0`` (m), ``fisher`` (3 x 3, order x0, y0, area).
    """
    rules.positive(noise_std, "noise_std", "Pa", "give the sensors' noise standard deviation")
    if not (np.isfinite(area) and area != 0):
        raise ValueError(f"area: defect area must be finite and non-zero (m^2), got {area!r}")
    missing = [k for k in NONLINEAR if k not in params]
    if missing:
        raise ValueError(f"params: missing {missing}; give every one of {NONLINEAR} in SI units")
    cols = []
    for name in ("x0", "y0"):
        up = dict(params, **{name: params[name] + step})
        dn = dict(params, **{name: params[name] - step})
        cols.append(area * (model.design(up)[0] - model.design(dn)[0]) / (2 * step))
    cols.append(model.design(params)[0])
    jac = np.column_stack(cols)
    fisher = jac.T @ jac / noise_std**2
    cov = np.linalg.pinv(fisher)
    return {"sd_x0": float(np.sqrt(cov[0, 0])), "sd_y0": float(np.sqrt(cov[1, 1])), "fisher": fisher}


def localisation_study(n_sides=(1, 2, 3, 4), components_sets=(("zz",), ("zx", "zz")), *, params=None,
                       area: float = 5e-8, noise_std: float = 10.0, n_times: int = 41, mcmc: bool = False,
                       rng: np.random.Generator | None = None, sampler_options: dict | None = None):
    """Table of CRB (and optionally emcee posterior sd) of the defect position per configuration.

    Parameters
    ----------
    n_sides : sequence of int
        Sensor grids of ``n x n`` (1 mm spacing).
    components_sets : sequence of tuple of str
        Stress components measured by every sensor.
    params : dict, optional
        Scene parameters (default :data:`DEFAULT_SCENE`: 0.8 N, E = 1 MPa, 3 mm deep, mu = 0.5).
    area : float
        Defect area S_d in m^2 (signal amplitude).
    noise_std : float
        Noise sd per sample, Pa.
    n_times : int
        Scan samples over +-6 mm.
    mcmc : bool
        Also sample the posterior (needs ``rng``); flat priors on x0, y0 (+-3 mm, +-2 mm).

    Returns
    -------
    pandas.DataFrame
        Columns ``n_sensors``, ``components``, ``crb_sd_x0_um``, ``crb_sd_y0_um`` and, with mcmc,
        ``post_sd_x0_um``, ``post_sd_y0_um``, ``post_mean_x0_um``, ``post_mean_y0_um``, ``converged``.
    """
    import pandas as pd

    params = dict(DEFAULT_SCENE if params is None else params)
    if mcmc and rng is None:
        raise ValueError("rng: the posterior widths need emcee; pass rng=np.random.default_rng(seed)")
    u = np.linspace(-6e-3, 6e-3, int(n_times))
    rows = []
    for comps in components_sets:
        for n_side in n_sides:
            model = DefectScanModel(u, square_sensors(n_side), comps)
            crb = cramer_rao(model, params, area, noise_std)
            row = {"n_sensors": n_side**2, "components": "+".join(comps), "crb_sd_x0_um": crb["sd_x0"] * 1e6,
                   "crb_sd_y0_um": crb["sd_y0"] * 1e6}
            if mcmc:
                data = model.simulate(params, area).ravel() + rng.normal(0, noise_std, model.n_data)
                priors = dict(params, x0=Uniform(-3e-3, 3e-3), y0=Uniform(-2e-3, 2e-3))
                res = sample_scene_posterior(model, data, noise_std, priors, Normal(0.0, 10 * area), rng=rng,
                                             **(sampler_options or {}))
                post = res.tree["posterior"]
                row.update(post_sd_x0_um=float(post["x0"].std()) * 1e6, post_sd_y0_um=float(post["y0"].std()) * 1e6,
                           post_mean_x0_um=float(post["x0"].mean()) * 1e6,
                           post_mean_y0_um=float(post["y0"].mean()) * 1e6, converged=res.converged)
            rows.append(row)
    return pd.DataFrame(rows)


def plot_localisation(table, path) -> None:
    """CRB (lines) and posterior sd (markers, if present) of x0 and y0 vs number of sensors (PNG)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4))
    axes = fig.subplots(1, 2, sharey=True)
    for ax, coord in zip(axes, ("x0", "y0")):
        for i, (comps, grp) in enumerate(table.groupby("components", sort=False)):
            ax.loglog(grp["n_sensors"], grp[f"crb_sd_{coord}_um"], "-", color=f"C{i}", label=f"CRB, {comps}")
            if f"post_sd_{coord}_um" in grp:
                ax.loglog(grp["n_sensors"], grp[f"post_sd_{coord}_um"], "o", color=f"C{i}",
                          label=f"posterior sd (emcee), {comps}")
        ax.set(xlabel="number of sensors", ylabel=f"sd of {coord} (um)", title=f"Defect localisation: {coord}")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)

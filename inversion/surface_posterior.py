"""The posterior of a surface inversion: the profile's mean, spread, draws, bands, files and figure.

Heights in m (positive towards the skin), coordinates in m (world frame), SI throughout; the
figure uses mm along the surface and um for heights. Touched nodes (in contact in some frame) carry
the Laplace (or sampled) posterior; untouched ones the prior conditioned on the touched nodes and
on the skin's upper bound (:mod:`tactilab.inversion.surface_bound`), from draws.
"""

from __future__ import annotations

import pathlib
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import norm

from .surface_plots import plot_surface

__all__ = ["SurfacePosterior", "CONTEXT_UNITS"]

#: units and long names of the context parameters
CONTEXT_UNITS = {"normal_force": ("N", "normal force of the finger"), "friction": ("1", "friction coefficient"),
                 "young_modulus": ("Pa", "Young's modulus of the skin")}


@dataclass
class SurfacePosterior:
    """Posterior of the touched surface (see the module docstring).

    Attributes
    ----------
    x : ndarray, shape (nx,)
        World x of the profile nodes, m.
    y : ndarray or None
        World y of the nodes (``"patch"``), m.
    mean, std : ndarray, shape ``(nx,)`` or ``(ny, nx)``
        Posterior mean and standard deviation of the heights, m (NaN at untouched nodes without a prior).
    map : ndarray
        The MAP heights, m.
    touched : ndarray of bool
        Nodes in contact in some frame.
    upper_bound : ndarray
        At untouched nodes, the height the surface stayed below (m, the other nodes at the MAP); NaN elsewhere.
    context : dict
        Free context parameter -> ``{"mean", "sd", "q05", "q95", "map", "units"}`` (SI).
    resolvable_band : dict
        ``k_max`` (rad/m), ``wavelength_min`` (m), ``fraction``: the Fourier modes whose posterior
        variance is below half the prior's (or, without a prior, below the MAP's variance).
    noise_std : float
        Data units.
    chi2 : float
        Sum of squared normalised residuals at the MAP (about the number of data when the model fits).
    n_data : int
    method : str
        ``"laplace"`` or ``"mcmc"``.
    message : str
        How the MAP search ended and how the posterior was computed.
    truth : ndarray or None
        The true heights, when known (simulated scans), m.
    """

    x: np.ndarray
    y: np.ndarray | None
    mean: np.ndarray
    std: np.ndarray
    map: np.ndarray
    touched: np.ndarray
    upper_bound: np.ndarray
    context: dict
    resolvable_band: dict
    noise_std: float
    chi2: float
    n_data: int
    method: str
    message: str
    draws: np.ndarray = field(repr=False)
    context_draws: dict = field(repr=False, default_factory=dict)
    truth: np.ndarray | None = field(default=None, repr=False)
    _sampler: object = field(default=None, repr=False)

    def __repr__(self) -> str:
        ctx = "; ".join(f"{k} = {v['mean']:.4g} +- {v['sd']:.2g} {v['units']}" for k, v in self.context.items())
        touched = float(np.mean(self.touched))
        return (f"SurfacePosterior(method={self.method!r}, {self.geometry} of {self.touched.size} nodes at "
                f"{self.spacing * 1e6:.3g} um, touched {100 * touched:.3g} %, median sd (touched) "
                f"{np.median(self.std[self.touched]) * 1e6 if self.touched.any() else float('nan'):.3g} um, "
                f"resolved wavelengths >= {self.resolvable_band['wavelength_min'] * 1e3:.3g} mm, chi2 "
                f"{self.chi2:.4g} / {self.n_data} data{'; ' + ctx if ctx else ''})")

    @property
    def geometry(self) -> str:
        return "line" if self.y is None else "patch"

    @property
    def spacing(self) -> float:
        """Node spacing along x, m."""
        return float(self.x[1] - self.x[0]) if self.x.size > 1 else 0.0

    @property
    def touched_fraction(self) -> float:
        return float(np.mean(self.touched))

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` new posterior draws of the heights, shape ``(n, *mean.shape)``, m."""
        if int(n) != n or n < 1:
            raise ValueError(f"n: need a positive whole number of draws, got {n!r}")
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng: expected a numpy Generator (np.random.default_rng(seed)), got {rng!r}")
        heights, _ = self._sampler(int(n), rng)
        return heights

    def band(self, level: float = 0.9) -> tuple[np.ndarray, np.ndarray]:
        """Central credible band of probability ``level`` at every node, ``(lower, upper)`` in m.

        Touched nodes: the Gaussian quantiles of their marginal; untouched ones: the quantiles of the
        constrained draws (without a prior: ``-inf`` up to the bound).
        """
        if not (0 < level < 1):
            raise ValueError(f"level: the band's probability must lie in (0, 1), got {level!r}")
        z = norm.ppf(0.5 + level / 2)
        lower, upper = self.mean - z * self.std, self.mean + z * self.std
        u = ~self.touched
        if u.any():
            if np.isnan(self.mean[u]).all():
                lower[u], upper[u] = -np.inf, self.upper_bound[u]
            else:
                q = np.quantile(self.draws, [0.5 - level / 2, 0.5 + level / 2], axis=0)
                lower[u], upper[u] = q[0][u], q[1][u]
        return lower, upper

    def relief(self, level: float = 0.9) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The relief: every draw minus its mean over the touched nodes (the level a scan at a given force
        cannot measure), as ``(sd, lower, upper)`` per node, m: what the data say about the shape.

        Without a prior the heights already are this relief and only touched nodes have draws.
        """
        if not (0 < level < 1):
            raise ValueError(f"level: the band's probability must lie in (0, 1), got {level!r}")
        flat = self.draws.reshape(self.draws.shape[0], -1)
        rel = flat - flat[:, self.touched.reshape(-1)].mean(axis=1, keepdims=True)
        q = np.quantile(rel, [0.5 - level / 2, 0.5 + level / 2], axis=0)
        shape = self.mean.shape
        return rel.std(axis=0, ddof=1).reshape(shape), q[0].reshape(shape), q[1].reshape(shape)

    # ---------------------------------------------------------------- files
    @property
    def tree(self):
        """An arviz ``DataTree``: ``posterior`` (height draws, dims chain, draw, [y,] x; context
        draws), ``profile`` (mean, sd, MAP, 90 % band, touched, upper bound, truth), CF-style attrs."""
        import arviz_base as azb

        dims_h = ["x"] if self.y is None else ["y", "x"]
        post = {"height": self.draws[None]}
        for name, d in self.context_draws.items():
            post[name] = np.asarray(d)[None]
        coords = {"x": self.x} if self.y is None else {"x": self.x, "y": self.y}
        tree = azb.from_dict({"posterior": post}, dims={"height": dims_h}, coords=coords,
                             attrs={"/": self._attrs()})
        tree["posterior"]["height"].attrs.update(units="m", long_name="surface height (positive towards the skin)")
        for name in self.context_draws:
            units, long_name = CONTEXT_UNITS[name]
            tree["posterior"][name].attrs.update(units=units, long_name=long_name)
        for c in coords:
            tree["posterior"][c].attrs.update(units="m", long_name=f"world {c} of the profile node")
        tree["profile"] = self._profile_dataset()
        return tree

    def _attrs(self) -> dict:
        attrs = dict(method=self.method, message=self.message, geometry=self.geometry, noise_std=self.noise_std,
                     chi2=self.chi2, n_data=self.n_data, touched_fraction=self.touched_fraction,
                     resolvable_k_max_rad_per_m=self.resolvable_band["k_max"],
                     resolvable_wavelength_min_m=self.resolvable_band["wavelength_min"],
                     conventions="heights in m, positive towards the skin; world frame; SI")
        for name, d in self.context.items():
            for key in ("mean", "sd", "q05", "q95", "map"):
                attrs[f"{name}_{key}"] = float(d[key])
        return attrs

    def _profile_dataset(self):
        import xarray as xr

        dims = ("x",) if self.y is None else ("y", "x")
        lower, upper = self.band(0.9)
        data = {"mean": (self.mean, "m", "posterior mean height"), "sd": (self.std, "m", "posterior sd of the height"),
                "map": (self.map, "m", "maximum a posteriori height"),
                "lower_90": (lower, "m", "lower edge of the central 90 % band"),
                "upper_90": (upper, "m", "upper edge of the central 90 % band"),
                "touched": (self.touched.astype(np.uint8), "1", "node in contact in some frame (1)"),
                "upper_bound": (self.upper_bound, "m", "height the surface stayed below (untouched nodes)")}
        if self.truth is not None:
            data["truth"] = (np.asarray(self.truth), "m", "true height (simulated scan)")
        coords = {"x": ("x", self.x, {"units": "m", "long_name": "world x of the profile node"})}
        if self.y is not None:
            coords["y"] = ("y", self.y, {"units": "m", "long_name": "world y of the profile node"})
        return xr.Dataset({k: (dims, v, {"units": u, "long_name": ln}) for k, (v, u, ln) in data.items()},
                          coords=coords)

    def to_netcdf(self, path) -> pathlib.Path:
        """Write :attr:`tree` to a netCDF4/HDF5 file (h5netcdf engine); returns the path."""
        path = pathlib.Path(path)
        self.tree.to_netcdf(path, engine="h5netcdf")
        return path

    def plot(self, path, truth=None) -> pathlib.Path:
        """Save a PNG: the profile with its 90 % band against the truth (when known), the untouched
        stretches shaded with their upper bound, and the posterior sd; mm along x, um for heights."""
        return plot_surface(self, pathlib.Path(path), self.truth if truth is None else np.asarray(truth))

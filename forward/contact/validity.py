"""How far the cheap texture models are from the solved contact: an error estimate per scene.

Two cheap models turn a texture of heights h into interfacial pressure without solving the contact:

- ``"linear"``: the superposition that full contact implies, the local (finger's) mean pressure
  plus the texture's ``E* |k| H~ / 2``, clipped at 0 (:func:`linear_pressure`);
- ``"modulation"``: docs/theory.md 4b, ``p_bar max(0, 1 + h / h_ref)`` with ``h_ref`` the texture's
  peak |height| by default, as the scenes use it (:func:`modulation_pressure`).

:func:`interface_model_errors` measures each against the solved contact on one periodic cell of
the texture pressed at the local mean pressure, through the sensor: the strain at ``depth`` under
the three pressures (the half-space's exact periodic transfer), error = max |eps_model - eps_exact|
/ max |eps_exact| per component (a component's scale at least 1e-3 of the largest component's, as
the scenes measure their error), the largest over the components. It is an ESTIMATE for a scene,
not a bound: a fingertip's pressure varies over the contact, so call it at the pressures that
matter (the peak and the mean), and its discretisation is that of the cell given. Its coverage on
``benchmarks/bench_interface_models.py`` (sinusoids against Westergaard's closed form, random rough
surfaces against a solve on a grid twice as fine) is in docs/scenes.md ("Validity of the cheap
texture models"). Full contact is decided from the spectrum alone: the linear pressure is the exact
one wherever it stays >= 0 (``mean_pressure >= full_contact_pressure``), and no solve is needed.
"""

from __future__ import annotations

import numpy as np

from tactilab.core import rules

from ..halfspace import HalfSpace, SurfaceLoad, pressure_from_deflection
from .solve import solve_contact

_VOIGT = ("xx", "yy", "zz", "yz", "zx", "xy")
#: a component's signal is measured against at least this share of the largest component's (the
#: scenes' rule: eps_yy vanishes at nu = 1/2 and has no relative error of its own)
_SIGNAL_FLOOR = 1e-3


def _cell(heights, spacing) -> tuple[np.ndarray, tuple[float, ...]]:
    h = rules.finite_array(heights, "heights", "m")
    if h.ndim not in (1, 2) or min(h.shape) < 4 or any(n % 2 for n in h.shape):
        raise ValueError(f"heights: need one periodic cell of shape (nx,) or (ny, nx), an even number >= 4 of "
                         f"nodes per axis, got shape {h.shape}; crop or resample the texture")
    return h, rules.spacing(spacing, h.ndim)


def _spacing_arg(spacing: tuple[float, ...]):
    return spacing[0] if len(spacing) == 1 else spacing


def linear_pressure(heights, spacing, mean_pressure: float, E: float, nu: float = 0.5) -> np.ndarray:
    """The full-contact superposition ``max(0, p_bar + E* |k| H~ / 2)`` (Pa), shape of ``heights``.

    Parameters
    ----------
    heights : ndarray, shape (nx,) or (ny, nx)
        One period of the texture, m, positive towards the skin.
    spacing : float or (float, float)
        Node spacing in m, x first.
    mean_pressure : float
        p_bar, the local mean (finger) pressure in Pa.
    E : float
        Young's modulus in Pa.
    nu : float
        Poisson's ratio in (-1, 0.5].
    """
    h, sp = _cell(heights, spacing)
    pm = rules.positive(mean_pressure, "mean_pressure", "Pa", "give the local mean pressure in Pa")
    texture = pressure_from_deflection(h, _spacing_arg(sp), E, nu).p
    return np.maximum(pm + texture, 0.0)


def modulation_pressure(heights, mean_pressure: float, reference_height: float | None = None) -> np.ndarray:
    """docs/theory.md 4b's ``p_bar max(0, 1 + h / h_ref)`` (Pa); ``h_ref`` defaults to max |h| (m)."""
    h = rules.finite_array(heights, "heights", "m")
    pm = rules.positive(mean_pressure, "mean_pressure", "Pa", "give the local mean pressure in Pa")
    peak = float(np.abs(h).max())
    if reference_height is None and peak == 0:
        return np.full(h.shape, pm)
    h_ref = peak if reference_height is None else rules.positive(reference_height, "reference_height", "m")
    return pm * np.clip(1.0 + h / h_ref, 0.0, None)


def full_contact_pressure(heights, spacing, E: float, nu: float = 0.5) -> float:
    """The mean pressure (Pa) above which the texture is in full contact: ``max(-E* |k| H~ / 2)``.

    For a sinusoid of amplitude Delta and period L it is Westergaard's ``pi E* Delta / L``.
    """
    h, sp = _cell(heights, spacing)
    return float(max(0.0, -pressure_from_deflection(h, _spacing_arg(sp), E, nu).p.min()))


def _strain(skin: HalfSpace, p: np.ndarray, spacing, depth: float, components) -> np.ndarray:
    field = skin.strain(SurfaceLoad(p=p, spacing=spacing, periodic=True), [depth], components=components)
    return field.data["strain"].isel(depth=0).transpose("component", ...).values


def _relative_errors(model: np.ndarray, exact: np.ndarray) -> float:
    """max over components of max |model - exact| / max |exact|, each scale floored at _SIGNAL_FLOOR of the largest."""
    scale = np.abs(exact).reshape(exact.shape[0], -1).max(axis=1)
    diff = np.abs(model - exact).reshape(exact.shape[0], -1).max(axis=1)
    if scale.max() == 0:  # no signal at all (a flat cell under a uniform pressure at nu = 1/2): nothing to miss
        return float("inf") if (diff > 0).any() else 0.0
    return float((diff / np.maximum(scale, _SIGNAL_FLOOR * scale.max())).max())


def interface_model_errors(heights, spacing, mean_pressure: float, E: float, nu: float = 0.5,
                           depth: float = 1e-3, *, components=_VOIGT, reference_height: float | None = None,
                           tol: float = 1e-8) -> dict[str, float]:
    """Estimated sensor error of the ``"linear"`` and ``"modulation"`` models on a periodic texture cell.

    The texture is pressed at ``mean_pressure`` by the exact periodic contact solver (skipped in
    full contact, where the linear model is exact); the strain at ``depth`` under each model's
    pressure is compared with that under the solved pressure (module docstring). When each axis
    has a multiple of 4 nodes (at least 16), the same is done on every other node; the estimate is
    1.05 x (the error + twice its change) + 1e-6, a margin for the cell's own discretisation whose
    coverage the benchmark measures. Cost: about 1.25 periodic solves of the cell (0.05 s at 256^2 nodes)
    and six strain fields.

    Parameters
    ----------
    heights : ndarray, shape (nx,) or (ny, nx)
        One period of the texture (m, positive towards the skin), an even number >= 4 of nodes per
        axis; 1-D is a plane-strain profile.
    spacing : float or (float, float)
        Node spacing in m, x first.
    mean_pressure : float
        The local mean (finger) pressure in Pa, > 0.
    E : float
        Young's modulus in Pa.
    nu : float
        Poisson's ratio in (-1, 0.5].
    depth : float
        Sensor depth in m (> 0).
    components : sequence of str
        Strain components compared (default all six; those without a signal are left out).
    reference_height : float, optional
        The modulation's h_ref in m; default the texture's peak |height| (as scenes do).
    tol : float
        The contact solver's tolerance.

    Returns
    -------
    dict
        ``"linear"``, ``"modulation"``: max |error| / max |signal| of the strain (dimensionless);
        ``"full_contact_pressure"``: p* of the texture (Pa); ``"load_ratio"``: mean_pressure / p*
        (inf for a flat cell); ``"contact_fraction"``: of the solved contact.

    Raises
    ------
    ValueError
        For a bad cell (shape, NaN), spacing, pressure, modulus, Poisson's ratio, depth or component.
    """
    h, sp = _cell(heights, spacing)
    pm = rules.positive(mean_pressure, "mean_pressure", "Pa", "give the local mean pressure in Pa")
    depth = rules.depth(depth)
    components = rules.components(components)
    if reference_height is not None:
        reference_height = rules.positive(reference_height, "reference_height", "m")
    skin = HalfSpace(E, nu)
    fine = _cell_errors(skin, h, sp, pm, depth, components, reference_height, tol)
    out = dict(fine)
    change = dict.fromkeys(("linear", "modulation"), 0.0)
    if all(n % 4 == 0 and n >= 16 for n in h.shape):  # the margin: the same cell on every other node
        coarse = _cell_errors(skin, h[(slice(None, None, 2),) * h.ndim], tuple(2 * d for d in sp), pm, depth,
                              components, reference_height, tol)
        change = {name: abs(fine[name] - coarse[name]) for name in change}
    for name in change:
        out[name] = _SAFETY * (fine[name] + _MARGIN * change[name]) + _FLOOR
    return out


#: the estimate is _SAFETY x (the cell's error + _MARGIN x its change on every other node) + _FLOOR;
#: the constants are those the benchmark's coverage was measured with (docs/scenes.md)
_MARGIN, _SAFETY, _FLOOR = 2.0, 1.05, 1e-6


def _cell_errors(skin, h, sp, pm, depth, components, reference_height, tol) -> dict[str, float]:
    """The errors of one cell, as measured (no margin)."""
    spacing_arg = _spacing_arg(sp)
    p_star = full_contact_pressure(h, spacing_arg, skin.E, skin.nu)
    linear = linear_pressure(h, spacing_arg, pm, skin.E, skin.nu)
    if pm >= p_star:  # full contact: the superposition is the solution (p >= 0 and gap 0 everywhere)
        exact, fraction = linear, 1.0
    else:
        sol = solve_contact(skin, h.max() - h, spacing_arg, mean_pressure=pm, periodic=True, tol=tol)
        exact, fraction = sol.pressure, float(sol.contact_fraction)
    eps_exact = _strain(skin, exact, spacing_arg, depth, components)
    out = {name: _relative_errors(_strain(skin, p, spacing_arg, depth, components), eps_exact)
           for name, p in (("linear", linear), ("modulation", modulation_pressure(h, pm, reference_height)))}
    out["full_contact_pressure"] = p_star
    out["load_ratio"] = pm / p_star if p_star > 0 else float("inf")
    out["contact_fraction"] = fraction
    return out

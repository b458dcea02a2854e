"""Exact periodic spectral solution of the elastic half-space (docs/theory.md section 2).

For each Fourier mode of the surface tractions the stress at depth z is

    sigma~(xi, eta, z) = E0 * exp(-rho z) + E1 * (rho z) exp(-rho z),

where the depth-independent coefficient spectra ``E0`` and ``E1`` are linear in the load
spectra (P~, Qx~, Qy~) and depend only on the direction (c, s) = (xi, eta)/rho and nu.
They are written out per Voigt component in :func:`_table_uncached`; the rotated-frame
formulas of docs/theory.md were multiplied out once, so no per-mode rotation is done.

Numerical care:
- ``exp(-rho z)`` is computed directly (never as a ratio), so rho z up to 1e4 and beyond
  underflows harmlessly to 0.
- The rho = 0 mode uses its direction-averaged limit (c^2 = s^2 = 1/2, odd terms 0): it
  carries the total load. In 1-D (plane strain) c^2 = 1, s = 0, which gives
  sigma_xx -> -P~(0).
- Terms odd in xi (eta) vanish on the Nyquist column (row) of an even-sized grid: that
  mode is its own mirror image, so only the average of +/- k is real-consistent. This
  makes the map exactly real-linear, and its adjoint the conjugate multiplier.
- nu enters only as a coefficient: nu = 0.5 is exact.

Fourier convention: f~ = sum f exp(-i (xi x + eta y)) (numpy's forward FFT), xi in rad/m.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
import scipy.fft as sfft

from . import _hotpath
from tactilab.core import jit
from tactilab.core import rules as check
from tactilab.core.rules import COMPONENTS as VOIGT
from ._hotpath import clear_transfer_cache  # noqa: F401  (re-export)
from .loads import SurfaceLoad


def angular_wavenumbers(shape: Sequence[int], spacing, half: bool = False) -> tuple[np.ndarray, ...]:
    """Angular wavenumbers (rad/m) of a periodic grid, x first: ``(xi, eta)``.

    The one wavenumber helper of the solver and the inversion (numpy's FFT convention,
    ``k = 2 pi * fftfreq(n, h)``). Axis order is always x first, whatever the array layout:
    arrays are stored ``(ny, nx)``, so in 2-D ``xi`` varies along the last axis and ``eta``
    along the first, and the two broadcast to the grid.

    Parameters
    ----------
    shape : (nx,) or (ny, nx)
        Real-space grid shape.
    spacing : float or (dx,) or (dx, dy)
        Grid spacing in m, x first (as :class:`SurfaceLoad.spacing`); one value means dx = dy.
    half : bool
        False (default): the full grid in ``fftfreq`` order. True: the ``rfftn`` half
        spectrum along x (``nx // 2 + 1`` non-negative xi).

    Returns
    -------
    tuple of ndarray, rad/m
        1-D: ``(xi,)`` of shape (nx,) (or (nx//2 + 1,) with ``half``).
        2-D: ``(xi, eta)`` of shapes (1, nx) and (ny, 1) (xi: (1, nx//2 + 1) with ``half``).
    """
    shape = tuple(int(n) for n in shape)
    if len(shape) not in (1, 2) or min(shape) < 1:
        raise ValueError(f"shape: expected a 1-D (nx,) or 2-D (ny, nx) grid of positive sizes, got {shape}; "
                         "give (nx,) or (ny, nx)")
    steps = check.spacing(spacing, len(shape))
    nx = shape[-1]
    xi = 2 * np.pi * (sfft.rfftfreq(nx, steps[0]) if half else sfft.fftfreq(nx, steps[0]))
    if len(shape) == 1:
        return (xi,)
    eta = 2 * np.pi * sfft.fftfreq(shape[0], steps[1])
    return xi[None, :], eta[:, None]


def _half_wavenumbers(shape: tuple[int, ...], spacing) -> tuple[np.ndarray, np.ndarray | None]:
    """``(xi, eta)`` of the rfft half spectrum, eta None in 1-D (the solver's internal form)."""
    ks = angular_wavenumbers(shape, spacing, half=True)
    return ks[0], (ks[1] if len(ks) == 2 else None)


@functools.lru_cache(maxsize=8)
def _cached_geometry(shape: tuple, spacing: tuple, dtype_name: str) -> "_Geometry":
    xi, eta = _half_wavenumbers(shape, spacing)
    return _Geometry(xi, eta, nyquist_x=shape[-1] % 2 == 0, nyquist_y=len(shape) == 2 and shape[0] % 2 == 0,
                     dtype=np.dtype(dtype_name))


class _Geometry:
    """Direction cosines of every mode, with the rho = 0 and Nyquist rules applied."""

    def __init__(self, xi: np.ndarray, eta: np.ndarray | None, nyquist_x: bool, nyquist_y: bool,
                 dtype=np.float64):
        self.tables: dict = {}
        if eta is None:  # plane strain: n = sign(xi) e_x
            self.rho = np.abs(xi).astype(dtype)
            self.c_odd = np.sign(xi).astype(dtype)
            if nyquist_x:
                self.c_odd[..., -1] = 0.0
            self.s_odd = np.zeros_like(self.rho)
            self.c2 = np.ones_like(self.rho)
            self.s2 = np.zeros_like(self.rho)
            self.cs_odd = np.zeros_like(self.rho)
            return
        rho = np.hypot(xi, eta)
        with np.errstate(invalid="ignore", divide="ignore"):
            c = np.where(rho > 0, xi / rho, 0.0)
            s = np.where(rho > 0, eta / rho, 0.0)
        zero = rho == 0
        self.rho = rho.astype(dtype)
        self.c2 = np.where(zero, 0.5, c * c).astype(dtype)
        self.s2 = np.where(zero, 0.5, s * s).astype(dtype)
        c_odd, s_odd = c.copy(), s.copy()
        if nyquist_x:
            c_odd[:, -1] = 0.0
        if nyquist_y:
            s_odd[eta.shape[0] // 2, :] = 0.0
        self.c_odd = c_odd.astype(dtype)
        self.s_odd = s_odd.astype(dtype)
        self.cs_odd = (c_odd * s_odd).astype(dtype)


_TABLE_CACHE_MAX_MODES = 2**18  # cache coefficient tables only while they stay small (memory)
_TABLE_CACHE_MAX_ENTRIES = 24  # six components at four Poisson ratios; a sweep over nu must not grow it


def _table(g: _Geometry, nu: float, component: str):
    """Coefficient table of one component, cached on the geometry for small grids."""
    if g.rho.size > _TABLE_CACHE_MAX_MODES:
        return _table_uncached(g, nu, component)
    key = (float(nu), component)
    if key not in g.tables:
        if len(g.tables) >= _TABLE_CACHE_MAX_ENTRIES:
            del g.tables[next(iter(g.tables))]  # oldest first
        g.tables[key] = _table_uncached(g, nu, component)
    return g.tables[key]


def _table_uncached(g: _Geometry, nu: float, component: str):
    """The coefficient table of one stress component (docs/theory.md s2, multiplied out).

    Returns a list of ``(which, load, kind, coef)``: the component's spectrum is
    E0 e^{-rho z} + E1 (rho z) e^{-rho z} with ``E_which = sum coef * L~`` over the load
    components, ``kind`` saying whether ``coef`` multiplies L~ as a real or an imaginary
    number. Each coefficient is purely real or purely imaginary, so they are stored as real
    arrays (or scalars) and the factor 1j is applied once per sum.
    """
    c, s, c2, s2, cs = g.c_odd, g.s_odd, g.c2, g.s2, g.cs_odd
    if component == "zz":  # E0 = -P, E1 = -(P - i q_par)
        return [(0, "p", "re", -1.0), (1, "p", "re", -1.0), (1, "qx", "im", c), (1, "qy", "im", s)]
    if component == "xx":  # E1 = c2 (P - i q_par)
        return [(0, "p", "re", -(c2 + 2 * nu * s2)), (0, "qx", "im", 2 * c * (c2 + (1 + nu) * s2)),
                (0, "qy", "im", 2 * nu * s * s2),
                (1, "p", "re", c2), (1, "qx", "im", -c * c2), (1, "qy", "im", -s * c2)]
    if component == "yy":  # E1 = s2 (P - i q_par)
        return [(0, "p", "re", -(s2 + 2 * nu * c2)), (0, "qx", "im", 2 * nu * c * c2),
                (0, "qy", "im", 2 * s * (s2 + (1 + nu) * c2)),
                (1, "p", "re", s2), (1, "qx", "im", -c * s2), (1, "qy", "im", -s * s2)]
    if component == "xy":
        return [(0, "p", "re", (2 * nu - 1) * cs), (0, "qx", "im", s * (c2 * (1 - 2 * nu) + s2)),
                (0, "qy", "im", c * (s2 * (1 - 2 * nu) + c2)),
                (1, "p", "re", cs), (1, "qx", "im", -s * c2), (1, "qy", "im", -c * s2)]
    if component == "zx":
        return [(0, "qx", "re", -1.0), (1, "p", "im", c), (1, "qx", "re", c2), (1, "qy", "re", cs)]
    if component == "yz":
        return [(0, "qy", "re", -1.0), (1, "p", "im", s), (1, "qx", "re", cs), (1, "qy", "re", s2)]
    raise ValueError(f"components: unknown component {component!r}; use one of {VOIGT}")


def _real_coefficients(g: _Geometry, nu: float, spectra: dict, row: np.ndarray) -> dict:
    """{(load, kind): [a0, a1]}: real coefficient arrays (or scalars) of one output row.

    Each load's contribution to a stress component is either real (even in the wavenumber)
    or imaginary (odd) in both E0 and E1, so its multiplier at depth z,
    a0 e^{-rho z} + a1 rho z e^{-rho z}, is formed with real arithmetic.
    """
    nonzero = np.flatnonzero(row)
    coefs: dict = {}
    for j in nonzero:
        for which, name, kind, coef in _table(g, nu, VOIGT[j]):
            if name not in spectra:
                continue
            pair = coefs.setdefault((name, kind), [0.0, 0.0])
            scaled = coef if row[j] == 1.0 else row[j] * coef  # unit rows reuse the cached table
            pair[which] = scaled if np.ndim(pair[which]) == 0 and pair[which] == 0.0 else pair[which] + scaled
    return coefs


def multiplier(g: _Geometry, nu: float, load_component: str, row: np.ndarray, depth: float) -> np.ndarray:
    """Exact complex multiplier from one load component to the output ``row @ sigma_voigt``.

    The same coefficient table as :func:`periodic_stress`, for operators and transfer functions.
    """
    rz = g.rho * depth
    e = np.exp(-rz)
    rze = rz * e
    out = np.zeros(g.rho.shape, dtype=np.result_type(g.rho.dtype, np.complex64))
    for (_, kind), (a0, a1) in _real_coefficients(g, nu, {load_component}, np.asarray(row, float)).items():
        m = a0 * e + a1 * rze
        out += m if kind == "re" else 1j * m
    return out


def _point_phases(shape, spacing, points: np.ndarray):
    """Fourier phases of off-grid points: (Ex (n_kx, n), Ey (ny, n) or None, column weights)."""
    nx = shape[-1]
    xi, eta = _half_wavenumbers(shape, spacing)
    # FFT index coordinates: node j sits at x = (j - nx//2) dx, i.e. x' = x + (nx//2) dx
    xp = points[:, 0] + (nx // 2) * spacing[0]
    ex = np.exp(1j * np.outer(np.ravel(xi), xp))
    w = np.full(nx // 2 + 1, 2.0)
    w[0] = 1.0
    if nx % 2 == 0:
        w[-1] = 1.0  # Nyquist: real part only (the average of +/- k)
    ex *= w[:, None]
    if len(shape) == 1:
        return ex, None
    yp = points[:, 1] + (shape[0] // 2) * spacing[1]
    ey = np.exp(1j * np.outer(np.ravel(eta), yp))
    return ex, ey


def _eval_points(spectrum: np.ndarray, phases, n_total: int) -> np.ndarray:
    """Exact trigonometric interpolant of an rfft half spectrum at off-grid points."""
    ex, ey = phases
    if ey is None:
        return (spectrum @ ex).real / n_total
    return np.einsum("yp,yp->p", ey, spectrum @ ex).real / n_total


def periodic_stress(load: SurfaceLoad, depths: Sequence[float], nu: float,
                    weights: np.ndarray, dtype=np.float64, workers: int | None = None,
                    points: np.ndarray | None = None) -> np.ndarray:
    """Linear combinations of the stress of a periodic load at several depths.

    Parameters
    ----------
    load : SurfaceLoad
        One period of the load (the grid is the period), tractions in Pa.
    depths : sequence of float
        Depths z > 0 in m.
    nu : float
        Poisson's ratio.
    weights : ndarray, shape (n_out, 6)
        Each output is ``weights[o] @ sigma_voigt``; identity rows select stress components,
        Hooke rows give strains.
    dtype : float32 or float64
        Working precision (float32 halves memory and FFT time, error ~1e-6 relative).
    workers : int, optional
        FFT threads. None (default): scipy's default, one thread unless the call sits inside
        ``scipy.fft.set_workers(n)``; -1: all CPUs. The result is bitwise the same for any
        number of threads.
    points : ndarray, shape (n, 2) or (n, 1), optional
        Off-grid evaluation points (x, y) in m: the exact trigonometric interpolant is
        summed there (cost n x n_modes) instead of the inverse FFT.

    Returns
    -------
    ndarray, shape (n_depth, n_out, *load.shape) or (n_depth, n_out, n)
    """
    dtype = np.dtype(dtype)
    cdtype = np.result_type(dtype, np.complex64)
    workers = _hotpath.threads(workers)
    shape = load.shape
    grid_key = (tuple(shape), tuple(load.spacing), dtype.name)
    g = _cached_geometry(*grid_key)
    names = tuple(sorted(load.components))
    n_spec = len(names)
    # work arrays: the load spectra, then two accumulators (reused between calls, see _hotpath)
    block = _hotpath.work_block(g.rho.shape, cdtype, n_spec + 2)
    spectra = {}  # one forward FFT per load component, reused for every depth and output
    for name, buf in zip(names, block):
        _hotpath.rfftn_into(load.components[name].astype(dtype, copy=False), buf, workers)
        spectra[name] = buf
    acc, term = block[n_spec], block[n_spec + 1]
    fused = jit.enabled()  # the compiled multiply-add (tactilab.core.jit), or its NumPy twin
    weights = np.atleast_2d(np.asarray(weights, dtype=float))
    out_shape = shape if points is None else (len(points),)
    out = np.empty((len(depths), weights.shape[0], *out_shape), dtype=dtype)
    phases = None if points is None else _point_phases(shape, load.spacing, np.asarray(points, float))
    for d, z in enumerate(depths):
        tables = _hotpath.depth_tables(g, grid_key, nu, names, weights, z, dtype, cdtype, _real_coefficients,
                                       fused)
        for o, terms in enumerate(tables):  # per output: its (load, multiplier) pairs, cached
            if fused:
                spectrum = _hotpath.apply_fused(terms, block[:n_spec], acc)
            else:
                spectrum = _hotpath.apply(terms, spectra, acc, term)
            if phases is None:
                _hotpath.inverse_into(spectrum, out[d, o], workers)  # the tables carry its 1/ny
            else:
                out[d, o] = _eval_points(spectrum, phases, shape[-1])  # likewise: divide by nx only
    return out


def transfer(xi: np.ndarray, eta: np.ndarray | None, depth: float, nu: float,
             load_component: str, components: Sequence[str] = VOIGT) -> np.ndarray:
    """Exact Fourier multiplier from one load component to stress components.

    ``sigma~_c(xi, eta, depth) = T[c] * L~(xi, eta)`` for the load component ``L``.

    Parameters
    ----------
    xi, eta : ndarray
        Angular wavenumbers in rad/m (broadcastable); ``eta=None`` for 1-D plane strain.
    depth : float
        Depth in m (> 0).
    nu : float
        Poisson's ratio.
    load_component : {"p", "qx", "qy"}
    components : sequence of str
        Voigt stress components wanted.

    Returns
    -------
    ndarray, complex, shape (len(components), *broadcast(xi, eta).shape)
        Multipliers (Pa per Pa). The rho = 0 mode holds its direction-averaged limit.
        No Nyquist rule is applied: pass the wavenumbers you mean.

    Raises
    ------
    ValueError
        For non-finite wavenumbers (naming the first bad index), a depth that is not finite
        and > 0, or an unknown load or stress component.
    """
    if load_component not in ("p", "qx", "qy"):
        raise ValueError(f"load_component: must be 'p', 'qx' or 'qy', got {load_component!r}")
    depth = check.depth(depth)
    nu = check.poisson_ratio(nu)
    components = check.components(components)
    xi = check.finite_array(xi, "xi", "rad/m")
    if eta is not None:
        xi, eta = np.broadcast_arrays(xi, check.finite_array(eta, "eta", "rad/m"))
    g = _Geometry(xi, eta, nyquist_x=False, nyquist_y=False)
    out = []
    for comp in components:
        out.append(multiplier(g, nu, load_component, np.eye(6)[VOIGT.index(comp)], depth))
    return np.asarray(out, dtype=complex)


def pressure_from_deflection(deflection: np.ndarray, spacing, young_modulus: float, nu: float) -> SurfaceLoad:
    """Pressure that imposes a normal surface deflection on a frictionless half-space.

    Uses P~ = E rho H~ / (2 (1 - nu^2)) (docs/theory.md section 2); periodic in the grid.

    Parameters
    ----------
    deflection : ndarray, shape (nx,) or (ny, nx)
        Surface deflection into the skin, in m (the undulating rigid surface's height).
    spacing : float or (float, float)
        Grid spacing in m.
    young_modulus : float
        E in Pa.
    nu : float
        Poisson's ratio.

    Returns
    -------
    SurfaceLoad
        The normal pressure, marked ``periodic=True`` (the grid is one period: the solver then
        uses the exact periodic method and its error estimate holds). Mean zero: a uniform
        deflection needs no pressure on an infinite half-space, so the mean is a free
        contact-force parameter.
    """
    h = check.finite_array(deflection, "deflection", "m")
    young_modulus = check.young_modulus(young_modulus)
    nu = check.poisson_ratio(nu)
    template = SurfaceLoad(p=np.zeros_like(h), spacing=spacing)
    xi, eta = _half_wavenumbers(h.shape, template.spacing)
    rho = np.abs(xi) if eta is None else np.hypot(xi, eta)
    axes = tuple(range(-h.ndim, 0))
    spec = sfft.rfftn(h, axes=axes) * (young_modulus * rho / (2 * (1 - nu**2)))
    p = sfft.irfftn(spec, s=h.shape, axes=axes)
    return SurfaceLoad(p=p, spacing=template.spacing, periodic=True)

"""Tractor displays: travelling-wave drives and the strain they produce at depth.

Builds on the closed forms of :mod:`tactilab.forward.tractors` (plane problem, rows of
tractors as strips uniform in y) and on the Cerruti point-force kernel of
:mod:`tactilab.forward.halfspace.kernels` for 2-D arrays of finite patches (3-D half-space).
Units are SI; tractor loads are line loads (N/m) in the plane model and tractions (Pa) on
patches; strain is a Voigt vector (xx, yy, zz, yz, zx, xy) with TENSOR shear.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .halfspace import positive
from tactilab.core import rules as check
from .tractors import tractor_row_strain


def travelling_wave_drive(tractor_x, height: Callable[[np.ndarray], np.ndarray], speed: float, times,
                          gain: float, lead: float = 0.0, traction_limit: float | None = None,
                          footprint: float | None = None) -> np.ndarray:
    """Tractor line loads that render a virtual surface scanned at speed V.

    ``q_n(t) = gain * H(x_n + V t + lead)``: each tractor follows the virtual height at its
    position as the display scans the surface (docs/theory.md 4a).

    Parameters
    ----------
    tractor_x : array_like, shape (n_tractors,)
        Tractor centres along x, m.
    height : callable
        The virtual surface H(x) (m), vectorised over an ndarray of positions in m.
    speed : float
        Scanning speed V, m/s.
    times : array_like, shape (nt,)
        Frame times, s.
    gain : float
        Line load per unit height, (N/m)/m: e.g. ``matching_line_load(...) / A`` from
        :mod:`tactilab.forward.synthesis`.
    lead : float
        Sampling lead along x, m (a quarter pitch aligns the rendered strain with the real one).
    traction_limit : float, optional
        Per-tractor traction limit, Pa (e.g. ``DisplayDescription.max_traction_pa``); needs
        ``footprint``. A drive whose traction ``|q| / footprint`` exceeds it raises ValueError.
    footprint : float, optional
        Tractor contact width along x, m (``DisplayDescription.tractor_width_m``).

    Returns
    -------
    ndarray, shape (nt, n_tractors)
        Line loads, N/m.
    """
    tx = check.finite_array(tractor_x, "tractor_x", "m").reshape(-1)
    t = check.finite_array(times, "times", "s").reshape(-1)
    v = float(check.finite_array(speed, "speed", "m/s"))
    g = float(check.finite_array(gain, "gain", "(N/m)/m"))
    s = float(check.finite_array(lead, "lead", "m"))
    if not callable(height):
        raise ValueError(f"height: expected a callable H(x) returning heights in m, got {type(height).__name__}")
    h = np.asarray(height(tx[None, :] + v * t[:, None] + s), dtype=float)
    if h.shape != (t.size, tx.size):
        raise ValueError(f"height: H(x) must return one height per position, shape {(t.size, tx.size)}, got {h.shape}")
    if not np.isfinite(h).all():
        raise ValueError("height: H(x) returned NaN or inf; give a surface defined at every tractor position")
    q = g * h
    if traction_limit is not None:
        limit = positive(traction_limit, "traction_limit", "Pa")
        if footprint is None:
            raise ValueError("footprint: needed with traction_limit to turn line loads (N/m) into tractions "
                             "(Pa); give the tractor contact width in m")
        c = positive(footprint, "footprint")
        peak = float(np.max(np.abs(q))) / c
        if peak > limit * (1 + 1e-12):
            raise ValueError(
                f"drive: peak traction {peak:.4g} Pa exceeds the display's traction_limit {limit:.4g} Pa; "
                f"lower the virtual amplitude or the gain by a factor {peak / limit:.3g} at least"
            )
    return q


def display_row_strain(display, x, depth: float, line_loads, young_modulus: float,
                       nu: float = 0.5) -> np.ndarray:
    """Strain at depth under one tractor row of a ``DisplayDescription`` (plane strain).

    The rows of the display are taken as uniform in y (each tractor a strip of width
    ``tractor_width_m`` along x): exact for rows much longer than the depth; for a 2-D array
    of short patches use :func:`display_patch_strain_3d`.

    Parameters
    ----------
    display : tactilab.data_schemas.display.DisplayDescription
    x : array_like, shape (nx,), m
    depth : float, m
    line_loads : array_like, shape (..., columns), N/m
    young_modulus : float, Pa
    nu : float

    Returns
    -------
    ndarray, shape (..., nx, 6), TENSOR shear
    """
    return tractor_row_strain(x, depth, display.tractor_x_m, line_loads, young_modulus, nu,
                              footprint=display.tractor_width_m)


def render_virtual_surface(display, height: Callable[[np.ndarray], np.ndarray], speed: float, times,
                           x, depth: float, gain: float, young_modulus: float, nu: float = 0.5,
                           lead: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Drive a display as a travelling wave over a virtual surface; return the drive and the strain.

    Every row gets the same drive (the plane model: rows uniform in y); the drive is checked
    against ``display.max_traction_pa`` over the footprint ``display.tractor_width_m``.

    Parameters
    ----------
    display : tactilab.data_schemas.display.DisplayDescription
    height : callable
        Virtual surface H(x), m.
    speed : float
        Scanning speed, m/s.
    times : array_like, shape (nt,)
        Frame times, s.
    x : array_like, shape (nx,)
        Receptor positions, m.
    depth : float
        Receptor depth, m.
    gain : float
        Line load per unit height, (N/m)/m.
    young_modulus : float
        E, Pa.
    nu : float
        Poisson's ratio.
    lead : float
        Sampling lead along x, m.

    Returns
    -------
    line_loads : ndarray, shape (nt, columns), N/m
    strain : ndarray, shape (nt, nx, 6), TENSOR shear
    """
    limit = display.max_traction_pa
    q = travelling_wave_drive(display.tractor_x_m, height, speed, times, gain, lead, traction_limit=limit,
                              footprint=display.tractor_width_m if limit is not None else None)
    return q, display_row_strain(display, x, depth, q, young_modulus, nu)


# ----- 2-D arrays of finite patches (3-D half-space) ---------------------------------------
def _panel_rule(length: float, max_panel: float, order: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss-Legendre nodes and weights on [-length/2, length/2]."""
    n_panels = max(1, int(math.ceil(length / max_panel)))
    t, w = np.polynomial.legendre.leggauss(order)
    edges = np.linspace(-0.5 * length, 0.5 * length, n_panels + 1)
    mid = 0.5 * (edges[1:] + edges[:-1])
    half = 0.5 * (edges[1] - edges[0])
    return (mid[:, None] + half * t[None, :]).ravel(), np.tile(w * half, n_panels)


def hooke_strain(stress_voigt: np.ndarray, young_modulus: float, nu: float) -> np.ndarray:
    """Isotropic Hooke's law: Voigt stress (..., 6) in Pa -> Voigt strain (..., 6), TENSOR shear."""
    e = check.young_modulus(young_modulus)
    v = check.poisson_ratio(nu)
    s = np.asarray(stress_voigt, dtype=float)
    trace = s[..., 0] + s[..., 1] + s[..., 2]
    out = (1 + v) * s / e
    out[..., :3] -= (v / e) * trace[..., None]
    return out


def patch_strain_3d(points, tractor_xy, tractions, width: float, length: float, young_modulus: float,
                    nu: float = 0.5, panels_per_depth: float = 2.0) -> np.ndarray:
    """Strain at points inside the skin under rectangular tractor patches pulling along +x (3-D).

    Each tractor is a ``width`` (x) by ``length`` (y) patch carrying a uniform tangential
    traction along +x. The Cerruti point-force stress (``tactilab.forward.halfspace.kernels``) is
    integrated over each patch with composite Gauss-Legendre quadrature, panels no longer
    than ``depth / panels_per_depth`` (4 nodes each), which resolves the kernel's smallest
    length scale, the depth of the point.

    Parameters
    ----------
    points : array_like, shape (n_points, 3)
        Field points (x, y, z), m, with z > 0 (depth).
    tractor_xy : array_like, shape (n_tractors, 2)
        Patch centres (x, y), m (``DisplayDescription.tractor_positions_m``).
    tractions : array_like, shape (..., n_tractors)
        Tangential traction of each patch along +x, Pa.
    width, length : float
        Patch size along x and y, m.
    young_modulus : float
        E, Pa.
    nu : float
        Poisson's ratio.
    panels_per_depth : float
        Quadrature panels per depth (>= 1); 2 gives about 1e-6 relative accuracy.

    Returns
    -------
    ndarray, shape (..., n_points, 6)
        Voigt strain with TENSOR shear.
    """
    from .halfspace import point_load_stress

    pts = check.finite_array(points, "points", "m")
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points: expected shape (n_points, 3) for (x, y, z) in m, got {pts.shape}")
    if np.any(pts[:, 2] <= 0):
        raise ValueError(f"points: depth z must be > 0 m inside the skin, got min z {pts[:, 2].min()!r}")
    centres = check.finite_array(tractor_xy, "tractor_xy", "m")
    if centres.ndim != 2 or centres.shape[1] != 2:
        raise ValueError(f"tractor_xy: expected shape (n_tractors, 2) for (x, y) in m, got {centres.shape}")
    tau = check.finite_array(tractions, "tractions", "Pa")
    if tau.shape[-1:] != (centres.shape[0],):
        raise ValueError(f"tractions: trailing axis must hold one traction per tractor ({centres.shape[0]}), "
                         f"got shape {tau.shape}; give shape (..., n_tractors) in Pa")
    a = positive(width, "width")
    b = positive(length, "length")
    per = positive(panels_per_depth, "panels_per_depth", "1")
    max_panel = float(pts[:, 2].min()) / max(per, 1.0)
    gx, wx = _panel_rule(a, max_panel)
    gy, wy = _panel_rule(b, max_panel)
    dx = (pts[:, None, 0] - centres[None, :, 0])[:, :, None, None] - gx[None, None, :, None]
    dy = (pts[:, None, 1] - centres[None, :, 1])[:, :, None, None] - gy[None, None, None, :]
    z = pts[:, 2][:, None, None, None]
    green = np.zeros((pts.shape[0], centres.shape[0], 6))
    weights = wx[:, None] * wy[None, :]
    # loop over points keeps memory at n_tractors * n_nodes, whatever the number of points
    for i in range(pts.shape[0]):
        s = point_load_stress(dx[i], dy[i], z[i], fx=1.0, nu=nu)  # (ntr, ngx, ngy, 6) per N
        green[i] = np.einsum("tabc,ab->tc", s, weights)
    stress = np.einsum("...t,ptc->...pc", tau, green)
    return hooke_strain(stress, young_modulus, nu)


def display_patch_strain_3d(display, points, tractions, young_modulus: float, nu: float = 0.5) -> np.ndarray:
    """Strain under every tractor of a ``DisplayDescription`` (3-D, finite patches).

    Parameters
    ----------
    display : tactilab.data_schemas.display.DisplayDescription
    points : array_like, shape (n_points, 3), m
    tractions : array_like, shape (..., rows, columns), Pa (along +x)
    young_modulus : float, Pa
    nu : float

    Returns
    -------
    ndarray, shape (..., n_points, 6), TENSOR shear
    """
    tau = check.finite_array(tractions, "tractions", "Pa")
    if tau.shape[-2:] != display.shape:
        raise ValueError(f"tractions: trailing axes must be the display shape {display.shape} (rows, columns), "
                         f"got {tau.shape}; give one traction in Pa per tractor")
    flat = tau.reshape(tau.shape[:-2] + (display.n_tractors,))
    return patch_strain_3d(points, display.tractor_positions_m, flat, display.tractor_width_m,
                           display.tractor_length_m, young_modulus, nu)

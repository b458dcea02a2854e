"""Partial slip and stuck contact: the tangential traction under a given pressure.

:func:`solve_tangential` finds the tangential traction ``q`` on the skin (Pa) for a given normal
solution (pressure ``p`` and contact mask), a Coulomb coefficient ``mu`` and a total tangential
force ``Q`` (N in 3-D, N/m in plane strain), on the grid of a
:class:`~tactilab.forward.contact.ContactCompliance` (periodic or isolated, ``(ny, nx)`` or ``(nx,)``).

Sign convention (that of :func:`~tactilab.forward.contact.interfacial_traction`): ``q`` acts on the
skin. The rigid surface is displaced tangentially by the rigid shift ``s`` (m) relative to the
skin's far field; the skin's surface moves by ``u_t`` (m). The slip of the skin relative to the
surface is ``u_t - s`` and friction drags the skin along the surface's motion:

- stick zone: ``u_t = s`` (no slip) and ``|q| < mu p``;
- slip zone: ``|q| = mu p`` and ``q = mu p (s - u_t) / |s - u_t|`` (``q`` opposes the skin's slip);
- ``q = 0`` outside the contact, and ``sum(q) dA = Q``.

A surface sliding along +x over the skin gives ``qx = +mu p``, as ``interfacial_traction`` says.
The slip is counted from the unloaded state (one loading step): exact for a monotonic tangential
load, as in Cattaneo--Mindlin and Ciavarella--Jaeger. ``"stuck"`` (``mu = inf``) has no slip zone:
``u_t = s`` over the whole contact (Mindlin's no-slip solution).

Algorithm: these conditions are the optimality conditions of the convex problem::

    min_q  1/2 q.C q + q.u_p    subject to  |q_i| <= mu p_i  and  sum_i q_i dA = Q

with ``C`` the tangential surface compliance, ``u_p`` a fixed displacement (below) and ``s`` the
Lagrange multiplier of the force. :mod:`~tactilab.forward.contact.friction_qp` solves it with an
accelerated projected gradient (FISTA with restart) whose projection onto the friction discs and
the force is exact, until the stick and slip sets settle, then semismooth Newton steps (conjugate
gradients on the stick tractions and the slip directions). Why not a Polonsky--Keer-like active-set
conjugate gradient alone: in 3-D the bound is a disc, not a one-sided bound, and the slip direction
is unknown; a prototype of it converged in 42 products in plane strain but wandered in 3-D at
nu = 1/2, where the slip rotates. The projected gradient needs no set heuristics and keeps every
iterate admissible; the Newton phase removes its slow linear tail (128^2 Hertz at tol 1e-8: 96
compliance products instead of 347). ``"stuck"`` is linear (no bound): conjugate gradients on the
contact nodes with the force held fixed. An isolated grid is solved on the contact's bounding box
(its operator depends on offsets only), whose padded FFT is smaller.

Normal-tangential coupling (nu < 1/2) and loading history: ``pressure_displacement`` is a fixed
tangential displacement added to ``C q`` in the slip. ``C_tp p`` (the pressure's, from
:meth:`ContactCompliance.tangential_from_normal`) loads in one step from the unloaded state
(proportional loading: at nu < 1/2 the normal load alone then leaves Spence's outward slip
annulus). A step from a previous state ``(p_prev, q_prev)`` passes ``C_tp (p - p_prev) - C q_prev``:
a normal load applied first without friction is ``q_prev = 0``, and that is the path on which
Cattaneo--Mindlin is the reference. The result carries the normal displacement produced by ``q``
(``normal_displacement``, :meth:`ContactCompliance.normal_from_tangential`) for the normal solve's
gap; the caller alternates the two solves until the pressure stops changing.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np
from scipy import fft as sfft

from tactilab.core import rules as check

from .compliance import ContactCompliance
from .friction_qp import solve_partial, solve_stuck
from .hertz import _check_friction

#: relative margin below the friction bound under which a contact node counts as stuck
STICK_MARGIN = 1e-6

#: the cropped operators of each grid's compliance (its spectra are cached inside), by box shape
_CROPS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass(frozen=True)
class TangentialSolution:
    """The tangential traction of a partial-slip or stuck contact (see the module docstring).

    Attributes
    ----------
    qx, qy : ndarray, grid shape
        Tangential traction on the skin along +x, +y in Pa; ``qy`` is None in plane strain.
    stick, slip : ndarray of bool, grid shape
        Contact nodes with ``|q| < mu p (1 - STICK_MARGIN)``, and the others (``|q| = mu p``).
    shift : ndarray, shape (1,) or (2,)
        Rigid tangential shift ``s`` of the surface relative to the skin's far field, m (x, y);
        defined up to the compliance's rigid-body constant (periodic: the mean displacement).
    displacement : ndarray, shape (1 or 2,) + grid shape
        Tangential surface displacement ``u_t`` in m, including the pressure's part.
    normal_displacement : ndarray, grid shape
        Normal surface displacement (m, into the skin) produced by ``q``: 0 at nu = 1/2.
    iterations : int
        Compliance products (on the contact's bounding box for an isolated grid).
    converged : bool
        Whether ``residual <= tol``.
    residual : float
        Optimality residual: the largest change of one projected gradient step, over ``max |q|``
        (partial; see :mod:`~tactilab.forward.contact.friction_qp`), or the largest slip in the
        contact over the largest displacement (stuck).
    """

    qx: np.ndarray
    qy: np.ndarray | None
    stick: np.ndarray
    slip: np.ndarray
    shift: np.ndarray
    displacement: np.ndarray
    normal_displacement: np.ndarray
    iterations: int
    converged: bool
    residual: float


def solve_tangential(compliance, pressure, contact, friction, tangential_force, *, stuck: bool = False,
                     pressure_displacement=None, tol: float = 1e-8, max_iter: int | None = None,
                     initial=None) -> TangentialSolution:
    """Tangential traction for a partial-slip (``stuck=False``) or stuck contact under a given pressure.

    Parameters
    ----------
    compliance : ContactCompliance
        The grid's surface compliance (shape ``(nx,)`` or ``(ny, nx)``, spacing, periodic or not).
    pressure : ndarray, grid shape
        Contact pressure ``p >= 0`` in Pa (the normal solution).
    contact : ndarray of bool, grid shape
        The contact nodes (where the tangential traction may be non-zero).
    friction : float
        Coulomb coefficient ``mu >= 0``; ``inf`` only with ``stuck=True`` (then ignored).
    tangential_force : float or sequence of float
        Total tangential force on the skin: ``Qx`` in N/m (plane strain) or ``(Qx, Qy)`` in N (3-D).
        Partial slip needs ``|Q| <= mu P`` with ``P = sum(p) dA``; ``|Q| = mu P`` is full sliding.
    stuck : bool
        True: no slip anywhere in the contact (Mindlin's no-slip solution).
    pressure_displacement : ndarray, shape (1 or 2,) + grid shape, optional
        Fixed tangential surface displacement (m) added to ``C q``: the pressure's (nu < 1/2) or a
        loading step's history (see the module docstring); None: zero.
    tol : float
        Stop when ``residual <= tol`` (see :class:`TangentialSolution`).
    max_iter : int, optional
        Most compliance products (default 5000).
    initial : ndarray, shape (1 or 2,) + grid shape, optional
        A traction (Pa) to start from (a warm start); made admissible before use.

    Returns
    -------
    TangentialSolution

    Raises
    ------
    ValueError
        For a bad shape, a NaN or negative pressure, ``mu < 0`` or NaN, ``mu = inf`` without ``stuck``,
        a force that is not finite or (partial slip) above ``mu P``, or ``tol`` / ``max_iter`` out of range.
    """
    shape, dims = tuple(compliance.shape), compliance.ndim
    p = _grid(pressure, "pressure", shape, "Pa")
    if np.any(p < 0):
        raise ValueError(f"pressure: must be >= 0 Pa (it pushes into the skin), min {p.min():g} Pa; "
                         f"pass the normal solution's pressure")
    mask = np.asarray(contact)
    if mask.shape != shape or mask.dtype != bool:
        raise ValueError(f"contact: expected a bool mask of the grid's shape {shape}, got "
                         f"{mask.dtype} {mask.shape}; pass the normal solution's contact mask")
    mu = math.inf if stuck else _check_friction(friction)
    if math.isinf(mu) and not stuck:
        raise ValueError("friction: partial slip needs a finite friction coefficient, got inf; "
                         "use condition='stuck' for mu -> infinity")
    Q = _force(tangential_force, dims)
    tol = check.positive(tol, "tol", "1", "the default is 1e-8")
    max_iter = 5000 if max_iter is None else int(max_iter)
    if max_iter < 1:
        raise ValueError(f"max_iter: must be >= 1, got {max_iter}; None picks 5000")
    d = 1 if dims == 1 else 2
    offset = np.zeros((d,) + shape) if pressure_displacement is None else \
        _grid(pressure_displacement, "pressure_displacement", (d,) + shape, "m")
    start = None if initial is None else _grid(initial, "initial", (d,) + shape, "Pa")
    area = float(np.prod(compliance.spacing))
    nodes = np.nonzero(mask)
    total = float(p[nodes].sum()) * area
    if stuck:
        bound = np.full(nodes[0].size, math.inf)
        if not nodes[0].size and np.any(Q != 0):
            raise ValueError("contact: a stuck contact with a tangential force needs at least one contact node")
    else:
        if np.linalg.norm(Q) > mu * total * (1 + 1e-12):
            raise ValueError(f"tangential_force: |Q| = {np.linalg.norm(Q):g} exceeds the friction limit mu P = "
                             f"{mu * total:g} (mu = {mu:g}, P = {total:g}); the contact slides: use "
                             f"condition='sliding', or lower the force / raise the friction")
        bound = mu * p[nodes]
        nodes, bound = tuple(i[bound > 0] for i in nodes), bound[bound > 0]  # mu p = 0: no traction there

    apply = _nodal_operator(compliance, nodes, d)
    u_p = np.stack([offset[j][nodes] for j in range(d)], axis=1)
    q0 = None if start is None else np.stack([start[j][nodes] for j in range(d)], axis=1)
    if not nodes[0].size:  # no node can carry traction (Q = 0 checked)
        q, s, its, res = np.zeros((nodes[0].size, d)), np.zeros(d), 0, 0.0
    elif stuck:
        q, s, its, res = solve_stuck(apply, area, Q, u_p, q0, tol, max_iter)
    elif np.any(Q) and np.linalg.norm(Q) >= mu * total * (1 - 1e-12):  # full sliding: the only admissible q
        q, s, its, res = bound[:, None] * (Q / np.linalg.norm(Q))[None, :], np.zeros(d), 0, 0.0
    else:
        q, s, its, res = solve_partial(apply, bound, area, Q, u_p, q0, tol, max_iter)
    q_grid = np.zeros((d,) + shape)
    for j in range(d):
        q_grid[j][nodes] = q[:, j]
    u = np.stack(compliance.tangential(*q_grid), axis=0) if d == 2 else compliance.tangential(q_grid[0])[0][None]
    if nodes[0].size and np.any(q):  # a cropped plane-strain operator differs by a constant: shift s with it
        s = s + np.mean(np.stack([u[j][nodes] for j in range(d)], axis=1) - apply(q), axis=0)
    uz = compliance.normal_from_tangential(*q_grid) if d == 2 else compliance.normal_from_tangential(q_grid[0])
    stick = np.zeros(shape, dtype=bool)
    stick[nodes] = np.hypot.reduce(q, axis=1) < bound * (1 - STICK_MARGIN) if d == 2 else \
        np.abs(q[:, 0]) < bound * (1 - STICK_MARGIN)
    return TangentialSolution(qx=q_grid[0], qy=q_grid[1] if d == 2 else None, stick=stick, slip=mask & ~stick,
                              shift=s, displacement=u + offset, normal_displacement=uz, iterations=its,
                              converged=bool(res <= tol), residual=float(res))


def _nodal_operator(compliance, nodes: tuple, d: int):
    """``q (n, d) -> u_t (n, d)`` at the contact nodes. An isolated grid is cropped to the contact's
    bounding box first (grown so that its padded FFT length is 5-smooth): its operator depends on
    offsets only, and a smaller padded FFT is cheaper."""
    shape = tuple(compliance.shape)
    if not compliance.periodic and nodes[0].size:
        lo = [int(i.min()) for i in nodes]
        box = tuple(_fast_half(int(i.max()) - l + 1) for i, l in zip(nodes, lo))
        if all(b < n for b, n in zip(box, shape)):
            crops = _CROPS.setdefault(compliance, {})
            if box not in crops:  # kept with the grid's operator: a coupled or warm-started solve reuses it
                if len(crops) >= 4:
                    crops.pop(next(iter(crops)))
                crops[box] = ContactCompliance(compliance.skin, box, compliance.spacing, periodic=False)
            compliance = crops[box]
            nodes, shape = tuple(i - l for i, l in zip(nodes, lo)), box

    def apply(q: np.ndarray) -> np.ndarray:
        grids = [np.zeros(shape) for _ in range(d)]
        for j in range(d):
            grids[j][nodes] = q[:, j]
        u = compliance.tangential(*grids)
        return np.stack([u[j][nodes] for j in range(d)], axis=1)

    return apply


def _fast_half(n: int) -> int:
    """The least m >= n whose double is a fast FFT length (the zero-padded operator's size)."""
    m = n
    while sfft.next_fast_len(2 * m, real=True) != 2 * m:
        m += 1
    return m


def _grid(value, name: str, shape: tuple, unit: str) -> np.ndarray:
    arr = check.finite_array(value, name, unit)
    if arr.shape != shape:
        raise ValueError(f"{name}: expected shape {shape} (the grid), got {arr.shape}")
    return arr


def _force(value, dims: int) -> np.ndarray:
    unit, want = ("N/m", "a number Qx") if dims == 1 else ("N", "a pair (Qx, Qy)")
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    if arr.shape != (1 if dims == 1 else 2,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"tangential_force: expected {want} of finite forces in {unit} on this "
                         f"{'plane-strain' if dims == 1 else '3-D'} grid, got {value!r}")
    return arr

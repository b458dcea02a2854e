"""The MAP of a surface inversion by Gauss-Newton, and the Laplace (Gaussian) posterior around it.

Unknowns, whitened (so that every prior term is ``|z|^2 / 2`` and the Hessian is at least I):

- the heights ``h = m0 + L z_h`` with ``L = C^(1/2)`` the prior covariance's circulant root
  (:class:`~tactilab.inversion.gaussian.StationaryPrior` on the profile grid); without a prior the
  heights themselves, restricted to the nodes the data see (the touched nodes), their level held
  at 0 (a uniform shift changes no datum at a given force: the heights are then a relief);
- each free context parameter ``theta = T(z)``: ``Normal(mean, sd)``: ``mean + sd z``;
  ``LogNormal(median, s)``: ``median exp(s z)``; ``Uniform(low, high)``: ``mid + half z`` with
  ``|z| <= 1`` and no prior term (flat).

Objective ``Phi(z) = |(d - f(z)) / sigma|^2 / 2 + (prior terms)``; the Gauss-Newton step solves
``(Jz^T Jz + P) dz = Jz^T r - P z`` (``Jz`` the scan Jacobian in whitened coordinates, divided by
sigma; ``P`` the prior's identity), then an Armijo backtracking line search on ``Phi`` with the
non-linear solve (the contact sets may change along the step; a Uniform parameter's step is cut at
its bounds). It stops when the Gauss-Newton decrement ``-g . dz`` falls below ``tol`` (nats; a
continuation stage before the last below ``STAGE_TOL``, 1 nat: it only starts the next), or
when the objective moved by less than ``STALL`` (1e-3 nats) over two iterations: near the MAP a contact node
entering or leaving the set makes the objective piecewise quadratic, and the line search then
creeps along the kink (the step that leaves the current piece is cut to a few percent).

Touched nodes: those whose largest load over the frames is at least ``TOUCH_THRESHOLD`` (2 %) of
the largest node's. A node the MAP leaves resting on the skin with almost no load (the prior
pulls it up, the data say it carried nothing) sits at a kink of the posterior: raising it loads
the skin, lowering it changes nothing. It is the bound's, not the data's: the contact-grid nodes
that read it leave the contact set of the final linearisation (they carry almost no load), its
Jacobian column vanishes, and it joins the untouched nodes (:mod:`.surface_bound`). (Zeroing its
column alone would let a uniform shift of the touched nodes change the data at the nodes that read
both, and the unidentifiable absolute level would look measured.)

The Laplace posterior is ``N(z_map, H^-1)``, ``H = Jz^T Jz + P`` at the MAP: the context
parameters are part of the state, so the heights' covariance is their block of ``H^-1``: the joint
Laplace approximation, with the context marginalised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from tactilab.core import rules

from .priors import LogNormal, Normal, Uniform
from .surface_jacobian import ScanJacobian

__all__ = ["ContextTransform", "LaplaceResult", "gauss_newton", "prior_root"]

#: condition number of the Fisher information above which a prior-free grid is refused
FISHER_CONDITION_LIMIT = 1e10
#: most continuation stages (tenfold each) of the noise sd
MAX_STAGES = 8
#: a node counts as touched when its largest load over the frames is at least this share of the
#: largest node's (a node the MAP left on the skin with almost no load is held by the bound)
TOUCH_THRESHOLD = 0.02
#: nats: the Gauss-Newton decrement at which a continuation stage before the last stops
STAGE_TOL = 1.0
#: an old Jacobian's step whose decrement is above this share of the previous one (and above 10
#: STALL: within that of the MAP a rebuild cannot pay) converges too slowly: the next iteration
#: rebuilds the Jacobian (``jacobian_every`` > 1)
SLOW = 0.25
#: nats: an objective that moves less over two iterations has stalled on a contact-set kink (the
#: posterior's own scale is 1 nat)
STALL = 1e-3


@dataclass(frozen=True)
class ContextTransform:
    """A free context parameter's prior and its whitened coordinate (see the module docstring)."""

    name: str
    prior: object

    def __post_init__(self):
        if not isinstance(self.prior, (Normal, LogNormal, Uniform)):
            raise ValueError(f"context: {self.name} needs a float (fixed), Uniform, Normal or LogNormal prior, got "
                             f"{type(self.prior).__name__}")

    @property
    def gaussian(self) -> bool:
        """Whether the prior adds ``z^2 / 2`` (Normal, LogNormal); Uniform is flat."""
        return not isinstance(self.prior, Uniform)

    def value(self, z):
        p = self.prior
        if isinstance(p, Normal):
            return p.mean + p.sd * z
        if isinstance(p, LogNormal):
            return p.median * np.exp(p.sigma_log * z)
        return 0.5 * (p.low + p.high) + 0.5 * (p.high - p.low) * z

    def slope(self, z) -> float:
        """``d theta / d z``."""
        p = self.prior
        if isinstance(p, Normal):
            return p.sd
        if isinstance(p, LogNormal):
            return float(self.value(z)) * p.sigma_log
        return 0.5 * (p.high - p.low)


@dataclass
class LaplaceResult:
    """The Gauss-Newton MAP and the Hessian there (whitened coordinates)."""

    z: np.ndarray
    heights: np.ndarray
    context: dict
    state: object
    jacobian: np.ndarray  # natural units, (n_data, n_profile + n_free), at the MAP
    hessian_factor: tuple  # cho_factor of H on the unknowns
    unknowns: np.ndarray  # indices of z that are unknowns (all, or the touched heights + context)
    touched: np.ndarray
    objective: float
    chi2: float
    iterations: int
    message: str
    history: list  # per iteration: (objective, decrement, step length, touched nodes)

    def covariance_z(self) -> np.ndarray:
        """``H^-1`` on the unknowns."""
        return cho_solve(self.hessian_factor, np.eye(self.unknowns.size))


def prior_root(prior, shape, spacing) -> np.ndarray:
    """The dense symmetric root ``L = C^(1/2)`` of a stationary prior on the profile grid, (n, n)."""
    lam = prior.spectrum(tuple(shape), spacing)
    n = int(np.prod(shape))
    axes = tuple(range(1, len(shape) + 1))
    eye = np.eye(n).reshape(n, *shape)
    root = np.fft.ifftn(np.fft.fftn(eye, axes=axes) * np.sqrt(lam), axes=axes).real
    return root.reshape(n, n)


def _context(z_c, transforms, fixed) -> dict | None:
    ctx = dict(fixed)
    for zk, tr in zip(z_c, transforms):
        v = float(tr.value(zk))
        if not math.isfinite(v) or (tr.name != "friction" and v <= 0) or v < 0:
            return None  # outside what the scan can solve: the line search backs off
        ctx[tr.name] = v
    return ctx


def gauss_newton(scan, data, noise_std, root, mean, transforms, fixed, *, max_iter=30, tol=1e-6,
                 touch_threshold=TOUCH_THRESHOLD, start=None, continuation=True,
                 jacobian_every: int = 1, jacobian_tol: float = 1e-8, workers: int = 1,
                 gradient_tol: float = 1e-8, solve_dtype=np.float64) -> LaplaceResult:
    """Gauss-Newton MAP with a line search, then the Hessian there (see the module docstring).

    Parameters
    ----------
    scan : ContactScan
    data : ndarray, shape (n_frames, n_out)
    noise_std : float
        Data units.
    root : ndarray (n, n) or None
        The prior covariance root ``L`` (m), or None for no prior (flat).
    mean : float
        Prior mean height, m.
    transforms : list of ContextTransform
        The free context parameters.
    fixed : dict
        Fixed context values.
    tol : float
        Nats: the last stage stops when the Gauss-Newton decrement falls below it (or the objective
        stalls, :data:`STALL`); the Gauss-Newton step left is then ``sqrt(tol)`` long in the
        Hessian's norm (posterior sd), the objective about ``tol / 2`` nats above its minimum.
    jacobian_every : int
        Iterations per explicit Jacobian (1: every iteration). Above 1 (with a prior), the last
        Jacobian drives the steps of the next ``jacobian_every - 1`` iterations while the gradient
        stays exact (one adjoint solve per frame, about a tenth of a Jacobian's solves): the
        iteration then stops at the same MAP (the exact gradient's zero), and the Laplace Hessian
        is the exact Jacobian's at the MAP. A step the line search had to cut, or a decrement above
        :data:`SLOW` times the previous one (and above 0.01 nats), rebuilds it; it is carried into the
        next continuation stage.
    jacobian_tol : float
        Relative residual of the Jacobian's restricted solves (:class:`ScanJacobian`'s ``tol``).
    workers : int
        Threads: over chunks of the Jacobian's and the gradients' restricted solves
        (:class:`ScanJacobian`'s), and over blocks of frames of the scan solves
        (:meth:`ContactScan.solve`).
    gradient_tol : float
        Relative residual of the exact gradients' restricted solves (``jacobian_every`` > 1): they
        only steer, the line search takes the objective itself; 1e-6 left the MAP of the issue's
        fingertip scan unchanged in four digits.
    solve_dtype : float64 or float32
        Precision of the iterations of the Jacobian's and the gradients' restricted solves
        (:class:`ScanJacobian`'s ``dtype``): float32 halves their FFT work and is refined until the
        float64 residual meets ``jacobian_tol`` and ``gradient_tol``.
    """
    if int(max_iter) < 1:
        raise ValueError(f"max_iter: the Gauss-Newton search needs at least 1 iteration, got {max_iter!r}")
    if int(jacobian_every) < 1:
        raise ValueError(f"jacobian_every: iterations per explicit Jacobian must be >= 1, got {jacobian_every!r}")
    if not 0 < jacobian_tol < 1:
        raise ValueError(f"jacobian_tol: the restricted solves' relative residual must lie in (0, 1), got "
                         f"{jacobian_tol!r}; e.g. 1e-8")
    if not 0 < gradient_tol < 1:
        raise ValueError(f"gradient_tol: the gradients' relative residual must lie in (0, 1), got "
                         f"{gradient_tol!r}; e.g. 1e-8")
    solve_dtype = rules.float_dtype(solve_dtype, "solve_dtype")
    names = [t.name for t in transforms]

    def jacobian(state):
        return _jacobian(scan, state, names, jacobian_tol, workers, solve_dtype)

    n, k = scan.profile.size, len(transforms)
    flat_h = root is None
    penal = np.concatenate([np.full(n, 0.0 if flat_h else 1.0), [1.0 if t.gaussian else 0.0 for t in transforms]])
    uniform = np.array([not t.gaussian for t in transforms], dtype=bool)

    def heights(z):
        zh = z[:n]
        return (zh.copy() if flat_h else mean + root @ zh).reshape(scan.profile.shape)

    last = {}  # the last solved z and its state: a stage's start and the final objective reuse it

    def evaluate(z, sigma, start=None):
        """The state and objective at ``z``; ``start``: a solved state near z whose frames start z's."""
        ctx = _context(z[n:], transforms, fixed)
        if ctx is None or (uniform.any() and np.abs(z[n:][uniform]).max() > 1):
            return None, math.inf
        if last.get("z") is None or not np.array_equal(last["z"], z):
            last["z"], last["state"] = z.copy(), scan.solve(heights(z), ctx, start=start, workers=workers)
        state = last["state"]
        r = (data - state.outputs).ravel() / sigma
        return state, 0.5 * float(r @ r) + 0.5 * float(np.sum(penal * z * z))

    z = np.zeros(n + k) if start is None else np.array(start, dtype=float)
    state, _ = evaluate(z, noise_std)
    if state is None:
        raise ValueError("context: the prior's centre is not a valid context (force and modulus > 0, friction >= 0)")
    # continuation: the noise sd starts at the initial misfit's rms and falls tenfold per stage to
    # noise_std, each stage's MAP starting the next (a steep objective far from the MAP sends plain
    # Gauss-Newton into spiky surfaces that touch only at their spikes)
    misfit = float(np.sqrt(np.mean(((data - state.outputs) / noise_std) ** 2)))
    stages = [misfit / 10.0**i for i in range(MAX_STAGES) if misfit / 10.0**i > 1.0 and continuation] + [1.0]
    history, messages, total = [], [], 0
    kept = {} if int(jacobian_every) > 1 else None  # the last Jacobian, carried into the next stage
    for j, factor in enumerate(stages):
        # a stage before the last only starts the next one (whose objective is tens of nats away):
        # its MAP to STAGE_TOL is enough
        stage_tol = tol if j == len(stages) - 1 else max(tol, STAGE_TOL)
        z, state, info, its = _descend(evaluate, jacobian, scan, data, noise_std * factor, z, names, transforms,
                                       root, penal, uniform, n, max_iter, stage_tol, history, int(jacobian_every),
                                       kept, workers, gradient_tol, solve_dtype)
        total += its
        messages.append(info)
    message = messages[-1] + (f" (after {len(stages) - 1} continuation stages in the noise sd)" if len(stages) > 1
                              else "")
    touched = loaded_nodes(scan, state, touch_threshold)
    # nodes resting on the skin with (almost) no load are the bound's, not the data's: the grid nodes
    # that read them leave the contact set of the linearisation (they carry almost nothing), so that
    # their columns vanish and a uniform shift of the touched nodes still changes no datum
    J, touched = jacobian(replace(state, contact=state.contact & ~reads_nodes(scan, ~touched)))
    unknowns = _unknowns(J, touched, transforms, z, root, noise_std, flat_h, n, scan.profile.spacing)
    A = _whiten(J, transforms, z, root, noise_std, n)[:, unknowns]
    factor = cho_factor(A.T @ A + np.diag(penal[unknowns]) + _gauge(A, unknowns, n, flat_h))
    _, phi = evaluate(z, noise_std)
    r = (data - state.outputs).ravel() / noise_std
    return LaplaceResult(z=z, heights=heights(z), context=dict(state.context), state=state, jacobian=J,
                         hessian_factor=factor, unknowns=unknowns, touched=touched, objective=phi,
                         chi2=float(r @ r), iterations=total, message=message, history=history)


def _descend(evaluate, jacobian, scan, data, sigma, z, names, transforms, root, penal, uniform, n, max_iter, tol,
             history, every=1, kept=None, workers=1, gradient_tol=1e-8, dtype=np.float64):
    """Gauss-Newton with an Armijo line search at one noise sd; returns (z, state, message, iterations).
    With ``every`` > 1 (and a prior) the Jacobian is rebuilt every ``every`` iterations (see
    gauss_newton); ``kept`` (a dict) holds the last one across calls (stages)."""
    flat_h = root is None
    kept = {} if kept is None else kept
    state, phi = evaluate(z, sigma)
    it, message, model, last_decrement = 0, "", None, math.inf
    age = 0 if "J" in kept else every
    for it in range(1, max_iter + 1):
        r = (data - state.outputs).ravel() / sigma
        fresh = "J" not in kept or age >= every or flat_h
        if fresh:
            J, touched = jacobian(state)
            if flat_h:  # without a prior, a node just entering the contact is held until it carries a load
                touched &= loaded_nodes(scan, state, TOUCH_THRESHOLD)
            kept.update(J=J, touched=touched)
            age = 0
        if fresh or model is None:  # the Gauss-Newton Hessian of the (last) Jacobian at this noise sd
            J, touched = kept["J"], kept["touched"]
            unknowns = _unknowns(J, touched, transforms, z, root, sigma, flat_h, n, scan.profile.spacing)
            A = _whiten(J, transforms, z, root, sigma, n)[:, unknowns]
            gauge = _gauge(A, unknowns, n, flat_h)
            model = cho_factor(A.T @ A + np.diag(penal[unknowns]) + gauge)
        if fresh:
            g = -(A.T @ r) + penal[unknowns] * z[unknowns] + gauge @ z[unknowns]
        else:  # the exact gradient by one adjoint solve per frame; the last Jacobian's Hessian
            adj = _whitened_adjoint(scan, state, names, transforms, z, root, sigma, n, r, kept, workers,
                                    gradient_tol, dtype)
            g = -adj[unknowns] + penal[unknowns] * z[unknowns]
        age += 1
        step = np.zeros_like(z)
        step[unknowns] = -cho_solve(model, g)
        decrement = -float(g @ step[unknowns])
        if decrement < tol:
            return z, state, f"converged: Gauss-Newton decrement {decrement:.2g} < {tol:g} nats", it
        if not fresh and decrement > max(SLOW * last_decrement, 10 * STALL):
            age = every  # an old Jacobian converging slowly, still far from the MAP: rebuild next
        last_decrement = decrement
        if uniform.any():  # a Uniform parameter's step stops at its bound
            zc, sc = z[n:][uniform], step[n:][uniform]
            with np.errstate(divide="ignore", invalid="ignore"):
                room = np.where(sc > 0, (1 - 1e-9 - zc) / sc, np.where(sc < 0, (-1 + 1e-9 - zc) / sc, np.inf))
            step *= min(1.0, float(room.min()))
        alpha = 1.0
        for _ in range(30):
            new_state, new_phi = evaluate(z + alpha * step, sigma, start=state)  # frames start at this iterate's
            if new_state is not None and new_phi <= phi - 1e-4 * alpha * decrement:
                break
            alpha *= 0.5
        else:
            if not fresh:  # an old Jacobian's step: rebuild it here and try again
                age = every
                continue
            return z, state, f"stopped: the line search found no decrease after 30 halvings (decrement " \
                             f"{decrement:.2g} nats)", it
        z, state, phi = z + alpha * step, new_state, new_phi
        if alpha < 1:  # the model overshot: rebuild the Jacobian at the new point
            age = every
        history.append((sigma, phi, decrement, alpha, int(touched.sum())))
        if len(history) >= 3 and history[-3][0] == sigma and history[-3][1] - phi < STALL:
            # creeping along a contact-set kink: the objective no longer moves
            return z, state, (f"converged: the objective changed by {history[-3][1] - phi:.2g} < {STALL:g} nats over "
                              f"2 iterations (last step {alpha:.2g} of the Gauss-Newton step)"), it
    return z, state, f"stopped at max_iter = {max_iter} iterations (decrement {decrement:.2g} nats)", it


def _whitened_adjoint(scan, state, names, transforms, z, root, sigma, n, r, kept, workers=1, tol=1e-8,
                      dtype=np.float64):
    """``Jz^T r`` (whitened coordinates, over sigma) by the scan Jacobian's adjoint, without the matrix.
    Its restricted solves are for the misfit ``r sigma`` (data units: the same in every continuation
    stage); ``kept`` holds the last ones (``"adjoint"``: they start the next iterate's) and the state
    they belong to with ``J^T (r sigma)`` (``"misfit"``: a stage that starts where the last one ended
    reuses it)."""
    if kept.get("misfit") is None or kept["misfit"][0] is not state:
        jac = ScanJacobian(scan, state, free=names, tol=tol, workers=workers, dtype=dtype)
        jt, kept["adjoint"] = jac.adjoint(r * sigma, initial=kept.get("adjoint"))
        kept["misfit"] = (state, jt)
    jt = kept["misfit"][1] / sigma
    out = np.empty(n + len(transforms))
    out[:n] = root.T @ jt[:n]
    for i, tr in enumerate(transforms):
        out[n + i] = jt[n + i] * tr.slope(z[n + i])
    return out / sigma


def reads_nodes(scan, nodes: np.ndarray) -> np.ndarray:
    """Per frame, the contact-grid nodes whose height interpolation reads any of the profile ``nodes``,
    shape (n_frames, *grid)."""
    idx, w = scan.interpolation
    hit = (nodes.reshape(-1)[idx] & (w > 0)).any(axis=-1)
    if scan.profile.y is None and len(scan.grid_shape) == 2:
        hit = np.broadcast_to(hit[:, None, :], (scan.n_frames, *scan.grid_shape))
    return hit


def loaded_nodes(scan, state, threshold: float) -> np.ndarray:
    """Profile nodes whose largest load over the frames (pressure read back through the
    interpolation) is at least ``threshold`` times the largest node's: the touched nodes."""
    load = np.zeros(scan.profile.size)
    for t in range(scan.n_frames):
        load = np.maximum(load, scan.node_heights_adjoint(state.pressure[t], frame=t).reshape(-1))
    return load >= threshold * load.max() if load.max() > 0 else np.zeros(scan.profile.size, dtype=bool)


def _jacobian(scan, state, names, tol, workers=1, dtype=np.float64):
    """The scan Jacobian (natural units) and the touched nodes (a non-zero column)."""
    J = ScanJacobian(scan, state, free=names, tol=tol, workers=workers, dtype=dtype).matrix()
    return J, np.abs(J[:, : scan.profile.size]).max(axis=0) > 0


def _whiten(J, transforms, z, root, sigma, n):
    """The Jacobian in whitened coordinates, divided by the noise sd."""
    Jz = np.empty_like(J)
    Jz[:, :n] = J[:, :n] if root is None else J[:, :n] @ root
    for i, tr in enumerate(transforms):
        Jz[:, n + i] = J[:, n + i] * tr.slope(z[n + i])
    return Jz / sigma


def _gauge(A, unknowns, n, flat_h) -> np.ndarray:
    """Without a prior, the level of the touched heights (a uniform shift changes no datum at a given
    force) is held where it is (at 0: the flat start): a curvature ``c u u^T`` along the uniform
    direction ``u`` of the touched heights, ``c`` the Fisher information's mean eigenvalue."""
    k = unknowns.size
    if not flat_h:
        return np.zeros((k, k))
    u = (unknowns < n).astype(float)
    u /= np.sqrt(u.sum()) if u.sum() else 1.0
    c = float(np.sum(A * A)) / max(k, 1) or 1.0
    return c * np.outer(u, u)


def _unknowns(J, touched, transforms, z, root, sigma, flat_h, n, spacing) -> np.ndarray:
    """All of z with a prior; without one the touched heights (checked: the data must resolve them) and the context."""
    if not flat_h:
        return np.arange(n + len(transforms))
    unknowns = np.concatenate([np.flatnonzero(touched), n + np.arange(len(transforms))])
    Jz = _whiten(J, transforms, z, root, sigma, n)[:, unknowns]
    fisher = np.linalg.eigvalsh(Jz.T @ Jz + _gauge(Jz, unknowns, n, True))
    if fisher[0] <= fisher[-1] / FISHER_CONDITION_LIMIT:
        ratio = f"{fisher[-1] / fisher[0]:.3g}" if fisher[0] > fisher[-1] * 1e-300 else "infinite"
        raise ValueError(
            f"spacing: without a prior the data must resolve every node of the grid, but the Fisher information "
            f"of the {int(touched.sum())} touched nodes has condition number "
            f"{ratio} > {FISHER_CONDITION_LIMIT:g} at spacing {spacing:.3g} m; give a prior "
            "(prior=StationaryPrior(...)) or a coarser spacing")
    return unknowns

"""The forward map of a surface inversion: surface heights -> sensor outputs through the solved contact.

A scan is a sequence of frames; in frame ``t`` the finger's contact grid (finger frame, node ``j``
at ``x_j = (j - nx // 2) dx``) sits with its origin at world x = ``positions[t]``. The surface
heights live on a profile grid in the world frame (:class:`ProfileGrid`: ``"line"``, a profile
h(x) with ridges along y, or ``"patch"``, h(x, y)); each frame reads them at its nodes by linear
(bilinear) interpolation. The frame's gap is the finger's own shape minus those heights, its
contact is solved at the given normal force (a periodic cell: its mean pressure) and the sensors
read the tractions through their node weights: ``outputs_t = Wp^T p_t + Wq^T qx_t`` with
``qx = mu D p`` (full sliding; ``D`` the friction direction).

Context parameters. The skin's modulus enters through the compliance ``A(E) = (E_ref / E) A_ref``,
so a solve at modulus E and force F is the reference solve at force ``F E_ref / E`` with pressures
scaled by ``E / E_ref``; strain sensors read the stress through Hooke's law, ``W(E) = W_ref E_ref / E``.
Only the reference compliance is ever built.

Limits: the frames are solved frictionless and the friction added as ``mu D p``, exact at nu = 1/2
(no normal-tangential coupling, as for the skin); at nu < 1/2 with friction the scan is refused.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from tactilab.core import rules
from tactilab.forward import ContactCompliance, HalfSpace, solve_scan

__all__ = ["ProfileGrid", "ContactScan", "ScanState", "CONTEXT_NAMES"]

#: the context parameters a scan can leave free
CONTEXT_NAMES = ("normal_force", "friction", "young_modulus")


@dataclass(frozen=True)
class ProfileGrid:
    """The surface's unknown heights: a world-frame grid.

    Parameters
    ----------
    x : ndarray, shape (nx,)
        World x of the nodes, m, uniform spacing.
    y : ndarray, shape (ny,) or None
        World y of the nodes (``"patch"``), m; None for a ``"line"`` profile (ridges along y).
    periodic : bool
        The grid is one period of the surface (a periodic cell); coordinates wrap.
    """

    x: np.ndarray
    y: np.ndarray | None = None
    periodic: bool = False

    @property
    def geometry(self) -> str:
        return "line" if self.y is None else "patch"

    @property
    def spacing(self) -> float:
        """Node spacing along x, m."""
        return float(self.x[1] - self.x[0]) if self.x.size > 1 else 1.0

    @property
    def shape(self) -> tuple[int, ...]:
        return (self.x.size,) if self.y is None else (self.y.size, self.x.size)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    def weights(self, coord: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Linear interpolation on one axis: node indices (..., 2) and weights (..., 2) at ``coord`` (m)."""
        h = float(axis[1] - axis[0]) if axis.size > 1 else 1.0
        s = (np.asarray(coord, dtype=float) - axis[0]) / h
        n = axis.size
        if self.periodic:
            s = np.mod(s, n)
        elif s.min() < -1e-9 or s.max() > n - 1 + 1e-9:
            raise ValueError(f"profile: the frames read the surface at x in [{axis[0] + h * s.min():.6g}, "
                             f"{axis[0] + h * s.max():.6g}] m, outside the profile grid [{axis[0]:.6g}, "
                             f"{axis[-1]:.6g}] m; build the grid over the whole scanned strip")
        lo = np.clip(np.floor(s + 1e-9), 0, max(n - 1, 0)).astype(np.int64)
        w = np.clip(s - lo, 0.0, 1.0)
        w[w < 1e-9] = 0.0  # a node on a profile node reads it alone (no round-off weight on the next one)
        hi = (lo + 1) % n if self.periodic else np.minimum(lo + 1, n - 1)
        return np.stack([lo, hi], axis=-1), np.stack([1.0 - w, w], axis=-1)


@dataclass
class ScanState:
    """The solved scan at given heights and context.

    Attributes
    ----------
    heights : ndarray, shape ``profile.shape``
        m.
    context : dict
        ``normal_force`` (N, or None for a periodic cell's mean pressure), ``friction``, ``young_modulus`` (Pa).
    pressure : ndarray, shape (n_frames, *grid)
        Pa, at the context's modulus.
    contact : ndarray of bool, shape (n_frames, *grid)
    node_heights : ndarray, shape (n_frames, *grid)
        The surface heights each frame read, m.
    outputs : ndarray, shape (n_frames, n_out)
        Pa (stress) or tensor strain.
    """

    heights: np.ndarray
    context: dict
    pressure: np.ndarray
    contact: np.ndarray
    node_heights: np.ndarray
    outputs: np.ndarray


class ContactScan:
    """A scan as a map from surface heights (and context) to sensor outputs (see the module docstring).

    Parameters
    ----------
    young_modulus, poisson_ratio : float
        The skin's reference modulus E_ref (Pa) and nu.
    grid_shape : tuple of int
        The contact grid, ``(nx,)`` (plane strain) or ``(ny, nx)``.
    spacing : float
        Contact-grid spacing, m (square nodes).
    shape_gap : ndarray, shape ``grid_shape``
        The finger's own gap at zero approach (``r^2 / (2 R)`` plus ridges), m; zeros for a flat cell.
    positions : ndarray, shape (n_frames,)
        World x of the finger frame's origin per frame, m.
    weights_p, weights_q : ndarray, shape (n_nodes, n_out)
        Sensor output per unit pressure and per unit qx at each node (cell area included), at E_ref.
    profile : ProfileGrid
    quantity : {"stress", "strain"}
    normal_force, mean_pressure : float
        Exactly one: N (N/m in plane strain), or the mean pressure of a periodic cell, Pa.
    friction : float
        Coulomb coefficient mu (full sliding).
    friction_direction : float
        +1 or -1: ``qx = D mu p`` on the skin.
    periodic : bool
        The contact grid is one period.
    y_offset : float
        World y of the scan line (``"patch"``), m.
    tol : float
        The frames' solver tolerance.
    """

    def __init__(self, *, young_modulus, poisson_ratio, grid_shape, spacing, shape_gap, positions, weights_p,
                 weights_q, profile: ProfileGrid, quantity="stress", normal_force=None, mean_pressure=None,
                 friction=0.0, friction_direction=1.0, periodic=False, y_offset=0.0, tol=1e-10):
        self.grid_shape = tuple(int(n) for n in grid_shape)
        self.spacing = rules.spacing(spacing, 1)[0]
        self.skin = HalfSpace(E=float(young_modulus), nu=float(poisson_ratio))
        if friction > 0 and self.skin.nu < 0.5:
            raise ValueError(f"poisson_ratio: the surface inversion solves frictionless frames and adds q = mu p, "
                             f"exact only at nu = 0.5 (no normal-tangential coupling), got nu = {poisson_ratio!r} "
                             f"with friction {friction!r}; use nu = 0.5 or friction 0")
        if (normal_force is None) == (mean_pressure is None):
            raise ValueError("normal_force, mean_pressure: give exactly one (a finger's force, or a periodic "
                             "cell's mean pressure)")
        self.compliance = ContactCompliance(self.skin, self.grid_shape, (self.spacing,) * len(self.grid_shape),
                                            bool(periodic))
        self.periodic = bool(periodic)
        self.shape_gap = np.asarray(shape_gap, dtype=float)
        self.positions = np.atleast_1d(np.asarray(positions, dtype=float))
        self.weights_p = np.asarray(weights_p, dtype=float)
        self.weights_q = np.asarray(weights_q, dtype=float)
        n_nodes = int(np.prod(self.grid_shape))
        for name, w in (("weights_p", self.weights_p), ("weights_q", self.weights_q)):
            if w.ndim != 2 or w.shape[0] != n_nodes or not np.all(np.isfinite(w)):
                raise ValueError(f"{name}: expected finite weights of shape ({n_nodes}, n_out), got {w.shape}")
        if self.shape_gap.shape != self.grid_shape:
            raise ValueError(f"shape_gap: expected shape {self.grid_shape}, got {self.shape_gap.shape}")
        self.profile = profile
        self.quantity = quantity
        self.reference = {"normal_force": None if normal_force is None else float(normal_force),
                          "friction": float(friction), "young_modulus": float(young_modulus)}
        self.mean_pressure = None if mean_pressure is None else float(mean_pressure)
        self.direction = float(friction_direction)
        self.y_offset = float(y_offset)
        self.tol = float(tol)
        self._interp = self._build_interpolation()
        steps = -np.diff(self.positions, prepend=self.positions[0]) / self.spacing
        whole = np.allclose(steps, np.round(steps), rtol=0, atol=1e-9)
        # the surface moves -step nodes in the finger frame: the engine's warm start follows it
        self._shifts = np.round(steps).astype(np.int64) if whole else None

    # ---------------------------------------------------------------- geometry
    @property
    def n_frames(self) -> int:
        return self.positions.size

    @property
    def n_out(self) -> int:
        return self.weights_p.shape[1]

    @property
    def cell_area(self) -> float:
        return self.spacing ** len(self.grid_shape)

    def node_x(self) -> np.ndarray:
        nx = self.grid_shape[-1]
        return (np.arange(nx) - nx // 2) * self.spacing

    def node_y(self) -> np.ndarray:
        ny = self.grid_shape[0]
        return (np.arange(ny) - ny // 2) * self.spacing

    def _build_interpolation(self):
        """Per frame: profile indices and weights of each node's height (line: per column)."""
        pr = self.profile
        wx = self.node_x()[None, :] + self.positions[:, None]  # world x, (n_frames, nx)
        ix, ax = pr.weights(wx, pr.x)
        if pr.y is None:
            return ix, ax  # (n_frames, nx, 2)
        if len(self.grid_shape) != 2:
            raise ValueError("geometry: a 'patch' profile needs a 3-D contact grid (ny, nx)")
        iy, ay = pr.weights(self.node_y() + self.y_offset, pr.y)  # (ny, 2)
        idx = iy[None, :, None, :, None] * pr.x.size + ix[:, None, :, None, :]  # (t, ny, nx, 2, 2)
        wts = ay[None, :, None, :, None] * ax[:, None, :, None, :]
        t, ny, nx = idx.shape[:3]
        return idx.reshape(t, ny, nx, 4), wts.reshape(t, ny, nx, 4)

    @property
    def interpolation(self) -> tuple[np.ndarray, np.ndarray]:
        """Per frame, the profile indices and weights each node (line: each column) reads,
        shapes ``(n_frames, nx, 2)`` (line) or ``(n_frames, ny, nx, 4)`` (patch)."""
        return self._interp

    def node_heights(self, heights) -> np.ndarray:
        """Heights read by every frame at its nodes, shape (n_frames, *grid), m."""
        h = np.asarray(heights, dtype=float).reshape(-1)
        idx, w = self._interp
        vals = (h[idx] * w).sum(axis=-1)
        if self.profile.y is None and len(self.grid_shape) == 2:
            vals = np.broadcast_to(vals[:, None, :], (self.n_frames, *self.grid_shape))
        return np.ascontiguousarray(vals)

    def node_heights_adjoint(self, field, frame: int | None = None) -> np.ndarray:
        """The adjoint of :meth:`node_heights`: (n_frames, *grid) -> ``profile.shape``; with ``frame``,
        one frame's field (``grid``) through that frame's interpolation alone."""
        f = np.asarray(field, dtype=float)
        if self.profile.y is None and len(self.grid_shape) == 2:
            f = f.sum(axis=-2)
        idx, w = self._interp
        if frame is not None:
            idx, w = idx[frame], w[frame]
        out = np.bincount(idx.reshape(-1), weights=(f[..., None] * w).reshape(-1), minlength=self.profile.size)
        return out.reshape(self.profile.shape)

    # ---------------------------------------------------------------- context
    def context(self, values: dict | None = None) -> dict:
        """The scene's context with ``values`` substituted (names in :data:`CONTEXT_NAMES`)."""
        out = dict(self.reference)
        for name, v in (values or {}).items():
            if name not in CONTEXT_NAMES:
                raise ValueError(f"context: unknown parameter {name!r}; use {', '.join(CONTEXT_NAMES)}")
            out[name] = float(v)
        return out

    def output_scale(self, ctx: dict) -> float:
        """``W(E) / W(E_ref)``: E_ref / E for strain sensors, 1 for stress."""
        return self.reference["young_modulus"] / ctx["young_modulus"] if self.quantity == "strain" else 1.0

    def effective_weights(self, ctx: dict) -> np.ndarray:
        """Output per unit pressure at each node with the friction traction included, (n_nodes, n_out)."""
        return self.output_scale(ctx) * (self.weights_p + self.direction * ctx["friction"] * self.weights_q)

    # ---------------------------------------------------------------- the solve
    def solve(self, heights, context: dict | None = None, *, start: ScanState | None = None,
              workers: int = 1) -> ScanState:
        """Solve every frame at ``heights`` (``profile.shape``, m) and the context, with the scene
        engine (:func:`tactilab.forward.solve_scan`, each frame warm-started from the previous one,
        or with ``start``, an earlier solved scan at nearby heights, from that scan's same frame).

        The frames skip the engine's check solve (its error estimate, which a scan state does not
        report): the pressures are the same to the scan's ``tol``. ``workers`` threads solve
        contiguous blocks of frames (the engine's FFTs and compiled kernels release the GIL; its work
        arrays are per thread); without ``start`` each block's first frame starts cold, and frames
        that all read the same heights (a flat surface: the Gauss-Newton start) are solved once."""
        h = np.asarray(heights, dtype=float)
        if h.shape != self.profile.shape or not np.all(np.isfinite(h)):
            raise ValueError(f"heights: expected finite values of shape {self.profile.shape} (m), got {h.shape}")
        if start is not None and (not isinstance(start, ScanState) or start.pressure.shape != (self.n_frames,
                                                                                            *self.grid_shape)):
            raise ValueError(f"start: expected a ScanState of this scan (pressure of shape "
                             f"{(self.n_frames, *self.grid_shape)}), got {type(start).__name__}; or None")
        ctx = self.context(context)
        ratio = ctx["young_modulus"] / self.reference["young_modulus"]  # p = ratio * p_ref
        load = {"mean_pressure": self.mean_pressure / ratio} if self.mean_pressure is not None else \
            {"normal_force": ctx["normal_force"] / ratio}
        H = self.node_heights(h)
        initial = None if start is None else \
            start.pressure * (self.reference["young_modulus"] / start.context["young_modulus"])
        workers = rules.workers(workers)

        def block(frames: range):
            return solve_scan(self.skin, lambda i: self.shape_gap - H[frames[i]],
                              (self.spacing,) * len(self.grid_shape), n_frames=len(frames), periodic=self.periodic, tol=self.tol,
                              shifts=None if self._shifts is None else self._shifts[frames.start: frames.stop],
                              initial=None if initial is None else initial[frames.start: frames.stop],
                              estimate_error=False, **load)

        if start is None and np.all(H == H[:1]):  # every frame reads the same heights (a flat surface): one solve
            sol = block(range(0, 1))
            pressure = ratio * np.broadcast_to(sol.pressure, (self.n_frames, *self.grid_shape)).copy()
            contact = np.broadcast_to(sol.contact, pressure.shape).copy()
        else:
            k = max(1, min(int(workers), self.n_frames))
            edges = np.linspace(0, self.n_frames, k + 1).round().astype(int)
            blocks = [range(a, b) for a, b in zip(edges[:-1], edges[1:])]
            if k == 1:
                sols = [block(blocks[0])]
            else:
                with ThreadPoolExecutor(max_workers=k) as pool:
                    sols = list(pool.map(block, blocks))
            pressure = ratio * np.concatenate([s.pressure for s in sols])
            contact = np.concatenate([s.contact for s in sols])
        outputs = pressure.reshape(self.n_frames, -1) @ self.effective_weights(ctx)
        return ScanState(heights=h.copy(), context=ctx, pressure=pressure, contact=contact, node_heights=H,
                         outputs=outputs)

    def final_gap(self, state: ScanState) -> np.ndarray:
        """The gap after loading in every frame, ``g0 + uz - delta`` (m, 0 in contact), shape (n_frames, *grid)."""
        ratio = state.context["young_modulus"] / self.reference["young_modulus"]
        out = np.empty_like(state.pressure)
        for t in range(self.n_frames):
            g = self.shape_gap - state.node_heights[t] + self.compliance.normal(state.pressure[t] / ratio)
            delta = float(g[state.contact[t]].mean()) if state.contact[t].any() else float(g.min())
            out[t] = np.maximum(g - delta, 0.0)
        return out

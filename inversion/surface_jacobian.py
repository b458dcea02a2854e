"""The Jacobian of a scan's outputs with respect to the surface heights and the free context.

At a solved scan (:class:`~tactilab.inversion.surface_scan.ScanState`) with frame ``t``'s contact
set ``C_t`` fixed, the pressure responds to the heights through the restricted compliance
(:class:`tactilab.forward.ContactLinearisation`: ``A_CC dp - d_delta = dh_C``, ``sum dp = 0`` at a
given force), not at all off ``C_t``; the outputs follow through the finger's node weights:

    d out_t = W_eff^T (E / E_ref) S_t T_t dh + (context columns),

with ``T_t`` the interpolation of the profile onto frame ``t``'s nodes, ``S_t`` the symmetric
restricted solve, ``W_eff = W(E) (Wp + D mu Wq)``. Context columns (natural units):

- normal force F: ``dp = f_t / dA`` with ``f_t`` the force response (``sum f_t = 1``);
- friction mu: ``d out = W(E) D Wq^T p``;
- modulus E: ``dp = (p - P_t f_t) / E`` (``P_t`` the nodal pressure sum; the contact of modulus E at
  force F is the reference one at force ``F E_ref / E``), plus ``-out / E`` for strain sensors.

:class:`ScanJacobian` is a ``scipy.sparse.linalg.LinearOperator`` (heights, then the free context
parameters -> outputs of every frame, flattened frame by frame) with its adjoint; ``matrix()``
builds it explicitly by adjoint solves, one batched solve (all frames) per sensor output.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy.sparse.linalg import LinearOperator

from tactilab.forward import ContactLinearisation

__all__ = ["ScanJacobian"]


class ScanJacobian(LinearOperator):
    """``d outputs / d (heights, free context)`` at a solved scan, with its adjoint.

    Parameters
    ----------
    scan : ContactScan
    state : ScanState
        The solved scan to linearise at.
    free : sequence of str
        The free context parameters, in column order after the heights (``normal_force``,
        ``friction``, ``young_modulus``; natural units N, 1, Pa).
    tol : float
        Relative residual of the restricted solves (default 1e-8: on a fingertip's 212^2 grid the
        solutions then differ from those at 1e-10 by 5e-8 of their largest value, in 15 iterations
        instead of 22 at 1e-12; Gauss-Newton and the Laplace covariance need far less).
    workers : int
        Threads over chunks of the restricted solves (:class:`tactilab.forward.ContactLinearisation`'s).
    dtype : float64 or float32
        Precision of the restricted solves' iterations (:class:`tactilab.forward.ContactLinearisation`'s:
        float32 is refined until the float64 residual meets ``tol``).

    Attributes
    ----------
    dims, dimsd : tuple
        Model shape ``(n_profile + n_free,)`` and data shape ``(n_frames, n_out)``.
    """

    def __init__(self, scan, state, free=(), *, tol: float = 1e-8, workers: int = 1, dtype=np.float64):
        self.scan, self.state, self.free = scan, state, tuple(free)
        if scan.mean_pressure is not None and "normal_force" in self.free:
            raise ValueError("free: a periodic cell is loaded by its mean pressure, it has no normal_force to free")
        self.n_h = scan.profile.size
        n_model = self.n_h + len(self.free)
        self.dims, self.dimsd = (n_model,), (scan.n_frames, scan.n_out)
        super().__init__(dtype=np.float64, shape=(scan.n_frames * scan.n_out, n_model))
        self.lin = ContactLinearisation(scan.compliance, state.contact, force_control=True, tol=tol, workers=workers,
                                        dtype=dtype)
        ctx = state.context
        self.ratio = ctx["young_modulus"] / scan.reference["young_modulus"]
        self.W = scan.effective_weights(ctx)  # (n_nodes, n_out)
        self.Wq = scan.output_scale(ctx) * scan.direction * scan.weights_q
        self._force = None  # the force responses, computed when a context column needs them

    def _force_response(self) -> np.ndarray:
        if self._force is None:  # one solve per distinct contact set
            first, which = self._distinct()
            self._force = self.lin.force_response(frames=first)[which]
        return self._force

    def _context_pressure(self, name: str) -> np.ndarray | None:
        """dp per unit of a context parameter, (n_frames, *grid); None when it acts on the weights only."""
        st, scan = self.state, self.scan
        if name == "normal_force":
            return self._force_response() / scan.cell_area
        if name == "young_modulus":
            total = st.pressure.reshape(scan.n_frames, -1).sum(axis=1)
            f = self._force_response()
            return (st.pressure - total.reshape((-1,) + (1,) * len(scan.grid_shape)) * f) / st.context["young_modulus"]
        return None

    def _context_output(self, name: str) -> np.ndarray:
        """The part of d out / d context that does not pass through the pressure, (n_frames, n_out)."""
        st, scan = self.state, self.scan
        p = st.pressure.reshape(scan.n_frames, -1)
        if name == "friction":
            return p @ self.Wq
        if name == "young_modulus" and scan.quantity == "strain":
            return -st.outputs / st.context["young_modulus"]
        return np.zeros((scan.n_frames, scan.n_out))

    # ---------------------------------------------------------------- products
    def _matvec(self, v):
        v = np.asarray(v, dtype=float).reshape(-1)
        scan = self.scan
        H = scan.node_heights(v[: self.n_h].reshape(scan.profile.shape))
        dp = self.ratio * self.lin.solve(H)
        out = np.zeros((scan.n_frames, scan.n_out))
        for k, name in enumerate(self.free):
            c = v[self.n_h + k]
            extra = self._context_pressure(name)
            if extra is not None:
                dp = dp + c * extra
            out += c * self._context_output(name)
        out += dp.reshape(scan.n_frames, -1) @ self.W
        return out.reshape(-1)

    def _rmatvec(self, y):
        return self.adjoint(y)[0]

    def adjoint(self, y, initial=None) -> tuple[np.ndarray, np.ndarray]:
        """``J^T y`` and its restricted solves, which can start the next adjoint's.

        Parameters
        ----------
        y : ndarray, shape (n_frames * n_out,) or (n_frames, n_out)
            Per unit of output (1 / Pa for stress).
        initial : ndarray, shape (n_frames, *grid), optional
            A start for the restricted solves: an earlier adjoint's (an earlier Gauss-Newton
            iterate's, whose contact sets and residuals are close); the answer is the same to ``tol``.

        Returns
        -------
        grad : ndarray, shape (n_profile + n_free,)
        solves : ndarray, shape (n_frames, *grid)
            The restricted solves ``S_t W y_t`` (m per unit of output), at the reference modulus.
        """
        scan = self.scan
        y = np.asarray(y, dtype=float).reshape(scan.n_frames, scan.n_out)
        g = (y @ self.W.T).reshape(scan.n_frames, *scan.grid_shape)  # d<y, out> / dp per frame
        sg = self.lin.solve(g, initial=initial)
        grad_h = scan.node_heights_adjoint(self.ratio * sg)
        extra = []
        for name in self.free:
            if name in ("normal_force", "young_modulus") and self._force is None:
                val = self._context_dot(name, g, sg)
            else:
                e = self._context_pressure(name)
                val = float(np.sum(e * g)) if e is not None else 0.0
            extra.append(val + float(np.sum(self._context_output(name) * y)))
        return np.concatenate([grad_h.reshape(-1), np.asarray(extra)]), sg

    def _context_dot(self, name: str, g: np.ndarray, sg: np.ndarray) -> float:
        """``<dp/d theta, g>`` for the force and the modulus without the force responses' solves:
        ``f = f0 - S A f0`` (``f0`` uniform on the set, sum 1; ``S`` the symmetric restricted solve),
        so ``<f, g> = <f0, g> - <A f0, S g>``: one compliance product per frame, ``S g`` is at hand."""
        scan, lin = self.scan, self.lin
        fg = np.empty(scan.n_frames)
        for t in range(scan.n_frames):
            f0 = lin.mask[t] / lin.n_contact[t]
            fg[t] = float(np.sum(f0 * g[t])) - float(np.sum(scan.compliance.normal(f0) * sg[t]))
        if name == "normal_force":
            return float(fg.sum()) / scan.cell_area
        st = self.state
        p = st.pressure.reshape(scan.n_frames, -1)
        pg = np.einsum("ti,ti->t", p, g.reshape(scan.n_frames, -1))
        return float(np.sum(pg - p.sum(axis=1) * fg)) / st.context["young_modulus"]

    def _matmat(self, X):
        return np.column_stack([self._matvec(col) for col in np.asarray(X).T])

    def _rmatmat(self, Y):
        return np.column_stack([self._rmatvec(col) for col in np.asarray(Y).T])

    def matrix(self) -> np.ndarray:
        """The explicit Jacobian, shape (n_frames * n_out, n_profile + n_free), by adjoint solves.

        One restricted solve per distinct contact set and sensor output, batched over chunks of
        sets (a chunk's right-hand sides are all its sets' outputs: they share their windows), each
        chunk's solves started from the previous chunk's last set's (the same right-hand sides on a
        neighbouring frame's set); with ``workers`` threads, each solves a contiguous run of sets;
        rows ordered frame by frame as the flattened outputs.
        """
        scan = self.scan
        n_out, grid = scan.n_out, scan.grid_shape
        J = np.zeros((scan.n_frames, n_out, self.shape[1]))
        weights = np.ascontiguousarray(self.W.T.reshape(n_out, *grid))
        # the right-hand sides are the same in every frame: one solve per distinct contact set (at a
        # flat surface every frame has the finger's own contact, so one frame's solves serve all)
        first, which = self._distinct()
        per = max(1, self.lin.chunk // n_out)
        starts = np.arange(0, first.size, per)
        lin = self.lin

        def stream(chunks: np.ndarray, solver: ContactLinearisation):
            previous = None  # the last set's solves: a scan's neighbouring sets differ at a few nodes
            for lo in chunks:
                sets = first[lo: lo + per]
                rhs = np.broadcast_to(weights, (sets.size, n_out, *grid)).reshape(-1, *grid)
                start = None if previous is None else \
                    np.broadcast_to(previous, (sets.size, n_out, *grid)).reshape(rhs.shape)
                x = solver.solve(rhs, frames=np.repeat(sets, n_out), initial=start).reshape(sets.size, n_out, *grid)
                previous = x[-1]
                cols = self._columns(self.ratio * x)
                for i in range(sets.size):
                    frames = np.flatnonzero(which == lo + i)
                    J[frames, :, : self.n_h] = self._adjoint_rows(cols[i], frames)

        k = min(lin.workers, starts.size)
        if k == 1:
            stream(starts, lin)
        else:  # contiguous runs of sets, one thread each (one solver each: no waiting on each other's chunks)
            solvers = [ContactLinearisation(scan.compliance, lin.mask, force_control=True, tol=lin.tol,
                                            chunk=lin.chunk, dtype=lin.dtype) for _ in range(k)]
            with ThreadPoolExecutor(max_workers=k) as pool:
                list(pool.map(stream, np.array_split(starts, k), solvers))
        for k, name in enumerate(self.free):
            extra = self._context_pressure(name)
            if extra is not None:
                J[:, :, self.n_h + k] += extra.reshape(scan.n_frames, -1) @ self.W
            J[:, :, self.n_h + k] += self._context_output(name)
        return J.reshape(scan.n_frames * n_out, -1)

    def _distinct(self) -> tuple[np.ndarray, np.ndarray]:
        """The first frame of each distinct contact set, and each frame's set (an index into them)."""
        seen, first, which = {}, [], np.empty(self.scan.n_frames, dtype=int)
        for t, m in enumerate(self.lin.mask):
            key = np.packbits(m).tobytes()
            if key not in seen:
                seen[key] = len(first)
                first.append(t)
            which[t] = seen[key]
        return np.asarray(first, dtype=int), which

    def _columns(self, x: np.ndarray) -> np.ndarray:
        """A line profile's columns: every row of a column reads the same heights (sum over y)."""
        return x.sum(axis=-2) if self.scan.profile.y is None and len(self.scan.grid_shape) == 2 else x

    def _adjoint_rows(self, cols: np.ndarray, frames: np.ndarray) -> np.ndarray:
        """``T_t^T x_o`` in each of ``frames`` for one set's fields ``cols`` (n_out, *grid; a line
        profile's column sums): -> (frames, n_out, n_profile)."""
        idx, w = self.scan.interpolation
        n_out, n_h = cols.shape[0], self.n_h
        offset = (np.arange(n_out) * n_h).reshape((n_out,) + (1,) * (idx.ndim - 1))
        out = np.empty((frames.size, n_out, n_h))
        for i, t in enumerate(frames):
            vals = cols[..., None] * w[t]
            out[i] = np.bincount((idx[t][None] + offset).reshape(-1), weights=vals.reshape(-1),
                                 minlength=n_out * n_h).reshape(n_out, n_h)
        return out

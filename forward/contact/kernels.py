"""The fused passes of the preconditioned contact loop (:mod:`.preconditioned`), compiled or in NumPy.

Between its FFT products an iteration of :func:`.preconditioned.preconditioned_cg` makes about 30
elementwise NumPy passes over the grid (each a read and a write of one or two grid arrays): 1.3 to
1.5 FFT floors per iteration on a periodic grid (docs/contact.md, Cost). Here they are grouped
into seven functions, each one loop over the grid when compiled (:mod:`tactilab.core.jit`: numba;
two for :func:`project` under force control) and the original NumPy calls otherwise (the NumPy
twin, with ``TACTILAB_JIT=0`` or without numba): 0.55 to 0.7 floors. Each function takes
``compiled`` (the caller asks :func:`tactilab.core.jit.enabled` once per solve) and gives the same
elementwise values either way; only the order of the additions in a sum differs (the compiled sums
add in SIMD lanes, NumPy's einsum and sum in blocks), so the two paths' iterates agree to round-off
(tests/test_contact_kernels.py).

The passes, in the order of an iteration (arrays of the grid's shape, C-contiguous, float64 unless
said; ``g`` gap in m, ``p`` pressure in Pa, ``u`` displacement in m):

1. :func:`gap`: the pending force rescaling of ``p`` and ``u``, ``g = g0 + u``, and the count and
   sum of ``g`` over the contact set ``p > 0``;
2. :func:`residual`: ``g -= delta``, the working set ``S = (g < 0) | (p > 0)``, ``r = g S`` and
   ``max |r|``;
3. :func:`project`: after ``z = K r``: ``z`` minus its mean on ``S`` (force control), masked by ``S``,
   and the products ``<r, z>``, ``<r, z_old>``;
4. :func:`direction`: ``t = beta t S + z`` and ``<r, t>``;
5. :func:`dot`: ``<A t, t>``;
6. :func:`descend`: ``p -= tau t``, negative pressures clipped to 0 and the first ones recorded,
   the sum of ``p``;
7. :func:`subtract_scaled`: ``u -= tau A t``, when the displacement is updated rather than
   recomputed.
"""

from __future__ import annotations

import numpy as np

from tactilab.core import jit

from .normal import _dot


def _flat(a: np.ndarray) -> np.ndarray:
    """A 1-D view of a C-contiguous array (the kernels loop over one index)."""
    return a.reshape(-1)


# -- the compiled kernels: one loop each, no temporaries -----------------------------------------
# Sums are reassociated (jit.njit(reassociate=True): SIMD lanes, twice as fast as one running sum,
# whose adder latency took as long as the memory traffic); every other value is computed as in the
# NumPy twin. Masks enter as 0/1 factors, not branches (the working set is scattered).

#: the bits of a float64 without its sign
_MAGNITUDE = np.int64(0x7FFFFFFFFFFFFFFF)


@jit.njit(reassociate=True)
def _gap_kernel(g0, u, p, g, factor):
    n_in, total = 0, 0.0
    if factor != 1.0:  # the force's rescaling, in the same pass
        for i in range(g.size):
            u[i] *= factor
            p[i] *= factor
            g[i] = v = g0[i] + u[i]
            inside = p[i] > 0.0
            total += v * np.float64(inside)
            n_in += np.int64(inside)
        return n_in, total
    for i in range(g.size):
        g[i] = v = g0[i] + u[i]
        inside = p[i] > 0.0
        total += v * np.float64(inside)  # as NumPy's sum of g * inside
        n_in += np.int64(inside)
    return n_in, total


@jit.njit
def _residual_kernel(g, delta, p, S, r):
    # max |r| on the bits: a float's magnitude orders as its bits without the sign, and NaN's bits
    # exceed infinity's, so the integer maximum is max |r|, or NaN if any r is NaN, and it runs in
    # SIMD lanes where a float maximum that must keep NaN does not (4x slower)
    bits = r.view(np.int64)
    n_set, largest = 0, np.int64(0)
    for i in range(g.size):
        g[i] = v = g[i] - delta
        s = (v < 0.0) | (p[i] > 0.0)
        S[i] = s
        r[i] = v * np.float64(s)  # as NumPy's g * S: NaN stays NaN off the set
        n_set += np.int64(s)
        largest = max(largest, bits[i] & _MAGNITUDE)
    return largest, n_set


@jit.njit(reassociate=True)
def _masked_sum_kernel(z, S):
    total = 0.0
    for i in range(z.size):
        total += z[i] * np.float64(S[i])
    return total


@jit.njit(reassociate=True)
def _project_kernel(z, S, mean, r, z_old):
    rz, rz_old = 0.0, 0.0
    for i in range(z.size):
        z[i] = v = (z[i] - mean) * np.float64(S[i])
        rz += r[i] * v
        rz_old += r[i] * z_old[i]
    return rz, rz_old


@jit.njit(reassociate=True)
def _dot_kernel(a, b):
    total = 0.0
    for i in range(a.size):
        total += a[i] * b[i]
    return total


@jit.njit(reassociate=True)
def _dot_peak_kernel(a, b):
    total, peak = 0.0, 0.0
    for i in range(a.size):
        total += a[i] * b[i]
        peak = max(peak, abs(a[i]))
    return total, peak


@jit.njit(reassociate=True)
def _direction_kernel(t, z, S, beta, r):
    rt = 0.0
    if beta > 0.0:
        for i in range(t.size):
            t[i] = v = (t[i] * beta) * np.float64(S[i]) + z[i]
            rt += r[i] * v
    else:  # a restart
        for i in range(t.size):
            t[i] = v = z[i]
            rt += r[i] * v
    return rt


@jit.njit
def _descend_kernel(p, t, tau, nodes, values):
    # blocks of four nodes with four partial sums: the rare clipped node is a branch per block, which
    # keeps the loop from running in SIMD lanes, so the sum is split by hand
    s0 = s1 = s2 = s3 = 0.0
    m, size = 0, p.size
    tail = size - size % 4
    for i in range(0, tail, 4):
        v0, v1 = p[i] - t[i] * tau, p[i + 1] - t[i + 1] * tau
        v2, v3 = p[i + 2] - t[i + 2] * tau, p[i + 3] - t[i + 3] * tau
        if (v0 < 0.0) | (v1 < 0.0) | (v2 < 0.0) | (v3 < 0.0):
            for j in range(i, i + 4):
                v = p[j] - t[j] * tau
                if v < 0.0:
                    if m < nodes.size:
                        nodes[m] = j
                        values[m] = -v
                    m += 1
            v0, v1 = (0.0 if v0 < 0.0 else v0), (0.0 if v1 < 0.0 else v1)  # NaN stays, as np.maximum
            v2, v3 = (0.0 if v2 < 0.0 else v2), (0.0 if v3 < 0.0 else v3)
        p[i], p[i + 1], p[i + 2], p[i + 3] = v0, v1, v2, v3
        s0, s1, s2, s3 = s0 + v0, s1 + v1, s2 + v2, s3 + v3
    for i in range(tail, size):
        v0 = p[i] - t[i] * tau
        if v0 < 0.0:
            if m < nodes.size:
                nodes[m] = i
                values[m] = -v0
            m += 1
            v0 = 0.0
        p[i] = v0
        s0 += v0
    return m, (s0 + s1) + (s2 + s3)


@jit.njit
def _subtract_scaled_kernel(u, a, scale):
    for i in range(u.size):
        u[i] -= a[i] * scale


# -- the passes: compiled kernel or NumPy twin --------------------------------------------------
def gap(g0: np.ndarray, u: np.ndarray, p: np.ndarray, g: np.ndarray, inside: np.ndarray, factor: float,
        compiled: bool) -> tuple[int, float]:
    """Rescale ``u`` and ``p`` by ``factor`` (when not 1), then ``g = g0 + u`` and the contact set.

    Parameters
    ----------
    g0, u, p, g : ndarray, the grid's shape
        Initial gap (m), displacement (m), pressure (Pa), and the gap's output (m); ``u`` and ``p``
        are scaled in place.
    inside : ndarray of bool, the grid's shape
        Work array (the NumPy twin writes ``p > 0`` into it).
    factor : float
        The force rescaling left over from the previous iteration (1: none).
    compiled : bool
        Run the compiled kernel (else the NumPy twin).

    Returns
    -------
    n_in : int
        Nodes in contact (``p > 0``).
    sum_in : float
        Sum of ``g`` over them, m.
    """
    if compiled:
        n_in, total = _gap_kernel(_flat(g0), _flat(u), _flat(p), _flat(g), float(factor))
        return int(n_in), float(total)
    if factor != 1.0:
        u *= factor
        p *= factor
    np.add(g0, u, out=g)
    np.greater(p, 0.0, out=inside)
    return int(np.count_nonzero(inside)), _dot(g, inside)  # a masked sum (where=) is 5x slower


def residual(g: np.ndarray, delta: float, p: np.ndarray, inside: np.ndarray, S: np.ndarray, r: np.ndarray,
             compiled: bool) -> tuple[float, int]:
    """``g -= delta``, the working set ``S`` (in contact or penetrating) and the residual ``r = g S``.

    Parameters
    ----------
    g : ndarray, the grid's shape
        Gap in m, shifted in place by ``delta`` (m, the approach).
    p : ndarray, the grid's shape
        Pressure, Pa.
    inside : ndarray of bool, the grid's shape
        ``p > 0`` as :func:`gap`'s NumPy twin left it (the compiled kernel reads ``p`` instead).
    S : ndarray of bool, the grid's shape
        Output: the working set.
    r : ndarray, the grid's shape
        Output: the residual, m.
    compiled : bool
        Run the compiled kernel (else the NumPy twin).

    Returns
    -------
    residual : float
        ``max |r|`` in m (NaN if any ``r`` is NaN).
    n_set : int
        Nodes in ``S``.
    """
    if compiled:
        bits, n_set = _residual_kernel(_flat(g), float(delta), _flat(p), _flat(S), _flat(r))
        return float(np.int64(bits).view(np.float64)), int(n_set)
    g -= delta
    np.less(g, 0.0, out=S)
    S |= inside  # the working set: in contact, or penetrating (entering)
    np.multiply(g, S, out=r)
    return max(float(r.max()), -float(r.min())), int(np.count_nonzero(S))


def project(z: np.ndarray, S: np.ndarray, n_set: int, r: np.ndarray, z_old: np.ndarray, force: bool,
            compiled: bool) -> tuple[float, float]:
    """The preconditioned residual ``z`` restricted to the working set, and its products with ``r``.

    Parameters
    ----------
    z : ndarray, the grid's shape
        ``K r`` in Pa; in place: minus its mean on ``S`` (when ``force``, so that the step keeps the
        force), then 0 off ``S``.
    S : ndarray of bool, the grid's shape
        The working set, with ``n_set`` nodes.
    r, z_old : ndarray, the grid's shape
        The residual (m) and the previous iteration's ``z`` (Pa).
    force : bool
        Force control (remove the mean on ``S``).
    compiled : bool
        Run the compiled kernels (else the NumPy twin).

    Returns
    -------
    rz, rz_old : float
        ``<r, z>`` and ``<r, z_old>``, m Pa.
    """
    if compiled:
        zf, sf = _flat(z), _flat(S)
        mean = _masked_sum_kernel(zf, sf) / n_set if force else 0.0
        rz, rz_old = _project_kernel(zf, sf, float(mean), _flat(r), _flat(z_old))
        return float(rz), float(rz_old)
    if force:  # minus its mean on S (then masked): np.subtract(..., where=S) costs half an FFT pair
        z -= _dot(z, S) / n_set
    z *= S
    return _dot(r, z), _dot(r, z_old)


def direction(t: np.ndarray, z: np.ndarray, S: np.ndarray, beta: float, r: np.ndarray, compiled: bool) -> float:
    """The conjugate direction ``t = beta t S + z`` (``t = z`` when ``beta <= 0``), in place; ``<r, t>``.

    Parameters
    ----------
    t : ndarray, the grid's shape
        The previous direction, Pa; overwritten by the new one.
    z : ndarray, the grid's shape
        The projected preconditioned residual (:func:`project`), Pa.
    S : ndarray of bool, the grid's shape
        The working set (nodes that left it leave the direction).
    beta : float
        Polak-Ribiere's coefficient, clipped at 0.
    r : ndarray, the grid's shape
        The residual, m.
    compiled : bool
        Run the compiled kernel (else the NumPy twin).

    Returns
    -------
    float
        ``<r, t>``, m Pa.
    """
    if compiled:
        return float(_direction_kernel(_flat(t), _flat(z), _flat(S), float(beta), _flat(r)))
    if beta > 0:
        t *= beta
        t *= S
        t += z
    else:
        t[...] = z
    return _dot(r, t)


def dot(a: np.ndarray, b: np.ndarray, compiled: bool) -> float:
    """``sum(a * b)`` in one pass (``a``, ``b``: arrays of the grid's shape)."""
    return float(_dot_kernel(_flat(a), _flat(b))) if compiled else _dot(a, b)


def dot_peak(a: np.ndarray, b: np.ndarray, compiled: bool) -> tuple[float, float]:
    """``sum(a * b)`` and ``max |a|`` in one pass (``a``, ``b``: arrays of the grid's shape)."""
    if compiled:
        total, peak = _dot_peak_kernel(_flat(a), _flat(b))
        return float(total), float(peak)
    return _dot(a, b), max(float(a.max()), -float(a.min()))


def descend(p: np.ndarray, t: np.ndarray, tau: float, nodes: np.ndarray, values: np.ndarray, tmp: np.ndarray,
            force: bool, compiled: bool) -> tuple[int, float]:
    """The step ``p -= tau t`` with negative pressures clipped to 0, the first clipped ones recorded.

    Parameters
    ----------
    p : ndarray, the grid's shape
        Pressure, Pa, in place.
    t : ndarray, the grid's shape
        Direction, Pa per unit step.
    tau : float
        The step (dimensionless).
    nodes : ndarray of int64, shape (k,)
        Output: flat indices of the first ``k`` clipped nodes (those beyond are clipped, not recorded).
    values : ndarray, shape (k,)
        Output: the pressure added at each recorded node to bring it back to 0, Pa (positive).
    tmp : ndarray, the grid's shape
        Work array of the NumPy twin.
    force : bool
        Force control: return the sum of ``p`` (for the rescaling to the force).
    compiled : bool
        Run the compiled kernel (else the NumPy twin).

    Returns
    -------
    m : int
        Nodes clipped (all of them, recorded or not).
    sum_p : float
        Sum of the clipped ``p``, Pa (0 when not ``force`` in the NumPy twin, which skips it).
    """
    if compiled:
        m, total = _descend_kernel(_flat(p), _flat(t), float(tau), nodes, values)
        return int(m), float(total)
    np.multiply(t, tau, out=tmp)
    p -= tmp
    m = 0
    if float(p.min()) < 0:
        flat = _flat(p)
        clipped = np.flatnonzero(flat < 0.0)
        m = clipped.size
        k = min(m, nodes.size)
        nodes[:k] = clipped[:k]
        values[:k] = -flat[clipped[:k]]
        np.maximum(p, 0.0, out=p)
    return m, (float(p.sum()) if force else 0.0)


def subtract_scaled(u: np.ndarray, a: np.ndarray, scale: float, tmp: np.ndarray, compiled: bool) -> None:
    """``u -= scale * a`` in place (``u``, ``a``, ``tmp``: arrays of the grid's shape; ``tmp`` is the
    NumPy twin's work array)."""
    if compiled:
        _subtract_scaled_kernel(_flat(u), _flat(a), float(scale))
        return
    np.multiply(a, scale, out=tmp)
    u -= tmp

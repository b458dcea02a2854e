"""The fused passes of the preconditioned contact loop (:mod:`.preconditioned`), compiled or in NumPy.

Between its FFT products an iteration of :func:`.preconditioned.preconditioned_cg` makes about 30
elementwise NumPy passes over the grid (each a read and a write of one or two grid arrays): 1.3 to
1.5 FFT floors per iteration on a periodic grid (docs/contact.md, Cost). Here they are grouped
into six functions, each one loop over the grid when compiled (:mod:`tactilab.core.jit`: numba;
two for :func:`project` under force control) and the original NumPy calls otherwise (the NumPy
twin, with ``TACTILAB_JIT=0`` or without numba). Each function takes ``compiled`` (the caller asks
:func:`tactilab.core.jit.enabled` once per solve) and gives the same elementwise values either way;
only the order of the additions in a sum differs (the compiled sums add in SIMD lanes, NumPy's
einsum and sum in blocks), so the two paths' iterates agree to round-off
(tests/test_contact_kernels.py).

The passes before the step, in the order of an iteration (arrays of the grid's shape, C-contiguous,
float64 unless said; ``g`` gap in m, ``p`` pressure in Pa, ``u`` displacement in m):

1. :func:`gap`: the pending float32 clip correction and force rescaling of ``u`` (and the
   rescaling of ``p``), ``g = g0 + u``, and the count and sum of ``g`` over the contact set ``p > 0``;
2. :func:`residual`: ``g -= delta``, the working set ``S = (g < 0) | (p > 0)``, ``r = g S`` and
   ``max |r|``;
3. :func:`project`: after ``z = K r``: ``z`` minus its mean on ``S`` (force control), masked by ``S``,
   and the products ``<r, z>``, ``<r, z_old>``;
4. :func:`direction`: ``t = beta t S + z`` and ``<r, t>``.

Beside float32 direction products the residual ``r``, the direction ``t`` and the preconditioned
residuals ``z`` are float32 arrays (the float32 product's input as they are; a third less memory
traffic in the passes that read them): each value is computed in float64 and rounded once, and the
sums read the rounded values, on both paths; the convergence test's ``max |r|`` is of the unrounded
residual.

The step's passes (``<A t, t>``, ``p -= tau t`` clipped, ``u -= tau A t``) are in :mod:`.step_kernels`.
"""

from __future__ import annotations

import numpy as np

from tactilab.core import jit

from .normal import _dot
from .step_kernels import _dot_kernel


# -- the compiled kernels: one loop each, no temporaries -----------------------------------------
# Sums are reassociated (jit.njit(reassociate=True): SIMD lanes, twice as fast as one running sum,
# whose adder latency took as long as the memory traffic); every other value is computed as in the
# NumPy twin. Masks enter as 0/1 factors, not branches (the working set is scattered).

#: the bits of a float64 / float32 without its sign
_MAGNITUDE, _MAGNITUDE32 = np.int64(0x7FFFFFFFFFFFFFFF), np.int32(0x7FFFFFFF)


@jit.njit(reassociate=True)
def _gap_kernel(g0, u, p, g, factor):
    g0, u, p, g = g0.reshape(g0.size), u.reshape(u.size), p.reshape(p.size), g.reshape(g.size)  # 1-D views
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


@jit.njit(reassociate=True)
def _gap_pending_kernel(g0, u, p, g, factor, pending, bits):
    g0, u, p = g0.reshape(g0.size), u.reshape(u.size), p.reshape(p.size)  # 1-D views
    g, pending, bits = g.reshape(g.size), pending.reshape(pending.size), bits.reshape(bits.size)  # 1-D views
    # as _gap_kernel, with a pending float32 clip correction added to u first (u = (u + c) factor), and
    # max |c| on its bits (as _residual_kernel's maximum: NaN kept)
    n_in, total, largest = 0, 0.0, np.int32(0)
    for i in range(g.size):
        c = np.float64(pending[i])
        u[i] = w = (u[i] + c) * factor if factor != 1.0 else u[i] + c
        if factor != 1.0:
            p[i] *= factor
        g[i] = v = g0[i] + w
        inside = p[i] > 0.0
        total += v * np.float64(inside)
        n_in += np.int64(inside)
        largest = max(largest, bits[i] & _MAGNITUDE32)
    return n_in, total, largest


@jit.njit
def _residual_kernel(g, delta, p, S, r):
    g, p, S, r = g.reshape(g.size), p.reshape(p.size), S.reshape(S.size), r.reshape(r.size)  # 1-D views
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


@jit.njit
def _residual_single_kernel(g, delta, p, S, r):
    g, p, S, r = g.reshape(g.size), p.reshape(p.size), S.reshape(S.size), r.reshape(r.size)  # 1-D views
    # as _residual_kernel, r stored in float32; g keeps r in float64, whose bits give max |r| (the
    # convergence test's, unrounded)
    bits = g.view(np.int64)
    n_set, largest = 0, np.int64(0)
    for i in range(g.size):
        v = g[i] - delta
        s = (v < 0.0) | (p[i] > 0.0)
        S[i] = s
        g[i] = w = v * np.float64(s)
        r[i] = w
        n_set += np.int64(s)
        largest = max(largest, bits[i] & _MAGNITUDE)
    return largest, n_set


@jit.njit(reassociate=True)
def _project_kernel(z, S, mean, r, z_old):
    z, S = z.reshape(z.size), S.reshape(S.size)  # 1-D views
    r, z_old = r.reshape(r.size), z_old.reshape(z_old.size)  # 1-D views
    # z float64 or float32 (then the value is rounded to it before the products: read back)
    rz, rz_old = 0.0, 0.0
    for i in range(z.size):
        z[i] = (z[i] - mean) * np.float64(S[i])
        rz += r[i] * z[i]
        rz_old += r[i] * z_old[i]
    return rz, rz_old


@jit.njit(reassociate=True)
def _direction_kernel(t, z, S, beta, r):
    t, z, S, r = t.reshape(t.size), z.reshape(z.size), S.reshape(S.size), r.reshape(r.size)  # 1-D views
    # t, z float64 or float32 (then the value is rounded to t before the product: read back)
    rt = 0.0
    if beta > 0.0:
        for i in range(t.size):
            t[i] = (t[i] * beta) * np.float64(S[i]) + z[i]
            rt += r[i] * t[i]
    else:  # a restart
        for i in range(t.size):
            t[i] = z[i]
            rt += r[i] * t[i]
    return rt


# -- the passes: compiled kernel or NumPy twin --------------------------------------------------
def gap(g0: np.ndarray, u: np.ndarray, p: np.ndarray, g: np.ndarray, inside: np.ndarray, factor: float,
        compiled: bool, pending: np.ndarray | None = None) -> tuple[int, float]:
    """Add ``pending`` to ``u``, rescale ``u`` and ``p`` by ``factor`` (when not 1), then ``g = g0 + u``
    and the contact set.

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
    pending : ndarray of float32, the grid's shape, optional
        A clip correction (m) still to be added to ``u`` (before the rescaling).

    Returns
    -------
    n_in : int
        Nodes in contact (``p > 0``).
    sum_in : float
        Sum of ``g`` over them, m.
    peak : float
        ``max |pending|``, m (0 without one; NaN if any is NaN): the correction's a-posteriori error bound.
    """
    if compiled:
        if pending is not None:
            n_in, total, bits = _gap_pending_kernel(g0, u, p, g, float(factor), pending, pending.view(np.int32))
            return int(n_in), float(total), float(np.int32(bits).view(np.float32))
        n_in, total = _gap_kernel(g0, u, p, g, float(factor))
        return int(n_in), float(total), 0.0
    peak = 0.0
    if pending is not None:
        u += pending
        peak = max(float(pending.max()), -float(pending.min()))
    if factor != 1.0:
        u *= factor
        p *= factor
    np.add(g0, u, out=g)
    np.greater(p, 0.0, out=inside)
    return int(np.count_nonzero(inside)), _dot(g, inside), peak  # a masked sum (where=) is 5x slower


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
        Output: the residual, m: float64, or float32 beside float32 products (then ``g`` holds the
        residual in float64 on return, not the gap, and ``max |r|`` is of those unrounded values).
    compiled : bool
        Run the compiled kernel (else the NumPy twin).

    Returns
    -------
    residual : float
        ``max |r|`` in m (NaN if any ``r`` is NaN).
    n_set : int
        Nodes in ``S``.
    """
    single = r.dtype == np.float32
    if compiled:
        kernel = _residual_single_kernel if single else _residual_kernel
        bits, n_set = kernel(g, float(delta), p, S, r)
        return float(np.int64(bits).view(np.float64)), int(n_set)
    g -= delta
    np.less(g, 0.0, out=S)
    S |= inside  # the working set: in contact, or penetrating (entering)
    if single:
        g *= S
        r[...] = g
        return max(float(g.max()), -float(g.min())), int(np.count_nonzero(S))
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
        zf, sf = z, S
        mean = _dot_kernel(zf, sf) / n_set if force else 0.0  # _dot_kernel: the sum of z over S
        rz, rz_old = _project_kernel(zf, sf, float(mean), r, z_old)
        return float(rz), float(rz_old)
    if z.dtype != np.float64:  # float32 vectors: in float64, rounded once, as compiled
        wide = z.astype(float)
        if force:
            wide -= _dot(wide, S) / n_set
        wide *= S
        z[...] = wide
        return _dot(r, z.astype(float)), _dot(r, z_old.astype(float))
    if force:  # minus its mean on S (then masked): np.subtract(..., where=S) costs half an FFT pair
        z -= _dot(z, S) / n_set
    z *= S
    return _dot(r, z), _dot(r, z_old)


def direction(t: np.ndarray, z: np.ndarray, S: np.ndarray, beta: float, r: np.ndarray, compiled: bool) -> float:
    """The conjugate direction ``t = beta t S + z`` (``t = z`` when ``beta <= 0``), in place; ``<r, t>``.

    Parameters
    ----------
    t : ndarray, the grid's shape
        The previous direction, Pa; overwritten by the new one (float64, or float32 beside float32
        products: computed in float64 and rounded once).
    z : ndarray, the grid's shape
        The projected preconditioned residual (:func:`project`), Pa, of ``t``'s dtype.
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
        ``<r, t>``, m Pa (of the stored ``t``).
    """
    if compiled:
        return float(_direction_kernel(t, z, S, float(beta), r))
    if t.dtype != np.float64:  # float32 vectors: in float64, rounded once, as compiled
        wide = t * np.float64(beta) * S + z if beta > 0 else z.astype(float)
        t[...] = wide
        return _dot(r, t.astype(float))
    if beta > 0:
        t *= beta
        t *= S
        t += z
    else:
        t[...] = z
    return _dot(r, t)

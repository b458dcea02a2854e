"""The step of the preconditioned contact loop (:mod:`.preconditioned`): its fused passes, compiled or in NumPy.

After the direction ``t`` and its compliance product ``A t`` (float64, or float32 from the
mixed-precision product of :mod:`.single_correction`: each compiled kernel is specialised by
numba for either dtype, the NumPy twin promotes float32 to float64 exactly), the loop takes

5. ``<A t, t>``: :func:`dot` after a float64 product; after a float32 one by Parseval from ``t``'s
   spectrum, in the pass that multiplies it by the compliance's (:func:`scale_energy`);
6. :func:`descend`: ``p -= tau t`` with negative pressures clipped to 0 and the first ones recorded,
   the sum of ``p``, and in the same pass ``u -= tau A t`` (wasted on the iterations that recompute
   ``u`` in float64 instead) and ``max |A t|`` (the float32 product's error bound).

Each function takes ``compiled`` (:func:`tactilab.core.jit.enabled`, asked once per solve) and
gives the same elementwise values either way; only the order of the additions in a sum differs, as
in :mod:`.kernels` (the passes before the step), whose conventions these follow
(tests/test_contact_kernels.py).
"""

from __future__ import annotations

import numpy as np

from tactilab.core import jit

from .normal import _dot


def _flat(a: np.ndarray) -> np.ndarray:
    """A 1-D view of a C-contiguous array (the kernels loop over one index)."""
    return a.reshape(-1)


def _wide(a: np.ndarray) -> np.ndarray:
    """``a`` in float64 (the NumPy twins' sums of float32 arrays add in float64, as the kernels do)."""
    return a if a.dtype == np.float64 else a.astype(float)


@jit.njit(reassociate=True)
def _dot_kernel(a, b):
    a, b = a.reshape(a.size), b.reshape(b.size)  # 1-D views
    total = 0.0
    for i in range(a.size):
        total += np.float64(a[i]) * np.float64(b[i])
    return total


@jit.njit(reassociate=True)
def _scale_energy_kernel(spectrum, multiplier, nyquist):
    # the sum of multiplier |spectrum|^2 over the full spectrum (the half's columns counted twice, but the
    # first and a Nyquist last once), then the spectrum scaled by the real multiplier in place (complex64
    # times float32, as NumPy's)
    rows, cols = spectrum.shape
    edges = 0.0
    for i in range(rows):
        v = spectrum[i, 0]
        edges += np.float64(multiplier[i, 0]) * (np.float64(v.real) ** 2 + np.float64(v.imag) ** 2)
        if nyquist:
            v = spectrum[i, cols - 1]
            edges += np.float64(multiplier[i, cols - 1]) * (np.float64(v.real) ** 2 + np.float64(v.imag) ** 2)
    total = 0.0
    for i in range(rows):
        s, m = spectrum[i], multiplier[i]
        for j in range(cols):
            v = s[j]
            total += np.float64(m[j]) * (np.float64(v.real) ** 2 + np.float64(v.imag) ** 2)
            s[j] = v * m[j]
    return 2.0 * total - edges


def scale_energy(spectrum: np.ndarray, multiplier: np.ndarray, nyquist: bool, compiled: bool) -> float:
    """``spectrum *= multiplier`` in place and, in the same pass, ``sum(multiplier |spectrum|^2)`` over the
    full spectrum that the rfft half ``spectrum`` stands for: the solver's ``<A t, t>`` by Parseval.

    Parameters
    ----------
    spectrum : ndarray of complex64, shape (rows, cols)
        The half spectrum of ``t`` (the last axis the rfft's), scaled in place.
    multiplier : ndarray of float32, the same shape
        The real multiplier (a symmetric operator's spectrum).
    nyquist : bool
        Whether the last column is a Nyquist one (an even transform length along the last axis), counted
        once like the first; the others stand for two columns each.
    compiled : bool
        Run the compiled kernel (else the NumPy twin).

    Returns
    -------
    float
        The sum, before the scaling, in float64.
    """
    if compiled:
        return float(_scale_energy_kernel(spectrum, multiplier, bool(nyquist)))
    power = (spectrum.real.astype(float) ** 2 + spectrum.imag.astype(float) ** 2) * multiplier
    edges = float(power[:, 0].sum()) + (float(power[:, -1].sum()) if nyquist else 0.0)
    spectrum *= multiplier
    return 2.0 * float(power.sum()) - edges


@jit.njit
def _descend_kernel(p, t, tau, nodes, values, u, a, bits, magnitude):
    p, t, u, a = p.reshape(p.size), t.reshape(t.size), u.reshape(u.size), a.reshape(a.size)  # 1-D views
    bits = bits.reshape(bits.size)  # a's bits: max |a| on them (kernels._residual_kernel's way; NaN kept)
    peak = magnitude & 0
    # blocks of four nodes with four partial sums: the rare clipped node is a branch per block, which
    # keeps the loop from running in SIMD lanes, so the sum is split by hand
    s0 = s1 = s2 = s3 = 0.0
    m, size = 0, p.size
    tail = size - size % 4
    for i in range(0, tail, 4):
        u[i] -= np.float64(a[i]) * tau
        u[i + 1] -= np.float64(a[i + 1]) * tau
        u[i + 2] -= np.float64(a[i + 2]) * tau
        u[i + 3] -= np.float64(a[i + 3]) * tau
        peak = max(peak, max(max(bits[i] & magnitude, bits[i + 1] & magnitude),
                             max(bits[i + 2] & magnitude, bits[i + 3] & magnitude)))
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
        u[i] -= np.float64(a[i]) * tau
        peak = max(peak, bits[i] & magnitude)
        v0 = p[i] - t[i] * tau
        if v0 < 0.0:
            if m < nodes.size:
                nodes[m] = i
                values[m] = -v0
            m += 1
            v0 = 0.0
        p[i] = v0
        s0 += v0
    return m, (s0 + s1) + (s2 + s3), peak


def dot(a: np.ndarray, b: np.ndarray, compiled: bool) -> float:
    """``sum(a * b)`` in one pass, in float64 (``a``, ``b``: float64 or float32 arrays of the grid's shape)."""
    return float(_dot_kernel(a, b)) if compiled else _dot(_wide(a), _wide(b))


def descend(p: np.ndarray, t: np.ndarray, tau: float, nodes: np.ndarray, values: np.ndarray, tmp: np.ndarray,
            force: bool, u: np.ndarray, At: np.ndarray, compiled: bool) -> tuple[int, float]:
    """The step ``p -= tau t`` with negative pressures clipped to 0, the first clipped ones recorded, and
    the displacement's update ``u -= tau A t``.

    Parameters
    ----------
    p : ndarray, the grid's shape
        Pressure, Pa, in place.
    t : ndarray, the grid's shape
        Direction, Pa per unit step (float64, or float32 beside float32 products).
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
    u : ndarray, the grid's shape
        Displacement, m, in place (its clip corrections are the caller's).
    At : ndarray, the grid's shape, float64 or float32
        The direction's compliance product, m per unit step.
    compiled : bool
        Run the compiled kernel (else the NumPy twin).

    Returns
    -------
    m : int
        Nodes clipped (all of them, recorded or not).
    sum_p : float
        Sum of the clipped ``p``, Pa (0 when not ``force`` in the NumPy twin, which skips it).
    peak : float
        ``max |A t|``, m per unit step (NaN if any is NaN): the float32 product's error bound.
    """
    if compiled:
        single = At.dtype == np.float32
        kind, magnitude = (np.int32, np.int32(0x7FFFFFFF)) if single else (np.int64, np.int64(0x7FFFFFFFFFFFFFFF))
        m, total, bits = _descend_kernel(p, t, float(tau), nodes, values, u, At, At.view(kind), magnitude)
        return int(m), float(total), float(kind(bits).view(At.dtype))
    peak = max(float(At.max()), -float(At.min()))
    np.multiply(At, np.float64(tau), out=tmp)  # a float64 scalar: float32 products promote, as compiled
    u -= tmp
    np.multiply(t, np.float64(tau), out=tmp)
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
    return m, (float(p.sum()) if force else 0.0), peak

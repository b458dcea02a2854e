"""Compiled kernels: numba when it is installed and enabled, the NumPy twin of each kernel otherwise.

One switch for the whole package. A module that has a compiled kernel keeps its NumPy version
beside it (the two are tested to agree) and chooses at call time::

    from tactilab.core import jit

    @jit.njit
    def _fused(a, b, out): ...          # plain Python loops; compiled by numba when available

    if jit.enabled():
        _fused(a, b, out)
    else:
        np.add(a, b, out=out)           # the NumPy twin

``numba`` is the optional extra ``fast`` (``pip install 'tactilab[fast]'``); without it every kernel
runs its NumPy twin, with the same results. ``TACTILAB_JIT=0`` in the environment turns the
compiled kernels off (read at each call, so a test can switch it). Kernels compile on their first
call (about a second each) into numba's on-disk cache, so later processes start at once. They are
compiled single-threaded: the benchmarks compare one core with one core.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import TypeVar

try:  # optional: the "fast" extra
    import numba as _numba
except ImportError:  # pragma: no cover - exercised where numba is absent
    _numba = None

__all__ = ["available", "enabled", "njit"]

F = TypeVar("F", bound=Callable)


def available() -> bool:
    """True when numba can be imported (the ``fast`` extra is installed)."""
    return _numba is not None


def enabled() -> bool:
    """True when compiled kernels run: numba is available and ``TACTILAB_JIT`` is not ``0``."""
    return _numba is not None and os.environ.get("TACTILAB_JIT", "1").strip() != "0"


def njit(func: F | None = None, *, reassociate: bool = False):
    """Compile ``func`` with numba (no Python objects, on-disk cache, NumPy's error model).

    Without numba, ``func`` is returned as is: callers run their NumPy twin instead (see
    :func:`enabled`), never the pure-Python loops. ``fastmath`` stays off so that NaN and
    infinities propagate exactly as in NumPy.

    ``reassociate=True`` (used as ``@jit.njit(reassociate=True)``) lets the compiler reorder the
    additions of a sum (LLVM's ``reassoc`` flag alone), so that a loop that accumulates a sum runs
    in SIMD lanes: about twice as fast when the data are in cache. A sum's value then differs from
    the sequential one by round-off (as NumPy's own sums, which add in blocks, do); NaN and
    infinities still propagate, since no other fast-math flag is set. Give it only to kernels whose
    other results do not depend on the order of operations.
    """
    if func is None:
        return lambda f: njit(f, reassociate=reassociate)
    if _numba is None:
        return func
    flags = {"fastmath": {"reassoc"}} if reassociate else {}
    return _numba.njit(cache=True, nogil=True, error_model="numpy", **flags)(func)

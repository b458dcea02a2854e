"""Work arrays of the contact loop: carved from one allocation, and kept between solves of small grids.

The preconditioned loop (:mod:`.preconditioned`) and its float32 products (:mod:`.single_correction`)
use a dozen grid-sized work arrays. Fresh ones cost their first touch (page faults: 0.05 to 0.1 FFT
floors per iteration at 256^2 and 512^2), so the sets of small grids are kept per thread between
solves; and each set is carved from one allocation, which a large grid gets as one mapping and
returns to the system whole (separate grid-sized arrays left glibc's heap fragmented: a 1024^2
solve's peak memory was 35 MiB higher).
"""

from __future__ import annotations

import collections
import threading

import numpy as np

#: the most bytes of work arrays kept per thread between solves, for the last two grids solved (a fine grid
#: and its check grid, each with its float64 and float32 sets: grids up to 512^2); a solve on a larger grid
#: allocates its own and frees the kept ones first
KEPT_BYTES = 40 * 2**20
_KEPT = threading.local()


def work_arrays(shape: tuple[int, ...], dtype=np.float64, count: int = 7, bools: int = 2) -> tuple[np.ndarray, ...]:
    """The loop's work arrays (``count`` arrays of ``dtype``, then ``bools`` bool arrays, of ``shape``, contents
    undefined), kept per thread for the last two grids' sets while they fit :data:`KEPT_BYTES`."""
    key = (tuple(shape), np.dtype(dtype).str, count, bools)
    kept = getattr(_KEPT, "arrays", None)
    if kept is None:
        kept = _KEPT.arrays = collections.OrderedDict()
    if key in kept:
        kept.move_to_end(key)
        return kept[key]
    fresh = carve([(shape, dtype)] * count + [(shape, bool)] * bools)
    if sum(a.nbytes for a in fresh) > KEPT_BYTES // 2:
        kept.clear()  # a large grid: its memory comes first
        return fresh
    kept[key] = fresh
    while len(kept) > 4:  # two grids, each with its float64 set and, beside float32 products, its float32 one
        kept.popitem(last=False)
    return fresh


def carve(specs: list[tuple[tuple[int, ...], object]]) -> tuple[np.ndarray, ...]:
    """C-contiguous arrays of the ``(shape, dtype)`` in ``specs`` (contents undefined), carved from one
    allocation, each on a cache line of its own."""
    offsets, total = [], 0
    for shape, dtype in specs:
        total = -(-total // 64) * 64
        offsets.append(total)
        total += int(np.prod(shape)) * np.dtype(dtype).itemsize
    memory = np.empty(total + 64, np.uint8)
    start = -memory.ctypes.data % 64  # the first array on a cache line too
    return tuple(memory[start + o:start + o + int(np.prod(shape)) * np.dtype(dtype).itemsize].view(dtype).reshape(shape)
                 for o, (shape, dtype) in zip(offsets, specs))

"""The contact loop's work arrays (forward/contact/work_arrays.py): carved from one allocation, kept for small grids."""

import numpy as np

from tactilab.forward.contact import work_arrays as wa


def test_carve_gives_separate_aligned_arrays():
    specs = [((5, 7), np.float64), ((5, 7), bool), ((3,), np.float32), ((5, 4), np.complex64)]
    arrays = wa.carve(specs)
    for a, (shape, dtype) in zip(arrays, specs):
        assert a.shape == shape and a.dtype == dtype and a.flags.c_contiguous and a.ctypes.data % 64 == 0
    for i, a in enumerate(arrays):  # writing one leaves the others as they were
        for b in arrays:
            b[...] = 0
        a[...] = 1
        assert all(not b.any() for j, b in enumerate(arrays) if j != i)


def test_the_loops_work_arrays_are_kept_for_two_small_grids():
    """Kept per thread for the last two grids' sets (a fine grid and its check grid, float64 and float32);
    a grid beyond KEPT_BYTES gets fresh arrays and frees the kept ones."""
    wa._KEPT.arrays = None  # as a new thread
    first = wa.work_arrays((32, 32))
    assert wa.work_arrays((32, 32))[0] is first[0]
    assert len(first) == 9 and first[0].shape == (32, 32) and first[0].dtype == float and first[-1].dtype == bool
    single = wa.work_arrays((32, 32), np.float32, 3, 0)
    assert len(single) == 3 and single[0].dtype == np.float32 and single[0] is not first[0]
    for shape in ((16, 16), (8, 8), (4, 4)):
        wa.work_arrays(shape)
    # four sets kept, the least recent first out
    assert [key[0] for key in wa._KEPT.arrays] == [(32, 32), (16, 16), (8, 8), (4, 4)]
    n = int(np.sqrt(wa.KEPT_BYTES // 2 // 58)) + 8
    big = wa.work_arrays((n, n))
    assert wa.work_arrays((n, n))[0] is not big[0] and not wa._KEPT.arrays

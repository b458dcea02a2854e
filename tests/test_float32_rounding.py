"""float32 answers: the rounding estimate is relative to the field's peak and holds at any magnitude.

The oracle is the same computation in float64 (tol 1e-9); the float32 one (tol 1e-3) differs from it by
its rounding only. Before, a nodal-force method scaled a traction-relative float32 floor by peak traction
/ peak field (1e3x too big at 3 mm), and loads below about 1e-38 Pa or above 3e38 Pa left float32's
range (1e-40 Pa: true error 1e-4 at an estimate of 9e-5; 1e-44 Pa: 0.64; 1e38 Pa: NaN).
"""

import math
import warnings

import numpy as np
import pytest

from tactilab.forward.halfspace import HalfSpace, SurfaceLoad

N, H = 64, 1e-4
X = (np.arange(N) - N / 2) * H
ROUNDING = 5e-7 * math.log2(N * N)  # the float32 term, relative to the field's peak


@pytest.mark.parametrize("magnitude", [1e-300, 1e-44, 1e-40, 1.0, 1e38, 1e300])
@pytest.mark.parametrize("periodic, method", [(True, "spectral"), (False, "dcfft")])
def test_float32_estimate_covers_the_true_rounding_at_every_magnitude(magnitude, periodic, method):
    p = magnitude * np.exp(-(X[:, None] ** 2 + X[None, :] ** 2) / 2e-4 ** 2)
    qx = 0.3 * magnitude * np.exp(-((X[:, None] - 1e-3) ** 2 + X[None, :] ** 2) / 2e-4 ** 2)
    load = SurfaceLoad(p=p, qx=qx, spacing=H, periodic=periodic)
    hs = HalfSpace(E=1e6, nu=0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # huge loads are implausible and say so; not the point here
        exact = hs.stress(load, 3e-3, method=method, tol=1e-9)
        single = hs.stress(load, 3e-3, method=method, tol=1e-3)
    assert single.data.attrs["dtype"] == "float32" and exact.data.attrs["dtype"] == "float64"
    a, b = exact.data["stress"].values, single.data["stress"].values.astype(float)
    assert np.isfinite(b).all()
    true = np.abs(b - a).max() / np.abs(a).max()
    assert true <= single.error_estimate
    # the float32 estimate is the float64 one plus the rounding relative to the field's peak, never that
    # rounding scaled by peak traction / peak field (10 to 1000 at depth)
    assert single.error_estimate <= exact.error_estimate + ROUNDING * (1 + 1e-9)
    assert true >= 1e-8  # it is float32 rounding that was measured (eps32 = 1.2e-7)

"""The solver's dot test, and the load-to-sensor operator passing it on every path."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.linalg import LinearOperator, aslinearoperator

from tactilab.forward import HalfSpace, dottest

HS = HalfSpace(1.5e5, 0.45)


@pytest.mark.parametrize("loads", [("p",), ("qx", "p")])
@pytest.mark.parametrize("path", ["fft-periodic", "fft-padded", "dense"])
@pytest.mark.parametrize("ndim", [1, 2])
@pytest.mark.parametrize("quantity", ["stress", "strain"])
def test_load_to_sensor_passes_the_dot_test_on_every_path(rng, loads, path, ndim, quantity):
    shape = (18,) if ndim == 1 else (7, 9)
    spacing = 1e-4 if ndim == 1 else (1e-4, 1.4e-4)
    sensors = None
    if path == "dense":
        sensors = rng.uniform(-5e-4, 5e-4, size=(5, ndim))
    op = HS.operator(shape, spacing, sensors=sensors, depth=2e-4, components=("zz", "xz", "xx"), loads=loads,
                     quantity=quantity, periodic=path == "fft-periodic")
    assert op.path == path and op.shape[1] == len(loads) * int(np.prod(shape))
    assert dottest(op, rng=rng, rtol=1e-11) <= 1e-11


def test_dottest_catches_a_wrong_adjoint(rng):
    bad = aslinearoperator(np.arange(6.0).reshape(2, 3))
    good = dottest(bad, rng=rng)
    assert good < 1e-14
    wrong = LinearOperator((2, 3), matvec=lambda x: bad.matvec(x), rmatvec=lambda y: 2 * bad.rmatvec(y),
                           dtype=float)
    with pytest.raises(ValueError, match=r"dottest: adjoint mismatch 5.000e-01 exceeds rtol=1e-10"):
        dottest(wrong, rng=rng)
    assert dottest(wrong, rng=rng, raise_error=False) == pytest.approx(0.5)

    class BatchOnlyWrong(LinearOperator):  # matvec right, matmat adjoint wrong
        def __init__(self):
            super().__init__(dtype=float, shape=(2, 3))

        def _matvec(self, x):
            return bad.matvec(x)

        def _rmatvec(self, y):
            return bad.rmatvec(y)

        def _rmatmat(self, y):
            return -bad.rmatmat(y)

    with pytest.raises(ValueError, match=r"mismatch 2\.000e\+00 .*matmat/rmatmat column"):
        dottest(BatchOnlyWrong(), rng=rng)


def test_dottest_validation():
    with pytest.raises(ValueError, match="op: expected a LinearOperator with matvec and rmatvec"):
        dottest(np.eye(3))
    with pytest.raises(ValueError, match="rtol: must be finite and > 0"):
        dottest(aslinearoperator(np.eye(3)), rtol=0.0)
    with pytest.raises(ValueError, match="n_columns: must be a whole number >= 1"):
        dottest(aslinearoperator(np.eye(3)), n_columns=0)


def test_inversion_uses_the_solvers_dottest(monkeypatch):
    from tactilab.inversion import operators

    seen = []
    monkeypatch.setattr(operators, "_solver_dottest", lambda op, rng, rtol: seen.append(rtol) or 0.0)
    assert operators.dottest(aslinearoperator(np.eye(2)), rtol=1e-9) == 0.0 and seen == [1e-9]
    assert "def dottest" in open(operators.__file__).read().split("_solver_dottest(op")[0]


@pytest.mark.parametrize("path", ["fft-periodic", "fft-padded", "dense"])
def test_load_to_sensor_refuses_non_finite_input(path):
    """One NaN used to give NaN everywhere (through the FFTs) without a word."""
    sensors = np.array([[1e-5, 2e-5], [-3e-4, 1e-4]]) if path == "dense" else None
    op = HS.operator((6, 8), 1e-4, sensors=sensors, depth=2e-4, components=("zz", "zx"), loads=("p", "qx"),
                     periodic=path == "fft-periodic")
    x = np.ones(op.shape[1])
    x[7] = np.nan
    with pytest.raises(ValueError, match=r"x \(model: tractions\): must be finite \(no NaN or inf\) in Pa, got nan "
                                         r"at index 7"):
        op.matvec(x)
    y = np.ones(op.shape[0])
    y[3] = np.inf
    with pytest.raises(ValueError, match=r"x \(data: sensor values\): must be finite .* got inf at index 3"):
        op.rmatvec(y)
    with pytest.raises(ValueError, match=r"x \(data: sensor values\): must be finite .* at index 3"):
        op.H @ y
    block = np.ones((op.shape[1], 2))
    block[5, 1] = -np.inf
    with pytest.raises(ValueError, match=r"x \(model: tractions\): must be finite .* got -inf at index \(5, 1\)"):
        op.matmat(block)
    assert np.all(np.isfinite(op @ np.ones(op.shape[1])))


def test_transfer_refuses_non_finite_wavenumbers():
    from tactilab.forward.halfspace import transfer

    xi = np.linspace(0, 1e4, 5)
    xi[2] = np.nan
    with pytest.raises(ValueError, match=r"xi: must be finite \(no NaN or inf\) in rad/m, got nan at index 2"):
        transfer(xi, None, 1e-3, 0.5, "p")
    with pytest.raises(ValueError, match=r"eta: must be finite .* got inf at index \(1, 0\)"):
        transfer(np.zeros((1, 3)), np.array([[0.0], [np.inf]]), 1e-3, 0.5, "p")

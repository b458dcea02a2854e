"""The method registry's template: guarded public methods, error scales as attributes, and the
selection beside METHODS."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tactilab.forward import HalfSpace, SurfaceLoad
from tactilab.forward.halfspace import METHODS, AccuracyWarning, Method, select_method
from tactilab.forward.halfspace.methods import DCFFT, ClosedForm, Problem, Spectral


def _problem(load, depths=(3e-4,), points=None, dtype=np.float64):
    return Problem(load, np.asarray(depths, float), 0.5, np.eye(6)[[2]], points, np.dtype(dtype))


def _gaussian(n=33, h=1e-4, periodic=False):
    x = (np.arange(n) - n // 2) * h
    xx, yy = np.meshgrid(x, x)
    return SurfaceLoad(p=1e4 * np.exp(-(xx**2 + yy**2) / (2 * (3 * h) ** 2)), spacing=h, periodic=periodic)


def test_subclasses_implement_only_the_hooks():
    for cls in METHODS.values():
        assert cls.compute is Method.compute and cls.error_estimate is Method.error_estimate
        assert "_compute" in cls.__dict__ and "_error" in cls.__dict__
    assert {name: cls.error_scale for name, cls in METHODS.items()} == {
        "closed_form": "traction", "spectral": "field", "dcfft": "traction"}


def test_compute_is_guarded():
    periodic = _problem(_gaussian(periodic=True))
    for cls in (DCFFT, ClosedForm):
        with pytest.raises(ValueError, match=f"method: '{cls.name}' cannot run here: the load is periodic"):
            cls().compute(periodic)
    off_grid = _problem(_gaussian(), points=np.array([[0.5e-4, 0.0]]))
    with pytest.raises(ValueError, match="method: 'dcfft' cannot run here: sensors lie off the grid nodes"):
        DCFFT().compute(off_grid)
    assert Spectral().compute(periodic).shape == (1, 1, 33, 33)


def test_error_scale_attribute_drives_the_rescaling():
    """A method registered under a new name keeps its scale (the facade used to switch on names)."""

    class Renamed(DCFFT):
        name = "my_dcfft"

    load = _gaussian()
    hs = HalfSpace(1e6)
    a = hs.stress(load, 3e-4, components=("zz",), method="dcfft")
    b = hs.stress(load, 3e-4, components=("zz",), method=Renamed)
    assert b.method == "my_dcfft"
    assert b.error_estimate == a.error_estimate
    problem = _problem(load)
    values = DCFFT().compute(problem)
    raw = DCFFT().error_estimate(problem)
    peak_traction = np.abs(load.p).max()
    assert DCFFT().field_error(problem, values) == pytest.approx(raw * peak_traction / np.abs(values).max())
    assert Spectral().field_error(_problem(_gaussian(periodic=True)), values) == Spectral().error_estimate(
        _problem(_gaussian(periodic=True)))


def test_select_method_picks_the_cheapest_method_that_meets_tol():
    problem = _problem(_gaussian())
    method, reason, candidates = select_method(problem, 1e-6)
    assert set(candidates) == set(METHODS)
    meeting = {name: c for name, c in candidates.items() if isinstance(c, tuple) and c[0] <= 1e-6}
    assert method.name == min(meeting, key=lambda name: meeting[name][1])
    assert reason.startswith("cheapest method")
    # the facade reports the same choice
    assert HalfSpace(1e6).stress(problem.load, 3e-4, components=("zz",)).method == method.name


def test_select_method_warns_when_no_method_meets_tol():
    problem = _problem(_gaussian(), depths=(1e-7,))  # far below the grid spacing
    with pytest.warns(AccuracyWarning, match="no method meets tol"):
        method, reason, _ = select_method(problem, 1e-6)
    assert reason.startswith("most accurate method available")


def test_select_method_forced_and_bad_names():
    problem = _problem(_gaussian())
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # forced methods that meet tol say nothing
        assert select_method(problem, 1e-6, "closed_form")[0].name == "closed_form"
        assert select_method(problem, 1e-6, DCFFT)[1] == "forced by the caller"
        assert select_method(_problem(_gaussian(periodic=True)), 1e-6, Spectral())[0].name == "spectral"
    with pytest.raises(ValueError, match="method: unknown method 'magic'"):
        select_method(problem, 1e-6, "magic")
    with pytest.raises(ValueError, match="method: expected 'auto', a method name or a Method subclass"):
        select_method(problem, 1e-6, 3)
    with pytest.raises(ValueError, match="method: 'dcfft' cannot run here"):
        select_method(_problem(_gaussian(periodic=True)), 1e-6, "dcfft")


def test_a_forced_method_that_misses_tol_warns_and_names_the_better_method():
    """``method="dcfft"`` at 1e-3 grid spacings deep returned -4.8e9 Pa for a -1e4 Pa field in
    silence; only ``auto`` warned although the method's own estimate knew."""
    load = _gaussian()
    hs = HalfSpace(1e6)
    with pytest.warns(AccuracyWarning, match=r"method 'dcfft' was forced, but its error estimate .* exceeds "
                                             r"tol=1e-06; no method meets it; 'spectral' is more accurate"):
        result = hs.stress(load, 1e-3 * 1e-4, components=("zz",), method="dcfft")
    assert result.error_estimate > 0.1  # and the result says so
    with pytest.warns(AccuracyWarning, match=r"method 'spectral' was forced, but its error estimate .* exceeds "
                                             r"tol=1e-06; 'dcfft' meets it \(estimate .*\): use method='dcfft'"):
        hs.stress(load, 3e-4, components=("zz",), method="spectral")
    with pytest.warns(AccuracyWarning, match=r"tol=1e-09; no registered method does better: refine"):
        hs.stress(load, 3e-4, components=("zz",), method="closed_form", tol=1e-9)


@pytest.mark.parametrize("method", ["dcfft", "closed_form"])
@pytest.mark.parametrize("width_in_spacings", [0.5, 1.0, 2.0])
def test_narrow_loads_are_covered_by_the_estimate(method, width_in_spacings):
    """A Gaussian of width 0.5 grid spacings at 3 spacings deep: true error 5e-2 against the
    continuous load, reported 1.1e-5, because the load's width never reached the estimator."""
    from tactilab.forward.halfspace import dcfft_stress
    from tactilab.forward.halfspace.methods import load_width

    h, z, refine = 1e-4, 3e-4, 8
    w = width_in_spacings * h

    def gaussian(step):
        n = 2 * int(round(max(8 * h, 8 * w) / step)) + 1
        x = (np.arange(n) - n // 2) * step
        xx, yy = np.meshgrid(x, x)
        return SurfaceLoad(p=-1e4 * np.exp(-((xx - 0.2 * h) ** 2 + yy**2) / (2 * w**2)), spacing=step)

    coarse = gaussian(h)
    assert load_width(coarse) == pytest.approx(w, rel=0.07)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        result = HalfSpace(1e6, 0.5).stress(coarse, z, components=("zz",), method=method)
    got = result.data["stress"].values[0, 0]
    # the continuous load, to quadrature accuracy: the same Gaussian 8x finer, read at the coarse nodes
    reference = dcfft_stress(gaussian(h / refine), [z], 0.5, ("zz",))[0, 0][::refine, ::refine]
    true_error = np.abs(got - reference).max() / np.abs(got).max()
    assert true_error <= result.error_estimate
    assert result.error_estimate <= 100 * true_error  # and useful

"""The cheap texture models' error estimate (forward/contact/validity.py) against closed forms and the benchmark.

Oracles: Westergaard's p* and full-contact pressure (Johnson 13.3) for the linear model; in full
contact the modulation's error on the shear strain is |p_bar / p* - 1| exactly (its texture term
is p_bar cos where the true one is p* cos, and zx carries no mean). Coverage: the benchmark at
reduced size (sinusoids against Westergaard, a random rough cell against a solve on a grid twice
as fine) -- the estimate must not understate any true error.
"""

import importlib.util
import math
import pathlib

import numpy as np
import pytest

from tactilab.forward import (WestergaardContact, full_contact_pressure, interface_model_errors, linear_pressure,
                              modulation_pressure)

ROOT = pathlib.Path(__file__).resolve().parents[1]
E, NU = 1e6, 0.5
L, DELTA = 1e-3, 2e-6
P_STAR = math.pi * E / (1 - NU**2) * DELTA / L


def sinusoid(n):
    x = (np.arange(n) - n // 2) * L / n
    return x, DELTA * np.cos(2 * np.pi * x / L)


def test_full_contact_pressure_and_the_linear_model_are_westergaards():
    x, h = sinusoid(64)
    assert full_contact_pressure(h, L / 64, E, NU) == pytest.approx(P_STAR, rel=1e-12)
    exact = WestergaardContact(DELTA, L, 1.5 * P_STAR, E, NU).pressure(x)
    assert np.allclose(linear_pressure(h, L / 64, 1.5 * P_STAR, E, NU), exact, rtol=0, atol=1e-9 * P_STAR)
    clipped = linear_pressure(h, L / 64, 0.5 * P_STAR, E, NU)
    assert clipped.min() == 0 and np.allclose(clipped, np.maximum(0.5 * P_STAR + P_STAR * np.cos(2 * np.pi * x / L), 0),
                                              atol=1e-9 * P_STAR)
    assert np.allclose(modulation_pressure(h, 1e3), 1e3 * (1 + np.cos(2 * np.pi * x / L)))
    assert np.allclose(modulation_pressure(h, 1e3, reference_height=DELTA / 2), 1e3 * np.clip(1 + 2 * h / DELTA, 0, None))
    assert np.array_equal(modulation_pressure(np.zeros(8), 1e3), np.full(8, 1e3))


@pytest.mark.parametrize("ratio", [1.5, 3.0])
def test_full_contact_needs_no_solve_and_the_modulation_error_is_known(ratio):
    _, h = sinusoid(64)
    est = interface_model_errors(h, L / 64, ratio * P_STAR, E, NU, 0.5e-3)
    assert est["contact_fraction"] == 1.0 and est["load_ratio"] == pytest.approx(ratio, rel=1e-12)
    assert est["linear"] == pytest.approx(1e-6, abs=1e-12)  # exact: only the floor
    assert est["modulation"] == pytest.approx(1.05 * (ratio - 1) + 1e-6, rel=1e-9)  # zx: |p_bar - p*| / p*


def test_partial_contact_estimate_covers_westergaard_and_plane_strain_and_3d_agree():
    _, h = sinusoid(64)
    est = interface_model_errors(h, L / 64, 0.3 * P_STAR, E, NU, 0.25e-3)
    assert 0 < est["contact_fraction"] < 1
    assert est["linear"] > 0.3 and est["modulation"] > 0.3  # both far off in partial contact (benchmark: 0.12, 0.41)
    ridges = np.repeat(h[None, :], 16, axis=0)  # the same texture as a 3-D cell of ridges along y
    est3 = interface_model_errors(ridges, L / 64, 0.3 * P_STAR, E, NU, 0.25e-3, components=("zz", "xx", "zx"))
    est2 = interface_model_errors(h, L / 64, 0.3 * P_STAR, E, NU, 0.25e-3, components=("zz", "xx", "zx"))
    assert est3["linear"] == pytest.approx(est2["linear"], rel=1e-6)
    assert est3["modulation"] == pytest.approx(est2["modulation"], rel=1e-6)


@pytest.mark.filterwarnings("ignore::UserWarning")  # light loads on small cells: patches of a few nodes
def test_the_benchmark_at_reduced_size_finds_every_true_error_covered(capsys):
    spec = importlib.util.spec_from_file_location("bench_interface_models",
                                                  ROOT / "benchmarks" / "bench_interface_models.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert bench.main(["--quick"]) == 0
    out = capsys.readouterr().out
    assert "(a) sinusoid" in out and "(b) random rough" in out
    assert "estimate covers the true error in 28 of 28 cases" in out


@pytest.mark.parametrize("call, match", [
    (lambda: interface_model_errors(np.zeros(63), 1e-5, 1e3, E), r"heights: need one periodic cell .* got shape \(63,\)"),
    (lambda: interface_model_errors(np.full(8, np.nan), 1e-5, 1e3, E), r"heights: must be finite"),
    (lambda: interface_model_errors(np.zeros(8), 1e-5, 0.0, E), r"mean_pressure: must be finite and > 0 Pa"),
    (lambda: interface_model_errors(np.zeros(8), 1e-5, 1e3, E, depth=-1.0), r"depth: .*finite and > 0 m"),
    (lambda: interface_model_errors(np.zeros(8), 1e-5, 1e3, E, reference_height=0.0),
     r"reference_height: must be finite and > 0 m"),
    (lambda: interface_model_errors(np.zeros(8), 1e-5, 1e3, E, components=("qq",)), r"unknown component"),
    (lambda: modulation_pressure(np.zeros(8), -1.0), r"mean_pressure: must be finite and > 0 Pa"),
])
def test_bad_inputs_are_refused(call, match):
    with pytest.raises(ValueError, match=match):
        call()

"""Figures the CLI and the demo write: sequential maps for non-negative fields, units on the axes, the
render-vs-real profile at a representative time (in ms), a 1-D sensor row that is not squashed flat,
L-curve ticks that do not overlap and named data units."""

from __future__ import annotations

import matplotlib.figure
import numpy as np
import pytest
import xarray as xr


@pytest.fixture
def figures(monkeypatch):
    """Record every matplotlib Figure made while the test runs."""
    made = []

    class Recording(matplotlib.figure.Figure):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self)

    monkeypatch.setattr(matplotlib.figure, "Figure", Recording)
    return made


def _field(values, name):
    x = np.linspace(-1e-3, 1e-3, 8)
    return xr.DataArray(values.reshape(1, 1, 8, 8), dims=("depth", "component", "y", "x"), name=name,
                        coords={"depth": [1e-3], "component": ["c"], "x": x, "y": x}, attrs={"units": "1"})


def test_non_negative_fields_get_a_sequential_map_signed_ones_a_diverging_map(tmp_path, figures):
    from tactilab.forward.plots import is_non_negative, plot_field

    rng = np.random.default_rng(0)
    plot_field(_field(rng.random(64), "von_mises"), tmp_path / "vm.png")
    plot_field(_field(rng.standard_normal(64), "strain"), tmp_path / "s.png")
    (vm,), (signed,) = (f.axes[0].collections for f in figures)
    assert vm.get_cmap().name == "viridis" and vm.get_clim()[0] == 0.0
    assert signed.get_cmap().name == "RdBu_r" and signed.get_clim()[0] == -signed.get_clim()[1]
    assert is_non_negative("von Mises", np.array([0.0])) and not is_non_negative("zz", np.array([-1.0, 2.0]))
    assert figures[0].axes[0].get_xlabel() == "x (mm)" and figures[0].axes[1].get_ylabel() == "c (strain)"


def test_rendered_vs_real_at_the_strongest_frame_in_ms(tmp_path, figures):
    from types import SimpleNamespace

    from tactilab.forward.finger_plots import plot_rendered_vs_real, representative_frame

    real = np.zeros((50, 5, 1))
    real[30] = 1e-3  # the stimulus reaches the sensors at frame 30; frame 0 is blank
    sensors = SimpleNamespace(positions_m=np.column_stack([np.linspace(-2e-3, 2e-3, 5), np.zeros(5)]),
                              components=("xx",))
    assert representative_frame(real) == 30
    plot_rendered_vs_real(sensors, 0.9 * real, real, tmp_path / "r.png", sampling_rate_hz=1000.0)
    top, bottom = figures[0].axes[:2] if figures[0].axes[0].get_xlabel() == "sensor x (mm)" else (None, None)
    assert top is not None and "t = 30.0 ms" in top.get_title()
    assert bottom.get_xlabel() == "time (ms)" and bottom.get_ylabel() == "xx (strain)"


def test_a_row_of_sensors_is_not_squashed(figures, tmp_path):
    from tactilab.data_schemas import load_example
    from tactilab.demo.records import _plot_scene

    _plot_scene(load_example("sliding_grating"), tmp_path / "s.png")
    heights, layout = figures[0].axes[:2]
    assert "µm" in heights.get_ylabel()
    lo, hi = layout.get_ylim()
    assert hi - lo >= 2.0  # mm: a 1-D row keeps a readable y extent


def test_criteria_name_the_data_unit_and_label_no_minor_ticks(tmp_path, figures):
    from tactilab.inversion.criteria import CriteriaResult, plot_criteria

    g = np.geomspace(1e-3, 1e3, 30)
    curves = {"gcv": 1 + g, "residual2": np.linspace(400, 900, 30), "seminorm2": np.linspace(9, 4, 30),
              "log_evidence": -g}
    result = CriteriaResult(lam={"gcv": 1.0, "lcurve": 1.0, "discrepancy": 1.0, "evidence": 1.0}, grid=g,
                            curves=curves, noise_std=20.0, notes={}, spread=1.0)
    plot_criteria(result, tmp_path / "c.png", data_unit="Pa")
    gcv, lcurve, disc, _ = figures[0].axes
    assert gcv.get_ylabel() == "GCV (Pa^2)" and "(Pa)" in lcurve.get_xlabel() and "(Pa)" in disc.get_ylabel()
    figures[0].canvas.draw()
    # the residual spans less than a decade: minor ticks stay unlabelled, so labels cannot overlap
    assert all(t.get_text() == "" for t in lcurve.xaxis.get_minorticklabels())

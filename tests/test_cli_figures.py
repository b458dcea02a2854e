"""Figures the CLI and the demo write: sequential maps for non-negative fields, units on the axes, the
render-vs-real profile at a representative time (in ms), a 1-D sensor row that is not squashed flat,
L-curve ticks that do not overlap and named data units."""

from __future__ import annotations

import pathlib

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


# ---- issue 25: figures that never hide data, clip a title or mislabel an axis --------------------------
def _inside(fig, artist) -> bool:
    """The artist's box lies inside the figure's (nothing clipped at the edges)."""
    fig.canvas.draw()
    box, page = artist.get_window_extent(), fig.bbox
    return box.x0 >= page.x0 - 1 and box.x1 <= page.x1 + 1 and box.y0 >= page.y0 - 1 and box.y1 <= page.y1 + 1


def _apart(fig, legend, ax) -> bool:
    fig.canvas.draw()
    return not legend.get_window_extent().overlaps(ax.get_window_extent())


@pytest.mark.parametrize("hypothesis, label", [("xx@1mm", "strain"), ("xx,zx@1mm", "strain (tensor shear in zx)")])
def test_metamer_pair_legend_sits_beside_the_curves_and_shear_is_named_only_for_shear(figures, tmp_path, hypothesis,
                                                                                       label):
    from tactilab.inversion import SinusoidFamily, TractorFamily, metamer_pair

    pair = metamer_pair(SinusoidFamily(4e-3).stimulus([1e-5]), TractorFamily([-1e-3, 1e-3], 1.54e6), hypothesis,
                        np.linspace(-5e-3, 5e-3, 41))
    pair.plot(tmp_path / "pair.png")
    fig = figures[-1]
    (ax,) = fig.axes
    assert ax.get_legend() is None and len(fig.legends) == 1 and _apart(fig, fig.legends[0], ax)
    assert ax.get_ylabel() == label


def test_evidence_panel_shows_its_peak_whatever_the_offset(figures, tmp_path):
    from tactilab.inversion.criteria import CriteriaResult, plot_criteria

    g = np.geomspace(1e-6, 1e6, 41)
    evidence = -1e6 * np.log10(g) ** 2 - 3.0  # a 1e6-nat fall around a sharp peak at lambda = 1
    curves = {"gcv": 1 + g, "residual2": np.linspace(400, 900, 41), "seminorm2": np.linspace(9, 4, 41),
              "log_evidence": evidence}
    result = CriteriaResult(lam={"gcv": 1.0, "lcurve": 1.0, "discrepancy": 1.0, "evidence": 1.0}, grid=g,
                            curves=curves, noise_std=20.0, notes={}, spread=1.0)
    plot_criteria(result, tmp_path / "c.png")
    ax = figures[0].axes[3]
    assert ax.get_yscale() == "symlog"
    y = ax.lines[0].get_ydata()
    assert y.max() == 0.0 and np.sum(y > -1.0) == 1  # drawn relative to its maximum: the peak stands out


def test_one_sensor_time_series_draws_no_heat_map_and_its_legend_hides_no_line(figures, tmp_path):
    from matplotlib.image import AxesImage

    from tactilab.data_schemas import Recording
    from tactilab.forward.finger_plots import plot_time_series

    for n_sensors, n_images in ((1, 0), (3, 1)):
        rec = Recording(values=np.random.default_rng(0).normal(size=(50, n_sensors, 1)), sampling_rate_hz=1e3,
                        sensor_ids=tuple(f"s{k}" for k in range(n_sensors)), components=("zz",), quantity="stress")
        plot_time_series(rec, tmp_path / "t.png")
        fig = figures[-1]
        images = [a for ax in fig.axes for a in ax.get_children() if isinstance(a, AxesImage)]
        assert len(images) == n_images
        assert _apart(fig, fig.axes[0].get_legend(), fig.axes[0])


def test_receptive_fields_title_of_a_one_sensor_scene_is_not_clipped(figures, tmp_path):
    from tactilab.data_schemas.files import load_scene
    from tactilab.forward.finger_plots import plot_receptive_fields
    from tactilab.forward.scanning import scene_finger

    finger = scene_finger(load_scene(pathlib.Path(__file__).parents[1] / "examples" / "fingerprint_texture.toml"),
                          None)
    assert finger.sensors.n_sensors == 1
    plot_receptive_fields(finger, tmp_path / "rf.png")
    fig = figures[-1]
    assert _inside(fig, fig._suptitle)


def test_display_strain_names_tensor_shear_only_on_shear_and_keeps_legends_off_the_curves(figures, tmp_path):
    from tactilab.demo.display import run_demo

    list(run_demo(tmp_path, progress=False))
    fig = next(f for f in figures if len(f.axes) == 3)
    xx, zx, rms = fig.axes
    assert "shear" not in xx.get_title() and "shear" not in xx.get_ylabel() and "TENSOR shear" in zx.get_title()
    assert all(ax.get_legend() is None for ax in fig.axes) and len(fig.legends) == 2
    assert all(_apart(fig, leg, ax) for leg in fig.legends for ax in fig.axes)


def test_comparison_legend_hides_no_point(figures, tmp_path):
    from test_models import _frame

    from tactilab.experiments import TransductionModel, compare_models, fit_transduction
    from tactilab.experiments.modelling.analysis import plot_comparison

    truth = TransductionModel("zx@1mm")
    frame = _frame(truth, 10, [0.5e-6, 1e-6, 2e-6], np.random.default_rng(1))
    fits = {h: fit_transduction(TransductionModel(h), frame) for h in ("zx@1mm", "zx@3mm")}
    plot_comparison(compare_models(fits), fits, tmp_path / "compare.png")
    fig = figures[-1]
    panel = fig.axes[1]
    assert _apart(fig, panel.get_legend(), panel)

"""Inversion figures are built on matplotlib.figure.Figure: they never switch the caller's backend
(no ``matplotlib.use``) and never go through pyplot's global figure manager."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest
from PIL import Image

from tactilab.inversion import choose_lambda, plot_corner, plot_criteria, plot_profile
from tactilab.inversion.criteria import SpectralForm
from tactilab.inversion.localisation import plot_localisation


@pytest.fixture
def no_backend_switch(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError(f"library code called matplotlib.use{args}")

    monkeypatch.setattr(matplotlib, "use", refuse)
    before = matplotlib.get_backend()
    yield
    assert matplotlib.get_backend() == before


def _is_png(path) -> tuple[int, int]:
    with Image.open(path) as im:
        assert im.format == "PNG"
        return im.size


def test_plots_leave_the_backend_alone(no_backend_switch, tmp_path, rng):
    import arviz_base as azb
    import pandas as pd

    x = np.linspace(-5e-3, 5e-3, 50)
    plot_profile(x, np.sin(x * 1e3) * 1e-3, np.full(50, 2e-4), tmp_path / "profile.png", truth=np.sin(x * 1e3) * 1e-3)
    tree = azb.from_dict({"posterior": {"x0": rng.normal(1e-3, 1e-4, (4, 200)),
                                        "y0": rng.normal(0.0, 2e-4, (4, 200))}})
    plot_corner(tree, tmp_path / "corner.png", truth={"x0": 1e-3, "y0": 0.0})
    r = np.geomspace(1e-4, 1e4, 40)
    form = SpectralForm(ratio=r, coef2=r / (1 + r) + 0.01 * rng.chisquare(1, 40), weights=np.ones(40), n_data=40)
    plot_criteria(choose_lambda(form, noise_std=0.1, warn_factor=1e300), tmp_path / "criteria.png")
    table = pd.DataFrame({"components": ["zz", "zz"], "n_sensors": [1, 4], "crb_sd_x0_um": [10.0, 5.0],
                          "crb_sd_y0_um": [20.0, 8.0]})
    plot_localisation(table, tmp_path / "loc.png")
    for name in ("profile", "corner", "criteria", "loc"):
        w, h = _is_png(tmp_path / f"{name}.png")
        assert w > 300 and h > 200

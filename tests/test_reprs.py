"""Short reprs: method, shapes, units and error estimate in one to a few lines, never raw arrays."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr


def _short(text: str, lines: int = 3) -> None:
    assert text.count("\n") < lines and len(text) < 600, text
    assert "array(" not in text and "[[" not in text and "..." not in text


def test_field_result_repr():
    from tactilab.forward import HalfSpace, SurfaceLoad

    load = SurfaceLoad(p=np.ones((64, 64)) * 1e3, spacing=1e-4)
    res = HalfSpace(E=1e6, nu=0.5).strain(load, [1e-3, 2e-3], components=["zz", "zx"])
    text = repr(res)
    _short(text, 1)
    assert text.startswith(f"FieldResult(method={res.method!r}, est. rel. error")
    assert "strain (depth=2, component=2, y=64, x=64) [strain]" in text
    assert res._repr_html_().startswith("<pre>FieldResult(")
    stress = HalfSpace(E=1e6, nu=0.5).stress(load, [1e-3], components=["zz"])
    assert "[Pa]" in repr(stress)


def test_linear_and_gaussian_reprs():
    from tactilab.inversion.gaussian import GaussianPosterior
    from tactilab.inversion.linear_common import LinearInversionResult

    lin = LinearInversionResult(model=np.zeros((2, 500)), method="fft", penalty="curvature", lam=0.38,
                                lam_source="evidence", criteria=None, residual_norm=612.0, iterations=0,
                                converged=True, message="m" * 1000)
    text = repr(lin)
    _short(text, 1)
    for key in ("method='fft'", "penalty='curvature'", "lam=0.38 (evidence)", "model shape (2, 500)",
                "residual ||Am-d|| = 612 data units"):
        assert key in text
    post = GaussianPosterior(mean=np.zeros(500), std=np.linspace(1, 2, 500), log_evidence=-123.4, method="dense",
                             noise_std=20.0, note="exact", dims=(500,), spacing=1e-4)
    text = repr(post)
    _short(text, 1)
    assert "method='dense'" in text and "mean shape (500,)" in text and "pointwise std median 1.5 [1, 2]" in text
    assert post._repr_html_().startswith("<pre>GaussianPosterior(")


def test_mcmc_result_repr():
    from tactilab.inversion.mcmc import MCMCResult

    tree = xr.DataTree.from_dict({"posterior": xr.Dataset({"x0": (("chain", "draw"), np.zeros((4, 1000)))})})
    summary = pd.DataFrame({"mean": [1.2e-3, 5e-8], "sd": [6e-6, 4e-10]}, index=["x0", "amplitude"])
    res = MCMCResult(tree=tree, converged=True, diagnostics={"n_steps": 1200, "rhat_max": 1.004, "ess_bulk_min": 812},
                     summary=summary, flat_parameters=[], map_estimates=[], message="")
    text = repr(res)
    _short(text, 2)
    assert "method='emcee', converged after 1200 steps, R-hat max 1.004, ESS bulk min 812" in text
    assert "x0 = 0.0012 +- 6e-06 m; amplitude = 5e-08 +- 4e-10 m^2" in text
    assert "'chain': 4, 'draw': 1000" in text


def test_run_result_repr():
    from tactilab.experiments.session.runner import RunResult

    res = RunResult(path=Path("sessions/sub-01"), status="complete", n_completed=40,
                    estimate={"threshold_m": 2.3456e-6, "procedure": "staircase"})
    text = repr(res)
    _short(text, 1)
    assert text == ("RunResult(status='complete', 40 trials, estimate {threshold_m=2.346e-06, procedure='staircase'}, "
                    "path='sessions/sub-01')")
    assert res._repr_html_().startswith("<pre>RunResult(")

"""Check: the Monte Carlo standard error of PSIS-LOO elpd (``elpd_mcse``) and the comparison of two
models that predict identical responses, over seeds.

Run: ``python benchmarks/bench_elpd_mcse.py [--seeds 2 3 4 5 6 7]``

xx@1mm and zx@1mm read the same peak of every sinusoidal grating, so fitted to the same trials
(the data of tests/test_models_fit.py: an observer reading zx@1mm, 60 trials at each of 4
amplitudes x 2 pitches) their elpd differ by Monte Carlo noise only. zx@1mm is fitted once
(rng 1), xx@1mm once per seed. Per seed: xx's elpd and its ``mcse``, the comparison's
``elpd_diff``, ``dse``, ``mcse_diff``, |elpd_diff| / dse (the z of a comparison that ignores the
Monte Carlo error), the z of ``compare_models`` (|elpd_diff| / sqrt(dse^2 + mcse_diff^2)) and its
verdict. Last line: the standard deviation of xx's elpd over the seeds (the Monte Carlo error
measured directly) against the mean of its ``mcse`` (the error estimated from one fit).
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from tactilab.data_schemas.experiment import Stimulus
from tactilab.experiments.modelling.models import TransductionModel, compare_models, fit_transduction

GRATING = Stimulus(amplitude_m=1e-6, pitch_m=4e-3, speed_m_per_s=0.02, duration_s=0.1)
FAST = {"tau_factor": 10.0, "check_every": 200}  # the tests' sampler settings


def _frame(model, n_per, amps, rng, pitches=(2e-3, 6e-3)):
    rows = []
    for p in pitches:
        for a in amps:
            stim = GRATING.model_copy(update={"amplitude_m": a, "pitch_m": p})
            blank = stim.model_copy(update={"amplitude_m": 0.0})
            prob = model.p_correct([(stim, blank)], "2ifc", 2e-4, 1.0, 0.02)[0]
            for ok in rng.random(n_per) < prob:
                first = rng.random() < 0.5
                rows.append({"stimuli": [stim, blank] if first else [blank, stim], "target": "1" if first else "2",
                             "correct": bool(ok)})
    return pd.DataFrame(rows)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[2, 3, 4, 5, 6, 7])
    args = parser.parse_args(argv)
    frame = _frame(TransductionModel("zx@1mm"), 60, [0.25e-6, 0.5e-6, 1e-6, 2e-6], np.random.default_rng(0))
    zx = fit_transduction(TransductionModel("zx@1mm"), frame, rng=1, sampler_options=FAST)
    head = (f"{'rng':>4s} {'elpd(xx)':>10s} {'mcse':>7s} {'elpd_diff':>10s} {'dse':>7s} {'mcse_diff':>10s} "
            f"{'|diff|/dse':>10s} {'z':>6s} {'|diff|/mcse_diff':>16s}  verdict")
    print(head + "\n" + "-" * len(head))
    elpds, mcses = [], []
    for seed in args.seeds:
        xx = fit_transduction(TransductionModel("xx@1mm"), frame, rng=seed, sampler_options=FAST)
        table = compare_models({"zx@1mm": zx, "xx@1mm": xx})
        row, other = table.iloc[1], table.loc["xx@1mm"]
        elpds.append(float(other["elpd"]))
        mcses.append(float(other["mcse"]))
        diff = abs(float(row["elpd_diff"]))
        print(f"{seed:4d} {other['elpd']:10.4f} {other['mcse']:7.4f} {row['elpd_diff']:10.4f} {row['dse']:7.4f} "
              f"{row['mcse_diff']:10.4f} {diff / row['dse']:10.2f} {row['z']:6.2f} {diff / row['mcse_diff']:16.2f}  "
              f"{row['verdict']}", flush=True)
    print(f"sd of elpd(xx) over {len(elpds)} seeds: {np.std(elpds, ddof=1):.4f} nats; mean mcse: {np.mean(mcses):.4f} nats")


if __name__ == "__main__":
    main()

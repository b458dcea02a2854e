"""Benchmark: tactilab's expected information against ADOpy's on the same grid (parameter estimation).

Run (tactilab's environment; ADOpy 0.4.1 needs an older numpy, so it lives in its own one)::

    /root/.pyenv/versions/3.10.13/bin/python -m venv .bench-venv-adopy
    .bench-venv-adopy/bin/python -m pip install adopy "numpy<1.24" "pandas<2" "scipy<1.12"
    .venv/bin/python benchmarks/bench_design_adopy.py [--adopy-python .bench-venv-adopy/bin/python]

Where ADOpy applies (ONE psychometric model, the utility the mutual information between the next
response and the parameters), both compute the same quantity: ``information_gain(...,
utility="parameters")`` of :mod:`tactilab.experiments.modelling.design` with one model, and ADOpy's
``Engine.mutual_info``. The model is the 2IFC link of ``zx@1mm`` (docs/model_comparison.md):
P(correct) = 1/2 + (1/2 - lapse)(2 Phi((s / threshold)^exponent / sqrt 2) - 1), with s the
hypothesis's statistic of each of 200 candidates (20 amplitudes 2-60 um x 10 pitches 0.8-8 mm,
sinusoids) and the (threshold, exponent, lapse) grid and prior of ``ModelDiscrimination``.

tactilab chooses 40 trials (simulated observer); ADOpy replays the same (design, response)
history and reports its mutual information before every trial. Printed: the largest difference
of the two utilities over all candidates and trials, how often the choices coincide, the
information of ADOpy's choice under tactilab's utility, and the selection time per trial of each
(utility of all 200 candidates + argmax).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def _adopy_side(path_in: str, path_out: str) -> None:
    """Runs inside the ADOpy environment: replay the history, record mutual information per trial."""
    from adopy import Engine, Model, Task
    from scipy.special import ndtr

    data = np.load(path_in)
    stats, grid, log_prior, history = data["stats"], data["grid"], data["log_prior"], data["history"]

    def log_lik(s, t, b, lam, y):
        p = np.clip(0.5 + (0.5 - lam) * (2 * ndtr((s / t) ** b / np.sqrt(2)) - 1), 1e-300, 1 - 1e-16)
        with np.errstate(divide="ignore"):
            return np.where(y == 1, np.log(p), np.log1p(-p))

    task = Task(designs=["s"], responses=["y"], name="2ifc")
    model = Model(task=task, params=["t", "b", "lam"], func=log_lik)
    engine = Engine(task, model, grid_design={"s": stats}, grid_param={("t", "b", "lam"): grid},
                    grid_response={"y": [0, 1]}, noise_ratio=1e-12, dtype=np.float64)
    engine.log_prior = log_prior.astype(np.float64)
    engine.reset()
    mi, times = [], []
    for index, y in history:
        mi.append(np.array(engine.mutual_info, dtype=np.float64))
        t0 = time.perf_counter()
        engine.update({"s": stats[index]}, {"y": int(y)})
        _ = engine.mutual_info  # the next trial's utilities (what a selection waits for)
        _ = int(np.argmax(engine.mutual_info))
        times.append(time.perf_counter() - t0)
    np.savez(path_out, mi=np.array(mi), times=np.array(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--adopy-python", default=".bench-venv-adopy/bin/python")
    parser.add_argument("--trials", type=int, default=40)
    args = parser.parse_args()
    from scipy.special import logsumexp

    from tactilab.data_schemas.experiment import Stimulus
    from tactilab.experiments import ModelDiscrimination, TransductionModel
    from tactilab.experiments.modelling.design import information_gain

    cands = [Stimulus(amplitude_m=a, pitch_m=p, speed_m_per_s=0.02, duration_s=0.1)
             for a in np.geomspace(2e-6, 6e-5, 20) for p in np.geomspace(0.8e-3, 8e-3, 10)]
    models = [TransductionModel(h) for h in ("zx@1mm", "zx@2mm")]
    design = ModelDiscrimination(models, cands, utility="parameters", rng=0)
    table = design.table[:, :1, :]  # one model: zx@1mm
    entropy = design._entropy_table[:, :1, :]  # H(P(correct)) per candidate and grid point, computed once
    log_w = design._log_posterior[0] - logsumexp(design._log_posterior[0])  # its grid prior
    stats = design.stats[0, :, 0]
    rng = np.random.default_rng(3)
    truth = np.array([[float(np.median(stats)), 1.3, 0.02]])
    from tactilab.experiments.modelling._transduction_data import p_correct_table

    p_true = p_correct_table("2ifc", stats, np.zeros_like(stats), truth)[0]
    ours, history, times = [], [], []
    log_post = log_w.copy()
    for _ in range(args.trials):
        t0 = time.perf_counter()
        w = np.exp(log_post - log_post.max())
        u = information_gain(table, (w / w.sum())[None, :], "parameters", entropy)
        index = int(np.argmax(u))
        times.append(time.perf_counter() - t0)
        ours.append(u)
        y = bool(rng.random() < p_true[index])
        history.append((index, int(y)))
        t0 = time.perf_counter()
        log_post = log_post + (design._log_p if y else design._log_q)[index, 0]
        times[-1] += time.perf_counter() - t0  # update + the next selection, as timed for ADOpy
    with tempfile.TemporaryDirectory() as tmp:
        path_in, path_out = os.path.join(tmp, "in.npz"), os.path.join(tmp, "out.npz")
        np.savez(path_in, stats=stats, grid=design.grid, log_prior=log_w, history=np.array(history))
        subprocess.run([args.adopy_python, __file__, "--adopy-side", path_in, path_out], check=True)
        out = np.load(path_out)
        theirs, their_times = out["mi"], out["times"]
    ours = np.array(ours)
    diff = np.abs(ours - theirs)
    same = np.mean(np.argmax(ours, axis=1) == np.argmax(theirs, axis=1))
    rel_loss = [(u.max() - u[int(np.argmax(v))]) / u.max() for u, v in zip(ours, theirs)]
    print(f"{len(cands)} candidates, {design.grid.shape[0]} grid points (threshold x exponent x lapse), "
          f"{args.trials} trials; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    print(f"largest |I_tactilab - I_ADOpy| over all candidates and trials: {diff.max():.2e} nats "
          f"(largest utility {ours.max():.3f} nats)")
    print(f"same candidate chosen on {same:.0%} of trials; ADOpy's choice loses at most {max(rel_loss):.1e} "
          "of the best expected information under tactilab's utility")
    print(f"selection time per trial (Bayes update + utilities of all candidates + argmax): tactilab median "
          f"{np.median(times) * 1e3:.2f} ms (max {np.max(times) * 1e3:.2f}); ADOpy (update + mutual_info + argmax) median "
          f"{np.median(their_times) * 1e3:.2f} ms (max {np.max(their_times) * 1e3:.2f})")


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--adopy-side":
        _adopy_side(sys.argv[2], sys.argv[3])
    else:
        main()

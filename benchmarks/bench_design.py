"""Benchmark: adaptive model discrimination against the method of constant stimuli.

Run: ``python benchmarks/bench_design.py [--observers 50] [--max-trials 5000] [--selection-only]``

Scenarios (2IFC against a blank interval, ideal surface, peak statistic):

- (a) depth: ``zx@1mm`` against ``zx@2mm``; 100 sinusoidal candidates (10 amplitudes 2-60 um
  x 10 pitches 0.8-8 mm, log-spaced);
- (b) component: ``xx@1mm`` against ``zx@1mm``; 40 candidates (sinusoid and square, 5
  amplitudes 3-60 um x 4 pitches 1-6 mm). Sinusoids alone are metameric for this pair.

Each simulated observer reads one model (the first half of the observers the first model, the
rest the second) with threshold_strain log-uniform over [0.3, 3] x the median statistic of
its model over the candidates, exponent lognormal (median 1.2, log-sd 0.25) and lapse uniform
on [0, 0.04]; responses are Bernoulli draws from the model's 2IFC link (what
``SimulatedObserver.from_model`` answers). Both designs use the same grid posterior and the same
stopping rule (a model at 0.99 that is not metameric with a rival over the stimuli shown):

- adaptive: :class:`ModelDiscrimination` (``utility="model"``);
- constant stimuli: every candidate once per block, in a new random order each block.

Table 1: trials to stop (median and 90th percentile over observers), the share that ended on
the wrong model, and the share that reached ``--max-trials`` undecided. Table 2: selection time
per trial with 200 candidates, per utility. Table 3: grid accuracy: the posterior log-odds of
the true model after the same 200 constant-stimuli trials with the default grid and with a grid
twice as fine in threshold and exponent.
"""

from __future__ import annotations

import argparse
import math
import os
import time
import warnings

import numpy as np

from tactilab.data_schemas.experiment import Stimulus
from tactilab.experiments import ModelDiscrimination, TransductionModel
from tactilab.experiments._transduction_data import p_correct_table


def _grid(surfaces, amps, pitches):
    return [Stimulus(surface=w, amplitude_m=a, pitch_m=p, speed_m_per_s=0.02, duration_s=0.1)
            for w in surfaces for a in amps for p in pitches]


SCENARIOS = {
    "(a) zx@1mm vs zx@2mm": (("zx@1mm", "zx@2mm"),
                             _grid(("sinusoid",), np.geomspace(2e-6, 6e-5, 10), np.geomspace(0.8e-3, 8e-3, 10))),
    "(b) xx@1mm vs zx@1mm": (("xx@1mm", "zx@1mm"),
                             _grid(("sinusoid", "square"), np.geomspace(3e-6, 6e-5, 5), np.geomspace(1e-3, 6e-3, 4))),
}


def _observer(design, truth, rng):
    s = design.stats[truth]
    theta = [float(np.median(s[:, 0]) * math.exp(rng.uniform(math.log(0.3), math.log(3)))),
             float(1.2 * math.exp(0.25 * rng.standard_normal())), float(rng.uniform(0, 0.04))]
    return p_correct_table("2ifc", s[:, 0], s[:, 1], np.array([theta]))[0]


def _run(models, candidates, truth, seed, adaptive, max_trials):
    rng = np.random.default_rng(seed)
    d = ModelDiscrimination(models, candidates, rng=seed, max_trials=max_trials)
    p = _observer(d, truth, rng)
    order: list[int] = []
    while not d.finished:
        if adaptive:
            i = d.choose()
        else:
            if not order:
                order = list(rng.permutation(len(d.candidates)))
            i = order.pop()
        d.observe(i, bool(rng.random() < p[i]))
    return len(d.probabilities), d.winner, d.names[truth]


def table_trials(n_observers, max_trials):
    print(f"Table 1 -- trials to 0.99 posterior probability, {n_observers} simulated observers per scenario")
    print(f"{'scenario':24s} {'design':18s} {'median':>7s} {'p90':>7s} {'wrong':>7s} {'undecided':>9s} {'wall s':>7s}")
    for name, (hyps, cands) in SCENARIOS.items():
        models = [TransductionModel(h) for h in hyps]  # statistics computed once, shared by every run
        medians = {}
        for label, adaptive in (("adaptive", True), ("constant stimuli", False)):
            t0 = time.perf_counter()
            rows = [_run(models, cands, k * 2 // n_observers, 1000 + k, adaptive, max_trials)
                    for k in range(n_observers)]
            n = np.array([r[0] for r in rows])
            wrong = np.mean([r[1] is not None and r[1] != r[2] for r in rows])
            undecided = np.mean([r[1] is None for r in rows])
            medians[label] = float(np.median(n))
            print(f"{name:24s} {label:18s} {np.median(n):7.0f} {np.percentile(n, 90):7.0f} {wrong:7.1%} "
                  f"{undecided:9.1%} {time.perf_counter() - t0:7.1f}")
        print(f"{'':24s} {'ratio adaptive/CS':18s} {medians['adaptive'] / medians['constant stimuli']:7.2f}")


def table_selection():
    print("\nTable 2 -- selection time per trial, 200 candidates (2 models, grid 28 x 9 x 4 per model)")
    cands = _grid(("sinusoid",), np.geomspace(2e-6, 6e-5, 20), np.geomspace(0.8e-3, 8e-3, 10))
    models = [TransductionModel(h) for h in ("zx@1mm", "zx@2mm")]
    for utility in ("model", "parameters", "both"):
        d = ModelDiscrimination(models, cands, utility=utility, rng=0)
        rng = np.random.default_rng(0)
        d.choose()  # warm-up (first call allocates)
        times, cpu = [], []
        for _ in range(300):
            t0, c0 = time.perf_counter(), time.thread_time()
            i = d.choose()
            times.append(time.perf_counter() - t0)
            cpu.append(time.thread_time() - c0)
            d.observe(i, bool(rng.random() < 0.8))
        print(f"  utility={utility:10s} wall median {np.median(times) * 1e3:5.2f} ms, p99 "
              f"{np.percentile(times, 99) * 1e3:5.2f} ms, max {np.max(times) * 1e3:5.2f} ms;  CPU (this thread) "
              f"median {np.median(cpu) * 1e3:5.2f} ms, max {np.max(cpu) * 1e3:5.2f} ms")
    print(f"  (load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs: wall-clock spikes above the CPU time "
          "are waits for a CPU)")


def table_grid_accuracy(n_repeats=10):
    print("\nTable 3 -- grid accuracy: log-odds of the true model after 200 constant-stimuli trials")
    hyps, cands = SCENARIOS["(a) zx@1mm vs zx@2mm"]
    models = [TransductionModel(h) for h in hyps]
    diffs = []
    for k in range(n_repeats):
        rng = np.random.default_rng(50 + k)
        coarse = ModelDiscrimination(models, cands, max_trials=10_000)
        fine = ModelDiscrimination(models, cands, n_grid=(49, 17), max_trials=10_000)
        p = _observer(coarse, k % 2, rng)
        odds = []
        for _ in range(200):
            i = int(rng.integers(len(cands)))
            y = bool(rng.random() < p[i])
            coarse.observe(i, y)
            fine.observe(i, y)
        for d in (coarse, fine):
            pr = d.model_probabilities()
            t = d.names[k % 2]
            odds.append(math.log(pr[t]) - math.log(1 - pr[t]) if pr[t] < 1 else math.inf)
        diffs.append(odds[0] - odds[1])
        print(f"  observer {k}: log-odds default grid {odds[0]:8.2f}   fine grid {odds[1]:8.2f}")
    print(f"  largest |difference| {np.max(np.abs(diffs)):.2f} nats")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--observers", type=int, default=50)
    parser.add_argument("--max-trials", type=int, default=5000)
    parser.add_argument("--selection-only", action="store_true", help="only table 2 (selection time)")
    args = parser.parse_args()
    warnings.simplefilter("ignore")  # metameric warnings of sub-designs are expected
    if not args.selection_only:
        table_trials(args.observers, args.max_trials)
    table_selection()
    if not args.selection_only:
        table_grid_accuracy()


if __name__ == "__main__":
    main()

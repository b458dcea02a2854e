"""Benchmark: transduction-model fits (likelihood per unique stimulus) and the statistics behind them.

Run: ``python benchmarks/bench_models.py [--trials 700 7000 70000] [--compare-trials 40 400 2000 7000]
[--emcee-up-to 400] [--tables 0 1 2 3]``

Table 0 -- ``compare``: CPU time of fitting two and four transduction models to the same
simulated trials and comparing them (``fit_transduction`` per model, then ``compare_models``),
by quadrature (``method="grid"``, the default) and by emcee (the reference, run only up to
``--emcee-up-to`` trials), and the largest |elpd(grid) - elpd(emcee)| over the models with
the emcee fits' largest Monte Carlo standard error beside it.

Table 1 -- ``fit_transduction`` of simulated 2IFC trials (20 unique stimuli: 5 amplitudes x 4
pitches, an observer reading zx@1mm): wall time of the statistics (once per unique stimulus),
of the whole fit (4 emcee ensembles to the sampler's own convergence rules) in wall time and in
this process's CPU time (what an unshared machine's wall time would be), the steps taken,
and the size of the per-trial log-likelihood kept in the tree (bounded: the draws kept shrink
as trials grow, at most 8e6 values = 64 MB).

Table 2 -- one likelihood evaluation for 16 walkers: per condition (what the sampler's target
uses) against per trial (what the tree stores).

Table 3 -- the cost of one statistic (peak, refined; rms) per unique stimulus.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from tactilab.data_schemas.experiment import Stimulus
from tactilab.experiments.modelling import compare_models
from tactilab.experiments.modelling.models import TransductionModel, fit_transduction
from tactilab.experiments.modelling._transduction_data import TransductionLikelihood, conditions, default_priors

BASE = Stimulus(amplitude_m=1e-6, pitch_m=4e-3, speed_m_per_s=0.02, duration_s=0.1)
AMPS = (0.15e-6, 0.3e-6, 0.6e-6, 1.2e-6, 2.4e-6)
PITCHES = (1.5e-3, 3e-3, 6e-3, 10e-3)


def _frame(n_trials, rng):
    import pandas as pd

    truth = TransductionModel("zx@1mm")
    stims = [BASE.model_copy(update={"amplitude_m": a, "pitch_m": p}) for a in AMPS for p in PITCHES]
    blank = [s.model_copy(update={"amplitude_m": 0.0}) for s in stims]
    which = rng.integers(len(stims), size=n_trials)
    p = truth.p_correct(list(zip(stims, blank)), "2ifc", 1e-4, 1.0, 0.02)[which]
    first = rng.random(n_trials) < 0.5
    rows = [{"stimuli": [stims[w], blank[w]] if f else [blank[w], stims[w]], "target": "1" if f else "2",
             "correct": bool(c)} for w, f, c in zip(which, first, rng.random(n_trials) < p)]
    return pd.DataFrame(rows)


MODELS = ("zx@1mm", "zx@3mm", "xx@2mm", "zx@2mm")


def _compare(frame, names, method):
    """CPU seconds of fitting every model (fresh statistics caches) and comparing; the table."""
    c0 = time.process_time()
    options = {"rng": 0, "method": "emcee"} if method == "emcee" else {}
    fits = {h: fit_transduction(TransductionModel(h), frame, **options) for h in names}
    table = compare_models(fits)
    return time.process_time() - c0, table


def table_compare(sizes, emcee_up_to) -> None:
    print("Table 0: compare (fit every model + PSIS-LOO comparison), CPU seconds of this process")
    head = (f"{'trials':>7s} {'models':>6s} {'grid CPU':>9s} {'emcee CPU':>10s} {'max |d elpd|':>13s} "
            f"{'emcee mcse':>11s}  grid verdicts")
    print(head + "\n" + "-" * len(head))
    for n in sizes:
        frame = _frame(n, np.random.default_rng(n))
        for k in (2, 4):
            t_grid, grid = _compare(frame, MODELS[:k], "grid")
            if n <= emcee_up_to:
                t_em, em = _compare(frame, MODELS[:k], "emcee")
                diff = max(abs(grid.loc[h, "elpd"] - em.loc[h, "elpd"]) for h in MODELS[:k])
                extra = f"{t_em:8.2f} s {diff:13.3f} {em['mcse'].max():11.3f}"
            else:
                extra = f"{'-':>10s} {'-':>13s} {'-':>11s}"
            print(f"{n:7d} {k:6d} {t_grid:7.2f} s {extra}  " + ", ".join(f"{h}: {v}" for h, v in grid["verdict"].items()))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, nargs="+", default=[700, 7000, 70000])
    parser.add_argument("--compare-trials", type=int, nargs="+", default=[40, 400, 2000, 7000])
    parser.add_argument("--emcee-up-to", type=int, default=400, help="run the emcee reference up to this many trials")
    parser.add_argument("--tables", type=int, nargs="+", default=[0, 1, 2, 3])
    args = parser.parse_args(argv)
    if 0 in args.tables:
        table_compare(args.compare_trials, args.emcee_up_to)
    if 1 in args.tables:
        table_fits(args.trials)
    if 2 in args.tables or 3 in args.tables:
        table_costs(args.tables)


def table_fits(sizes) -> None:
    print("Table 1: fit_transduction (zx@1mm, 2IFC, 20 unique stimuli)")
    head = f"{'trials':>7s} {'statistics':>11s} {'fit total':>10s} {'fit CPU':>9s} {'steps':>6s} {'converged':>9s} {'draws':>6s} {'per-trial ll':>13s}"
    print(head + "\n" + "-" * len(head))
    for n in sizes:
        frame = _frame(n, np.random.default_rng(n))
        model = TransductionModel("zx@1mm")
        t0 = time.perf_counter()
        conditions(model, frame)
        t_stat = time.perf_counter() - t0
        model = TransductionModel("zx@1mm")  # fresh cache: the fit pays for the statistics too
        t0, c0 = time.perf_counter(), time.process_time()
        fit = fit_transduction(model, frame, rng=0, method="emcee")
        t_fit, c_fit = time.perf_counter() - t0, time.process_time() - c0
        ll = fit.tree["log_likelihood"]["correct"]
        print(f"{n:7d} {t_stat:9.2f} s {t_fit:8.2f} s {c_fit:7.2f} s {int(fit.diagnostics['n_steps']):6d} {str(fit.converged):>9s} "
              f"{ll.shape[0] * ll.shape[1]:6d} {ll.nbytes / 2**20:10.1f} MB")


def table_costs(tables) -> None:
    frame = _frame(7000, np.random.default_rng(1))
    model = TransductionModel("zx@1mm")
    data = conditions(model, frame)
    lik = TransductionLikelihood(data, default_priors(data, None))
    theta = lik.initial(np.random.default_rng(0), 16)
    print("\nTable 2: one likelihood evaluation, 16 walkers, 7000 trials")
    for label, fn in (("per condition (20)", lik.total_log_likelihood), ("per trial (7000)", lik.log_likelihood)):
        fn(theta)
        reps = 200
        t0 = time.perf_counter()
        for _ in range(reps):
            fn(theta)
        print(f"{label:20s} {1e6 * (time.perf_counter() - t0) / reps:9.1f} us")
    print("\nTable 3: one statistic per unique stimulus")
    for surface in ("sinusoid", "square"):
        for statistic in ("peak", "rms"):
            for hyp in ("zx@1mm", "xx,zx@1mm,2mm", "max_shear@1mm"):
                stim = BASE.model_copy(update={"surface": surface})
                t0 = time.perf_counter()
                value = TransductionModel(hyp, statistic=statistic).statistic_of(stim)
                print(f"{surface:9s} {statistic:5s} {hyp:15s} {1e3 * (time.perf_counter() - t0):8.2f} ms  "
                      f"value {value:.6g}")


if __name__ == "__main__":
    main()

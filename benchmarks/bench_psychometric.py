"""Benchmark: ``fit_psychometric`` against psignifit 4 on the same data, timed in the same run.

Run (psignifit is a benchmark-only dependency, never a tactilab one)::

    python -m venv .bench-venv && .bench-venv/bin/pip install psignifit -e .
    .bench-venv/bin/python benchmarks/bench_psychometric.py [--repeats 5]

For each simulated data set (seeded binomial draws) both fit with psignifit's default priors:
``fit_psychometric(..., overdispersion=False)`` against ``psignifit(..., fixed_parameters={"eta": 0})``,
and ``overdispersion=True`` against psignifit's default (eta free). Table 1 gives the relative
differences of threshold and width (MAP and mean, %), and of the 95 % interval ends as a % of
psignifit's interval width; agreement means <= 2 % and <= 5 %. Table 2 gives the median wall
time of one fit for each (after one warm-up fit, so imports do not count) and the speed-up.
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings

import numpy as np
from scipy.stats import norm

from tactilab.experiments import fit_psychometric

C = {"norm": norm.ppf(0.95) - norm.ppf(0.05)}


def _data(seed, experiment, n_levels=7, n_trials=40, t=2.0, w=1.0, lapse=0.02, guess_yes_no=0.05):
    x = np.linspace(0.5, 3.5, n_levels)
    guess = {"2AFC": 0.5, "4AFC": 0.25, "yes/no": guess_yes_no}[experiment]
    p = guess + (1 - guess - lapse) * norm.cdf(C["norm"] * (x - t) / w)
    k = np.random.default_rng(seed).binomial(n_trials, p)
    return x, k, np.full(n_levels, n_trials)


CASES = [  # (label, experiment, sigmoid, overdispersion, seed)
    *[(f"2AFC norm s{s}", "2AFC", "norm", False, s) for s in range(4)],
    ("2AFC logistic", "2AFC", "logistic", False, 10),
    ("2AFC gumbel", "2AFC", "gumbel", False, 11),
    ("2AFC rgumbel", "2AFC", "rgumbel", False, 12),
    ("2AFC tdist", "2AFC", "tdist", False, 13),
    ("4AFC norm", "4AFC", "norm", False, 14),
    ("yes/no norm", "yes/no", "norm", False, 15),
    ("2AFC norm, eta free", "2AFC", "norm", True, 16),
]
OURS = {"2AFC": "2afc", "4AFC": "nafc:4", "yes/no": "yes_no"}


def _diffs(s, res, name):
    """(MAP %, mean %, worst CI95 end in % of psignifit's interval width)."""
    ref_map, ref_mean = res.parameter_estimate_MAP[name], res.parameter_estimate_mean[name]
    lo, hi = res.confidence_intervals[name]["0.95"]
    return (100 * abs(s.map / ref_map - 1), 100 * abs(s.mean / ref_mean - 1),
            100 * max(abs(s.ci95[0] - lo), abs(s.ci95[1] - hi)) / (hi - lo))


def _table(title, rows):
    print(title)
    head = f"{'data set':24s} {'thr MAP':>8s} {'thr mean':>8s} {'thr CI':>8s} {'w MAP':>8s} {'w mean':>8s} {'w CI':>8s}"
    print(head + "\n" + "-" * len(head))
    worst = np.zeros(6)
    for label, d in rows:
        vals = (*d["threshold"], *d["width"])
        worst = np.maximum(worst, vals)
        print(f"{label:24s} " + " ".join(f"{v:7.2f}%" for v in vals))
    print(f"{'worst':24s} " + " ".join(f"{v:7.2f}%" for v in worst))
    return bool(np.all(worst[[0, 1, 3, 4]] <= 2.0) and np.all(worst[[2, 5]] <= 5.0))


def _time(fn, repeats):
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed fits per method and data set")
    args = parser.parse_args(argv)
    try:
        import psignifit
    except ImportError:
        raise SystemExit("psignifit is not installed here: run this in the benchmark venv (see the docstring)")
    import importlib.metadata

    rows, times, fine_rows = [], [], []
    for label, experiment, sig, over, seed in CASES:
        x, k, n = _data(seed, experiment)
        ours = lambda: fit_psychometric(x, n_correct=k, n_trials=n, experiment=OURS[experiment], sigmoid=sig,
                                        overdispersion=over, rng=seed)
        kw = dict(experiment_type=experiment, sigmoid=sig, verbose=False,
                  fixed_parameters=None if over else {"eta": 0.0})

        def theirs():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return psignifit.psignifit(np.c_[x, k, n], **kw)

        t_ours, fit = _time(ours, args.repeats)
        t_theirs, res = _time(theirs, args.repeats)
        times.append((label, t_ours, t_theirs))
        diffs = {name: _diffs(fit.params[name], res, name) for name in ("threshold", "width")}
        rows.append((label, diffs))
        if not over:  # psignifit on a 3x finer grid: its own discretisation error shrinks
            fine = dict(threshold=120, width=120, **({"lambda": 20, "gamma": 20} if experiment == "yes/no"
                                                     else {"lambda": 40}))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ref = psignifit.psignifit(np.c_[x, k, n], grid_steps=fine, **kw)
            fine_rows.append((label, {name: _diffs(fit.params[name], ref, name) for name in ("threshold", "width")}))

    print(f"psignifit {importlib.metadata.version('psignifit')}; numbers are |ours - psignifit|")
    ok_default = _table("\nTable 1a: agreement with psignifit's default grid (threshold, width: MAP and mean in % "
                        "of psignifit's; CI95 ends in % of its interval width)", rows)
    ok_fine = _table("\nTable 1b: the same against psignifit on a 3x finer grid (threshold and width 120 steps)",
                     fine_rows)
    print("\nTable 2: wall time of one fit (median of", args.repeats, "after a warm-up)")
    head = f"{'data set':24s} {'tactilab':>10s} {'psignifit':>10s} {'speed-up':>9s}"
    print(head + "\n" + "-" * len(head))
    for label, a, b in times:
        print(f"{label:24s} {1e3 * a:8.1f} ms {1e3 * b:8.1f} ms {b / a:8.1f}x")
    ok_time = all(a < 0.2 and b / a >= 3 for label, a, b in times if "eta" not in label)
    ok_eta = all(b / a >= 3 for label, a, b in times if "eta" in label)
    print(f"\ntargets: every binomial fit < 0.2 s and >= 3x faster: {'met' if ok_time else 'NOT met'} "
          f"(beta-binomial, eta free: >= 3x faster {'met' if ok_eta else 'NOT met'}, not < 0.2 s); "
          f"MAP/mean within 2 % and CI ends within 5 %: default grid {'met' if ok_default else 'NOT met'}, "
          f"finer grid {'met' if ok_fine else 'NOT met'}")


if __name__ == "__main__":
    main()

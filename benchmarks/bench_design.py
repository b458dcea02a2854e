"""Benchmark: adaptive model discrimination against the method of constant stimuli.

Run: ``python benchmarks/bench_design.py [--observers 50] [--max-trials 5000] [--calibration 200]
[--tables 1234] [--seed-offset 0] [--adaptive-only] [--per-observer 20 100]`` (``--seed-offset N`` shifts the observers'
seeds of tables 1 and 4 by N: a development set apart from the reported one; ``--adaptive-only``
runs only table 1's adaptive rows).

Scenarios (2IFC against a blank interval, ideal surface, peak statistic):

- (a) depth: ``zx@1mm`` against ``zx@2mm``; 100 sinusoidal candidates (10 amplitudes 2-60 um
  x 10 pitches 0.8-8 mm, log-spaced);
- (b) component: ``xx@1mm`` against ``zx@1mm``; 40 candidates (sinusoid and square, 5
  amplitudes 3-60 um x 4 pitches 1-6 mm). Sinusoids alone are metameric for this pair.

Each simulated observer reads one model (the first half of the observers the first model, the
rest the second) with threshold_strain log-uniform over [0.3, 3] x the median statistic of
its model over the candidates, exponent lognormal (median 1.2, log-sd 0.25) and lapse uniform
on [0, 0.04]; responses are Bernoulli draws from the model's 2IFC link (what
``SimulatedObserver.from_model`` answers). Every design uses the same grid posterior and the same
stopping rule (a model at 0.99 that is not metameric with a rival over the stimuli shown):

- adaptive: :class:`ModelDiscrimination` with ``utility="odds"`` (the expected increase of the
  true model's log posterior odds) and with its default ``utility="model"`` (the mutual
  information I(Y; m));
- constant stimuli: every candidate once per block, in a new random order each block;
- best prior allocation: fixed proportions over the candidates, chosen in advance to maximise
  the per-trial rate mu / sigma of ``power_analysis`` averaged over 16 draws per model from the
  design's grid prior (exponentiated-gradient ascent on the simplex; the rival's pseudo-true
  parameters by Nelder-Mead in power_analysis's coordinates, started from its best grid point;
  the result and its 10 % mixture with uniform are scored by ``power_analysis`` itself and the
  better kept); trials are shown in proportion (the candidate furthest behind its share next);
- bound: the same, chosen for each observer knowing its true model and parameters (not a
  competitor: no lab knows them).

An allocation whose ``power_analysis`` rate is 0 (the rival's free threshold, exponent and lapse
fit it exactly, e.g. one stimulus or one pitch) is reported as "rate 0" and not simulated.

Table 1: trials to stop (median and 90th percentile over observers), the number that ended on
the wrong model, and the number that reached ``--max-trials`` undecided, with each allocation's
rate. Table 2: selection time per trial with 200 candidates, per utility. Table 3: grid
accuracy: the posterior log-odds of the true model after the same 200 constant-stimuli trials
with the default grid and with a grid twice as fine in threshold and exponent. Table 4:
calibration of the stopping rule: adaptive runs stopping at 0.9 and 0.99 on fresh observers,
the wrong count against its expectation under a calibrated posterior (the sum of 1 - P(winner)).
Table 5 (``--tables 5``): the same per observer: each of ``--per-observer`` observers (scenario
(a)) answers many sessions anew; the spread of their wrong shares.
"""

from __future__ import annotations

import argparse
import math
import os
import time
import warnings

import numpy as np
from scipy.optimize import minimize

from tactilab.data_schemas.experiment import Stimulus
from tactilab.experiments import ModelDiscrimination, TransductionModel
from tactilab.experiments.modelling._transduction_data import p_correct_table
from tactilab.experiments.modelling.model_power import ZERO_RATE_NATS, _from_free, _to_free
from tactilab.experiments.modelling.models import power_analysis


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
    """(P(correct) per candidate, theta) of a simulated observer reading model ``truth``."""
    s = design.stats[truth]
    theta = [float(np.median(s[:, 0]) * math.exp(rng.uniform(math.log(0.3), math.log(3)))),
             float(1.2 * math.exp(0.25 * rng.standard_normal())), float(rng.uniform(0, 0.04))]
    return p_correct_table("2ifc", s[:, 0], s[:, 1], np.array([theta]))[0], np.array(theta)


ODDS, MODEL = 'adaptive, utility="odds"', 'adaptive, "model" (default)'


def _run(models, candidates, truth, seed, design_kind, max_trials, allocation=None, fine=None, n_grid=(25, 9),
         stop=0.99, utility="odds", response_seed=None):
    """One simulated session. ``design_kind``: adaptive, constant, allocation (fixed weights) or
    bound (the best allocation for this observer's true parameters, computed here).
    ``response_seed``: the responses from their own generator (the same observer, ``seed``, answering
    anew). Returns (trials, winner, true name, P(winner) at the end, allocation rate or None)."""
    rng = np.random.default_rng(seed)
    d = ModelDiscrimination(models, candidates, rng=seed, max_trials=max_trials, n_grid=n_grid, stop_probability=stop,
                            utility=utility)
    p, theta = _observer(d, truth, rng)
    if response_seed is not None:
        rng = np.random.default_rng(response_seed)
    rate = None
    if design_kind == "bound":
        allocation, rate, _, _ = best_allocation([(truth, theta)], d, fine, d.candidates)
        if rate == 0.0:  # the rival fits this allocation exactly: it never decides
            return max_trials, None, d.names[truth], float("nan"), rate
    order: list[int] = []
    counts = np.zeros(len(d.candidates))
    while not d.finished:
        if design_kind == "adaptive":
            i = d.choose()
        elif design_kind == "constant":
            if not order:
                order = list(rng.permutation(len(d.candidates)))
            i = order.pop()
        else:  # a fixed allocation, shown in proportion: the candidate furthest behind its share
            i = int(np.argmax(allocation * (counts.sum() + 1) - counts))
            counts[i] += 1
        d.observe(i, bool(rng.random() < p[i]))
    win = d.winner
    return len(d.probabilities), win, d.names[truth], (d.model_probabilities()[win] if win else float("nan")), rate


# ----- fixed allocations: maximise the per-trial rate mu / sigma of power_analysis ----------------
class _Truth:
    """One true (model, theta) against the rival: P(correct) of both, and the rival's projection.

    The rival's pseudo-true parameters (the KL projection of the truth over an allocation) are
    found as in power_analysis, in its free coordinates, by Nelder-Mead started from the best of
    the rival's grid points and the previous projection (a grid alone would let the optimiser
    exploit the grid's gaps: a single candidate the grid cannot fit exactly, a spurious rate).
    """

    def __init__(self, design, fine, m, theta):
        self.p = np.clip(p_correct_table("2ifc", design.stats[m, :, 0], design.stats[m, :, 1],
                                         np.array([theta]))[0], 1e-12, 1 - 1e-12)
        self.r = design.stats[1 - m]
        q = np.clip(fine.table[:, 1 - m, :], 1e-12, 1 - 1e-12)
        self.grid_kl = self.p[:, None] * np.log(self.p[:, None] / q) + (1 - self.p[:, None]) * np.log(
            (1 - self.p[:, None]) / (1 - q))
        self.grid = fine.grid
        self.u = None

    def q(self, u):
        return np.clip(p_correct_table("2ifc", self.r[:, 0], self.r[:, 1], _from_free(u, "2ifc")[None])[0],
                       1e-12, 1 - 1e-12)

    def kl(self, q):
        p = self.p
        return p * np.log(p / q) + (1 - p) * np.log((1 - p) / (1 - q))

    def rate(self, w):
        """(mu / sigma, d(mu / sigma)/dw) at allocation w (envelope theorem at the projection)."""
        g = int(np.argmin(w @ self.grid_kl))
        starts = [_to_free(self.grid[g], "2ifc")] + ([self.u] if self.u is not None else [])
        best = min((minimize(lambda u: float(w @ self.kl(self.q(u))), u0, method="Nelder-Mead",
                             options=dict(xatol=1e-6, fatol=1e-14, maxiter=600)) for u0 in starts),
                   key=lambda r: r.fun)
        self.u = best.x
        q = self.q(best.x)
        l1, l0 = np.log(self.p / q), np.log((1 - self.p) / (1 - q))
        k, s2 = self.p * l1 + (1 - self.p) * l0, self.p * l1 ** 2 + (1 - self.p) * l0 ** 2
        mu = float(w @ k)
        var = float(w @ s2) - mu * mu
        if mu <= ZERO_RATE_NATS or var <= 0:
            return 0.0, np.zeros_like(w)
        sd = math.sqrt(var)
        return mu / sd, (k * sd - mu * (s2 - 2 * mu * k) / (2 * sd)) / var


def optimise_allocation(truths, n_candidates, iters=80, eta=0.3):
    """Exponentiated-gradient ascent of the truths' mean rate over the simplex, from the uniform allocation."""
    w = np.full(n_candidates, 1.0 / n_candidates)
    best, best_val = w, -1.0
    for _ in range(iters):
        out = [t.rate(w) for t in truths]
        val, grad = float(np.mean([o[0] for o in out])), np.mean([o[1] for o in out], axis=0)
        if val > best_val:
            best, best_val = w, val
        w = w * np.exp(eta * grad / (np.abs(grad).max() + 1e-300))
        w /= w.sum()
    return best


def verified_rate(w, truths, design, candidates, n_total=1000):
    """Mean over truths of power_analysis's rate (continuous rival; exactly 0 when it fits the design)."""
    counts = np.round(w * n_total).astype(int)
    items = [(candidates[i], int(c)) for i, c in enumerate(counts) if c > 0]
    out = []
    for m, theta in truths:
        res = power_analysis(design.models[m], dict(zip(("threshold_strain", "exponent", "lapse"), map(float, theta))),
                             design.models[1 - m], items)
        out.append(res.rate)
    return float(np.mean(out)), len(items)


def best_allocation(truths, design, fine, candidates):
    """The best fixed allocation for the truths (model index, theta): optimised on the rival's fine grid,
    then the best by power_analysis's rate of it and of its mixtures with the uniform allocation."""
    w = optimise_allocation([_Truth(design, fine, m, theta) for m, theta in truths], len(candidates))
    u = np.full(len(candidates), 1.0 / len(candidates))
    options = [(a, (1 - a) * w + a * u) for a in (0.0, 0.1)]
    scored = [(verified_rate(v, truths, design, candidates), a, v) for a, v in options]
    (rate, support), mix, v = max(scored, key=lambda s: s[0][0])
    return v, rate, support, mix


def prior_truths(design, n_per_model, rng):
    """(model, theta) drawn from the design's grid prior."""
    w = design.weights()
    out = []
    for m in range(w.shape[0]):
        p = w[m] / w[m].sum()
        out += [(m, design.grid[g]) for g in rng.choice(p.size, n_per_model, p=p)]
    return out


def _summary(rows, n_observers):
    n = np.array([r[0] for r in rows])
    wrong = sum(r[1] is not None and r[1] != r[2] for r in rows)
    undecided = sum(r[1] is None for r in rows)
    return n, wrong, undecided


def table_trials(n_observers, max_trials, n_prior=16, seed_offset=0, adaptive_only=False):
    print(f"Table 1 -- trials to 0.99 posterior probability, {n_observers} simulated observers per scenario")
    print(f"{'scenario':24s} {'design':28s} {'rate':>7s} {'median':>7s} {'p90':>7s} {'wrong':>9s} "
          f"{'undecided':>10s} {'wall s':>7s}")
    for name, (hyps, cands) in SCENARIOS.items():
        models = [TransductionModel(h) for h in hyps]  # statistics computed once, shared by every run
        t0 = time.perf_counter()
        designs = [(ODDS, "adaptive", None, None), (MODEL, "model", None, None)]
        fine = None
        if not adaptive_only:
            design = ModelDiscrimination(models, cands, max_trials=max_trials)
            fine = ModelDiscrimination(models, cands, n_grid=(49, 17), max_trials=max_trials)
            truths = prior_truths(design, n_prior, np.random.default_rng(7))
            uniform = np.full(len(cands), 1.0 / len(cands))
            cs_rate, _ = verified_rate(uniform, truths, design, design.candidates)
            prior_w, prior_rate, support, mix = best_allocation(truths, design, fine, design.candidates)
            print(f"{'':24s} (prior-chosen allocation: {support} candidates, {mix:.0%} uniform mixed in; "
                  f"prior-mean rate mu/sigma {prior_rate:.4f} vs {cs_rate:.4f} for constant stimuli; "
                  f"{time.perf_counter() - t0:.0f} s)")
            designs += [("constant stimuli", "constant", None, cs_rate),
                        ("best prior allocation", "allocation", prior_w, prior_rate),
                        ("bound: true-param alloc.", "bound", None, None)]
        medians = {}
        for label, kind, w, rate in designs:
            t0 = time.perf_counter()
            if rate == 0.0:
                print(f"{name:24s} {label:28s} {0:7.4f}  rate 0: the rival fits this design exactly, it never decides")
                continue
            rows = [_run(models, cands, k * 2 // n_observers, seed_offset + 1000 + k,
                         "adaptive" if kind == "model" else kind, max_trials, w, fine,
                         utility="model" if kind == "model" else "odds") for k in range(n_observers)]
            n, wrong, undecided = _summary(rows, n_observers)
            if kind == "bound":
                rates = np.array([r[4] for r in rows])
                rate = float(np.median(rates))
                zero = int(np.sum(rates == 0))
            medians[label] = float(np.median(n))
            print(f"{name:24s} {label:28s} {rate if rate is not None else float('nan'):7.4f} {np.median(n):7.1f} "
                  f"{np.percentile(n, 90):7.0f} {wrong:3d} ({wrong / n_observers:4.0%}) {undecided:3d} ({undecided / n_observers:4.0%})"
                  f" {time.perf_counter() - t0:7.1f}" + (f"  [{zero} observers: rate 0]" if kind == "bound" and zero else ""))
        odds_model = medians[ODDS] / medians[MODEL]
        if adaptive_only:
            print(f"{'':24s} utility odds / model {odds_model:.2f}")
            continue
        for label in (ODDS, MODEL):
            ratio = medians[label] / medians["constant stimuli"]
            prior_ratio = medians[label] / medians.get("best prior allocation", math.inf)
            print(f"{'':24s} {label}: / constant stimuli {ratio:.3f} (goal <= 0.25); / best prior allocation "
                  f"{prior_ratio:.2f} (goal < 1)")
        print(f"{'':24s} utility odds / model {odds_model:.2f}")


def table_calibration(n_observers, max_trials, seed_offset=0):
    """Among adaptive runs that stop with a winner at P >= stop, the share that is wrong: a calibrated
    posterior gives at most 1 - stop, and about the sum over runs of 1 - P(winner) wrong runs."""
    print(f"\nTable 4 -- calibration of the stopping rule: {n_observers} adaptive observers per scenario and level "
          f"(seeds {5000 + seed_offset}+, not those of table 1)")
    print(f"{'scenario':24s} {'stop at':>7s} {'median':>7s} {'wrong':>13s} {'expected if calibrated':>23s} "
          f"{'undecided':>9s} {'wall s':>7s}")
    for name, (hyps, cands) in SCENARIOS.items():
        models = [TransductionModel(h) for h in hyps]
        for stop in (0.9, 0.99):
            t0 = time.perf_counter()
            rows = [_run(models, cands, k * 2 // n_observers, seed_offset + 5000 + k, "adaptive", max_trials, stop=stop)
                    for k in range(n_observers)]
            n, wrong, undecided = _summary(rows, n_observers)
            expected = float(np.nansum([1 - r[3] for r in rows]))
            print(f"{name:24s} {stop:7.2f} {np.median(n):7.0f} {wrong:4d} ({wrong / n_observers:5.1%}) "
                  f"{expected:16.1f} ({expected / n_observers:4.1%}) {undecided:9d} {time.perf_counter() - t0:7.1f}")


def table_per_observer(n_observers, n_repeats, max_trials, seed_offset=0):
    """The stopping rule's calibration per observer: each observer (true model and parameters
    fixed) answers ``n_repeats`` sessions anew; the share of decided sessions ending on the wrong
    model, per observer. Calibration holds on average over observers drawn from the prior, not
    for each one."""
    from scipy.stats import binom

    print(f"\nTable 5 -- the stopping rule per observer: {n_observers} observers x {n_repeats} sessions each "
          f"(observer seeds {7000 + seed_offset}+), scenario (a)")
    print(f"{'stop at':>7s} {'mean wrong':>10s} {'median':>7s} {'max':>6s} {'observers above 1 - stop':>25s} "
          f"{'signif. (p < 0.01)':>18s} {'wall s':>7s}")
    hyps, cands = SCENARIOS["(a) zx@1mm vs zx@2mm"]
    models = [TransductionModel(h) for h in hyps]
    for stop in (0.9, 0.99):
        t0, rates, significant = time.perf_counter(), [], 0
        for k in range(n_observers):
            seed = seed_offset + 7000 + k
            rows = [_run(models, cands, k % 2, seed, "adaptive", max_trials, stop=stop,
                         response_seed=seed * 10_000 + r) for r in range(n_repeats)]
            decided = [r for r in rows if r[1] is not None]
            wrong = sum(r[1] != r[2] for r in decided)
            rates.append(wrong / max(len(decided), 1))
            significant += int(binom.sf(wrong - 1, len(decided), 1 - stop) < 0.01)  # P(>= wrong | 1 - stop)
        rates = np.array(rates)
        print(f"{stop:7.2f} {rates.mean():10.1%} {np.median(rates):7.1%} {rates.max():6.1%} "
              f"{int(np.sum(rates > 1 - stop)):12d} of {n_observers:<8d} {significant:12d} {time.perf_counter() - t0:11.1f}")


def table_selection():
    print("\nTable 2 -- selection time per trial, 200 candidates (2 models, grid 28 x 9 x 4 per model)")
    cands = _grid(("sinusoid",), np.geomspace(2e-6, 6e-5, 20), np.geomspace(0.8e-3, 8e-3, 10))
    models = [TransductionModel(h) for h in ("zx@1mm", "zx@2mm")]
    for utility in ("odds", "model", "parameters", "both"):
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
        p, _ = _observer(coarse, k % 2, rng)
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
    parser.add_argument("--calibration", type=int, default=200, help="observers per scenario in table 4 (0: skip)")
    parser.add_argument("--per-observer", type=int, nargs=2, default=[20, 100], metavar=("OBSERVERS", "SESSIONS"),
                        help="table 5: observers and sessions per observer")
    parser.add_argument("--tables", default="1234", help="which tables to print, e.g. 14")
    parser.add_argument("--adaptive-only", action="store_true",
                        help="table 1: only the adaptive rows (both utilities), no allocations (fast)")
    parser.add_argument("--seed-offset", type=int, default=0,
                        help="added to the observers' seeds of tables 1 and 4 (a development set; default 0 reports)")
    args = parser.parse_args()
    warnings.simplefilter("ignore")  # metameric warnings of sub-designs are expected
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs at start")
    if "1" in args.tables:
        table_trials(args.observers, args.max_trials, seed_offset=args.seed_offset, adaptive_only=args.adaptive_only)
    if "2" in args.tables:
        table_selection()
    if "3" in args.tables:
        table_grid_accuracy()
    if "4" in args.tables and args.calibration:
        table_calibration(args.calibration, args.max_trials, seed_offset=args.seed_offset)
    if "5" in args.tables:
        table_per_observer(*args.per_observer, args.max_trials, seed_offset=args.seed_offset)


if __name__ == "__main__":
    main()

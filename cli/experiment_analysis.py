"""``tactilab experiment fit | compare | power``: analyse recorded sessions (parse, call, print).

Wire into the ``experiment`` command with ``add_subcommands(subparsers)``: each subcommand sets
its own ``_run`` default, so the dispatcher calls it directly.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from .common import make_out


def add_subcommands(sub) -> None:
    """Add ``fit``, ``compare`` and ``power`` to the ``experiment`` command's subparsers."""
    fit = sub.add_parser("fit", help="psychometric fit per condition (psignifit-4 priors): threshold with its "
                                     "95 %% interval in um / mm / mm/s / ms, and a PNG per condition")
    fit.add_argument("sessions", nargs="+", type=Path, metavar="SESSION", help="session .sqlite file(s), one task")
    fit.add_argument("--sigmoid", default="norm", help="norm, logistic, gumbel, rgumbel, tdist or weibull (default norm)")
    fit.add_argument("--out", type=Path, default=None, help="folder for the PNGs (default: the first session's folder)")
    fit.add_argument("--seed", type=int, default=0, help="seed for posterior draws (default 0)")
    fit.set_defaults(_run=run_fit)

    cmp = sub.add_parser("compare", help="fit transduction models (receptor hypotheses, strain dimensionless) to "
                                         "sessions and compare them by PSIS-LOO; table with verdicts and a PNG")
    cmp.add_argument("sessions", nargs="+", type=Path, metavar="SESSION", help="session .sqlite file(s), one task")
    cmp.add_argument("--model", action="append", required=True, metavar="HYPOTHESIS",
                     help="receptor hypothesis components@depths[:shear], depths with units, e.g. zx@1mm or "
                          "xx,zx@1.25mm; give two or more")
    cmp.add_argument("--statistic", default="peak", help="'peak' (largest |readout|) or 'rms' (default peak)")
    cmp.add_argument("--seed", type=int, default=0, help="seed for the samplers (default 0)")
    cmp.add_argument("--out", type=Path, default=None, help="folder for the PNG (default: the first session's folder)")
    cmp.set_defaults(_run=run_compare)

    power = sub.add_parser("power", help="trials needed to tell a true transduction model from a rival over a design "
                                         "(asymptotic; strain dimensionless)")
    power.add_argument("--true", required=True, dest="true_model", metavar="HYPOTHESIS",
                       help="the observer's hypothesis, e.g. zx@1mm (depths with units)")
    power.add_argument("--rival", required=True, metavar="HYPOTHESIS", help="the rival hypothesis, e.g. xx@1mm")
    power.add_argument("--design", required=True, type=Path, metavar="FILE",
                       help="TOML with [[trials]] tables: Stimulus fields with units (amplitude_m = \"1um\", "
                            "pitch_m = \"2mm\", speed_m_per_s = \"20mm/s\") and n = trials")
    power.add_argument("--task", default="2ifc", help="2ifc (against a blank) or yes_no (default 2ifc)")
    power.add_argument("--threshold", type=float, default=None,
                       help="true threshold strain (dimensionless) at d' = 1; default: the median statistic of the design")
    power.add_argument("--exponent", type=float, default=1.0, help="transducer exponent (dimensionless, default 1)")
    power.add_argument("--lapse", type=float, default=0.02, help="lapse rate in [0, 0.5) (default 0.02)")
    power.add_argument("--false-alarm", type=float, default=0.16, help="yes/no false-alarm rate (default 0.16)")
    power.add_argument("--out", type=Path, default=Path("."), help="folder for the PNG (default .)")
    power.set_defaults(_run=run_power)


def _out(args) -> Path:
    return make_out(args.out if args.out is not None else args.sessions[0].parent)


def run_fit(args: argparse.Namespace) -> int:
    from tactilab.experiments.analysis import fit_conditions

    fits = fit_conditions(args.sessions, sigmoid=args.sigmoid, rng=args.seed)
    out = _out(args)
    print(f"{'condition':52s} {'trials':>6s} {'threshold [95 % interval]':>32s} {'width':>9s} {'lapse':>6s} {'gof p':>6s}")
    for i, c in enumerate(fits):
        th, w, lam = (c.fit.params[k] for k in ("threshold", "width", "lapse"))
        interval = f"{th.map:.3g} [{th.ci95[0]:.3g}, {th.ci95[1]:.3g}] {c.unit}"
        print(f"{c.label:52s} {c.n_trials:6d} {interval:>32s} {w.map:9.3g} {lam.map:6.3f} {c.fit.gof_p:6.2f}")
        path = out / f"fit_{i + 1:02d}.png"
        c.fit.plot(path, xlabel=f"{c.parameter.rsplit('_', 1)[0]} ({c.unit.replace('um', 'µm')})", title=c.label)
        print(f"  wrote {path}")
    return 0


def run_compare(args: argparse.Namespace) -> int:
    from tactilab.experiments.analysis import compare_sessions, plot_comparison

    table, fits = compare_sessions(args.sessions, args.model, statistic=args.statistic, rng=args.seed)
    out = _out(args)
    print(f"{'model':24s} {'elpd':>10s} {'elpd_diff':>10s} {'dse':>8s} {'z':>7s} {'k max':>6s} {'converged':>9s}  verdict")
    for name, row in table.iterrows():
        print(f"{name:24s} {row['elpd']:10.2f} {row['elpd_diff']:10.2f} {row['dse']:8.2f} {row['z']:7.2f} "
              f"{row['pareto_k_max']:6.2f} {str(fits[name].converged):>9s}  {row['verdict']}")
    path = out / "compare.png"
    plot_comparison(table, fits, path)
    print(f"wrote {path}")
    return 0


def run_power(args: argparse.Namespace) -> int:
    import numpy as np

    from tactilab.experiments.analysis import plot_power, read_design
    from tactilab.experiments.models import TransductionModel, power_analysis

    design = read_design(args.design)
    true_model, rival = TransductionModel(args.true_model), TransductionModel(args.rival)
    threshold = args.threshold
    if threshold is None:
        stats = [true_model.statistic_of(s) for s, _ in design]
        threshold = float(np.median([s for s in stats if s > 0] or [1.0]))
    params = dict(threshold_strain=threshold, exponent=args.exponent, lapse=args.lapse)
    if args.task == "yes_no":
        params["false_alarm"] = args.false_alarm
    result = power_analysis(true_model, params, rival, design, task=args.task)
    n_design = sum(n for _, n in design)
    print(f"true {args.true_model} at threshold strain {threshold:.3g}, exponent {args.exponent:g}, "
          f"lapse {args.lapse:g}; rival {args.rival}")
    print("rival's pseudo-true parameters: " + ", ".join(f"{k} {v:.4g}" for k, v in result.rival_params.items()))
    print(f"mu {result.mu:.4g} nats/trial, sigma {result.sigma:.4g} nats/trial")
    for z in (2.0, 4.0):
        need = result.trials_for(z)
        print(f"trials for z = {z:g}: " + (f"{math.ceil(need)}" if math.isfinite(need) else
                                           "never (identical predictions on this design)"))
    print(f"P(z > 4) with the design's {n_design} trials: {result.p_select(n_design):.3f}")
    make_out(args.out)
    path = args.out / "power.png"
    plot_power(result, path, int(min(max(2 * result.trials_for(4.0), 4 * n_design), 1e6))
               if math.isfinite(result.trials_for(4.0)) else 4 * n_design)
    print(f"wrote {path}")
    return 0

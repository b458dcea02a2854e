"""``tactilab experiment fit | compare | power``: analyse recorded sessions (parse, call, print).

Wire into the ``experiment`` command with ``add_subcommands(subparsers)``: each subcommand sets
its own ``_run`` default, so the dispatcher calls it directly.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from .batch_options import add_worker_options, batch_where, wants_batch
from .common import check_hypothesis, make_out, renamed

_JSON_HELP = "print one JSON object (the summary, SI units or units in the key names) instead of text"
_FORCE_HELP = "replace PNGs of the same name that an earlier run wrote (without it they are refused)"


def add_subcommands(sub) -> None:
    """Add ``fit``, ``compare`` and ``power`` to the ``experiment`` command's subparsers."""
    fit = sub.add_parser("fit", help="psychometric fit per condition (psignifit-4 priors): threshold with its "
                                     "95 %% interval in um / mm / mm/s / ms, and a PNG per condition")
    fit.add_argument("sessions", nargs="+", type=Path, metavar="SESSION", help="session .sqlite file(s), one task")
    fit.add_argument("--sigmoid", default="auto",
                     help="auto (default: weibull on log levels for amplitude, pitch and duration, norm for a signed "
                          "speed), weibull or lognorm (log levels), or norm, logistic, gumbel, rgumbel, tdist (linear "
                          "levels: signed quantities only)")
    fit.add_argument("--out", type=Path, default=None,
                     help="folder for the PNGs, fit_01.png, ... (default: the first session's folder, with the "
                          "session's name first: <session>_fit_01.png, ...); an existing PNG needs --force")
    fit.add_argument("--force", action="store_true", help=_FORCE_HELP)
    fit.add_argument("--seed", type=int, default=0, help="seed for posterior draws (default 0)")
    fit.add_argument("--json", action="store_true", help=_JSON_HELP)
    fit.set_defaults(_run=run_fit)

    cmp = sub.add_parser("compare", help="fit transduction models (receptor hypotheses, strain dimensionless) to "
                                         "sessions and compare them by PSIS-LOO; table with verdicts and a PNG")
    cmp.add_argument("sessions", nargs="+", type=Path, metavar="SESSION", help="session .sqlite file(s), one task")
    cmp.add_argument("--model", action="append", required=True, metavar="HYPOTHESIS",
                     help="receptor hypothesis components@depths[:shear], depths with units, e.g. zx@1mm or "
                          "xx,zx@1.25mm; give two or more")
    cmp.add_argument("--statistic", default="peak", help="'peak' (largest |readout|) or 'rms' (default peak)")
    cmp.add_argument("--source", default="surface", choices=("surface", "display"),
                     help="strain the models read: 'surface' (the ideal virtual surface, default) or 'display' (what "
                          "the sessions' display renders, from the display description they recorded; all sessions "
                          "on one display; not with --workers or --scheduler)")
    cmp.add_argument("--method", default="grid", choices=("grid", "emcee"),
                     help="'grid' (quadrature on an adaptive grid: seconds, the same table for every seed) or "
                          "'emcee' (the samplers, the reference; slower, seed-dependent within Monte Carlo error); "
                          "default grid")
    cmp.add_argument("--seed", type=int, default=0, help="seed for --method emcee (default 0); the grid uses none")
    cmp.add_argument("--max-steps", type=int, default=None,
                     help="--method emcee only: step limit per ensemble (steps; default 20000); stops earlier once "
                          "converged")
    cmp.add_argument("--out", type=Path, default=None,
                     help="folder for the PNG, compare.png (default: the first session's folder, as "
                          "<session>_compare.png; an existing PNG needs --force); with --workers or --scheduler "
                          "the batch folder (default: <first session's folder>/compare-batch; the same folder resumes)")
    cmp.add_argument("--force", action="store_true", help=_FORCE_HELP)
    cmp.add_argument("--json", action="store_true", help=_JSON_HELP)
    add_worker_options(cmp, default_help="one pooled fit per model in-process, no batch; with --workers or "
                                         "--scheduler the sessions are grouped by their subject and each "
                                         "(subject, model) is fitted as one batch task")
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
    power.add_argument("--out", type=Path, default=Path("."),
                       help="folder for the PNG, power.png (default .; an existing one needs --force); the simulated "
                            "sweep's results go to <out>/power-batch (the same folder resumes)")
    power.add_argument("--force", action="store_true", help=_FORCE_HELP)
    power.add_argument("--seeds", type=int, default=None, metavar="N",
                       help="also simulate: N independent power estimates per trial count (count), one batch task "
                            "each (with --trials)")
    power.add_argument("--trials", default=None, metavar="LIST",
                       help="trial counts N of the simulated sweep, comma-separated counts (default: the design's "
                            "total, x2 and x4)")
    power.add_argument("--seed", type=int, default=0, help="batch seed of the simulated sweep (integer, default 0)")
    power.add_argument("--repeats", type=int, default=100,
                       help="simulated experiments per power estimate (count, default 100)")
    power.add_argument("--json", action="store_true", help=_JSON_HELP)
    add_worker_options(power, default_help="serial in-process")
    power.set_defaults(_run=run_power)


def _figure(args, name: str, index: int | None = None) -> Path:
    """Where a figure goes: ``--out/name`` or, by default, next to the first session with its name first
    (``<session>_name``), so analysing a second session in the same folder never replaces the first's;
    an existing file is refused without ``--force`` (:func:`tactilab.core.outputs.new_file`)."""
    from tactilab.core.outputs import new_file

    stem, suffix = name.rsplit(".", 1)
    stem = stem if index is None else f"{stem}_{index:02d}"
    if args.out is not None:
        return new_file(make_out(args.out) / f"{stem}.{suffix}", args.force)
    first = Path(args.sessions[0])
    more = f"+{len(args.sessions) - 1}" if len(args.sessions) > 1 else ""
    return new_file(make_out(first.parent) / f"{first.stem}{more}_{stem}.{suffix}", args.force)


def run_fit(args: argparse.Namespace) -> int:
    from tactilab.experiments.modelling import fit_conditions

    fits = fit_conditions(args.sessions, sigmoid=args.sigmoid, rng=args.seed)
    paths = [_figure(args, "fit.png", i + 1) for i in range(len(fits))]  # all checked before any is written
    if args.json:
        rows = []
        for c, path in zip(fits, paths):
            c.fit.plot(path, xlabel=f"{c.parameter.rsplit('_', 1)[0]} ({c.unit.replace('um', 'µm')})", title=c.label)
            th = c.fit.params["threshold"]
            rows.append(dict(condition=c.label, parameter=c.parameter, unit=c.unit, n_trials=c.n_trials,
                             threshold=th.map, threshold_ci95=list(th.ci95), width=c.fit.params["width"].map,
                             lapse=c.fit.params["lapse"].map, gof_p=c.fit.gof_p, png=str(path)))
        print(json.dumps({"command": "experiment fit", "conditions": rows}))
        return 0
    print(f"{'condition':52s} {'trials':>6s} {'threshold [95 % interval]':>32s} {'width':>9s} {'lapse':>6s} {'gof p':>6s}")
    for c, path in zip(fits, paths):
        th, w, lam = (c.fit.params[k] for k in ("threshold", "width", "lapse"))
        interval = f"{th.map:.3g} [{th.ci95[0]:.3g}, {th.ci95[1]:.3g}] {c.unit}"
        print(f"{c.label:52s} {c.n_trials:6d} {interval:>32s} {w.map:9.3g} {lam.map:6.3f} {c.fit.gof_p:6.2f}")
        c.fit.plot(path, xlabel=f"{c.parameter.rsplit('_', 1)[0]} ({c.unit.replace('um', 'µm')})", title=c.label)
        print(f"  wrote {path}")
    return 0


def _text(value) -> str:
    return str(getattr(value, "values", value))


def _compare_row(row, converged) -> dict:
    sep = float(row["separation"])
    return dict(elpd=float(row["elpd"]), elpd_diff=float(row["elpd_diff"]), dse=float(row["dse"]), z=float(row["z"]),
                pareto_k_max=float(row["pareto_k_max"]), converged=bool(converged),
                separation=None if math.isnan(sep) else sep, verdict=_text(row["verdict"]), reason=_text(row["reason"]))


def _sampler(args: argparse.Namespace) -> dict | None:
    if args.method != "emcee":
        if args.max_steps is not None:
            raise ValueError(f"--max-steps: only for --method emcee (the grid has no steps), got {args.max_steps}; "
                             "drop it or add --method emcee")
        return None
    steps = 20000 if args.max_steps is None else args.max_steps
    if steps < 1:
        raise ValueError(f"--max-steps: must be >= 1 step, got {steps}; e.g. 20000")
    return {"max_steps": steps}


def run_compare(args: argparse.Namespace) -> int:
    for text in args.model:
        check_hypothesis(text, "--model")
    if wants_batch(args):
        if args.source != "surface":
            raise ValueError("--source: 'display' is for a pooled comparison; drop --workers/--scheduler or use "
                             "--source surface")
        return _run_compare_batch(args)
    from tactilab.experiments.modelling import compare_sessions, plot_comparison

    display = _recorded_display(args.sessions) if args.source == "display" else None
    path = _figure(args, "compare.png")  # checked before the fits
    with renamed({"max_steps": "--max-steps"}):  # emcee's memory rule names the option
        table, fits = compare_sessions(args.sessions, args.model, statistic=args.statistic, rng=args.seed,
                                       method=args.method, sampler_options=_sampler(args), source=args.source,
                                       display=display)
    plot_comparison(table, fits, path)
    if args.json:
        print(json.dumps({"command": "experiment compare", "models": {
            name: _compare_row(row, fits[name].converged) for name, row in table.iterrows()}, "png": str(path)}))
        return 0
    print(f"{'model':24s} {'elpd':>10s} {'elpd_diff':>10s} {'dse':>8s} {'z':>7s} {'separ.':>7s} {'k max':>6s} "
          f"{'converged':>9s}  verdict")
    for name, row in table.iterrows():
        print(f"{name:24s} {row['elpd']:10.2f} {row['elpd_diff']:10.2f} {row['dse']:8.2f} {row['z']:7.2f} "
              f"{row['separation']:7.2f} {row['pareto_k_max']:6.2f} {str(fits[name].converged):>9s}  {row['verdict']}")
    _print_reasons(table["verdict"], table["reason"], table.index, "")
    print(f"wrote {path}")
    return 0


def _recorded_display(sessions):
    """A SimulatedDisplay of the display description the sessions recorded (all the same one)."""
    from tactilab.data_schemas.display import DisplayDescription
    from tactilab.experiments.devices import SimulatedDisplay
    from tactilab.experiments.session import session_header

    metas = [session_header(path).meta for path in sessions]
    shas = {m.get("display_sha256") for m in metas}
    if len(shas) != 1 or metas[0].get("display_description") is None:
        raise ValueError(f"--source: 'display' needs sessions recorded on one display with its description; got "
                         f"{len(shas)} display description(s) {sorted(map(str, shas))}; compare them per display "
                         "or use --source surface")
    return SimulatedDisplay(DisplayDescription.model_validate(metas[0]["display_description"]), realtime=False)


def _print_reasons(verdicts, reasons, names, indent: str) -> None:
    """The reason under the table for every row without a plain verdict (not identifiable, no verdict)."""
    for name, verdict, reason in zip(names, verdicts, reasons):
        if str(verdict).startswith(("not identifiable", "no verdict")) and reason:
            print(f"{indent}{name}: {verdict}: {reason}")


def _run_compare_batch(args: argparse.Namespace) -> int:
    from tactilab.experiments.modelling import compare_many, sessions_by_subject

    if len(args.model) < 2 or len(set(args.model)) != len(args.model):
        raise ValueError(f"--model: give two or more different hypotheses, got {args.model}; e.g. --model zx@1mm "
                         "--model xx@1mm")
    subjects = sessions_by_subject(args.sessions)
    out = make_out(args.out if args.out is not None else Path(args.sessions[0]).parent / "compare-batch")
    table = compare_many(subjects, args.model, seed=args.seed, out_dir=out, statistic=args.statistic,
                         method=args.method, sampler_options=_sampler(args),
                         progress=not args.json, echo=(lambda _: None) if args.json else print, **batch_where(args))
    a = table.attrs
    if args.json:
        print(json.dumps({"command": "experiment compare", "subjects": {
            s: {m: _compare_row(table.sel(subject=s, model=m), table["converged"].sel(subject=s, model=m))
                for m in table["model"].values} for s in table["subject"].values},
            "n_run": a["n_run"], "n_skipped": a["n_skipped"], "n_failed": a["n_failed"],
            "failed": [k for k in a["failed"].split(";") if k], "out": str(out)}))
        return 1 if a["n_failed"] else 0
    for s in table["subject"].values:
        print(f"subject {s}")
        print(f"  {'model':22s} {'elpd':>10s} {'elpd_diff':>10s} {'dse':>8s} {'z':>7s} {'separ.':>7s} {'k max':>6s} "
              f"{'converged':>9s}  verdict")
        for m in table["model"].values:
            row = table.sel(subject=s, model=m)
            print(f"  {m:22s} {float(row['elpd']):10.2f} {float(row['elpd_diff']):10.2f} {float(row['dse']):8.2f} "
                  f"{float(row['z']):7.2f} {float(row['separation']):7.2f} {float(row['pareto_k_max']):6.2f} "
                  f"{str(bool(row['converged'])):>9s}  {row['verdict'].values}")
        sub = table.sel(subject=s)
        _print_reasons([_text(v) for v in sub["verdict"]], [_text(v) for v in sub["reason"]], sub["model"].values, "  ")
    print(f"batch: {a['n_run']} fit(s) run, {a['n_skipped']} skipped (done before), {a['n_failed']} failed; "
          f"files: {out / 'results'} (one DataTree per subject and model), {out / 'compare_many.nc'} (the table)"
          + (f", {out / 'errors.tsv'}" if a["n_failed"] else ""))
    return 1 if a["n_failed"] else 0


def _counts(text: str, name: str) -> list[int]:
    try:
        return [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise ValueError(f"{name}: expected comma-separated trial counts (integers >= 1), got {text!r}; "
                         "e.g. 100,200,400") from None


def run_power(args: argparse.Namespace) -> int:
    import numpy as np

    from tactilab.experiments.modelling import plot_power, read_design
    from tactilab.experiments.modelling import TransductionModel, power_analysis

    from tactilab.core.outputs import new_file

    ns = _counts(args.trials, "--trials") if args.trials is not None else None
    if args.seeds is None and (wants_batch(args) or args.trials is not None):
        raise ValueError("--seeds: --workers, --scheduler and --trials belong to the simulated sweep; give the number "
                         "of simulated power estimates per trial count, e.g. --seeds 4")
    if args.seeds is not None and args.repeats < 1:
        raise ValueError(f"--repeats: must be >= 1 simulated experiment, got {args.repeats}; e.g. 100")
    check_hypothesis(args.true_model, "--true")
    check_hypothesis(args.rival, "--rival")
    design = read_design(args.design)
    if args.seeds is not None:  # the sweep's sizes and memory, before anything is computed or written
        from tactilab.experiments.modelling import check_power_sweep

        n_design = sum(n for _, n in design)
        ns = ns if ns is not None else [n_design, 2 * n_design, 4 * n_design]
        with renamed({"n_seeds": "--seeds", "n_repeats": "--repeats", "n_trials": "--trials"}):
            check_power_sweep(ns, args.seeds, args.repeats)
    path = new_file(args.out / "power.png", args.force)  # before the computation: an earlier run's PNG stays
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
    make_out(args.out)
    plot_power(result, path, int(min(max(2 * result.trials_for(4.0), 4 * n_design), 1e6))
               if math.isfinite(result.trials_for(4.0)) else 4 * n_design)
    sweep = None
    if args.seeds is not None:
        from tactilab.experiments.modelling import power_sweep

        sweep = power_sweep(true_model, params, rival, design, ns, n_seeds=args.seeds, seed=args.seed,
                            out_dir=args.out / "power-batch", task=args.task, n_repeats=args.repeats,
                            progress=not args.json, echo=(lambda _: None) if args.json else print,
                            **batch_where(args))
    need = {z: result.trials_for(z) for z in (2.0, 4.0)}
    if args.json:
        summary = dict(command="experiment power", true=args.true_model, rival=args.rival, threshold_strain=threshold,
                       exponent=args.exponent, lapse=args.lapse, rival_params=result.rival_params,
                       mu_nats_per_trial=result.mu, sigma_nats_per_trial=result.sigma,
                       trials_for_z2=need[2.0] if math.isfinite(need[2.0]) else None,
                       trials_for_z4=need[4.0] if math.isfinite(need[4.0]) else None,
                       design_trials=n_design, p_select_design=result.p_select(n_design), png=str(path))
        if sweep is not None:
            summary["simulated"] = dict(
                n_trials=[int(n) for n in sweep["n_trials"].values], repeats=args.repeats, seeds=args.seeds,
                p_select=[[None if np.isnan(v) else float(v) for v in row] for row in sweep["p_select"].values],
                p_select_mean=[None if np.isnan(v) else float(v) for v in sweep["p_select_mean"].values],
                p_asymptotic=[float(v) for v in sweep["p_asymptotic"].values], n_run=sweep.attrs["n_run"],
                n_skipped=sweep.attrs["n_skipped"], n_failed=sweep.attrs["n_failed"], out=str(args.out / "power-batch"))
        print(json.dumps(summary))
        return 1 if sweep is not None and sweep.attrs["n_failed"] else 0
    print(f"true {args.true_model} at threshold strain {threshold:.3g}, exponent {args.exponent:g}, "
          f"lapse {args.lapse:g}; rival {args.rival}")
    print("rival's pseudo-true parameters: " + ", ".join(f"{k} {v:.4g}" for k, v in result.rival_params.items()))
    print(f"mu {result.mu:.4g} nats/trial, sigma {result.sigma:.4g} nats/trial")
    for z in (2.0, 4.0):
        print(f"trials for z = {z:g}: " + (f"{math.ceil(need[z])}" if math.isfinite(need[z]) else
                                           "never (identical predictions on this design)"))
    print(f"P(z > 4) with the design's {n_design} trials: {result.p_select(n_design):.3f}")
    if sweep is not None:
        print(f"simulated P(z > 4) ({args.seeds} estimate(s) of {args.repeats} simulated experiments each):")
        print(f"{'trials':>8s} {'mean':>7s} {'min':>7s} {'max':>7s} {'asymptotic':>10s}")
        for j, n in enumerate(sweep["n_trials"].values):
            col = sweep["p_select"].values[:, j]
            print(f"{int(n):8d} {sweep['p_select_mean'].values[j]:7.3f} {np.nanmin(col) if np.isfinite(col).any() else np.nan:7.3f} "
                  f"{np.nanmax(col) if np.isfinite(col).any() else np.nan:7.3f} {sweep['p_asymptotic'].values[j]:10.3f}")
        a = sweep.attrs
        print(f"batch: {a['n_run']} point(s) run, {a['n_skipped']} skipped (done before), {a['n_failed']} failed; "
              f"files in {args.out / 'power-batch'}")
    print(f"wrote {path}")
    return 1 if sweep is not None and sweep.attrs["n_failed"] else 0

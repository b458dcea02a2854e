"""Session analysis helpers behind ``tactilab experiment fit | compare | power``.

- :func:`fit_conditions`: one psychometric fit per condition (the test stimulus with the varied
  parameter left out), levels in display units (um, mm, mm/s, ms); :func:`fit_summary`: one line
  per condition with the threshold and its 95 % interval (for run summaries and status);
- :func:`compare_sessions`: fit transduction models to sessions and compare them;
- :func:`read_design`: a power-analysis design file (TOML, quantities with units);
- :func:`plot_comparison`, :func:`plot_power`: figures (matplotlib Figure API).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tactilab.data_schemas.experiment import Stimulus

from ..session import DISPLAY_UNITS
from .psychometric import PsychometricFit, fit_psychometric, sigmoid_core

#: varied parameters that cannot be <= 0 (data_schemas Stimulus): fitted on log levels
POSITIVE = ("amplitude_m", "pitch_m", "duration_s")

_LABEL_FIELDS = {"pitch_m": ("pitch", 1e3, "mm"), "speed_m_per_s": ("speed", 1e3, "mm/s"),
                 "amplitude_m": ("amplitude", 1e6, "um"), "duration_s": ("duration", 1e3, "ms")}


@dataclass
class ConditionFit:
    """A psychometric fit of one condition: ``fit`` is in ``unit`` (= SI x ``scale``)."""

    label: str
    parameter: str
    unit: str
    scale: float
    n_trials: int
    fit: PsychometricFit
    levels: tuple[float, ...] = ()  #: distinct levels tested, in ``unit``


def _session_rows(paths):
    from ..session import SessionLog

    kinds, rows = set(), []
    for path in ([paths] if isinstance(paths, (str, Path)) else paths):
        if not Path(path).is_file():
            raise ValueError(f"session: no session file at {str(path)!r}")
        log = SessionLog(path)
        try:
            kinds.add(log.meta()["protocol"]["task"]["kind"])
            rows += log.trials()
        finally:
            log.close()
    if len(kinds) > 1:
        raise ValueError(f"session: mixed tasks {sorted(kinds)}; analyse sessions of one task together")
    return rows, kinds.pop() if kinds else None


def _test_stimulus(trial, kind):
    if kind == "2ifc" and trial.target in ("1", "2"):
        return trial.stimuli[int(trial.target) - 1]
    return trial.stimuli[-1]


def sigmoid_for(parameter: str, sigmoid: str = "auto") -> str:
    """The sigmoid a condition varying ``parameter`` is fitted with: ``auto`` gives ``weibull`` (log
    levels, as psignifit users fit positive quantities) for a positive quantity (:data:`POSITIVE`)
    and ``norm`` for a signed one (a speed); a linear-level sigmoid on a positive quantity is
    refused, since its interval can reach impossible values below 0."""
    if sigmoid == "auto":
        return "weibull" if parameter in POSITIVE else "norm"
    if parameter in POSITIVE and not sigmoid_core(sigmoid).log_levels:
        raise ValueError(f"sigmoid: {sigmoid!r} fits {parameter} on linear levels, where its interval can reach "
                         "below 0 (impossible for a positive quantity); use 'auto' or 'weibull' (log levels) or "
                         "'lognorm'")
    return sigmoid


def fit_conditions(paths, *, sigmoid: str = "auto", rng=None) -> list[ConditionFit]:
    """One :func:`fit_psychometric` per condition of the sessions (2IFC/2AFC: proportion correct;
    yes/no: proportion "yes" on signal trials).

    ``sigmoid="auto"`` (default): ``weibull`` on log levels for a positive quantity (amplitude,
    pitch, duration), ``norm`` for a signed one (speed); see :func:`sigmoid_for`.

    Raises
    ------
    ValueError
        For a missing file, mixed tasks, a task without correct answers, a condition with
        fewer than two levels, or a linear-level sigmoid on a positive quantity.
    """
    rows, kind = _session_rows(paths)
    if kind not in ("2ifc", "2afc", "yes_no"):
        raise ValueError(f"session: psychometric fits need a 2ifc, 2afc or yes_no task, got {kind!r}")
    groups: dict[tuple, list] = {}
    for t in rows:
        if t.correct is None or (kind == "yes_no" and t.target != "yes"):
            continue
        stim = _test_stimulus(t, kind)
        key = (t.parameter, stim.surface) + tuple((f, getattr(stim, f)) for f in _LABEL_FIELDS if f != t.parameter)
        groups.setdefault(key, []).append((t.level, bool(t.correct)))
    if not groups:
        raise ValueError("session: no scored trials to fit")
    out = []
    gen = np.random.default_rng(rng)
    for key, items in groups.items():
        parameter, surface, rest = key[0], key[1], key[2:]
        name, scale, unit = DISPLAY_UNITS.get(parameter, (parameter, 1.0, "SI"))
        label = ", ".join([surface] + [f"{_LABEL_FIELDS[f][0]} {v * _LABEL_FIELDS[f][1]:.4g} {_LABEL_FIELDS[f][2]}"
                                       for f, v in rest])
        levels = np.array([lv for lv, _ in items]) * scale
        correct = np.array([c for _, c in items], dtype=float)
        if np.unique(levels).size < 2:
            raise ValueError(f"session: condition '{label}' has trials at one {name} only; a fit needs >= 2 levels")
        fit = fit_psychometric(levels, correct, experiment="yes_no" if kind == "yes_no" else "2afc",
                               sigmoid=sigmoid_for(parameter, sigmoid), rng=gen)
        out.append(ConditionFit(label, parameter, unit, scale, len(items), fit,
                                tuple(float(v) for v in np.unique(levels))))
    return out


def fit_summary(paths, *, sigmoid: str = "auto", rng=0) -> list[str]:
    """One line per condition for a run summary or ``experiment status``: the fitted threshold and
    its 95 % interval in display units, e.g. ``amplitude threshold 0.295 um (95 % interval 0.159 to
    0.424 um; psychometric fit of 100 trials; sinusoid, pitch 2 mm, ...)``.
    """
    lines = []
    for c in fit_conditions(paths, sigmoid=sigmoid, rng=rng):
        th = c.fit.params["threshold"]
        name = DISPLAY_UNITS.get(c.parameter, (c.parameter,))[0]
        lines.append(f"{name} threshold {th.map:.3g} {c.unit} (95 % interval {th.ci95[0]:.3g} to {th.ci95[1]:.3g} "
                     f"{c.unit}; psychometric fit of {c.n_trials} trials; {c.label})")
    return lines


def condition_table(paths, *, sigmoid: str = "auto", rng=0) -> list[dict]:
    """Per condition, SI values for ``experiment status --json``: keys carry the varied
    parameter's SI unit (``threshold_m``, ``threshold_ci95_m``, ``levels_m`` for an amplitude;
    ``_m_per_s`` for a speed, ``_s`` for a duration).

    Raises
    ------
    ValueError
        As :func:`fit_conditions` (no scored trials, one level only, a task without fits).
    """
    rows = []
    for c in fit_conditions(paths, sigmoid=sigmoid, rng=rng):
        unit = c.parameter.split("_", 1)[1] if "_" in c.parameter else "si"
        th = c.fit.params["threshold"]
        rows.append({"condition": c.label, "parameter": c.parameter, "n_trials": c.n_trials,
                     f"levels_{unit}": [v / c.scale for v in c.levels],
                     f"threshold_{unit}": th.map / c.scale,
                     f"threshold_ci95_{unit}": [th.ci95[0] / c.scale, th.ci95[1] / c.scale]})
    return rows


def compare_sessions(paths, hypotheses, *, statistic: str = "peak", rng=None, method: str = "grid",
                     n_ensembles: int = 4, sampler_options=None, source: str = "surface", display=None):
    """Fit one TransductionModel per hypothesis string to the sessions; returns (table, fits).

    ``method="grid"`` (default): quadrature, the same table for every ``rng``; ``"emcee"``:
    the samplers (``rng``, ``n_ensembles``, ``sampler_options``). ``source="display"`` with a
    ``display`` (a SimulatedDisplay of the sessions' display description) fits the strain the
    display renders instead of the ideal surface's. The table is
    :func:`~.comparison.compare_models`' (verdicts only where the design can tell models apart).
    """
    from .comparison import compare_models
    from .models import TransductionModel, fit_transduction

    if len(hypotheses) < 2:
        raise ValueError("model: give at least two hypotheses to compare, e.g. --model zx@1mm --model xx@1mm")
    if len(set(hypotheses)) != len(hypotheses):
        raise ValueError(f"model: each hypothesis once, got {list(hypotheses)}")
    if method != "emcee" and sampler_options:
        raise ValueError(f"sampler_options: only for method='emcee', got {dict(sampler_options)}; drop them or pass "
                         "method='emcee'")
    gen = np.random.default_rng(rng)
    models = {h: TransductionModel(h, statistic=statistic, source=source, display=display) for h in hypotheses}
    options = dict(rng=gen, n_ensembles=n_ensembles, sampler_options=sampler_options) if method == "emcee" else {}
    fits = {h: fit_transduction(m, list(paths), method=method, **options) for h, m in models.items()}
    return compare_models(fits), fits


def read_design(path) -> list[tuple[Stimulus, int]]:
    """Read a design file: TOML with ``[[trials]]`` tables of Stimulus fields (units allowed,
    e.g. ``amplitude_m = "1um"``) and ``n`` (trials at that stimulus)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"design: no design file at {str(path)!r}")
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"design: {path} is not valid TOML ({exc})") from None
    items = data.get("trials")
    if not isinstance(items, list) or not items:
        raise ValueError(f"design: {path} needs [[trials]] tables with Stimulus fields and n, e.g. "
                         "amplitude_m = \"1um\", pitch_m = \"2mm\", speed_m_per_s = \"20mm/s\", n = 40")
    out = []
    for i, item in enumerate(items):
        item = dict(item)
        n = item.pop("n", None)
        if not isinstance(n, int) or n < 1:
            raise ValueError(f"design: trials[{i}] needs n = a whole number of trials >= 1, got {n!r}")
        out.append((Stimulus.model_validate(item), n))
    return out


def plot_comparison(table, fits, path) -> None:
    """ELPD per model (+- se, with elpd_diff +- dse), and observed vs predicted P(correct) per condition."""
    from matplotlib.figure import Figure

    from ._transduction_data import p_correct_table

    fig = Figure(figsize=(10, 4.8), layout="constrained")
    ax, bx = fig.subplots(1, 2)
    names = list(table.index)
    ax.errorbar(range(len(names)), table["elpd"], yerr=table["se"], fmt="o", capsize=4)
    ax.set_xticks(range(len(names)), [f"{n}\n" + str(v).replace(": ", ":\n").replace(" on this", "\non this")
                                      for n, v in zip(names, table["verdict"])], fontsize=7)
    for i, (_, row) in enumerate(table.iterrows()):
        if i:
            # above the error bar and centred on it, so that the last model's label stays in the axes
            ax.annotate(f"diff {row['elpd_diff']:.1f} +- {row['dse']:.1f}\n(z {row['z']:.2f}; "
                        f"separation {row['separation']:.2g})", (i, row["elpd"] + row["se"]),
                        textcoords="offset points", xytext=(0, 4), ha="center", va="bottom", fontsize=7)
    ax.set_xlim(-0.5, len(names) - 0.5)
    ax.margins(y=0.2)
    ax.set_ylabel("ELPD (PSIS-LOO, +- se), nats")
    ax.set_title("model comparison (higher is better)", fontsize=9)
    for i, name in enumerate(names):
        fit = fits[name]
        data = fit.conditions
        theta = np.column_stack([fit.tree["posterior"][p].values.ravel() for p in fit.params])
        pred = p_correct_table(data["kind"], data["s1"], data["s2"], theta[:: max(1, len(theta) // 400)]).mean(0)
        order = np.argsort(data["s1"])
        bx.plot(data["s1"][order], (data["k"] / data["n"])[order], "o", color=f"C{i}", alpha=0.5, ms=5,
                label=f"observed, on {name}'s axis")
        bx.plot(data["s1"][order], pred[order], "-", color=f"C{i}", label=f"{name} (posterior mean)")
    bx.set_xscale("log")
    bx.set_xlabel("test-interval statistic under each model (strain)")
    bx.set_ylabel("proportion correct")
    # below the panel: a legend inside would hide the points at the low end of the curves
    bx.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncols=2)
    fig.savefig(path, dpi=110)


def plot_power(result, path, n_max: int) -> None:
    """P(the truth wins by z > 2 and z > 4) against the number of trials."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.5, 4), layout="constrained")
    ax = fig.add_subplot()
    n = np.unique(np.geomspace(10, max(n_max, 20), 60).astype(int))
    for z in (2.0, 4.0):
        ax.plot(n, [result.p_select(int(v), z=z) for v in n], label=f"z > {z:g}")
    ax.set_xscale("log")
    ax.set_xlabel("trials")
    ax.set_ylabel("P(true model selected)")
    ax.set_ylim(-0.02, 1.02)
    need = result.trials_for(4.0)
    ax.set_title(f"mu = {result.mu:.3g} nats/trial, sigma = {result.sigma:.3g}; "
                 f"z = 4 needs {need:.0f} trials" if math.isfinite(need) else "identical predictions: no power",
                 fontsize=9)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)

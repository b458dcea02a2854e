"""What happened in a session, for people and for scripts: ``experiment status`` and run summaries.

:func:`session_summary` reads a session file (never writes it) and returns one JSON-ready dict in
SI units, each key carrying its unit (``rt_median_s``, ``threshold_m``): progress, status in plain
words, safety interventions by kind, late / skipped / missing frames with their rates, display
faults, repeated trials and why, per condition the levels and the fitted threshold with its 95 %
interval (:func:`.analysis.condition_table`), the display description's hash and the warnings a
person should read. :func:`summary_lines` renders it as a table in mm, µm, ms and counts.
"""

from __future__ import annotations

import statistics
from collections import Counter
from datetime import datetime
from pathlib import Path
from typing import Any

from ..session import SessionLog

#: a frame rate above this fraction (late, skipped or missing) is reported as a warning
FRAME_WARN_FRACTION = 0.01
_DISPLAY = {"m": (1e3, "mm"), "m_per_s": (1e3, "mm/s"), "s": (1e3, "ms")}


def _status_words(info: dict[str, Any], events: list[dict[str, Any]]) -> str:
    """``complete``, ``running (...)``, ``interrupted (...)`` or ``failed (...)``, with the reason."""
    status = info["status"]
    if status == "complete":
        return f"complete: all {info['completed']} planned trials done" if info["completed"] == info["planned"] \
            else f"complete: the procedure finished after {info['completed']} trials"
    if status == "running":
        owner = info.get("owner") or {}
        return (f"running: pid {owner.get('pid', '?')} on {owner.get('host', '?')}, last heartbeat "
                f"{owner.get('heartbeat_utc', '?')}")
    last = next((e for e in reversed(events) if e["kind"] in ("session_stopped", "session_failed",
                                                              "display_fault", "session_started",
                                                              "session_resumed")), None)
    reason = (last or {}).get("payload", {}).get("reason")
    fault = next((e for e in reversed(events) if e["kind"] in ("display_fault", "session_started", "session_resumed")),
                 None)
    if status == "failed" and fault is not None and fault["kind"] == "display_fault":
        return (f"failed: a display fault in trial {fault['trial_index']} ({fault['payload'].get('reason')}); "
                "resume repeats the trial")
    if status == "failed":
        return f"failed: {reason or 'an unexpected error'}; resume to go on"
    if last is not None and last["kind"] == "session_stopped":
        why = f"stopped cleanly ({reason})"
    elif last is not None and last["kind"] == "display_fault":
        why = f"stopped by a display fault in trial {last['trial_index']} ({reason})"
    else:
        why = "killed or crashed (no stop was recorded)"
    return f"interrupted: {why}; resume to go on"


def _repeats(events: list[dict[str, Any]], trials) -> list[dict[str, Any]]:
    """Trials run more than once, with why the earlier attempt did not count."""
    why, current = {}, None
    for e in events:
        if e["kind"] == "trial_planned":
            current = (e["trial_index"], e["attempt"])
        elif e["kind"] == "trial_complete":
            current = None
        elif e["kind"] == "display_fault":
            why[(e["trial_index"], e["attempt"])] = f"display fault: {e['payload'].get('reason', '?')}"
        elif e["kind"] in ("session_stopped", "session_failed") and current is not None:
            why.setdefault(current, f"{e['kind'].removeprefix('session_')}: {e['payload'].get('reason', '?')}")
            current = None
        elif e["kind"] in ("session_started", "session_resumed") and current is not None:
            why.setdefault(current, "the run was killed during it (no stop was recorded)")
            current = None
    out = []
    for t in trials:
        if t.attempt:
            reasons = [why.get((t.trial_index, a), "interrupted") for a in range(t.attempt)]
            out.append({"trial_index": t.trial_index, "attempts": t.attempt + 1, "felt_before": t.repeated,
                        "why": "; ".join(reasons)})
    return out


def session_summary(path: str | Path, *, rng: int = 0) -> dict[str, Any]:
    """Everything a person should know about a session, JSON-ready, SI units (unit in each key).

    Parameters
    ----------
    path : path
        The session's .sqlite file (read only; safe while a runner writes).
    rng : int
        Seed of the psychometric fits' bootstrap (the same seed gives the same intervals).

    Raises
    ------
    ValueError, FileNotFoundError
        For a missing, foreign or damaged session file (one line naming it).
    """
    from .analysis import condition_table
    from ..session import session_status

    info = session_status(path)
    log = SessionLog(path)
    try:
        events, trials, meta = log.events(), log.trials(), log.meta()
    finally:
        log.close()
    safety = [e["payload"] for e in events if e["kind"] == "safety_intervention"]
    by_kind = dict(sorted(Counter(str(p.get("kind", "unknown")) for p in safety).items()))
    frames_by_kind = {k: sum(int(p.get("n_frames") or 0) for p in safety if str(p.get("kind", "unknown")) == k)
                      for k in by_kind}
    # frames the display played: every scored trial's, and every attempt a display fault aborted (its
    # frames reached the skin too; older files logged only the faulted interval's count)
    aborted = sum(int(e["payload"].get("frames_sent_trial", e["payload"].get("frames_sent")) or 0)
                  for e in events if e["kind"] == "display_fault")
    scored = sum(t.frames_sent for t in trials)
    frames = {"frames_sent": scored + aborted, "frames_sent_aborted": aborted}
    for what in ("late", "skipped", "missing"):  # counted per scored trial: fractions of the scored trials' frames
        n = sum(getattr(t, f"frames_{what}") for t in trials)
        frames[f"frames_{what}"] = n
        frames[f"frames_{what}_fraction"] = n / scored if scored else 0.0
    faults = [{"trial_index": e["trial_index"], "attempt": e["attempt"], "reason": e["payload"].get("reason")}
              for e in events if e["kind"] == "display_fault"]
    rts = [t.rt_s for t in trials]
    stamps = [datetime.fromisoformat(e["utc"]) for e in events]
    try:
        conditions, fit_note = condition_table([path], rng=rng), None
    except ValueError as exc:
        conditions, fit_note = [], " ".join(str(exc).split())
    summary = {
        "path": str(path), "subject": info["subject"], "session": info["session"], "task": info["task"],
        "method": info["method"], "parameter": info["parameter"],
        "status": info["status"], "status_text": _status_words(info, events),
        "trials_completed": info["completed"], "trials_planned": info["planned"],
        "interrupted_trial": info["interrupted_trial"],
        "repeated_trials": _repeats(events, trials), "display_faults": faults,
        "safety_interventions": len(safety), "safety_interventions_by_kind": by_kind,
        "safety_limited_frames_by_kind": frames_by_kind,
        **frames,
        "rt_median_s": statistics.median(rts) if rts else None,
        "rt_min_s": min(rts) if rts else None, "rt_max_s": max(rts) if rts else None,
        "created_utc": meta.get("created_utc"),
        "elapsed_s": (max(stamps) - min(stamps)).total_seconds() if stamps else 0.0,
        "procedure_estimate_si": info["estimate"], "conditions": conditions, "fit_note": fit_note,
        "display_id": info["display_id"], "display_sha256": info["display_sha256"],
        "seed": info["seed"], "package_version": info["package_version"],
    }
    summary["warnings"] = _warnings(summary)
    return summary


def _warnings(s: dict[str, Any]) -> list[str]:
    out = []
    if s["safety_interventions"]:
        kinds = ", ".join(f"{k} {n}" for k, n in s["safety_interventions_by_kind"].items())
        out.append(f"{s['safety_interventions']} safety interventions ({kinds}): the display did not play "
                   "every stimulus as commanded")
    for what in ("late", "skipped", "missing"):
        if s[f"frames_{what}_fraction"] > FRAME_WARN_FRACTION:
            out.append(f"{s[f'frames_{what}']} of {s['frames_sent'] - s['frames_sent_aborted']} frames {what} "
                       f"({100 * s[f'frames_{what}_fraction']:.1f} %, above {100 * FRAME_WARN_FRACTION:g} %)")
    for f in s["display_faults"]:
        out.append(f"display fault in trial {f['trial_index']}: {f['reason']}")
    return out


def _show(value: float, unit: str) -> str:
    scale, shown = _DISPLAY.get(unit, (1.0, unit))
    if unit == "m" and abs(value) < 1e-4:
        scale, shown = 1e6, "µm"
    return f"{value * scale:.3g} {shown}"


def _progress(done: int, planned: int) -> str:
    if done <= planned:
        return f"{done} of {planned} planned trials ({100 * done / planned if planned else 100:.0f} %)"
    return f"{done} trials: {planned} planned by the procedure and {done - planned} on top (catch trials)"


def summary_lines(s: dict[str, Any]) -> list[str]:
    """The summary as an aligned two-column table for people (mm, µm, ms, counts, percentages)."""
    rows = [("session", s["path"]),
            ("subject / session / task", f"sub-{s['subject']} / ses-{s['session']} / {s['task']} "
                                         f"({s['method']} on {s['parameter']})"),
            ("status", s["status_text"]),
            ("progress", _progress(s["trials_completed"], s["trials_planned"]))]
    if s["repeated_trials"]:
        rows.append(("repeated trials", "; ".join(f"trial {r['trial_index']} x{r['attempts']} ({r['why']})"
                                                  for r in s["repeated_trials"])))
    else:
        rows.append(("repeated trials", "none"))
    kinds = ", ".join(f"{k} {n} ({s['safety_limited_frames_by_kind'][k]} frames)"
                      for k, n in s["safety_interventions_by_kind"].items())
    rows.append(("safety interventions", f"{s['safety_interventions']}" + (f": {kinds}" if kinds else "")))
    aborted = f" ({s['frames_sent_aborted']} in trials a display fault aborted)" if s.get("frames_sent_aborted") else ""
    rows.append(("frames", f"{s['frames_sent']} sent{aborted}; " + ", ".join(
        f"{s[f'frames_{w}']} {w} ({100 * s[f'frames_{w}_fraction']:.2g} %)" for w in ("late", "skipped", "missing"))))
    rows.append(("display faults", str(len(s["display_faults"]))))
    if s["rt_median_s"] is not None:
        rows.append(("response time", f"median {s['rt_median_s'] * 1e3:.0f} ms (range {s['rt_min_s'] * 1e3:.0f} "
                                      f"to {s['rt_max_s'] * 1e3:.0f} ms)"))
    rows.append(("elapsed", f"{s['elapsed_s'] * 1e3:.0f} ms from the first to the last event (created "
                            f"{s['created_utc']})"))
    from ..session import format_estimate

    try:
        running = format_estimate(s["procedure_estimate_si"], s["parameter"]).replace(" um", " µm")
    except (KeyError, TypeError, ValueError):
        running = "n/a"
    if not s["conditions"]:  # the procedure's running value is a rough start value, never shown beside a fit
        rows.append(("procedure's start value", f"{running} (rough: the procedure's running value, not a fit)"))
    for i, c in enumerate(s["conditions"], 1):
        unit = c["parameter"].split("_", 1)[1]
        lo, hi = c[f"threshold_ci95_{unit}"]
        levels = c[f"levels_{unit}"]
        rows.append((f"condition {i}", c["condition"]))
        rows.append(("  fitted threshold",
                     f"{_show(c[f'threshold_{unit}'], unit)} (95 % interval {_show(lo, unit)} to "
                     f"{_show(hi, unit)}; psychometric fit)"))
        rows.append(("  trials", f"{c['n_trials']} trials at {len(levels)} levels from "
                     f"{_show(min(levels), unit)} to {_show(max(levels), unit)}"))
    if s["fit_note"]:
        rows.append(("fitted threshold", f"none yet ({s['fit_note']})"))
    rows.append(("display", f"{s['display_id']}, description SHA-256 {s['display_sha256'] or 'not recorded'}"))
    rows.append(("warnings", str(len(s["warnings"])) if s["warnings"] else "none"))
    width = max(len(k) for k, _ in rows)
    return [f"{k:<{width}}  {v}" for k, v in rows] + [f"  - {w}" for w in s["warnings"]]

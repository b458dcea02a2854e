"""Demo section: from recorded responses to "which strain does touch read?".

Two simulated 2IFC sessions (constant stimuli over amplitude, gratings of 2 mm and 8 mm pitch)
answered by an observer that reads the peak tensor shear strain eps_zx at 1 mm depth; then a
psychometric fit per condition (weibull on log amplitude, psignifit-4 priors, 95 % intervals) and a PSIS-LOO comparison
of that hypothesis with a rival that reads eps_zx at 3 mm, with the power the design had.
"""

from __future__ import annotations

import pathlib
from typing import Iterator

from tactilab.data_schemas import DisplayDescription, Protocol
from tactilab.experiments import (SimulatedDisplay, SimulatedObserver, TransductionModel, compare_sessions,
                                  fit_conditions, new_session, plot_comparison, power_analysis)

TRUTH, RIVAL = "zx@1mm", "zx@3mm"
THRESHOLD_STRAIN, LAPSE = 1e-4, 0.02
AMPLITUDES_UM = (0.15, 0.3, 0.6, 1.2, 2.4)


def _protocol(pitch_mm: float, seed: int) -> Protocol:
    return Protocol.model_validate(dict(
        name=f"pitch{pitch_mm:g}mm", seed=seed, task=dict(kind="2ifc"),
        stimulus=dict(amplitude_m="1um", pitch_m=f"{pitch_mm:g}mm", speed_m_per_s="20mm/s", duration_s="50ms"),
        procedure=dict(method="constant_stimuli", parameter="amplitude_m",
                       levels=[f"{a}um" for a in AMPLITUDES_UM], repeats_per_block=4, n_blocks=5)))


def run_demo(report_dir: pathlib.Path, progress: bool = True) -> Iterator[str]:
    """Simulate, fit and compare into ``report_dir/analysis``; yield lines to print."""
    out = pathlib.Path(report_dir) / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    truth = TransductionModel(TRUTH)
    yield (f"analysis: an observer reading the peak tensor shear strain {TRUTH} (threshold strain "
           f"{THRESHOLD_STRAIN:g} at d' = 1, lapse {LAPSE:g}) does 2IFC detection of 2 mm and 8 mm gratings")
    paths = []
    for seed, pitch in enumerate((2.0, 8.0), start=1):
        protocol = _protocol(pitch, seed)
        path = out / f"sub-DEMO_ses-0{seed}_task-{protocol.name}.sqlite"
        for stale in (path, path.with_name(path.name + ".lock")):
            stale.unlink(missing_ok=True)
        observer = SimulatedObserver.from_model(protocol, truth, THRESHOLD_STRAIN, lapse=LAPSE, seed=seed)
        new_session(protocol, path, SimulatedDisplay(DisplayDescription.braille_row(), realtime=False), observer,
                    subject="DEMO", session=f"0{seed}", realtime=False, progress=progress)
        paths.append(path)
    for i, c in enumerate(fit_conditions(paths, sigmoid="weibull", rng=0)):
        th = c.fit.params["threshold"]
        png = out / f"fit_{i + 1:02d}.png"
        c.fit.plot(png, xlabel="amplitude (µm)", title=c.label)
        yield (f"analysis: {c.label}: amplitude threshold {th.map:.3g} µm, 95 % interval "
               f"[{th.ci95[0]:.3g}, {th.ci95[1]:.3g}] µm ({c.n_trials} trials; plot {png})")
    table, fits = compare_sessions(paths, [TRUTH, RIVAL], rng=0)
    png = out / "compare.png"
    plot_comparison(table, fits, png)
    for name, row in table.iterrows():
        yield (f"analysis: {name:8s} elpd {row['elpd']:8.2f}  elpd_diff {row['elpd_diff']:6.2f} +- "
               f"{row['dse']:.2f}  z {row['z']:.2f}  -> {row['verdict']} (converged: {fits[name].converged})")
    design = [(s, 1) for s in {t.stimuli[0] if t.target == "1" else t.stimuli[1]: None
                               for t in _trials(paths)}]
    power = power_analysis(truth, dict(threshold_strain=THRESHOLD_STRAIN, exponent=1.0, lapse=LAPSE),
                           TransductionModel(RIVAL), design)
    yield (f"analysis: the design's power: {power.mu:.3f} nats/trial on average; z = 4 needs about "
           f"{power.trials_for(4.0):.0f} trials, these sessions have {sum(1 for _ in _trials(paths))} "
           f"(comparison plot {png})")


def _trials(paths):
    from tactilab.experiments import SessionLog

    for path in paths:
        log = SessionLog(path)
        try:
            yield from log.trials()
        finally:
            log.close()

"""The simulated observer's options of ``tactilab experiment run | resume`` (parse, build).

Without ``--observer`` the observer reads today's default (the RMS deviatoric strain norm at
1 mm depth, ``deviatoric_norm@1mm`` with the ``rms`` statistic). With ``--observer HYPOTHESIS``
it reads that receptor hypothesis through a TransductionModel, its threshold in the readout
units of the hypothesis and statistic (the unit of ``power --threshold``). Whenever the display
is simulated the observer feels what the display renders (``--observer-strain display``, clipping
included) unless told ``surface``; on resume, the session's recorded observer is rebuilt.
"""

from __future__ import annotations

import argparse

_THRESHOLD_HELP = ("simulated observer: the readout felt at d' = 1, in the readout units of the observer's "
                   "hypothesis and statistic (tensor strain, dimensionless, as TransductionModel computes it: the "
                   "unit of `power --threshold` and SimulatedObserver.from_model); without --observer the RMS "
                   "deviatoric strain norm at 1 mm depth, default 2e-3; with --observer required; on resume "
                   "default the session's own observer")


def add_observer_args(p: argparse.ArgumentParser) -> None:
    """``--observer``, ``--observer-statistic``, ``--observer-threshold``, ``--observer-strain``."""
    p.add_argument("--observer", default=None, metavar="HYPOTHESIS",
                   help="simulated observer reads this receptor hypothesis, e.g. zx@2mm or xx,zx@1mm (depths with "
                        "units); default deviatoric_norm@1mm read as rms (or on resume the session's own)")
    p.add_argument("--observer-statistic", default=None, choices=("peak", "rms"),
                   help="with --observer: 'peak' (largest |readout|, default) or 'rms' of the readout")
    p.add_argument("--observer-threshold", default=None, help=_THRESHOLD_HELP)
    p.add_argument("--observer-strain", default=None,
                   help="simulated observer feels 'surface' (the ideal virtual surface's strain), 'display' (what "
                        "the simulated display renders after the safety limits, clipping included) or, with "
                        "--observer, 'contact' (a physical grating pressed by the protocol's [finger], through the "
                        "solved contact); default display whenever the display is simulated, else surface; on "
                        "resume the session's own")


def _simulated(display) -> bool:
    return callable(getattr(display, "steady_drive", None))


def observer_responses(kind: str, protocol, display, args: argparse.Namespace, recorded: dict | None = None):
    """The response source of a run or resume from the observer options (and the recorded observer)."""
    from tactilab.experiments.session import make_responses

    recorded = dict(recorded or {})
    if kind != "simulated":
        for flag, value in (("--observer", args.observer), ("--observer-statistic", args.observer_statistic)):
            if value is not None:
                raise ValueError(f"{flag}: only with --responses simulated, got --responses {kind}")
        return make_responses(kind, protocol, display)
    strain = args.observer_strain
    if strain is None and not recorded:
        strain = "display" if _simulated(display) else "surface"
    hypothesis = args.observer if args.observer is not None else recorded.get("hypothesis")
    if hypothesis is None:
        if args.observer_statistic is not None:
            raise ValueError(f"--observer-statistic: needs --observer (a hypothesis to read), got "
                             f"--observer-statistic {args.observer_statistic} alone; e.g. --observer zx@2mm")
        return make_responses(kind, protocol, display, threshold=args.observer_threshold, strain=strain,
                              recorded=recorded or None)
    return _hypothesis_observer(protocol, display, args, recorded, hypothesis, strain)


def _hypothesis_observer(protocol, display, args, recorded, hypothesis, strain):
    from tactilab.data_schemas.units import to_si
    from tactilab.experiments.modelling import hypothesis_observer

    from .common import check_hypothesis

    check_hypothesis(hypothesis, "--observer")
    source = strain if strain is not None else recorded.get("strain", "surface")
    if source not in ("surface", "display", "contact"):
        raise ValueError(f"--observer-strain: must be 'surface', 'display' or 'contact', got {source!r}")
    if source == "display" and not _simulated(display):
        raise ValueError("--observer-strain: 'display' needs a simulated display (--display sim); use surface")
    if args.observer_threshold is not None:
        threshold = to_si(args.observer_threshold, "dimensionless", name="--observer-threshold")
    elif "threshold_strain" in recorded and args.observer is None:
        threshold = recorded["threshold_strain"]
    else:
        raise ValueError(f"--observer-threshold: give the readout of {hypothesis} felt at d' = 1 (tensor strain, "
                         "dimensionless, the unit of `power --threshold`), e.g. --observer-threshold 1.4e-3")
    if not threshold > 0:
        raise ValueError(f"--observer-threshold: must be a strain > 0, got {args.observer_threshold!r}; e.g. 1.4e-3")
    statistic = args.observer_statistic or recorded.get("statistic", "peak")
    try:
        return hypothesis_observer(protocol, hypothesis, threshold_strain=threshold, statistic=statistic,
                                   source=source, display=display if source == "display" else None,
                                   seed=recorded.get("seed"), exponent=recorded.get("exponent", 1.0),
                                   lapse=recorded.get("lapse", 0.0))
    except ValueError as exc:
        if str(exc).startswith("source:"):
            raise ValueError("--observer-strain" + str(exc)[len("source"):]) from None
        raise

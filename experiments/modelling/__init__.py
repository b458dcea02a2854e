"""tactilab.experiments.modelling: models of the observer, fitted to recorded sessions.

Psychometric-function fits as psignifit 4 does them (:mod:`.psychometric`), transduction models
(which strain does touch read?) fitted by quadrature or emcee (:mod:`.models`) and compared by
PSIS-LOO (:mod:`.comparison`) where the design can tell them apart (:mod:`.identifiability`), power to tell
two models apart (:mod:`.model_power`), the adaptive design that tells them apart trial by trial
(:mod:`.design`, registered as the ``model_discrimination`` procedure), per-condition fits and
model comparisons of session files (:mod:`.analysis`), the session summary with its fits
(:mod:`.session_report`) and the batch jobs over subjects, seeds and designs (:mod:`.batch`).

Door rule: this package is the room's one door. Code outside the room imports it from here,
never from the modules inside. This room sits on top: it reads sessions (``session``) and builds
on the procedure template (``procedures``), through their doors, and no room imports it. It
imports nothing from ``devices``: a transduction model of a display's strain asks the
:class:`~tactilab.experiments.devices.SimulatedDisplay` it is given (``steady_drive``,
``strain``). The rooms import one way: ``devices`` and ``procedures`` <- ``session`` <-
``modelling`` (tests/test_experiments_rooms.py enforces both rules).
"""

from tactilab.core import attach

#: public name -> module of this room that defines it (loaded on first use)
_EXPORTS = {
    "ParamSummary": "psychometric",
    "PsychometricFit": "psychometric",
    "SIGMOIDS": "psychometric",
    "fit_psychometric": "psychometric",
    "sigmoid_core": "psychometric",
    "TransductionFit": "models",
    "TransductionModel": "models",
    "FingerContact": "contact_stimulus",
    "compare_models": "comparison",
    "elpd_mcse": "comparison",
    "VERDICTS": "comparison",
    "Separation": "identifiability",
    "separation": "identifiability",
    "fit_transduction": "models",
    "PowerResult": "model_power",
    "power_analysis": "model_power",
    "ModelDiscrimination": "design",
    "HypothesisObserver": "observer",
    "hypothesis_observer": "observer",
    "ConditionFit": "analysis",
    "compare_sessions": "analysis",
    "condition_table": "analysis",
    "fit_conditions": "analysis",
    "fit_summary": "analysis",
    "plot_comparison": "analysis",
    "plot_power": "analysis",
    "read_design": "analysis",
    "session_summary": "session_report",
    "summary_lines": "session_report",
    "COMPARE_COLUMNS": "batch",
    "compare_many": "batch",
    "design_sweep": "batch",
    "power_sweep": "batch",
    "check_power_sweep": "batch",
    "sessions_by_subject": "batch",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS)

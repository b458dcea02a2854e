"""tactilab.experiments.procedures: which level the next trial shows, and what the trial is.

The procedure template with its state/history split and exact replay (:mod:`.base`), constant
stimuli and transformed staircases (:mod:`.staircase`), psi / QUEST+ (:mod:`.psi`), tasks that turn
a level into a trial's stimuli and score the answer (:mod:`.tasks`), and the registries of
procedures and likelihoods (:mod:`.registry`) behind :func:`make_procedure` (:mod:`.build`).
A built-in procedure's module loads the first time a protocol names it, so a staircase session
loads neither psi nor the modelling room.

Door rule: this package is the room's one door. Code outside the room imports it from here,
never from the modules inside, and this room imports no other room of
:mod:`tactilab.experiments` (the registry names ``model_discrimination``'s door and class in the
modelling room as strings, loaded on first use; no import statement names that room). The rooms import one
way: ``devices`` and ``procedures`` <- ``session`` <- ``modelling``
(tests/test_experiments_rooms.py enforces both rules).
"""

from tactilab.core import attach

#: public name -> module of this room that defines it (loaded on first use)
_EXPORTS = {
    "Likelihood": "base",
    "PlannedLevel": "base",
    "Procedure": "base",
    "replay": "base",
    "ConstantStimuli": "staircase",
    "Staircase": "staircase",
    "Psi": "psi",
    "psychometric": "psi",
    "resolve_likelihood": "psi",
    "PlannedStimulus": "tasks",
    "TrialPlan": "tasks",
    "base_stimulus": "tasks",
    "blank": "tasks",
    "outcome_of": "tasks",
    "plan_trial": "tasks",
    "score": "tasks",
    "make_procedure": "build",
    "BUILTIN_PROCEDURES": "registry",
    "ENTRY_POINT_GROUP": "registry",
    "UnregisteredError": "registry",
    "get_likelihood": "registry",
    "procedure_factory": "registry",
    "register_likelihood": "registry",
    "register_procedure": "registry",
    "registered_likelihoods": "registry",
    "registered_procedures": "registry",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS)

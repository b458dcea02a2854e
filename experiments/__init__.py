"""tactilab.experiments: psychophysics on tactile displays, recorded durably.

Protocols, procedures (constant stimuli, staircases, psi), displays (simulated, UDP, with safety
limits), responses (terminal, simulated observer), durable session recording, resume and export.
Import from here::

    from tactilab.experiments import new_session, resume_session, export_session, SimulatedObserver

The part has four rooms, each a subpackage with one door (its ``__init__``): ``devices``
(displays, the UDP link, the emulator, safety, the device registry), ``procedures`` (staircases,
constant stimuli, psi, tasks, the procedure and likelihood registries), ``session`` (runner,
recording, resume, export, responses) and ``modelling`` (psychometric and transduction fits, model
comparison, power, model-discrimination design, session analysis). Imports between rooms go one
way, ``devices`` and ``procedures`` <- ``session`` <- ``modelling``, through the doors; every name
below comes from a room's door. docs/experiments.md ("Experiments rooms") says where new code goes.
"""

from tactilab.core import attach, package_version

#: public name -> the room (subpackage) whose door exports it
_EXPORTS = {
    "new_session": "session",
    "RunResult": "session",
    "DisplayFault": "devices",
    "Runner": "session",
    "resume_session": "session",
    "session_status": "session",
    "replay_session": "session",
    "export_session": "session",
    "session_dataframe": "session",
    "session_summary": "modelling",
    "compare_sessions": "modelling",
    "fit_conditions": "modelling",
    "plot_comparison": "modelling",
    "SessionLog": "session",
    "RecordingError": "session",
    "SessionLockedError": "session",
    "Display": "devices",
    "DisplayError": "devices",
    "SafeDisplay": "devices",
    "SimulatedDisplay": "devices",
    "UdpDisplay": "devices",
    # the display UDP frame format (docs/udp-frame-format.md)
    "ARM": "devices",
    "FRAME": "devices",
    "encode": "devices",
    "decode": "devices",
    "emulate": "devices",
    "register_device": "devices",
    "SimulatedObserver": "session",
    "TerminalResponses": "session",
    "true_threshold_2ifc": "session",
    "ConstantStimuli": "procedures",
    "Staircase": "procedures",
    "Psi": "procedures",
    "make_procedure": "procedures",
    "register_likelihood": "procedures",
    "register_procedure": "procedures",
    "UnregisteredError": "procedures",
    "Procedure": "procedures",
    "PlannedLevel": "procedures",
    "fit_psychometric": "modelling",
    "PsychometricFit": "modelling",
    "ParamSummary": "modelling",
    "SIGMOIDS": "modelling",
    "TransductionModel": "modelling",
    "TransductionFit": "modelling",
    "fit_transduction": "modelling",
    "compare_models": "modelling",
    "elpd_mcse": "modelling",
    "power_analysis": "modelling",
    "PowerResult": "modelling",
    "power_sweep": "modelling",
    "design_sweep": "modelling",
    "compare_many": "modelling",
    "sessions_by_subject": "modelling",
    "ModelDiscrimination": "modelling",
}

__version__ = package_version()
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS)

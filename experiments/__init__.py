"""tactilab.experiments: psychophysics on tactile displays, recorded durably.

Protocols, procedures (constant stimuli, staircases, psi), displays (simulated, UDP, with safety
limits), responses (terminal, simulated observer), durable session recording, resume and export.
Import from here::

    from tactilab.experiments import new_session, resume_session, export_session, SimulatedObserver
"""

from tactilab.core import attach, package_version

#: public name -> module that defines it
_EXPORTS = {
    "new_session": "runner",
    "RunResult": "runner",
    "DisplayFault": "display_faults",
    "Runner": "runner",
    "resume_session": "resume",
    "session_status": "resume",
    "replay_session": "resume",
    "export_session": "export",
    "session_dataframe": "export",
    "session_summary": "session_report",
    "SessionLog": "recording",
    "RecordingError": "recording",
    "SessionLockedError": "recording",
    "Display": "display",
    "DisplayError": "display",
    "SafeDisplay": "safety",
    "SimulatedDisplay": "simulated_display",
    "UdpDisplay": "udp",
    # the display UDP frame format (docs/udp-frame-format.md)
    "FRAME": "udp",
    "encode": "udp",
    "decode": "udp",
    "emulate": "emulator",
    "SimulatedObserver": "responses",
    "TerminalResponses": "responses",
    "true_threshold_2ifc": "responses",
    "ConstantStimuli": "procedures",
    "Staircase": "procedures",
    "Psi": "psi",
    "make_procedure": "build",
    "register_likelihood": "registry",
    "register_procedure": "registry",
    "UnregisteredError": "registry",
    "Procedure": "procedures",
    "PlannedLevel": "procedures",
    "fit_psychometric": "psychometric",
    "PsychometricFit": "psychometric",
    "ParamSummary": "psychometric",
    "SIGMOIDS": "psychometric",
    "TransductionModel": "models",
    "TransductionFit": "models",
    "fit_transduction": "models",
    "compare_models": "models",
    "elpd_mcse": "models",
    "power_analysis": "models",
    "PowerResult": "models",
    "power_sweep": "batch",
    "design_sweep": "batch",
    "compare_many": "batch",
    "sessions_by_subject": "batch",
    "ModelDiscrimination": "design",
}

__version__ = package_version()
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS)

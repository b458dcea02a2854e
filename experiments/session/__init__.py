"""tactilab.experiments.session: run, record, resume and export a session.

The runner (:mod:`.runner`: plan, record, present, respond, record; two commits per trial; stop
signals turned into a clean stop), durable recording (:mod:`.recording`), resume and status
(:mod:`.resume`), export to BIDS, CSV, Parquet and JSON (:mod:`.export`, :mod:`.bids`), response
sources (:mod:`.responses`: a terminal, a simulated observer) and the builders from text specs
(:mod:`.factory`).

Door rule: this package is the room's one door. Code outside the room imports it from here,
never from the modules inside. This room imports the ``devices`` and ``procedures`` rooms
(through their doors) and never ``modelling``. The rooms import one way: ``devices`` and
``procedures`` <- ``session`` <- ``modelling`` (tests/test_experiments_rooms.py enforces both
rules).
"""

from tactilab.core import attach

#: public name -> module of this room that defines it (loaded on first use)
_EXPORTS = {
    "DISPLAY_UNITS": "runner",
    "RunResult": "runner",
    "Runner": "runner",
    "format_estimate": "runner",
    "new_session": "runner",
    "trial_generators": "runner",
    "EVENT_KINDS": "recording",
    "NotSelfContainedWarning": "recording",
    "file_state": "recording",
    "Recorder": "recording",
    "RecordingError": "recording",
    "SessionLockedError": "recording",
    "SessionLog": "recording",
    "SessionTakenOverError": "recording",
    "Replayed": "resume",
    "SessionHeader": "resume",
    "check_same_display": "resume",
    "replay_session": "resume",
    "resume_session": "resume",
    "session_header": "resume",
    "session_status": "resume",
    "FORMATS": "export",
    "export_session": "export",
    "read_trials_csv": "export",
    "session_dataframe": "export",
    "session_record": "export",
    "write_dataset": "bids",
    "Response": "responses",
    "ResponseSource": "responses",
    "SimulatedObserver": "responses",
    "TerminalResponses": "responses",
    "receptor_strain": "responses",
    "rendered_strain": "responses",
    "true_threshold_2ifc": "responses",
    "signals_held": "signals",
    "stop_signals": "signals",
    "make_responses": "factory",
    "CLIPPED": "display_check",
    "check_display_limits": "display_check",
    "clipped_stimuli": "display_check",
    "drop_clipped": "display_check",
    "plan_for_display": "display_check",
    "next_session_path": "factory",
    "responses_from_spec": "factory",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS)

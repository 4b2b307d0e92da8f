"""Experiment runtime: protocols parsed into trial lists and presented with PsychoPy.

The protocol (:class:`Protocol`) is first turned into a plain list of :class:`Trial`
(:func:`build_trials`: ordering constraints, fixation jitter, breaks, anchors/practice,
end-of-session items, trigger codes) without any window; :func:`run_session` then walks it
in a PsychoPy window (or, simulated, on a virtual clock), writing one durable TSV row per
trial. PsychoPy is imported only when a window is opened.
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["clips", "datafile", "demographics", "display", "drawn_faces", "ordering", "protocol_schema",
                "psychophysics", "report", "responders", "runner", "screens", "session", "simulate", "stimuli",
                "trials", "triggers", "web"],
    submod_attrs={
        "datafile": ["TsvWriter", "read_completed", "session_stem"],
        "ordering": ["check_order", "constrained_order", "run_lengths"],
        "protocol_schema": ["Protocol"],
        "report": ["session_summary", "write_session_report"],
        "session": ["SessionResult", "default_seed", "load_protocol", "run_session"],
        "simulate": ["DEFAULT_MODEL", "ParticipantModel", "SimulatedParticipant", "load_participant_model"],
        "stimuli": ["StimulusSet", "load_stimuli", "select_stimuli"],
        "trials": ["Trial", "build_trials", "fixation_frame_range", "seconds_to_frames", "trials_frame"],
    },
)

__all__ = [
    "Protocol", "load_protocol", "StimulusSet", "load_stimuli", "select_stimuli", "Trial", "build_trials",
    "trials_frame", "seconds_to_frames", "fixation_frame_range", "constrained_order", "check_order", "run_lengths",
    "TsvWriter", "read_completed", "session_stem", "run_session", "SessionResult", "default_seed",
    "ParticipantModel", "SimulatedParticipant", "load_participant_model", "DEFAULT_MODEL",
    "session_summary", "write_session_report",
]

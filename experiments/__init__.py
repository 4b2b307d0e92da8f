"""Experiment runtime: protocols parsed into trial lists and presented with PsychoPy.

The protocol (:class:`Protocol`) is first turned into a plain list of :class:`Trial`
(:func:`build_trials`: ordering constraints, fixation jitter, breaks, anchors/practice,
end-of-session items, trigger codes) without any window; :func:`run_session` then walks it
in a PsychoPy window (or, simulated, on a virtual clock), writing one durable TSV row per
trial. PsychoPy is imported only when a window is opened.
"""

from experiments.datafile import TsvWriter, read_completed, session_stem
from experiments.ordering import check_order, constrained_order, run_lengths
from experiments.protocol_schema import Protocol
from experiments.report import session_summary, write_session_report
from experiments.session import SessionResult, default_seed, load_protocol, run_session
from experiments.simulate import DEFAULT_MODEL, ParticipantModel, SimulatedParticipant, load_participant_model
from experiments.stimuli import StimulusSet, load_stimuli, select_stimuli
from experiments.trials import Trial, build_trials, fixation_frame_range, seconds_to_frames, trials_frame

__all__ = [
    "Protocol", "load_protocol", "StimulusSet", "load_stimuli", "select_stimuli", "Trial", "build_trials",
    "trials_frame", "seconds_to_frames", "fixation_frame_range", "constrained_order", "check_order", "run_lengths",
    "TsvWriter", "read_completed", "session_stem", "run_session", "SessionResult", "default_seed",
    "ParticipantModel", "SimulatedParticipant", "load_participant_model", "DEFAULT_MODEL",
    "session_summary", "write_session_report",
]

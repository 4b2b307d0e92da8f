"""MNE ERP pipeline: BioSemi (or any MNE-readable) recordings to N170 / EPN / LPP window
amplitudes, rm-ANOVAs with linear vs quadratic contrasts, figures and source-space summaries.

Thesis ch. 7 (§7.3-7.4) is the reference design; see docs/erp.md.
"""

from analysis.erp.channels import biosemi128_map, nearest_channel_table, resolve_cluster
from analysis.erp.config import EventMap, event_map, find_recordings, load_erp_config, read_protocol_codes
from analysis.erp.io import find_trigger_events, read_recording
from analysis.erp.measures import measure_cells, window_measures
from analysis.erp.pipeline import ErpResult, SubjectResult, preprocess, process_subject, process_subjects, run_erp
from analysis.erp.report import write_erp_outputs
from analysis.erp.simulate import SimulationDesign, simulate_study
from analysis.erp.source import contrast_clusters, template_head

__all__ = [
    "EventMap", "ErpResult", "SimulationDesign", "SubjectResult", "biosemi128_map",
    "contrast_clusters", "event_map", "find_recordings", "find_trigger_events", "load_erp_config",
    "measure_cells", "nearest_channel_table", "preprocess", "process_subject", "process_subjects", "read_protocol_codes",
    "read_recording", "resolve_cluster", "run_erp", "simulate_study", "template_head", "window_measures",
    "write_erp_outputs",
]

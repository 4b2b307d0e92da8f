"""MNE ERP pipeline: BioSemi (or any MNE-readable) recordings to N170 / EPN / LPP window
amplitudes, rm-ANOVAs with linear vs quadratic contrasts, figures and source-space summaries.

Thesis ch. 7 (§7.3-7.4) is the reference design; see docs/erp.md.
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["atlas", "bdf", "brainvision_header", "channels", "config", "edf_header", "figures",
                "file_checks", "fsaverage_head", "io", "measures", "pipeline", "preprocessing", "quality",
                "report", "results", "simulate", "single_trials", "source", "stats"],
    submod_attrs={
        "channels": ["biosemi128_map", "nearest_channel_table", "resolve_cluster"],
        "config": ["EventMap", "event_map", "find_recordings", "load_erp_config", "read_protocol_codes"],
        "io": ["find_trigger_events", "read_recording"],
        "measures": ["measure_cells", "window_measures"],
        "pipeline": ["ErpResult", "SubjectResult", "preprocess", "process_subject", "process_subjects", "run_erp"],
        "report": ["write_erp_outputs"],
        "simulate": ["SimulationDesign", "simulate_study"],
        "source": ["contrast_clusters", "template_head"],
    },
)

__all__ = [
    "EventMap", "ErpResult", "SimulationDesign", "SubjectResult", "biosemi128_map",
    "contrast_clusters", "event_map", "find_recordings", "find_trigger_events", "load_erp_config",
    "measure_cells", "nearest_channel_table", "preprocess", "process_subject", "process_subjects", "read_protocol_codes",
    "read_recording", "resolve_cluster", "run_erp", "simulate_study", "template_head", "window_measures",
    "write_erp_outputs",
]

"""Low-level confounds of a stimulus set: do its image measures differ between the levels of its factors?

:mod:`~analysis.confounds.design_tests` tests an audit table (``appeal stimuli audit``) factor by
factor: means per level, their range against a threshold, a test across the items;
:mod:`~analysis.confounds.report` draws and writes it up (``report.md``/``report.html``).
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["design_tests", "report"],
    submod_attrs={
        "design_tests": ["DEFAULT_THRESHOLDS", "design_tests", "flagged", "level_means", "parse_thresholds"],
    },
)

__all__ = ["DEFAULT_THRESHOLDS", "design_tests", "flagged", "level_means", "parse_thresholds"]

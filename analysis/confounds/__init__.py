"""Low-level confounds of a stimulus set: do its image measures differ between the levels of its factors?

:mod:`~analysis.confounds.design_tests` tests an audit table (``appeal stimuli audit``) factor by
factor: means per level, their range against a threshold, a test across the items;
:mod:`~analysis.confounds.report` draws and writes it up (``report.md``/``report.html``).
"""

from analysis.confounds.design_tests import DEFAULT_THRESHOLDS, design_tests, flagged, level_means, parse_thresholds

__all__ = ["DEFAULT_THRESHOLDS", "design_tests", "flagged", "level_means", "parse_thresholds"]

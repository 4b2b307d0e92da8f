"""Analysis: repeated-measures statistics on tidy tables and the MNE ERP pipeline."""

# Rating-study statistics (issue 3); see analysis/stats and docs/statistics.md.
from analysis.stats import rm_anova

__all__ = ["rm_anova"]

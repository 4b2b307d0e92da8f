"""Analysis: repeated-measures statistics on tidy tables and the MNE ERP pipeline."""

# Rating-study statistics (issue 3); see analysis/stats and docs/statistics.md.
from analysis.stats import compare_trends, polynomial_contrasts, rm_anova, tukey_hsd

__all__ = ["compare_trends", "polynomial_contrasts", "rm_anova", "tukey_hsd"]

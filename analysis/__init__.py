"""Analysis: repeated-measures statistics on tidy tables and the MNE ERP pipeline."""

# Rating-study statistics (issue 3); see analysis/stats and docs/statistics.md.
from analysis.stats import (compare_trends, cronbach_alpha, mixed_model_anova, polynomial_contrasts, rm_anova,
                            tukey_hsd, within_ci)

__all__ = ["compare_trends", "cronbach_alpha", "mixed_model_anova", "polynomial_contrasts", "rm_anova",
           "tukey_hsd", "within_ci"]

# ERP pipeline (issue 8); see analysis/erp and docs/erp.md.
from analysis.erp import run_erp, simulate_study  # noqa: E402

__all__ += ["run_erp", "simulate_study"]

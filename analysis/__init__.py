"""Analysis: repeated-measures statistics on tidy tables and the MNE ERP pipeline."""

# Rating-study statistics (issue 3); see analysis/stats and docs/statistics.md.
from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["confounds", "covariates_schema", "erp", "erp_schema", "mixed_schema", "psychometric",
                "ratings_schema", "stats"],
    submod_attrs={
        "stats": ["compare_trends", "cronbach_alpha", "mixed_model_anova", "polynomial_contrasts", "rm_anova",
            "tukey_hsd", "within_ci"],
        "erp": ["run_erp", "simulate_study"],
    },
)

__all__ = ["compare_trends", "cronbach_alpha", "mixed_model_anova", "polynomial_contrasts", "rm_anova",
           "tukey_hsd", "within_ci"]


__all__ += ["run_erp", "simulate_study"]

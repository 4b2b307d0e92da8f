"""Analysis: repeated-measures statistics on tidy tables and the MNE ERP pipeline."""

# Rating-study statistics (issue 3); see analysis/stats and docs/statistics.md.
from appeal.lazy import attach as _attach

# the sub-modules load on first use (Scientific Python SPEC 1, as MNE-Python and SciPy do): importing the
# package costs nothing until a name below is used
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

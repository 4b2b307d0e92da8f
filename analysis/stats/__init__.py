"""Rating-study statistics that agree with R (car, afex, emmeans).

Repeated-measures ANOVA with any number of within and between factors and sphericity
corrections, Tukey HSD from each effect's own error stratum, polynomial contrasts,
Cronbach's alpha, within-subject confidence intervals, mixed models for incomplete
designs, thesis-style reporting, figures and a simulated-rating generator.
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["anova", "clmm", "clmm_figures", "clmm_laplace", "contrasts", "covariates", "design", "formula",
                "intervals", "kenward_roger", "lmm", "lmm_anova", "lmm_emmeans", "lmm_report", "mixed", "plots",
                "posthoc", "random_structures", "records", "reference", "reliability", "reporting",
                "satterthwaite", "simulate", "sphericity", "study"],
    submod_attrs={
        "anova": ["ANOVA_COLUMNS", "anova_from_design", "fit_design", "rm_anova"],
        "contrasts": ["compare_trends", "contrasts_from_design", "polynomial_contrasts"],
        "intervals": ["within_ci", "within_ci_from_design"],
        "mixed": ["mixed_model_anova"],
        "reliability": ["cronbach_alpha"],
        "simulate": ["ScaleModel", "exp2_design", "simulate_ratings", "write_bids"],
        "design": ["Design", "prepare_design", "read_ratings", "read_table"],
        "posthoc": ["marginal_means", "pairwise_comparisons", "tukey_hsd"],
        "reporting": ["anova_text", "format_contrast", "format_effect", "format_p"],
    },
)

__all__ = ["ANOVA_COLUMNS", "Design", "ScaleModel", "anova_from_design", "anova_text", "compare_trends", "exp2_design", "contrasts_from_design", "cronbach_alpha",
           "fit_design", "format_contrast", "format_effect", "format_p", "marginal_means", "mixed_model_anova", "pairwise_comparisons",
           "polynomial_contrasts", "prepare_design", "read_ratings", "read_table", "rm_anova", "simulate_ratings", "tukey_hsd",
           "within_ci", "within_ci_from_design", "write_bids"]

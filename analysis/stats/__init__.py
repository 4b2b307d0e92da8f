"""Rating-study statistics that agree with R (car, afex, emmeans).

Repeated-measures ANOVA with any number of within and between factors and sphericity
corrections, Tukey HSD from each effect's own error stratum, polynomial contrasts,
Cronbach's alpha, within-subject confidence intervals, mixed models for incomplete
designs, thesis-style reporting, figures and a simulated-rating generator.
"""

from analysis.stats.anova import ANOVA_COLUMNS, anova_from_design, fit_design, rm_anova
from analysis.stats.contrasts import compare_trends, contrasts_from_design, polynomial_contrasts
from analysis.stats.intervals import within_ci, within_ci_from_design
from analysis.stats.mixed import mixed_model_anova
from analysis.stats.reliability import cronbach_alpha
from analysis.stats.simulate import ScaleModel, exp2_design, simulate_ratings, write_bids
from analysis.stats.design import Design, prepare_design, read_ratings, read_table
from analysis.stats.posthoc import marginal_means, pairwise_comparisons, tukey_hsd
from analysis.stats.reporting import anova_text, format_contrast, format_effect, format_p

__all__ = ["ANOVA_COLUMNS", "Design", "ScaleModel", "anova_from_design", "anova_text", "compare_trends", "exp2_design", "contrasts_from_design", "cronbach_alpha",
           "fit_design", "format_contrast", "format_effect", "format_p", "marginal_means", "mixed_model_anova", "pairwise_comparisons",
           "polynomial_contrasts", "prepare_design", "read_ratings", "read_table", "rm_anova", "simulate_ratings", "tukey_hsd",
           "within_ci", "within_ci_from_design", "write_bids"]

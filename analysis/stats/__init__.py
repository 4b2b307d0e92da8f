"""Rating-study statistics that agree with R (car, afex, emmeans).

Repeated-measures ANOVA with any number of within and between factors and sphericity
corrections, Tukey HSD from each effect's own error stratum, polynomial contrasts,
Cronbach's alpha, within-subject confidence intervals, mixed models for incomplete
designs, thesis-style reporting, figures and a simulated-rating generator.
"""

from analysis.stats.anova import ANOVA_COLUMNS, anova_from_design, fit_design, rm_anova
from analysis.stats.design import Design, prepare_design, read_ratings, read_table

__all__ = ["ANOVA_COLUMNS", "Design", "anova_from_design", "fit_design", "prepare_design", "read_ratings",
           "read_table", "rm_anova"]

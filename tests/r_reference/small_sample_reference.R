# Reference numbers for tests/test_stats_small_samples.py: designs at the edge of what the
# repeated-measures ANOVA can estimate (2 or 3 participants, more effect df than error df,
# no error variance).
#
# Run from the repository root:   Rscript tests/r_reference/small_sample_reference.R > tests/r_reference/small_sample_reference.out
# It (re)writes tests/data/stats_small_*.csv (deterministic: set.seed) and prints Python
# literals that the test reads from the .out file. Tools as in anova_reference.R (whose
# anova_ref / pairs_ref it reuses): car's univariate tests, afex::aov_ez (type 3, pes/ges),
# emmeans (model = "univariate", Tukey).
suppressPackageStartupMessages({library(afex); library(emmeans); library(car)})
options(warn = -1)
source_refs <- function() {
  # the reference functions of anova_reference.R, without running its data sets
  ex <- parse("tests/r_reference/anova_reference.R")
  keep <- sapply(ex, function(e) is.call(e) && identical(e[[1]], as.name("<-")) &&
                   as.character(e[[2]]) %in% c("fmt", "sorted_factors", "anova_ref", "pairs_ref"))
  for (e in ex[keep]) eval(e, globalenv())
}
source_refs()

set.seed(12)
n2 <- expand.grid(B = paste0("b", 1:2), A = paste0("a", 1:3), id = sprintf("s%02d", 1:2))[, c("id", "A", "B")]
n2$y <- round(rnorm(nrow(n2), 4, 1), 3)
write.csv(n2, "tests/data/stats_small_n2.csv", row.names = FALSE, quote = FALSE)

set.seed(13)
n3 <- expand.grid(A = paste0("a", 1:5), id = sprintf("s%02d", 1:3))[, c("id", "A")]
n3$y <- round(rnorm(nrow(n3), 4, 1), 3)
write.csv(n3, "tests/data/stats_small_n3_5levels.csv", row.names = FALSE, quote = FALSE)

# every participant's scores differ by a constant: no error variance for A
z3 <- expand.grid(A = paste0("a", 1:3), id = sprintf("s%02d", 1:3))[, c("id", "A")]
z3$y <- as.integer(z3$id) + as.integer(z3$A) * 0.5
write.csv(z3, "tests/data/stats_small_zero_error.csv", row.names = FALSE, quote = FALSE)

# 3 participants in 2 groups: 1 error df for a 3-level within factor
set.seed(14)
g3 <- expand.grid(A = paste0("a", 1:3), id = sprintf("s%02d", 1:3))[, c("id", "A")]
g3$group <- ifelse(g3$id == "s01", "g1", "g2")
g3 <- g3[, c("id", "group", "A")]
g3$y <- round(rnorm(nrow(g3), 4, 1), 3)
write.csv(g3, "tests/data/stats_small_n3_between.csv", row.names = FALSE, quote = FALSE)

cat("# ---- produced by: Rscript tests/r_reference/small_sample_reference.R\n")
cat(sprintf("# R %s, car %s, afex %s, emmeans %s\n\n", getRversion(), packageVersion("car"), packageVersion("afex"), packageVersion("emmeans")))
f1 <- anova_ref("R_N2", n2, "y", "id", c("A", "B"))
f2 <- anova_ref("R_N3_5LEVELS", n3, "y", "id", "A")
f3 <- anova_ref("R_ZERO_ERROR", z3, "y", "id", "A")
f4 <- anova_ref("R_N3_BETWEEN", g3, "y", "id", "A", "group")
pairs_ref("R_PAIRS_N2_A", f1, ~A)
pairs_ref("R_PAIRS_N2_AB", f1, ~A:B)
pairs_ref("R_PAIRS_N3_5LEVELS", f2, ~A)

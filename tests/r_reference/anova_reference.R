# Reference numbers for tests/test_stats_anova.py and tests/test_stats_posthoc.py.
#
# Run from the repository root:   Rscript tests/r_reference/anova_reference.R
# It (re)writes the small CSV data sets tests/data/stats_*.csv (deterministic: set.seed)
# and prints Python dict literals that are pasted into the tests.
# Tools: R 4 with car (Anova.mlm univariate tests, Mauchly, GG/HF), afex (aov_ez, type 3,
# pes/ges) and emmeans (model = "univariate", pairs(adjust = "tukey")).
suppressPackageStartupMessages({library(afex); library(emmeans); library(car)})
options(warn = -1)
dir.create("tests/data", showWarnings = FALSE)

fmt <- function(x) ifelse(is.na(x), "NAN", sprintf("%.17g", x))
sorted_factors <- function(d, cols) {
  for (c in cols) d[[c]] <- factor(as.character(d[[c]]), levels = sort(unique(as.character(d[[c]])), method = "radix"))
  d
}

# ---------------------------------------------------------------- data sets
set.seed(1)
d2 <- expand.grid(B = paste0("b", 1:4), A = paste0("a", 1:3), id = sprintf("s%02d", 1:8))[, c("id", "A", "B")]
subj <- rnorm(8, 0, 0.8); names(subj) <- sprintf("s%02d", 1:8)
effA <- c(a1 = -0.6, a2 = 0, a3 = 0.9); effB <- c(b1 = 0.3, b2 = -0.2, b3 = 0.5, b4 = -0.4)
slope <- rnorm(8, 0, 0.5); names(slope) <- names(subj)
d2$rating <- round(pmin(7, pmax(1, 4 + effA[as.character(d2$A)] + effB[as.character(d2$B)] +
  subj[as.character(d2$id)] + slope[as.character(d2$id)] * (as.integer(d2$A) - 2) + rnorm(nrow(d2), 0, 0.9))))
write.csv(d2, "tests/data/stats_within2_likert.csv", row.names = FALSE, quote = FALSE)

set.seed(2)
d3 <- expand.grid(C = paste0("c", 1:4), B = paste0("b", 1:3), A = paste0("a", 1:2), id = sprintf("p%d", 1:6))[, c("id", "A", "B", "C")]
u <- rnorm(6); v <- rnorm(6, 0, 0.4)
d3$y <- 10 + u[as.integer(d3$id)] + 0.7 * (d3$A == "a2") + c(0, 0.4, 1.1)[as.integer(d3$B)] +
  v[as.integer(d3$id)] * as.integer(d3$C) + 0.3 * (d3$A == "a2") * as.integer(d3$C) + rnorm(nrow(d3), 0, 0.6)
d3$y <- round(d3$y, 6)
write.csv(d3, "tests/data/stats_within3_cont.csv", row.names = FALSE, quote = FALSE)

set.seed(3)
d4 <- expand.grid(rep = 1:2, expression = c("angry", "happy"), material = paste0("m", 0:2),
                  shape = paste0("s", 0:2), character = c("female", "male"), id = sprintf("sub-%02d", 1:10))
d4 <- d4[, c("id", "character", "shape", "material", "expression", "rep")]
u <- rnorm(10, 0, 0.7); w <- rnorm(10, 0, 0.5)
mu <- 3.5 + 0.5 * as.integer(d4$shape) - 0.4 * (as.integer(d4$material) - 2)^2 - 0.6 * (d4$expression == "angry") +
  0.3 * (d4$shape == "s2") * (d4$material == "m0") + u[as.integer(d4$id)] + w[as.integer(d4$id)] * as.integer(d4$shape)
d4$appeal <- round(pmin(7, pmax(1, mu + rnorm(nrow(d4), 0, 1))))
write.csv(d4, "tests/data/stats_within4_likert_reps.csv", row.names = FALSE, quote = FALSE)

data(obk.long, package = "afex")
ob <- obk.long[, c("id", "treatment", "gender", "phase", "hour", "value")]
ob$id <- sprintf("o%02d", as.integer(as.character(ob$id)))
write.csv(ob, "tests/data/stats_obk_long.csv", row.names = FALSE, quote = FALSE)

# ---------------------------------------------------------------- references
anova_ref <- function(name, d, dv, id, within, between = NULL) {
  d <- sorted_factors(d, c(id, within, between))
  fit <- aov_ez(id = id, dv = dv, data = d, within = within, between = between, type = 3,
                fun_aggregate = mean, include_aov = TRUE, anova_table = list(es = c("pes", "ges"), correction = "none"))
  s <- summary(fit$Anova, multivariate = FALSE)
  uni <- s$univariate.tests; adj <- s$pval.adjustments; sph <- s$sphericity.tests
  es <- anova(fit, es = c("pes", "ges"), correction = "none")
  cat(sprintf("%s = {\n", name))
  for (term in rownames(uni)) {
    if (term == "(Intercept)") next
    g <- function(tab, col) if (term %in% rownames(tab)) tab[term, col] else NA
    vals <- c(SS = uni[term, "Sum Sq"], error_SS = uni[term, "Error SS"], num_df = uni[term, "num Df"],
              den_df = uni[term, "den Df"], F = uni[term, "F value"], p = uni[term, "Pr(>F)"],
              mauchly_W = g(sph, "Test statistic"), mauchly_p = g(sph, "p-value"),
              gg_eps = g(adj, "GG eps"), hf_eps = g(adj, "HF eps"), p_gg = g(adj, "Pr(>F[GG])"),
              p_hf = g(adj, "Pr(>F[HF])"), pes = es[term, "pes"], ges = es[term, "ges"])
    # with a singular error SSP matrix car leaves eps NA but fills Pr(>F[GG]/[HF]) with 0
    # (a placeholder, not a p value): report NA there
    if (is.na(vals[["gg_eps"]])) vals[["p_gg"]] <- NA
    if (is.na(vals[["hf_eps"]])) vals[["p_hf"]] <- NA
    cat(sprintf("    %s: {%s},\n", shQuote(term, "cmd"),
                paste(sprintf("%s: %s", shQuote(names(vals), "cmd"), fmt(vals)), collapse = ", ")))
  }
  cat("}\n\n")
  fit
}

pairs_ref <- function(name, fit, spec) {
  em <- emmeans(fit, spec, model = "univariate")
  pr <- as.data.frame(summary(pairs(em, adjust = "tukey")))
  cat(sprintf("%s = [\n", name))
  for (i in seq_len(nrow(pr)))
    cat(sprintf("    (%s, %s, %s, %s, %s, %s),\n", shQuote(as.character(pr$contrast[i]), "cmd"), fmt(pr$estimate[i]),
                fmt(pr$SE[i]), fmt(pr$df[i]), fmt(pr$t.ratio[i]), fmt(pr$p.value[i])))
  cat("]\n\n")
}

poly_ref <- function(name, d, dv, id, factor, within, between = NULL) {
  d <- sorted_factors(d, c(id, within, between))
  m <- aggregate(d[[dv]], by = d[c(id, between, factor)], FUN = mean)
  w <- reshape(m, idvar = c(id, between), timevar = factor, direction = "wide")
  lev <- levels(d[[factor]]); Y <- as.matrix(w[paste0("x.", lev)])
  P <- contr.poly(length(lev))
  cat(sprintf("%s = {\n", name))
  for (j in seq_len(ncol(P))) {
    w$score <- as.vector(Y %*% P[, j])
    f <- if (is.null(between)) score ~ 1 else as.formula(paste("score ~", paste(between, collapse = "*")))
    ctr <- if (is.null(between)) NULL else setNames(rep(list(contr.sum), length(between)), between)
    a <- car::Anova(lm(f, data = w, contrasts = ctr), type = 3)
    ss <- a["(Intercept)", "Sum Sq"]; sse <- a["Residuals", "Sum Sq"]
    cat(sprintf("    %d: (%s, %s, %s, %s, %s),\n", j, fmt(a["(Intercept)", "F value"]), fmt(a["(Intercept)", "Df"]),
                fmt(a["Residuals", "Df"]), fmt(a["(Intercept)", "Pr(>F)"]), fmt(ss / (ss + sse))))
  }
  cat("}\n\n")
}

cat("# ---- produced by: Rscript tests/r_reference/anova_reference.R\n")
cat(sprintf("# R %s, car %s, afex %s, emmeans %s\n\n", getRversion(), packageVersion("car"), packageVersion("afex"), packageVersion("emmeans")))
f2 <- anova_ref("R_WITHIN2", d2, "rating", "id", c("A", "B"))
f3 <- anova_ref("R_WITHIN3", d3, "y", "id", c("A", "B", "C"))
f4 <- anova_ref("R_WITHIN4", d4, "appeal", "id", c("character", "shape", "material", "expression"))
fo <- anova_ref("R_OBK", ob, "value", "id", c("phase", "hour"), c("treatment", "gender"))

pairs_ref("R_PAIRS_W2_A", f2, ~A)
pairs_ref("R_PAIRS_W2_AB", f2, ~A:B)
pairs_ref("R_PAIRS_W4_SHAPE", f4, ~shape)
pairs_ref("R_PAIRS_W4_SHAPE_MATERIAL", f4, ~shape:material)
pairs_ref("R_PAIRS_OBK_PHASE", fo, ~phase)
pairs_ref("R_PAIRS_OBK_TREATMENT", fo, ~treatment)
pairs_ref("R_PAIRS_OBK_TREATMENT_PHASE", fo, ~treatment:phase)

poly_ref("R_POLY_W2_B", d2, "rating", "id", "B", c("A", "B"))
poly_ref("R_POLY_W4_SHAPE", d4, "appeal", "id", "shape", c("character", "shape", "material", "expression"))
poly_ref("R_POLY_OBK_HOUR", ob, "value", "id", "hour", c("phase", "hour"), c("treatment", "gender"))

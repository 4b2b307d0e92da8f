# Reference numbers for tests/test_stats_reliability.py (Cronbach's alpha, Cousineau-Morey
# intervals) and tests/test_stats_mixed.py (lmer + car::Anova type III Wald tests).
#
# Run from the repository root:  Rscript tests/r_reference/reliability_intervals_mixed_reference.R
# Data: tests/data/stats_within2_likert.csv (from anova_reference.R) and
# tests/data/stats_scales.csv (written here, set.seed).
suppressPackageStartupMessages({library(lme4); library(car)})
fmt <- function(x) sprintf("%.17g", x)

# --- Cronbach's alpha (items = scales, observations = subject x stimulus), Feldt 95% CI
set.seed(4)
d <- expand.grid(stimulus = paste0("st", 1:4), id = sprintf("s%02d", 1:12))[, c("id", "stimulus")]
base <- rnorm(nrow(d), 4, 1)
d$appeal <- round(pmin(7, pmax(1, base + rnorm(nrow(d), 0, 0.6))))
d$reassurance <- round(pmin(7, pmax(1, base + rnorm(nrow(d), 0, 0.8))))
d$attractiveness <- round(pmin(7, pmax(1, 0.8 * base + 1 + rnorm(nrow(d), 0, 0.7))))
write.csv(d, "tests/data/stats_scales.csv", row.names = FALSE, quote = FALSE)
X <- as.matrix(d[, c("appeal", "reassurance", "attractiveness")])
k <- ncol(X); n <- nrow(X)
alpha <- k / (k - 1) * (1 - sum(apply(X, 2, var)) / var(rowSums(X)))
lo <- 1 - (1 - alpha) * qf(0.975, n - 1, (n - 1) * (k - 1))
hi <- 1 - (1 - alpha) * qf(0.025, n - 1, (n - 1) * (k - 1))
cat("# ---- produced by: Rscript tests/r_reference/reliability_intervals_mixed_reference.R\n")
cat(sprintf("R_ALPHA = (%s, %s, %s)  # alpha, Feldt 95%% CI low, high\n\n", fmt(alpha), fmt(lo), fmt(hi)))

# --- Cousineau (2005) normalisation + Morey (2008) correction, 95% CI half-widths
w <- read.csv("tests/data/stats_within2_likert.csv")
cm <- function(w, factors) {
  m <- aggregate(w$rating, by = w[c("id", factors)], FUN = mean)
  names(m)[ncol(m)] <- "y"
  m$norm <- m$y - ave(m$y, m$id) + mean(m$y)
  M <- nrow(unique(m[factors])); n <- length(unique(m$id))
  s <- aggregate(m$norm, by = m[factors], FUN = sd)
  mu <- aggregate(m$y, by = m[factors], FUN = mean)
  hw <- qt(0.975, n - 1) * s$x / sqrt(n) * sqrt(M / (M - 1))
  data.frame(s[factors], mean = mu$x, hw = hw)
}
for (f in list("A", c("A", "B"))) {
  r <- cm(w, f)
  cat(sprintf("R_CM_%s = {\n", paste(f, collapse = "")))
  for (i in seq_len(nrow(r))) cat(sprintf("    %s: (%s, %s),\n", shQuote(paste(unlist(r[i, f]), collapse = ":"), "cmd"), fmt(r$mean[i]), fmt(r$hw[i])))
  cat("}\n\n")
}

# --- linear mixed model with a random intercept per subject, type III Wald chi-square
w2 <- w[!(w$id == "s03" & w$A == "a2" & w$B == "b4") & !(w$id == "s05" & w$A == "a1"), ]
fit <- lmer(rating ~ A * B + (1 | id), data = w2, REML = TRUE, contrasts = list(A = contr.sum, B = contr.sum))
a <- car::Anova(fit, type = 3)
cat("# lmer(rating ~ A * B + (1 | id), REML, contr.sum) on stats_within2_likert.csv without s03/a2/b4 and s05/a1;\n")
cat("# car::Anova(fit, type = 3): {term: (Chisq, Df, p)}\n")
cat("R_LMER = {\n")
for (t in rownames(a)) cat(sprintf("    %s: (%s, %s, %s),\n", shQuote(t, "cmd"), fmt(a[t, "Chisq"]), fmt(a[t, "Df"]), fmt(a[t, "Pr(>Chisq)"])))
cat("}\n")
cat(sprintf("R_LMER_SIGMA = %s\nR_LMER_SD_ID = %s\n", fmt(sigma(fit)), fmt(attr(VarCorr(fit)$id, "stddev"))))

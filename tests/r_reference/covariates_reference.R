# Reference numbers for tests/test_stats_covariates.py (stimulus audit measures as covariates:
# a linear mixed model with a centred covariate, lme4 + lmerTest; the ANCOVA-style slope of the
# rm-ANOVA path, lm with cell and participant dummies; the rm-ANOVA of the adjusted cell means, afex).
#
# Run from the repository root:   Rscript tests/r_reference/covariates_reference.R > tests/r_reference/covariates_reference.out
# It (re)writes tests/data/covariates_ratings.csv (trials) and tests/data/covariates_audit.csv (an
# audit table as `appeal stimuli audit` writes it, reduced to a few measures) deterministically
# (set.seed) and prints Python literals. Sum-to-zero contrasts, as the Python side.
suppressPackageStartupMessages({library(lme4); library(lmerTest); library(afex)})
options(warn = -1, contrasts = c("contr.sum", "contr.poly"))
dir.create("tests/data", showWarnings = FALSE)
cat(sprintf("# ---- produced by: Rscript tests/r_reference/covariates_reference.R\n# %s, lme4 %s, lmerTest %s, afex %s\n\n",
            R.version.string, packageVersion("lme4"), packageVersion("lmerTest"), packageVersion("afex")))

fmt <- function(x) ifelse(is.na(x), "NAN", ifelse(is.infinite(x), "Inf", sprintf("%.17g", x)))
vec <- function(x) paste0("[", paste(fmt(x), collapse = ", "), "]")
strs <- function(x) paste0("[", paste0('"', x, '"', collapse = ", "), "]")
tight <- lmerControl(optimizer = "nloptwrap", calc.derivs = TRUE,
                     optCtrl = list(xtol_abs = 1e-12, ftol_abs = 1e-14, xtol_rel = 1e-12, ftol_rel = 1e-15, maxeval = 1e5))

# ---------------------------------------------------------------- data
# 3 shape levels x 4 characters = 12 stimuli (each stimulus in one shape cell, so a stimulus's
# luminance varies within the shape cells); 16 participants rate every stimulus twice.
set.seed(3204)
np <- 16; nc <- 4
audit <- expand.grid(character = sprintf("c%d", 1:nc), shape = paste0("s", 1:3))
audit$file <- sprintf("%s/%s.png", audit$shape, audit$character)
audit$face_L_mean <- round(55 + 4 * (as.integer(audit$shape) - 2) + rnorm(nrow(audit), 0, 6), 4)
audit$face_rms_contrast <- round(0.2 + rnorm(nrow(audit), 0, 0.04), 5)
audit <- audit[, c("file", "character", "shape", "face_L_mean", "face_rms_contrast")]
write.csv(audit, "tests/data/covariates_audit.csv", row.names = FALSE, quote = FALSE)

d <- expand.grid(rep = 1:2, stim = seq_len(nrow(audit)), participant_id = sprintf("p%02d", 1:np))
d$stimulus <- audit$file[d$stim]
d$shape <- audit$shape[d$stim]
d$character <- audit$character[d$stim]
u <- rnorm(np, 0, 0.7); w <- rnorm(nrow(audit), 0, 0.4)
sh <- as.integer(factor(d$shape)) - 2
d$rating <- round(4 + 0.5 * sh + 0.06 * (audit$face_L_mean[d$stim] - 55) + u[as.integer(factor(d$participant_id))] +
  w[d$stim] + rnorm(nrow(d), 0, 0.8), 4)
d <- d[, c("participant_id", "stimulus", "shape", "character", "rep", "rating")]
write.csv(d, "tests/data/covariates_ratings.csv", row.names = FALSE, quote = FALSE)

# ---------------------------------------------------------------- the mixed model
d$face_L_mean <- audit$face_L_mean[match(d$stimulus, audit$file)]
d$face_L_mean <- d$face_L_mean - mean(d$face_L_mean)  # centred at the grand mean of the trials
d$shape <- factor(d$shape)
m <- lmer(rating ~ shape + face_L_mean + (1 | participant_id) + (1 | stimulus), data = d, REML = TRUE, control = tight)
co <- summary(m)$coefficients
a3 <- anova(m, type = 3)
cat("R_LMM = {\n")
cat(sprintf('  "formula": "%s",\n', "rating ~ shape + face_L_mean + (1 | participant_id) + (1 | stimulus)"))
cat(sprintf('  "reml_deviance": %s, "sigma": %s,\n', fmt(REMLcrit(m)), fmt(sigma(m))))
cat(sprintf('  "coef_names": %s,\n', strs(rownames(co))))
cat(sprintf('  "beta": %s,\n  "se": %s,\n  "df": %s,\n  "t": %s,\n  "p": %s,\n',
            vec(co[, "Estimate"]), vec(co[, "Std. Error"]), vec(co[, "df"]), vec(co[, "t value"]), vec(co[, "Pr(>|t|)"])))
cat(sprintf('  "anova_terms": %s,\n  "F": %s,\n  "num_df": %s,\n  "den_df": %s,\n  "anova_p": %s,\n',
            strs(rownames(a3)), vec(a3[, "F value"]), vec(a3[, "NumDF"]), vec(a3[, "DenDF"]), vec(a3[, "Pr(>F)"])))
cat("}\n\n")

# ---------------------------------------------------------------- the ANCOVA-style adjustment
# slope from the trial-level regression with the cells (shape) and participants as fixed effects
d$cell <- factor(d$shape)
fit <- lm(rating ~ cell + participant_id + face_L_mean, data = d)
b <- unname(coef(fit)["face_L_mean"])
d$adjusted <- d$rating - b * d$face_L_mean
cm <- aggregate(adjusted ~ participant_id + shape, data = d, FUN = mean)
aov <- suppressMessages(aov_ez("participant_id", "adjusted", cm, within = "shape",
                                anova_table = list(correction = "none", es = "pes")))
tab <- aov$anova_table
cat("R_ANCOVA = {\n")
cat(sprintf('  "slope": %s,\n', fmt(b)))
cat(sprintf('  "cell_means_participant": %s,\n  "cell_means_shape": %s,\n  "cell_means": %s,\n',
            strs(as.character(cm$participant_id)), strs(as.character(cm$shape)), vec(cm$adjusted)))
cat(sprintf('  "F": %s, "num_df": %s, "den_df": %s, "p": %s,\n', fmt(tab[1, "F"]), fmt(tab[1, "num Df"]),
            fmt(tab[1, "den Df"]), fmt(tab[1, "Pr(>F)"])))
cat("}\n")

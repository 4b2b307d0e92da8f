# Reference numbers for tests/test_stats_lmm.py (linear mixed models: lme4, lmerTest, pbkrtest,
# afex::mixed, emmeans).
#
# Run from the repository root:   Rscript tests/r_reference/lmm_reference.R > tests/r_reference/lmm_reference.out
# It (re)writes the data sets tests/data/lmm_*.csv (deterministic: set.seed) and prints Python
# literals. Fits are converged tightly (nloptwrap BOBYQA with xtol/ftol 1e-12..1e-14) and use
# sum-to-zero contrasts, as the Python side does.
suppressPackageStartupMessages({library(lme4); library(lmerTest); library(pbkrtest); library(afex); library(emmeans)})
options(warn = -1, contrasts = c("contr.sum", "contr.poly"))
emm_options(lmer.df = "satterthwaite", msg.interaction = FALSE, msg.nesting = FALSE)
dir.create("tests/data", showWarnings = FALSE)
cat(sprintf("# ---- produced by: Rscript tests/r_reference/lmm_reference.R\n# %s, lme4 %s, lmerTest %s, pbkrtest %s, afex %s, emmeans %s\n\n",
            R.version.string, packageVersion("lme4"), packageVersion("lmerTest"), packageVersion("pbkrtest"),
            packageVersion("afex"), packageVersion("emmeans")))

fmt <- function(x) ifelse(is.na(x), "NAN", ifelse(is.infinite(x), "Inf", sprintf("%.17g", x)))
vec <- function(x) paste0("[", paste(fmt(x), collapse = ", "), "]")
strs <- function(x) paste0("[", paste0('"', x, '"', collapse = ", "), "]")
tight <- lmerControl(optimizer = "nloptwrap", calc.derivs = TRUE,
                     optCtrl = list(xtol_abs = 1e-12, ftol_abs = 1e-14, xtol_rel = 1e-12, ftol_rel = 1e-15, maxeval = 1e5))

# ---------------------------------------------------------------- data sets
# 1. crossed: every participant rates every face at every shape x material level
set.seed(30)
np <- 24; ns <- 12
d1 <- expand.grid(material = paste0("m", 1:2), shape = paste0("s", 1:3), stimulus = sprintf("face%02d", 1:ns),
                  participant = sprintf("p%02d", 1:np))[, c("participant", "stimulus", "shape", "material")]
u0 <- rnorm(np, 0, 0.8); us <- matrix(rnorm(np * 3, 0, 0.45), np, 3); w0 <- rnorm(ns, 0, 0.5)
sh <- as.integer(d1$shape) - 2
d1$rating <- round(4 + 0.6 * sh - 0.3 * (d1$material == "m2") + 0.25 * sh * (d1$material == "m2") +
  u0[as.integer(d1$participant)] + us[cbind(as.integer(d1$participant), as.integer(d1$shape))] +
  w0[as.integer(d1$stimulus)] + rnorm(nrow(d1), 0, 0.9), 4)
write.csv(d1, "tests/data/lmm_crossed.csv", row.names = FALSE, quote = FALSE)

# 2. nested: participants within labs (lab-level group factor), a within-participant condition
set.seed(31)
d2 <- expand.grid(trial = 1:6, condition = c("c1", "c2", "c3"), participant = 1:5, lab = sprintf("lab%d", 1:6))
d2$participant <- sprintf("q%d", d2$participant)  # participant codes repeat across labs: nesting by lab/participant
d2$group <- ifelse(d2$lab %in% c("lab1", "lab3", "lab5"), "g1", "g2")
lab_eff <- rnorm(6, 0, 0.7); names(lab_eff) <- sprintf("lab%d", 1:6)
pkey <- paste(d2$lab, d2$participant)
p_eff <- rnorm(length(unique(pkey)), 0, 0.5); names(p_eff) <- unique(pkey)
d2$y <- round(10 + c(c1 = 0, c2 = 0.5, c3 = 1.2)[as.character(d2$condition)] + 0.4 * (d2$group == "g2") +
  lab_eff[as.character(d2$lab)] + p_eff[pkey] + rnorm(nrow(d2), 0, 1), 4)
d2 <- d2[, c("lab", "participant", "group", "condition", "trial", "y")]
write.csv(d2, "tests/data/lmm_nested.csv", row.names = FALSE, quote = FALSE)

# 3. unbalanced with missing cells: the crossed design with 20 % of rows dropped at random and
#    two participants who never saw shape s3
set.seed(32)
d3 <- d1[sample(nrow(d1), round(0.8 * nrow(d1))), ]
d3 <- d3[!(d3$participant %in% c("p03", "p07") & d3$shape == "s3"), ]
d3 <- d3[order(d3$participant, d3$stimulus, d3$shape, d3$material), ]
write.csv(d3, "tests/data/lmm_unbalanced.csv", row.names = FALSE, quote = FALSE)

# 4. small crossed design for Kenward-Roger (pbkrtest is n x n)
set.seed(33)
d4 <- expand.grid(rep = 1:2, shape = paste0("s", 1:3), stimulus = sprintf("f%d", 1:6), participant = sprintf("r%02d", 1:12))
d4 <- d4[, c("participant", "stimulus", "shape", "rep")]
a <- rnorm(12, 0, 0.7); b <- matrix(rnorm(12 * 3, 0, 0.5), 12, 3); cst <- rnorm(6, 0, 0.5)
d4$rating <- round(4 + 0.5 * (as.integer(d4$shape) - 2) + a[as.integer(d4$participant)] +
  b[cbind(as.integer(d4$participant), as.integer(d4$shape))] + cst[as.integer(d4$stimulus)] + rnorm(nrow(d4), 0, 0.6), 4)
d4 <- d4[-c(5, 17, 40, 41, 88, 120, 151, 200, 333, 401), ]  # a few missing rows: unbalanced
write.csv(d4, "tests/data/lmm_small.csv", row.names = FALSE, quote = FALSE)

# ---------------------------------------------------------------- references
prep <- function(d, cols) { for (c in cols) d[[c]] <- factor(as.character(d[[c]]), levels = sort(unique(as.character(d[[c]])), method = "radix")); d }

lmm_ref <- function(name, formula, d, factors, emm_specs = list(), kr = FALSE) {
  d <- prep(d, factors)
  m <- lmerTest::lmer(formula, data = d, REML = TRUE, control = tight)
  mml <- lmerTest::lmer(formula, data = d, REML = FALSE, control = tight)
  co <- summary(m)$coefficients
  vc <- as.data.frame(VarCorr(m), order = "lower.tri")
  a3 <- anova(m, type = 3, ddf = "Satterthwaite")
  cat(sprintf("%s = {\n", name))
  cat(sprintf('  "formula": "%s",\n', paste(deparse(formula, width.cutoff = 500), collapse = "")))
  cat(sprintf('  "reml_deviance": %s, "ml_deviance": %s, "sigma": %s, "ml_sigma": %s,\n', fmt(REMLcrit(m)),
              fmt(deviance(mml)), fmt(sigma(m)), fmt(sigma(mml))))
  cat(sprintf('  "theta": %s, "ml_theta": %s, "singular": %s,\n', vec(getME(m, "theta")), vec(getME(mml, "theta")),
              ifelse(isSingular(m), "True", "False")))
  cat(sprintf('  "max_grad_r": %s,\n', fmt(max(abs(m@optinfo$derivs$gradient)))))
  cat(sprintf('  "coef_names": %s,\n  "beta": %s,\n  "se": %s,\n  "df_satt": %s,\n  "ml_beta": %s,\n',
              strs(rownames(co)), vec(co[, "Estimate"]), vec(co[, "Std. Error"]), vec(co[, "df"]), vec(fixef(mml))))
  cat(sprintf('  "vc_grp": %s, "vc_var1": %s, "vc_var2": %s,\n  "vc_vcov": %s, "vc_sdcor": %s,\n',
              strs(vc$grp), strs(ifelse(is.na(vc$var1), "", vc$var1)), strs(ifelse(is.na(vc$var2), "", vc$var2)),
              vec(vc$vcov), vec(vc$sdcor)))
  cat(sprintf('  "anova_terms": %s,\n  "anova_F": %s,\n  "anova_numdf": %s,\n  "anova_dendf": %s,\n  "anova_p": %s,\n',
              strs(rownames(a3)), vec(a3[["F value"]]), vec(a3$NumDF), vec(a3$DenDF), vec(a3[["Pr(>F)"]])))
  am <- afex::mixed(formula, data = d, method = "S", type = 3, control = tight, progress = FALSE, check_contrasts = TRUE)
  at <- am$anova_table
  cat(sprintf('  "afex_terms": %s,\n  "afex_F": %s,\n  "afex_dendf": %s,\n  "afex_p": %s,\n',
              strs(rownames(at)), vec(at$F), vec(at$`den Df`), vec(at$`Pr(>F)`)))
  if (kr) {
    ak <- anova(m, type = 3, ddf = "Kenward-Roger")
    ck <- summary(m, ddf = "Kenward-Roger")$coefficients
    cat(sprintf('  "kr_F": %s,\n  "kr_dendf": %s,\n  "kr_p": %s,\n  "kr_coef_df": %s,\n  "kr_coef_se": %s,\n',
                vec(ak[["F value"]]), vec(ak$DenDF), vec(ak[["Pr(>F)"]]), vec(ck[, "df"]), vec(ck[, "Std. Error"])))
  }
  for (spec in names(emm_specs)) {
    for (mode in c("satterthwaite", if (kr) "kenward-roger")) {
      e <- emmeans(m, emm_specs[[spec]], lmer.df = mode)
      es <- as.data.frame(summary(e))
      pw <- as.data.frame(summary(pairs(e, adjust = "tukey")))
      tag <- if (mode == "satterthwaite") spec else paste0(spec, "_kr")
      cat(sprintf('  "emm_%s": {"levels": %s, "emmean": %s, "SE": %s, "df": %s},\n', tag,
                  strs(apply(es[, all.vars(emm_specs[[spec]]), drop = FALSE], 1, paste, collapse = ":")),
                  vec(es$emmean), vec(es$SE), vec(es$df)))
      cat(sprintf('  "pairs_%s": {"contrast": %s, "estimate": %s, "SE": %s, "df": %s, "t": %s, "p": %s},\n', tag,
                  strs(as.character(pw$contrast)), vec(pw$estimate), vec(pw$SE), vec(pw$df), vec(pw$t.ratio), vec(pw$p.value)))
      if (length(all.vars(emm_specs[[spec]])) == 1 && nlevels(d[[all.vars(emm_specs[[spec]])]]) >= 3) {
        po <- as.data.frame(summary(contrast(e, "poly")))
        cat(sprintf('  "poly_%s": {"contrast": %s, "estimate": %s, "SE": %s, "df": %s, "t": %s, "p": %s},\n', tag,
                    strs(as.character(po$contrast)), vec(po$estimate), vec(po$SE), vec(po$df), vec(po$t.ratio), vec(po$p.value)))
      }
    }
  }
  cat("}\n\n")
}

d1 <- read.csv("tests/data/lmm_crossed.csv")
lmm_ref("R_CROSSED", rating ~ shape * material + (1 + shape | participant) + (1 | stimulus), d1,
        c("participant", "stimulus", "shape", "material"), list(shape = ~ shape, shape_material = ~ shape * material))
d2 <- read.csv("tests/data/lmm_nested.csv")
lmm_ref("R_NESTED", y ~ condition * group + (1 | lab/participant), d2, c("lab", "participant", "group", "condition"),
        list(condition = ~ condition), kr = TRUE)
d3 <- read.csv("tests/data/lmm_unbalanced.csv")
lmm_ref("R_UNBALANCED", rating ~ shape * material + (1 + shape | participant) + (1 | stimulus), d3,
        c("participant", "stimulus", "shape", "material"), list(shape = ~ shape, material = ~ material))
d4 <- read.csv("tests/data/lmm_small.csv")
lmm_ref("R_SMALL", rating ~ shape + (1 + shape | participant) + (1 | stimulus), d4,
        c("participant", "stimulus", "shape"), list(shape = ~ shape), kr = TRUE)

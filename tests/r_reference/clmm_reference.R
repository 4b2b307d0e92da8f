# Reference numbers for tests/test_stats_clmm.py (cumulative-link mixed models, ordinal::clmm).
#
# Run from the repository root:
#   Rscript tests/r_reference/clmm_reference.R > tests/r_reference/clmm_reference.out
# (a few minutes: every fit is driven to tight convergence). It (re)writes the small CSV data sets
# tests/data/clmm_*.csv (deterministic: set.seed) and prints Python dict literals.
# Tools: R 4 with ordinal (clmm: Laplace, flexible thresholds), numDeriv and emmeans (mode = "prob").
#
# Settings: sum-to-zero contrasts, factor levels sorted (the Python side's order). clmm's defaults
# stop early (nlminb on a finite-difference gradient: max|grad| ~ 1e-3), so every fit here runs with
# clmm.control(gradTol = 1e-8 (inner Newton), rel.tol = x.tol = 1e-15, abs.tol = 0) and is
# restarted at its estimates while that helps; nlminb still stops at max|grad| 1e-5 .. 1e-4. The
# references ("estimate", "loglik", "sd", "se", LR tests) are then polished by Newton steps on the
# gradient and Hessian numDeriv computes (Richardson extrapolation) of clmm's own Laplace objective
# (ordinal:::getNLA) to max|grad| ~ 1e-6 (numDeriv's own accuracy); clmm's unpolished figures are kept beside them
# ("estimate_clmm", "loglik_clmm", "sd_clmm"), as are summary(clmm)'s standard errors
# ("se_summary": its deriv12 Hessian, steps of 1e-4 on an objective with inner-Newton noise, ~1e-4
# relative) and drop1's rows (clmm's default stopping). Comment lines give each model's gradients.
suppressPackageStartupMessages({library(ordinal); library(numDeriv); library(emmeans)})
options(warn = -1, contrasts = c("contr.sum", "contr.poly"))
dir.create("tests/data", showWarnings = FALSE)

fmt <- function(x) ifelse(is.na(x), "NAN", sprintf("%.17g", x))
q <- function(s) shQuote(s, "cmd")
sorted_factors <- function(d, cols) {
  for (c in cols) d[[c]] <- factor(as.character(d[[c]]), levels = sort(unique(as.character(d[[c]])), method = "radix"))
  d
}
CTRL <- clmm.control(gradTol = 1e-8, rel.tol = 1e-15, x.tol = 1e-15, abs.tol = 0, eval.max = 10000,
                     iter.max = 10000, innerCtrl = "noWarn")
# With a single random-intercept term clmm takes its C code path ("ssr", NRalgv3), whose Laplace
# determinant uses the Hessian of the last-but-one Newton iterate of the conditional modes (hess()
# runs before each step; the loop ends on the gradient test): its log-likelihood is off by ~5e-6
# (dataset 3). useMatrix = TRUE takes clmm's R code path (clmm.fit.env, the one every model with
# two or more terms takes), whose determinant is at the modes: that is the reference for such models,
# with the default path's figures kept as "*_clmm" (and its log-SD scale for cond.H).
CTRL_M <- CTRL; CTRL_M$useMatrix <- TRUE

# ---------------------------------------------------------------- data sets
# 1. crossed: 24 participants x 12 stimuli (face identities) x shape (3) x material (2), 7-point, logit
set.seed(11)
d1 <- expand.grid(material = c("matte", "glossy"), shape = c("s0", "s50", "s100"), stimulus = sprintf("f%02d", 1:12),
                  participant = sprintf("p%02d", 1:24))[, 4:1]
up <- rnorm(24, 0, 0.9); us <- rnorm(12, 0, 0.5)
eta <- c(s0 = -0.5, s50 = 0.2, s100 = 0.6)[as.character(d1$shape)] + 0.3 * (d1$material == "glossy") +
  0.3 * (d1$shape == "s100") * (d1$material == "glossy") + up[as.integer(d1$participant)] + us[as.integer(d1$stimulus)]
d1$rating <- findInterval(eta + rlogis(nrow(d1)), c(-2.2, -1.2, -0.4, 0.4, 1.3, 2.3)) + 1
write.csv(d1, "tests/data/clmm_crossed.csv", row.names = FALSE, quote = FALSE)

# 2. nested, probit: 4 sites / 6 participants each (labels p1..p6 repeat across sites), group between
#    participants, style (4 levels) within, 10 repetitions, 5-point
set.seed(12)
d2 <- expand.grid(rep = 1:10, style = c("cartoon", "painted", "photo", "sketch"), participant = paste0("p", 1:6),
                  site = c("lab_a", "lab_b", "lab_c", "lab_d"))[, c("site", "participant", "style", "rep")]
d2$group <- ifelse(as.integer(d2$participant) %% 2 == 0, "expert", "novice")
usite <- rnorm(4, 0, 0.5); upart <- rnorm(24, 0, 0.7)
pid <- (as.integer(d2$site) - 1) * 6 + as.integer(d2$participant)
eta <- c(cartoon = 0.3, painted = 0, photo = -0.4, sketch = 0.1)[as.character(d2$style)] +
  0.25 * (d2$group == "expert") - 0.3 * (d2$group == "expert") * (d2$style == "photo") +
  usite[as.integer(d2$site)] + upart[pid]
d2$rating <- findInterval(eta + rnorm(nrow(d2)), c(-1.3, -0.4, 0.5, 1.4)) + 1
d2 <- d2[, c("site", "participant", "group", "style", "rating")]
write.csv(d2, "tests/data/clmm_nested_probit.csv", row.names = FALSE, quote = FALSE)

# 3. one random term (clmm's single-term code path, log SD), a numeric covariate, and a 7-point
#    scale on which no one answered 4 or 7 (clmm drops the empty categories: thresholds 3|5 ...)
set.seed(13)
d3 <- expand.grid(trial = 1:20, participant = sprintf("s%02d", 1:30))[, 2:1]
d3$expression <- ifelse(d3$trial %% 2 == 0, "happy", "angry")
d3$luminance <- rep(c(0.2, 0.4, 0.6, 0.8), length.out = nrow(d3))  # (not "contrast": emmeans mislabels it)
d3$trial <- NULL
eta <- 0.6 * (d3$expression == "happy") + 1.2 * (d3$luminance - 0.5) + rnorm(30, 0, 1)[as.integer(factor(d3$participant))]
r <- findInterval(eta + rlogis(nrow(d3)), c(-2, -1, -0.3, 0.3, 1, 2.2)) + 1
r[r == 4] <- ifelse(runif(sum(r == 4)) < 0.5, 3, 5)
r[r == 7] <- 6
d3$rating <- r
write.csv(d3, "tests/data/clmm_missing_category.csv", row.names = FALSE, quote = FALSE)

# ---------------------------------------------------------------- references
# the Laplace objective -logLik(par) of a model (par as clmm's optimiser sees it) and its rho
objective <- function(formula, d, link, ctrl = CTRL) {
  rho <- clmm(formula, data = d, link = link, control = ctrl, doFit = FALSE)
  # one random-intercept term: clmm's "ssr" code (par = thresholds, beta, log SD); else the SDs
  fn <- if (!is.null(rho$par)) function(p) ordinal:::getNLA.ssr(rho, p) else function(p) ordinal:::getNLA(rho, p)
  list(fn = fn, rho = rho, ssr = !is.null(rho$par))
}
# gradients by numDeriv's Richardson extrapolation from steps of 1e-2 down to 3e-4 (relative): the
# objective has ~1e-11 of rounding noise, which its default steps (1e-4 down to 1e-5) amplify to
# ~1e-5; Hessians with its defaults (those larger steps make them worse, ~1e-4 relative)
ND <- list(eps = 1e-4, d = 0.01, r = 6, v = 2)
ngrad <- function(fn, x) numDeriv::grad(fn, x, method.args = ND)
nhess <- function(fn, x) numDeriv::hessian(fn, x)

# clmm, restarted at its own estimates while that lowers max|grad| (nlminb stops on its
# finite-difference gradient), then polished by Newton steps on numDeriv's (Richardson) gradient and
# Hessian of the same objective: "par" is the maximiser of clmm's Laplace likelihood to ~1e-8
fit_ref <- function(formula, d, link, ctrl = CTRL) {
  # the first call names global objects only, so that drop1's update() can re-evaluate it
  assign(".d", d, envir = globalenv())
  fit0 <- eval(bquote(clmm(.(formula), data = .d, link = .(link), control = .(ctrl))), globalenv())
  ob <- objective(formula, d, link, ctrl); fn <- ob$fn
  fit <- fit0; g <- ngrad(fn, fit$optRes$par)
  for (i in 1:3) {
    par <- fit$optRes$par; nf <- fit$dims$nfepar
    st <- if (ob$ssr) par else list(par[1:nf], par[-(1:nf)])
    f2 <- clmm(formula, data = d, link = link, control = ctrl, start = st)
    g2 <- ngrad(fn, f2$optRes$par)
    if (max(abs(g2)) >= max(abs(g))) break
    fit <- f2; g <- g2
  }
  par <- fit$optRes$par; grad_clmm <- g
  H <- nhess(fn, par)
  # Newton steps while the gradient is above numDeriv's noise (~3e-6 here; an objective test
  # cannot see a step's ~1e-12 gain through the objective's ~1e-11 rounding noise)
  for (i in 1:3) {
    if (max(abs(g)) < 2e-6) break
    p2 <- par - solve(H, g); g2 <- ngrad(fn, p2)
    if (max(abs(g2)) > 10 * max(abs(g))) break
    par <- p2; g <- g2; H <- nhess(fn, par)
  }
  list(fit0 = fit0, fit = fit, par = par, loglik = -fn(par), grad = g, grad_clmm = grad_clmm, H = H, V = solve(H),
       ob = ob)
}

# groups: Python group name of each of clmm's random terms (clmm orders them by number of levels)
clmm_ref <- function(name, formula, d, link, groups, emm = list(), lr_terms = NULL, ranef = FALSE) {
  single <- length(lme4::findbars(formula)) == 1 && !grepl("/", deparse(formula))
  ctrl <- if (single) CTRL_M else CTRL
  r <- fit_ref(formula, d, link, ctrl)
  fit <- if (single) fit_ref(formula, d, link, CTRL)$fit else r$fit   # clmm's default code path
  s <- summary(fit)
  nf <- fit$dims$nfepar; na <- fit$dims$nalpha; par <- r$par
  se <- sqrt(diag(r$V))[1:nf]
  sd <- if (r$ob$ssr) exp(par[-(1:nf)]) else par[-(1:nf)]
  Hc <- r$H  # cond.H in clmm's default parametrisation: log SD for a single term
  if (single) { j <- nf + 1; Hc[j, ] <- Hc[j, ] * sd; Hc[, j] <- Hc[, j] * sd; Hc[j, j] <- Hc[j, j] + r$grad[j] * sd }
  cat(sprintf("# %s: clmm: nlminb %s, max|grad| %.2g (numDeriv; clmm's own figure %.2g); polished: max|grad| %.2g\n",
              name, fit$optRes$message, max(abs(r$grad_clmm)), max(abs(fit$gradient)), max(abs(r$grad))))
  cat(sprintf("%s = {\n", name))
  cat(sprintf("    \"loglik\": %s, \"loglik_clmm\": %s, \"aic\": %s, \"n\": %d, \"edf\": %d,\n", fmt(r$loglik),
              fmt(fit$logLik), fmt(-2 * r$loglik + 2 * fit$edf), fit$dims$nobs, fit$edf))
  ev <- eigen(Hc, only.values = TRUE)$values
  cat(sprintf("    \"cond_H\": %s, \"cond_H_summary\": %s,\n", fmt(abs(max(ev) / min(ev))), fmt(s$condHess)))
  cat("    \"coef\": {\n")
  for (i in seq_len(nf)[-seq_len(na)]) {
    z <- par[i] / se[i]
    cat(sprintf("        %s: {\"estimate\": %s, \"se\": %s, \"z\": %s, \"p\": %s, \"estimate_clmm\": %s, \"se_summary\": %s},\n",
                q(names(fit$coefficients)[i]), fmt(par[i]), fmt(se[i]), fmt(z), fmt(2 * pnorm(-abs(z))),
                fmt(fit$coefficients[i]), fmt(s$coefficients[i, 2])))
  }
  cat("    },\n    \"thresholds\": {\n")
  for (i in seq_len(na))
    cat(sprintf("        %s: {\"estimate\": %s, \"se\": %s, \"estimate_clmm\": %s, \"se_summary\": %s},\n",
                q(names(fit$coefficients)[i]), fmt(par[i]), fmt(se[i]), fmt(fit$coefficients[i]), fmt(s$coefficients[i, 2])))
  cat("    },\n")
  vc <- VarCorr(fit)
  cat(sprintf("    \"sd\": {%s},\n", paste(sprintf("%s: %s", q(groups[names(vc)]), fmt(sd)), collapse = ", ")))
  cat(sprintf("    \"sd_clmm\": {%s},\n", paste(sprintf("%s: %s", q(groups[names(vc)]),
                                                      fmt(sapply(vc, function(v) attr(v, "stddev")))), collapse = ", ")))
  # the fit with the polished parameters (for ranef and emmeans)
  fitp <- fit
  fitp$coefficients[] <- par[1:nf]
  fitp$alpha[] <- par[seq_len(na)]
  if (nf > na) fitp$beta[] <- par[(na + 1):nf]
  if (ranef) {  # conditional modes at the polished parameters (as clmm.fit.env computes them)
    rho <- r$ob$rho; r$ob$fn(par)
    fitp$ranef <- rep.int(unlist(rho$ST), rho$dims$nlev.re) * rho$u
    fitp$condVar <- as.vector(Matrix::diag(Matrix::solve(rho$L)) * rep.int(unlist(rho$ST)^2, rho$dims$nlev.re))
    re <- ranef(fitp, condVar = TRUE)
    cat("    \"ranef\": {\n")
    for (g in names(re)) {
      cv <- attr(re[[g]], "condVar")[, 1]
      cat(sprintf("        %s: {%s},\n", q(groups[[g]]),
                  paste(sprintf("%s: (%s, %s)", q(rownames(re[[g]])), fmt(re[[g]][, 1]), fmt(cv)), collapse = ", ")))
    }
    cat("    },\n")
  }
  # predicted probabilities (random effects 0): emmeans, mode = "prob", with the accurate vcov
  for (spec in names(emm)) {
    e <- as.data.frame(summary(emmeans(fitp, emm[[spec]], mode = "prob", vcov. = r$V)))
    e$rating <- fit$y.levels[as.integer(e$rating)]  # emmeans numbers the categories 1..J (3|5: 4 is 5)
    vars <- all.vars(emm[[spec]])
    keys <- apply(e[, vars, drop = FALSE], 1, function(row) paste(trimws(as.character(row)), collapse = ":"))
    cat(sprintf("    %s: {\n", q(spec)))
    cat(paste(sprintf("        %s: (%s, %s),\n", q(keys), fmt(e$prob), fmt(e$SE)), collapse = ""))
    cat("    },\n")
  }
  # likelihood-ratio tests: refits without each term's columns of the sum-coded design (type III)
  if (!is.null(lr_terms)) {
    ff <- lme4::nobars(formula)
    X <- model.matrix(ff, d)
    asg <- attr(X, "assign"); tl <- attr(terms(ff), "term.labels")
    X <- X[, -1, drop = FALSE]; asg <- asg[-1]
    colnames(X) <- paste0("X", seq_len(ncol(X)))
    dd <- cbind(d, X)
    bars <- paste(sapply(lme4::findbars(formula), function(b) paste0("(", deparse(b), ")")), collapse = " + ")
    cat("    \"lr\": {\n")
    for (k in seq_along(tl)) {
      keep <- colnames(X)[asg != k]
      f0 <- as.formula(paste(all.vars(formula)[1], "~", paste(c(keep, bars), collapse = " + ")))
      r0 <- fit_ref(f0, dd, link, ctrl)
      lr <- 2 * (r$loglik - r0$loglik); df <- sum(asg == k)
      cat(sprintf("        %s: {\"df\": %d, \"loglik\": %s, \"aic\": %s, \"lr_chisq\": %s, \"p\": %s},\n", q(tl[k]), df,
                  fmt(r0$loglik), fmt(-2 * r0$loglik + 2 * r0$fit$edf), fmt(lr), fmt(pchisq(lr, df, lower.tail = FALSE))))
    }
    cat("    },\n")
    assign(".d", d, envir = globalenv())
    dr <- drop1(r$fit0, test = "Chisq")  # clmm's own fits (not restarted, not polished)
    cat("    \"drop1\": {\n")
    for (t in rownames(dr)[-1])
      cat(sprintf("        %s: {\"df\": %d, \"aic\": %s, \"lr_chisq\": %s, \"p\": %s},\n", q(t), as.integer(dr[t, "Df"]),
                  fmt(dr[t, "AIC"]), fmt(dr[t, "LRT"]), fmt(dr[t, "Pr(>Chi)"])))
    cat("    },\n")
  }
  cat("}\n\n")
  invisible(fit)
}

cat("# ---- produced by: Rscript tests/r_reference/clmm_reference.R > tests/r_reference/clmm_reference.out\n")
cat(sprintf("# R %s, ordinal %s, Matrix %s, numDeriv %s, emmeans %s\n\n", getRversion(), packageVersion("ordinal"),
            packageVersion("Matrix"), packageVersion("numDeriv"), packageVersion("emmeans")))

d <- sorted_factors(d1, c("participant", "stimulus", "shape", "material"))
d$rating <- factor(d$rating, levels = 1:7, ordered = TRUE)
clmm_ref("R_CLMM_CROSSED", rating ~ shape * material + (1 | participant) + (1 | stimulus), d, "logit",
         c(participant = "participant", stimulus = "stimulus"),
         emm = list(`shape:material` = ~ shape * material | rating, shape = ~ shape | rating), lr_terms = TRUE,
         ranef = TRUE)
clmm_ref("R_CLMM_CROSSED_ADDITIVE", rating ~ shape + material + (1 | participant) + (1 | stimulus), d, "logit",
         c(participant = "participant", stimulus = "stimulus"), lr_terms = TRUE)

d <- sorted_factors(d2, c("site", "participant", "group", "style"))
d$rating <- factor(d$rating, levels = 1:5, ordered = TRUE)
f2 <- rating ~ group * style + (1 | site/participant)
nm <- names(VarCorr(clmm(f2, data = d, link = "probit")))
clmm_ref("R_CLMM_NESTED_PROBIT", f2, d, "probit", setNames(ifelse(grepl(":", nm), "site:participant", "site"), nm),
         emm = list(`group:style` = ~ group * style | rating), lr_terms = TRUE)

d <- sorted_factors(d3, c("participant", "expression"))
d$rating <- factor(d$rating, levels = 1:7, ordered = TRUE)
clmm_ref("R_CLMM_MISSING_CATEGORY", rating ~ expression + luminance + (1 | participant), d, "logit",
         c(participant = "participant"), emm = list(expression = ~ expression | rating), lr_terms = TRUE)

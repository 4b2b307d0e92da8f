# Reference numbers for tests/test_stats_reference.py: a reference condition (photographs rated at
# the end of a session) against the matched shape/material levels (thesis section 6.4), per
# participant means, paired t-tests and Holm's adjustment, with base R only.
#
# Run from the repository root:
#   Rscript tests/r_reference/reference_comparison_reference.R > tests/r_reference/reference_comparison_reference.out
# It (re)writes tests/data/stats_reference.csv (deterministic: set.seed) and prints Python literals.
set.seed(21)
shape <- c("1.0", "0.5", "0.0")
material <- c("flat", "blur50", "original")
ids <- sprintf("s%02d", 1:7)
main <- expand.grid(rep = 1:2, material = material, shape = shape, id = ids, stringsAsFactors = FALSE)
main$phase <- "main"
main$rating <- round(pmin(7, pmax(1, 2 + 1.2 * (match(main$shape, rev(shape)) - 1)
                                  + 0.5 * (match(main$material, material) - 1) + rnorm(nrow(main), 0, 1))), 3)
photo <- expand.grid(rep = 1:2, id = ids, stringsAsFactors = FALSE)
photo$shape <- "photograph"; photo$material <- "photograph"; photo$phase <- "end"
photo$rating <- round(pmin(7, 5 + rnorm(nrow(photo), 0, 0.8)), 3)
photo <- photo[photo$id != "s07", ]  # one participant never rated the photographs
all <- rbind(main[, c("id", "phase", "shape", "material", "rating")], photo[, c("id", "phase", "shape", "material", "rating")])
names(all)[1] <- "participant_id"
write.csv(all, "tests/data/stats_reference.csv", row.names = FALSE, quote = FALSE)

fmt <- function(x) ifelse(is.na(x), "NAN", sprintf("%.12g", x))
ref <- tapply(photo$rating, photo$id, mean)
cat("R_REFERENCE = {\n")
cat(sprintf("  'photograph': {'mean': %s, 'sd': %s, 'n': %d},\n", fmt(mean(ref)), fmt(sd(ref)), length(ref)))
ps <- c(); rows <- list()
for (i in seq_along(shape)) {
  sel <- main$shape == shape[i] & main$material == material[i]
  lev <- tapply(main$rating[sel], main$id[sel], mean)
  both <- intersect(names(ref), names(lev))
  tt <- t.test(ref[both], lev[both], paired = TRUE)
  ps <- c(ps, tt$p.value)
  rows[[i]] <- c(mean(lev), sd(lev), length(lev), mean(ref[both] - lev[both]), tt$statistic, tt$parameter, tt$p.value)
}
holm <- p.adjust(ps, method = "holm")
for (i in seq_along(shape)) {
  r <- rows[[i]]
  cat(sprintf("  'shape %s / material %s': {'mean': %s, 'sd': %s, 'n': %d, 'diff': %s, 't': %s, 'df': %s, 'p': %s, 'p_holm': %s},\n",
              shape[i], material[i], fmt(r[1]), fmt(r[2]), as.integer(r[3]), fmt(r[4]), fmt(r[5]), fmt(r[6]), fmt(r[7]), fmt(holm[i])))
}
cat("}\n")

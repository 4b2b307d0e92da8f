"""Psychometric fits (issue 34): maximum-likelihood and psignifit-style Bayesian fits, a tidy table.

The functions, simulated observers and adaptive procedures live in the core
(:mod:`appeal.psychophysics`), because the runtime that runs a procedure uses them too; they are
re-exported here for the analyst.

* :mod:`~analysis.psychometric.fit` – maximum-likelihood and psignifit-style Bayesian fits, a tidy
  table.
* :mod:`~analysis.psychometric.priors` – psignifit 4's default priors.
"""

from analysis.psychometric.fit import FitResult, fit_bayes, fit_ml, fit_table
from appeal.psychophysics import (FAMILIES, ConstantStimuli, PsiProcedure, SimulatedObserver, UpDownStaircase,
                                  constant_stimuli, psi, psi_inverse, run_procedure, sigmoid)

__all__ = ["FAMILIES", "psi", "psi_inverse", "sigmoid", "FitResult", "fit_ml", "fit_bayes", "fit_table",
           "SimulatedObserver", "constant_stimuli", "PsiProcedure", "UpDownStaircase", "ConstantStimuli",
           "run_procedure"]

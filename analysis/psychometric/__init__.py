"""Psychometric functions, fits, simulated observers and adaptive procedures (issue 34's maths).

Pure functions and small classes; nothing here touches files, the CLI or the PsychoPy runtime.

* :mod:`~analysis.psychometric.functions` – logistic, cumulative Gaussian and Weibull families in
  psignifit 4's threshold/width parameterisation.
* :mod:`~analysis.psychometric.fit` – maximum-likelihood and psignifit-style Bayesian fits, a tidy
  table.
* :mod:`~analysis.psychometric.observers` – simulated observers, the method of constant stimuli.
* :mod:`~analysis.psychometric.adaptive` – the psi method and a transformed up–down staircase.
"""

from analysis.psychometric.adaptive import PsiProcedure, UpDownStaircase, run_procedure
from analysis.psychometric.fit import FitResult, fit_bayes, fit_ml, fit_table
from analysis.psychometric.functions import FAMILIES, psi, psi_inverse, sigmoid
from analysis.psychometric.observers import SimulatedObserver, constant_stimuli

__all__ = ["FAMILIES", "psi", "psi_inverse", "sigmoid", "FitResult", "fit_ml", "fit_bayes", "fit_table",
           "SimulatedObserver", "constant_stimuli", "PsiProcedure", "UpDownStaircase", "run_procedure"]

"""Psychometric fits (issue 34): maximum-likelihood and psignifit-style Bayesian fits, a tidy table.

The functions, simulated observers and adaptive procedures live in the core
(:mod:`appeal.psychophysics`), because the runtime that runs a procedure uses them too; they are
re-exported here for the analyst.

* :mod:`~analysis.psychometric.fit` – maximum-likelihood and psignifit-style Bayesian fits, a tidy
  table.
* :mod:`~analysis.psychometric.map_search` – the MAP polish: a bounded, restarted simplex with a budget.
* :mod:`~analysis.psychometric.priors` – psignifit 4's default priors.
* :mod:`~analysis.psychometric.schema` – the ``kind: psychometric`` analysis file.
* :mod:`~analysis.psychometric.study` – ``appeal analyze psychometric``: fits per participant and
  condition, pooled fits, the comparison of thresholds, figures (:mod:`~analysis.psychometric.figures`)
  and the report.
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["figures", "fit", "map_search", "planning", "priors", "schema", "study"],
    submod_attrs={
        "fit": ["FitResult", "fit_bayes", "fit_ml", "fit_table"],
        "schema": ["PsychometricAnalysis"],
        "study": ["PsychometricResult", "analyze_psychometric_study", "read_trials"],
    },
)
from appeal.psychophysics import (FAMILIES, ConstantStimuli, PsiProcedure, SimulatedObserver, UpDownStaircase,
                                  constant_stimuli, psi, psi_inverse, run_procedure, sigmoid)

__all__ = ["FAMILIES", "psi", "psi_inverse", "sigmoid", "FitResult", "fit_ml", "fit_bayes", "fit_table",
           "SimulatedObserver", "constant_stimuli", "PsiProcedure", "UpDownStaircase", "ConstantStimuli",
           "run_procedure", "PsychometricAnalysis", "PsychometricResult", "analyze_psychometric_study", "read_trials"]

"""Psychometric functions, simulated observers and adaptive procedures: what the runtime that
runs a psychophysical procedure and the analysis that fits its answers must agree on.

* :mod:`~appeal.psychophysics.functions` – logistic, cumulative Gaussian and Weibull families in
  psignifit 4's threshold/width parameterisation.
* :mod:`~appeal.psychophysics.observers` – simulated observers, the method of constant stimuli.
* :mod:`~appeal.psychophysics.procedures` – the psi method, a transformed up–down staircase and
  the method of constant stimuli as procedures that pick each next level, with their state.
* :mod:`~appeal.psychophysics.states` – the schema a state read back from a data file is checked
  against before a procedure is built from it (bounded sizes, plain JSON, nothing executed).
* :mod:`~appeal.psychophysics.continuum` – finding a level among a continuum's levels.
* :mod:`~appeal.psychophysics.intervals` – credible intervals from a grid posterior.
"""

from appeal.psychophysics.functions import FAMILIES, psi, psi_inverse, sigmoid
from appeal.psychophysics.intervals import credible_interval
from appeal.psychophysics.observers import SimulatedObserver, constant_stimuli
from appeal.psychophysics.procedures import (ConstantStimuli, PsiProcedure, UpDownStaircase, procedure_from_dict,
                                             procedure_from_json, run_procedure)

__all__ = ["FAMILIES", "psi", "psi_inverse", "sigmoid", "credible_interval", "SimulatedObserver", "constant_stimuli",
           "ConstantStimuli", "PsiProcedure", "UpDownStaircase", "procedure_from_dict", "procedure_from_json",
           "run_procedure"]

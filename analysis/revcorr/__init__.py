"""Reverse-correlation analysis (issue 53): each participant's AU model of each expression.

* :mod:`~analysis.revcorr.models` – mutual information between AU presence and the answer, its
  permutation test corrected across AUs, the logistic classification image, recovery of known models.
* :mod:`~analysis.revcorr.planning` – trials needed: recovery of simulated participants' known models
  as the number of trials grows.
* :mod:`~analysis.revcorr.levels` – whether a stimulus level changes the models (mixed models of MI,
  each participant's changes).
* :mod:`~analysis.revcorr.trials` – the trials table, read and checked (hostile input).
* :mod:`~analysis.revcorr.study` – ``appeal analyze revcorr``: models per participant x level,
  temporal profiles, consensus, figures and the report.
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["levels", "models", "planning", "study", "trials"],
    submod_attrs={
        "levels": ["level_agreement", "level_effects"],
        "models": ["au_models", "logistic_image", "mi_permutation_test", "model_recovery", "mutual_information"],
        "planning": ["expected_models", "recovery_table", "simulate_participant"],
        "study": ["RevcorrResult", "analyze_revcorr"],
        "trials": ["RevcorrTrials", "read_revcorr_trials", "simulated_table"],
    },
)

"""Reverse correlation of facial expressions (Jack et al. 2012): what the stimulus engine, the
runtime and the analysis must agree on.

* :mod:`~appeal.revcorr.grammar` – the generative grammar: the rigs' FACS action units, random
  trials (1-6 AUs, six temporal parameters each) drawn from seeds, their time courses.
* :mod:`~appeal.revcorr.observers` – simulated participants with a known AU model per emotion.
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["grammar", "observers"],
    submod_attrs={
        "grammar": ["ACTION_UNITS", "AuMotion", "Trial", "action_units", "au_curve", "draw_trial", "draw_trials",
                    "presence_matrix", "trial_curves"],
        "observers": ["DONT_KNOW", "EMOTIONS", "PROTOTYPES", "TemplateObserver", "amplitude_matrix"],
    },
)

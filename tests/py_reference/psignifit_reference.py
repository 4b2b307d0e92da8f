"""psignifit 4's MAP threshold and width on the simulated data sets of tests/test_psychometric.py.

psignifit (PyPI, GPL-3) is a test dependency of Appeal Lab only (never imported by the package);
this script is run by hand and its output is committed beside it:

    python tests/py_reference/psignifit_reference.py > tests/py_reference/psignifit_reference.out

The tests compare our fits with these numbers, so the agreement is checked on every run even
where psignifit is missing; psignifit_agreement.py adds its posterior's true mode and intervals.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from test_psychometric import PSIGNIFIT_CASES, _psignifit_case  # noqa: E402


def main() -> None:
    import psignifit as ps

    out = {}
    for family, nafc in PSIGNIFIT_CASES:
        d = _psignifit_case(family, nafc)
        if family == "weibull":  # psignifit 4.3's Weibull is a Gumbel on whatever axis it is given
            d = d.copy()
            d[:, 0] = np.log(d[:, 0])
        res = ps.psignifit(d, sigmoid=family, experiment_type="2AFC" if nafc else "yes/no")
        est = dict(res.parameter_estimate_MAP)
        out[f"{family}-{nafc or 'yesno'}"] = {k: float(est[k]) for k in ("threshold", "width")}
    from importlib.metadata import version

    print(f"# psignifit {version('psignifit')}: MAP threshold and width")
    print(f"PSIGNIFIT = {out!r}")


if __name__ == "__main__":
    main()

"""Demo stage 0: the software this demo ran with."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from appeal.demo import DemoStage
from appeal.provenance import package_versions
from appeal.report import ReportSection


def _run(out: Path, seed: int) -> ReportSection:
    versions = package_versions()
    table = out / "versions.csv"
    pd.DataFrame({"package": list(versions), "version": [v or "not installed" for v in versions.values()]}).to_csv(table, index=False)
    return ReportSection(title="Environment", text=f"Seed: {seed}. Package versions used by this run:", tables=[table])


STAGE = DemoStage(name="environment", title="Environment", order=0, run=_run)

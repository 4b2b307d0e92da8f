"""The audit's outputs, shared by ``appeal stimuli audit``, ``appeal stimuli grid`` and the demo.

:func:`write_audit` measures a checked stimulus set (:mod:`stimulus_engine.audit`), tests the
measures against the design (:mod:`analysis.confounds`) and writes the tables, figures and
report; :func:`write_grid_page` writes a rendered grid's ``index.html``: its contact sheets and
what its audit found to differ between levels.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from appeal.cells import write_table

if TYPE_CHECKING:  # pandas loads when the audit runs, not with every command's --help
    import pandas as pd

__all__ = ["AuditOutputs", "write_audit", "write_grid_page"]


@dataclass(frozen=True)
class AuditOutputs:
    """What :func:`write_audit` wrote: the tables, the tests and the files."""

    table: pd.DataFrame
    tests: pd.DataFrame
    paired: dict[str, str]
    folder: Path
    report_html: Path

    @property
    def n_flagged(self) -> int:
        """How many factor × measure pairs differ beyond their thresholds."""
        return int(self.tests["flagged"].astype(bool).sum()) if not self.tests.empty else 0

    def summary(self) -> str:
        """One line for the terminal."""
        n_warn = int((self.table["warning"].fillna("") != "").sum())
        n_none = int((self.table["mask"] == "none").sum()) if "mask" in self.table else 0
        flags = (f"{self.n_flagged} factor x measure pairs differ beyond their thresholds" if not self.tests.empty
                 else "no factors to test")
        return (f"{len(self.table)} images audited: {self.folder / 'audit.csv'}; {flags}; report {self.report_html}"
                + (f"; {n_none} without a face (whole-image measures only)" if n_none else "")
                + (f"; {n_warn - n_none} without eye positions (see the warning column)" if n_warn > n_none else ""))


def write_audit(job, out: Path, *, thresholds: Mapping[str, float] | None = None,
                item: Sequence[str] | None = None) -> AuditOutputs:
    """Audit ``job`` (:func:`stimulus_engine.audit.workflow.read_audit_inputs`) into ``out``.

    Writes ``audit.csv`` (one row per image), ``audit.png`` (means per level), and with factors
    ``design_tests.csv`` (:func:`analysis.confounds.design_tests`), ``level_means.csv`` and
    ``flags.png``; then ``report.md`` and ``report.html``.
    """
    from analysis.confounds import design_tests, level_means
    from analysis.confounds.report import plot_flags, write_report
    from stimulus_engine.audit.workflow import (audit_factors, declared_factors, paired_factors, plot_audit,
                                                 run_audit)

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    table = run_audit(job)
    write_table(table, out / "audit.csv")
    factors = audit_factors(table)
    paired = paired_factors(table, declared_factors(table))
    figures = [plot_audit(table, out / "audit.png", factors)]
    tables = [out / "audit.csv"]
    if factors != ["file"]:
        tests = design_tests(table, factors, thresholds=thresholds, item=item)
        write_table(tests, out / "design_tests.csv")
        write_table(level_means(table, factors, tests["measure"].unique()), out / "level_means.csv")
        figures.insert(0, plot_flags(tests, out / "flags.png"))
        tables = [out / "design_tests.csv", out / "level_means.csv", *tables]
    else:
        import pandas as pd

        tests = pd.DataFrame()
    _, html = write_report(out, table, tests, source=str(job.source), figures=figures, tables=tables, paired=paired,
                           thresholds_set=thresholds)
    return AuditOutputs(table, tests, paired, out, html)


def write_grid_page(out: Path, sheets: Sequence[Path], audit: AuditOutputs | None, title: str) -> Path:
    """``out/index.html``: the grid's contact sheets and measures, and (with an audit) which image
    measures differ between its levels, linking the audit's report."""
    from appeal.report import ReportSection, write_index_html
    from analysis.confounds.report import findings_markdown

    sections = []
    if audit is not None and not audit.tests.empty:
        text = (findings_markdown(audit.tests, audit.paired)
                + f"\n\nThe audit's report: [{audit.report_html.relative_to(out)}]({audit.report_html.relative_to(out)}).")
        sections.append(ReportSection("What differs between levels (stimulus audit)", text,
                                      figures=[audit.folder / "flags.png"]))
    elif audit is not None:
        sections.append(ReportSection("Stimulus audit", links=[audit.report_html]))
    else:
        sections.append(ReportSection("Stimulus audit", "Not run (--no-audit): `appeal stimuli audit DIR --out DIR/audit`."))
    sheets = [Path(s) for s in sheets]
    sections.append(ReportSection("Contact sheets", figures=[s for s in sheets if s.suffix == ".png"
                                                               and s.name.startswith(("contact", "filmstrip"))]))
    rest = [s for s in sheets if s.suffix == ".png" and not s.name.startswith(("contact", "filmstrip"))]
    if rest:
        sections.append(ReportSection("Measures", figures=rest,
                                      tables=[s.with_suffix(".csv") for s in rest if s.with_suffix(".csv").is_file()]))
    sections.append(ReportSection("Files", links=[p for p in (out / "manifest.csv", out / "landmarks.csv") if p.is_file()]))
    return write_index_html(out / "index.html", title, sections)

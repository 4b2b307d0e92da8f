"""The end-to-end demo: stages run in order, each writing into its own folder.

A stage is registered by a module in ``appeal_cli/demo_stages/`` that defines
``STAGE = DemoStage(...)``. This module only knows how to run stages and write the page.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from appeal.logs import logger
from appeal.provenance import now_iso
from appeal.report import ReportSection, write_index_html

__all__ = ["DemoStage", "run_demo"]


@dataclass(frozen=True)
class DemoStage:
    """One demo stage.

    Attributes
    ----------
    name : str
        Short name; also the stage's sub-folder of the demo output.
    title : str
        Heading on the report page.
    order : int
        Stages run in increasing order (stimuli 100s, experiments 200s, analysis 300s).
    run : callable
        ``run(out_dir, seed) -> ReportSection``; writes only below ``out_dir``. It may read
        earlier stages' outputs through ``out_dir.parent / <their name>``.
    """

    name: str
    title: str
    order: int
    run: Callable[[Path, int], ReportSection]


def missing_data(title: str, needs: Sequence[str], what: str, stage: str) -> ReportSection | None:
    """The section of a stage whose registered datasets ``needs`` are not all on this machine:
    ``what`` it would show, which datasets are missing and the command that fetches them (None
    when all are there)."""
    from appeal.datasets import find_dataset

    missing = [n for n in needs if find_dataset(n) is None]
    if not missing:
        return None
    return ReportSection(title=title, text=(
        f"Not shown: {what} and needs the datasets {', '.join(missing)}, which are not on this machine. "
        f"Fetch them with `appeal data fetch {' '.join(missing)}` and run `appeal demo --only {stage}` again."))


def run_demo(stages: Sequence[DemoStage], out: Path, seed: int) -> tuple[Path, list[ReportSection]]:
    """Run ``stages`` in order into ``out`` and write ``out/index.html``.

    A failing stage is reported on the page and the remaining stages still run.

    Returns
    -------
    index : Path
        The report page.
    sections : list of ReportSection
        One per stage; ``failed`` is set for stages that raised.
    """
    sections = []
    for stage in sorted(stages, key=lambda s: (s.order, s.name)):
        stage_dir = out / stage.name
        stage_dir.mkdir(parents=True, exist_ok=True)
        logger.info("demo stage '%s' ...", stage.name)
        started = now_iso()
        try:
            section = stage.run(stage_dir, seed)
        except Exception as exc:  # noqa: BLE001 - reported on the page and in the exit code
            logger.exception("demo stage '%s' failed", stage.name)
            section = ReportSection(title=stage.title, failed=f"{type(exc).__name__}: {exc}".splitlines()[0])
        section.note = f"stage '{stage.name}' started {started}, ended {now_iso()}"
        sections.append(section)
    intro = ("The end-to-end demo of Appeal Lab on its embedded default assets. "
             "Each section below is one stage; every file it wrote is linked. "
             "`provenance.json` records the command, seed and software versions.")
    index = write_index_html(out / "index.html", "Appeal Lab demo", sections, intro=intro)
    return index, sections

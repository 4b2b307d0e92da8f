"""``appeal demo``: every stage on the embedded defaults, one report page."""

from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

import click

from appeal_cli import demo_stages
from appeal_cli.groups import CONTEXT, cli
from appeal_cli.options import out_options, seed_option
from appeal.demo import DemoStage, run_demo
from appeal.errors import AppealInputError
from appeal.outputs import output_run


def discover_stages() -> list[DemoStage]:
    """Every ``STAGE`` defined by a module of :mod:`appeal_cli.demo_stages`."""
    stages = []
    for mod in pkgutil.iter_modules(demo_stages.__path__):
        stage = getattr(importlib.import_module(f"{demo_stages.__name__}.{mod.name}"), "STAGE", None)
        if isinstance(stage, DemoStage):
            stages.append(stage)
    return sorted(stages, key=lambda s: (s.order, s.name))


@cli.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal demo --out demo_out            # everything, then open demo_out/index.html
  appeal demo --out demo_out --force    # again, replacing the earlier demo
  appeal demo --out d --only ratings    # one stage""")
@out_options(default="demo_out")
@seed_option()
@click.option("--only", multiple=True, metavar="STAGE", help="Run only these stages (repeatable).")
@click.option("--list", "list_only", is_flag=True, help="List the stages and exit.")
def demo(out: Path, force: bool, resume: bool, seed: int, only: tuple[str, ...], list_only: bool) -> int:
    """Run every stage of the platform end to end on the embedded default assets.

    Nothing is downloaded: stimuli come from procedurally generated heads, the real face scan
    in the package (menpo3d's "james", BSD-3) and eight photographs of four people (London
    set, CC BY 4.0); participants and EEG are simulated. The result is DIR/index.html linking
    every figure and table.
    Exits 1 if any stage failed (the page says which and why).
    """
    stages = discover_stages()
    if list_only:
        for s in stages:
            click.echo(f"{s.name:20s} {s.title}")
        return 0
    if only:
        unknown = sorted(set(only) - {s.name for s in stages})
        if unknown:
            raise AppealInputError(f"--only: unknown stage(s) {', '.join(unknown)} (expected: {', '.join(s.name for s in stages)})")
        stages = [s for s in stages if s.name in only]
    with output_run(out, force=force, resume=resume, seed=seed) as run:
        index, sections = run_demo(stages, run.out, seed)
        failed = [s.title for s in sections if s.failed]
        run.extra["failed_stages"] = failed
    click.echo(f"Demo report: {index}")
    if failed:
        click.echo(f"{len(failed)} stage(s) failed: {', '.join(failed)}", err=True)
        return 1
    return 0

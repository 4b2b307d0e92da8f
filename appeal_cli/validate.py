"""``appeal validate``: check study files without running anything."""

from __future__ import annotations

from pathlib import Path

import click

from appeal_cli.groups import CONTEXT, cli
from appeal.errors import AppealInputError


@cli.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal validate protocols/exp2_stylisation.yaml
  appeal validate protocols/*.yaml protocols/grids/*.yaml protocols/analysis/*.yaml
  appeal validate --schema-only protocols/exp2_stylisation.yaml   # before its stimuli are rendered""")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--schema-only", is_flag=True,
              help="Check the files themselves only, not the inputs they need to run (e.g. a protocol's stimuli).")
def validate(files: tuple[Path, ...], schema_only: bool) -> None:
    """Check study files (grids, protocols, analyses) and report every problem.

    Each FILE is YAML with a `kind:` key (grid, protocol, ratings or erp). Problems are
    printed one per line as `FILE: dotted.path: message`; relative paths inside a file
    resolve against the file's folder, and named input files and folders must exist --
    including inputs produced by an earlier stage, such as a protocol's stimulus manifest and
    images (skip those with --schema-only). Exits 2 if any file has a problem.
    """
    from appeal_cli.kinds import input_problems, load_any_study_file  # pydantic and the schemas: when it runs

    problems: list[str] = []
    for f in files:
        try:
            kind, model = load_any_study_file(f)
        except AppealInputError as exc:
            problems.extend(exc.lines)
            continue
        missing = [] if schema_only else input_problems(kind, model, f)
        if missing:
            problems.extend(missing)
        else:
            click.echo(f"{f}: ok ({kind})")
    if problems:
        raise AppealInputError(problems)

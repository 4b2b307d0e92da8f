"""Options shared by many commands (outputs, seeds, parallel work)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from appeal.errors import AppealInputError

F = Callable[..., Any]


def out_options(required: bool = True, default: str | None = None) -> Callable[[F], F]:
    """``--out DIR``, ``--force`` and ``--resume`` (see :func:`appeal.outputs.prepare_out_dir`)."""

    def deco(f: F) -> F:
        f = click.option("--resume", is_flag=True, help="Continue in a non-empty DIR, keeping what is there.")(f)
        f = click.option("--force", is_flag=True, help="Overwrite a non-empty DIR (one an earlier run made is emptied).")(f)
        f = click.option("--out", "out", type=click.Path(path_type=Path), required=required and default is None,
                         default=default, show_default=default is not None, metavar="DIR",
                         help="Output folder; must be empty or new unless --force/--resume.")(f)
        return f

    return deco


def seed_option(default: int = 0) -> Callable[[F], F]:
    """``--seed S``: every random choice of the command derives from it (recorded in provenance)."""
    return click.option("--seed", type=int, default=default, show_default=True, metavar="S",
                        help="Seed of all randomness; same inputs + seed give identical outputs.")


def parallel_options(f: F) -> F:
    """``--n-jobs N`` and ``--scheduler ADDRESS`` (local processes or a Dask cluster)."""
    f = click.option("--scheduler", metavar="ADDRESS", envvar="APPEAL_SCHEDULER", default=None,
                     help="Dask distributed scheduler (tcp://host:8786); default $APPEAL_SCHEDULER, else local.")(f)
    f = click.option("--n-jobs", "n_jobs", type=int, default=None, metavar="N",
                     help="Local worker processes (default: all cores; 1 = in this process).")(f)
    return f


def refuse_existing_file(path: Path, force: bool) -> None:
    """A single output file (not a folder): refuse to overwrite it without --force, or to write
    it into a folder that does not exist (one-line errors)."""
    if path.exists() and not force:
        raise AppealInputError(f"{path}: output file exists (use --force to overwrite)")
    if not path.parent.exists():
        raise AppealInputError(f"{path}: output folder {path.parent} does not exist")

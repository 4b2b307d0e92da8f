"""Output folders: refuse to clobber, log to ``DIR/log.txt``, record ``DIR/provenance.json``.

Every command that produces files runs inside :func:`output_run`::

    with output_run(out, force=force, resume=resume, seed=seed, inputs=[grid_file]) as run:
        ...  # write into run.out
"""

from __future__ import annotations

import contextlib
import json
import logging
import shutil
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from appeal.errors import AppealInputError
from appeal.logs import add_log_file, logger, remove_log_file
from appeal.provenance import now_iso, provenance_record, write_provenance

__all__ = ["OutputRun", "prepare_out_dir", "output_run", "failed_run_only", "describe_seed", "require_inside",
           "remove_inside"]

#: What a run that failed before writing anything leaves behind (reused without --force).
_RUN_RECORDS = frozenset({"log.txt", "provenance.json"})


def failed_run_only(out: Path) -> bool:
    """True when ``out`` holds nothing but the log and provenance of a run that failed.

    Such a folder is reused without ``--force``: the failed run wrote no results, and its
    log (which records the error) is appended to, not replaced.
    """
    names = {p.name for p in out.iterdir()}
    if not names or not names <= _RUN_RECORDS or "provenance.json" not in names:
        return False
    try:
        status = json.loads((out / "provenance.json").read_text(encoding="utf-8")).get("status", "")
    except (OSError, ValueError, AttributeError):
        return False
    return isinstance(status, str) and status.startswith("failed")


def require_inside(root: str | Path, path: str | Path, field: str = "output") -> Path:
    """``path`` resolved, after checking that it lies inside the folder ``root``.

    Every path a command builds from data (a participant label, a file name from a manifest) is
    checked with this before anything is written or removed there. Both are resolved, following
    symbolic links of the parts that exist, so neither ``..`` in a label nor a symbolic link
    planted in the output folder leads outside it.

    Parameters
    ----------
    root : path-like
        The output folder (``--out``); it need not exist yet.
    path : path-like
        The file or folder about to be written or removed.
    field : str
        What the path is for, named in the message.

    Returns
    -------
    Path
        ``path`` resolved.

    Raises
    ------
    AppealInputError
        When the resolved path is not ``root`` or below it.
    """
    top = Path(root).expanduser().resolve()
    target = Path(path).expanduser().resolve()
    if target != top and top not in target.parents:
        raise AppealInputError(f"{path}: {field}: resolves to {target}, outside the output folder {top} "
                               "(a '..' or a symbolic link?); nothing was written")
    return target


def remove_inside(root: str | Path, path: str | Path, field: str = "output") -> None:
    """Remove the file or folder ``path`` (when it exists) after :func:`require_inside`; a symbolic
    link is removed itself, never what it points to."""
    path = Path(path)
    if path.is_symlink():
        require_inside(root, path.parent, field)
        path.unlink()
    elif path.exists():
        require_inside(root, path, field)
        shutil.rmtree(path) if path.is_dir() else path.unlink()


def describe_seed(seed: int | dict[str, int] | None) -> str:
    """How a run's randomness is seeded, in words, for the log."""
    if seed is None:
        return "no random choices"
    if isinstance(seed, dict):
        return "seeds " + ", ".join(f"{k}={v}" for k, v in seed.items()) if seed else "no random choices"
    return f"seed {seed}"


def prepare_out_dir(out: str | Path, *, force: bool = False, resume: bool = False) -> Path:
    """Create ``out`` or check that it may be written into.

    Parameters
    ----------
    out : str | Path
        The output folder.
    force : bool
        Allow a non-empty folder. A folder an earlier ``appeal`` run made (it holds
        ``provenance.json``) is emptied first; any other folder is written into as is.
    resume : bool
        Allow a non-empty folder and keep what is there (the command continues).

    Returns
    -------
    Path
        The folder, resolved.

    Raises
    ------
    AppealInputError
        If ``out`` is a file, or a non-empty folder and neither ``force`` nor ``resume``.
    """
    out = Path(out).expanduser()
    if out.exists() and not out.is_dir():
        raise AppealInputError(f"{out}: --out must be a folder, but a file of that name exists")
    if out.is_dir() and any(out.iterdir()) and not failed_run_only(out):
        if resume:
            return out.resolve()
        if not force:
            raise AppealInputError(
                f"{out}: output folder is not empty (use --force to overwrite or --resume to continue)"
            )
        if (out / "provenance.json").is_file():
            for child in out.iterdir():
                shutil.rmtree(child) if child.is_dir() and not child.is_symlink() else child.unlink()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise AppealInputError(f"{out}: cannot create output folder ({exc.strerror})") from None
    return out.resolve()


@dataclass
class OutputRun:
    """A running command's output folder and what will go into its provenance record."""

    out: Path
    seed: int | dict[str, int] | None
    inputs: list[Path]
    argv: list[str]
    started: str
    extra: dict[str, Any] = field(default_factory=dict)

    def path(self, *parts: str, mkdir: bool = True) -> Path:
        """A path inside the output folder (its parent folder is created)."""
        p = self.out.joinpath(*parts)
        if mkdir:
            p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def add_inputs(self, paths: Iterable[str | Path]) -> None:
        """Record further input files (hashed into the provenance at the end)."""
        self.inputs.extend(Path(p) for p in paths)


@contextlib.contextmanager
def output_run(
    out: str | Path,
    *,
    force: bool = False,
    resume: bool = False,
    seed: int | dict[str, int] | None = None,
    inputs: Iterable[str | Path] = (),
    argv: list[str] | None = None,
) -> Iterator[OutputRun]:
    """Prepare ``out``, log into ``out/log.txt`` and write ``out/provenance.json`` at the end.

    The provenance is written whether the body succeeds or raises; its ``status`` says
    which (``"ok"`` or ``"failed: <error>"``). A failure is also logged to ``log.txt``
    (with the traceback when it is not a bad-input error). A folder left holding only the
    log and provenance of a failed run is reused by the next run without ``force``.

    Parameters
    ----------
    out : str | Path
        Output folder (see :func:`prepare_out_dir` for ``force`` and ``resume``).
    force, resume : bool
        See :func:`prepare_out_dir`.
    seed : int | dict of str to int | None
        The seed of all randomness in the run; a mapping names several (e.g. seeds read
        from the input file); None for a run that makes no random choices.
    inputs : iterable of path-like
        Input files to hash into the record.
    argv : list of str | None
        The command line (default ``sys.argv``).

    Yields
    ------
    OutputRun
        The run; write files under ``run.out``.
    """
    folder = prepare_out_dir(out, force=force, resume=resume)
    run = OutputRun(out=folder, seed=seed, inputs=[Path(p) for p in inputs],
                    argv=list(sys.argv if argv is None else argv), started=now_iso())
    handler = add_log_file(folder / "log.txt")
    logger.info("writing to %s (%s)", folder, describe_seed(seed))
    status = "ok"
    try:
        yield run
    except BaseException as exc:
        status = f"failed: {type(exc).__name__}: {exc}".splitlines()[0]
        _log_failure(handler, exc)
        raise
    finally:
        record = provenance_record(argv=run.argv, inputs=run.inputs, seed=run.seed, started=run.started,
                                   ended=now_iso(), extra={"status": status, **run.extra})
        write_provenance(folder, record)
        remove_log_file(handler)


def _log_failure(handler: logging.Handler, exc: BaseException) -> None:
    """Write why the run failed into the log file only (the command line reports it on stderr)."""
    import click

    expected = isinstance(exc, (AppealInputError, click.ClickException, KeyboardInterrupt, SystemExit))
    if isinstance(exc, AppealInputError):
        msg = "failed: " + " | ".join(exc.lines)
    elif isinstance(exc, click.ClickException):
        msg = f"failed: {exc.format_message()}"
    elif isinstance(exc, (KeyboardInterrupt, SystemExit)):
        msg = f"stopped: {type(exc).__name__}"
    else:
        msg = f"failed with an internal error: {type(exc).__name__}: {exc}"
    record = logger.makeRecord(logger.name, logging.ERROR, __file__, 0, msg, (),
                               None if expected else (type(exc), exc, exc.__traceback__))
    handler.handle(record)

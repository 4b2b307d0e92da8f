"""The ``appeal`` command line: the only code that imports all three rooms.

Command modules in this package attach themselves to the groups of
:mod:`appeal_cli.groups`; :func:`main` imports them all, runs the command and turns
errors into exit codes (0 ok, 2 bad input, 1 internal error) without tracebacks.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
import traceback

import click

from appeal.allocator import keep_heap_pad
from appeal.errors import AppealInputError
from appeal_cli.groups import cli

__all__ = ["cli", "main"]

_GLOBAL_FLAGS = {"-v": "--verbose", "--verbose": "--verbose", "-q": "--quiet", "--quiet": "--quiet"}


#: Modules of the package that hold no command (helpers the commands import when they run).
_NOT_COMMANDS = ("groups", "options", "kinds", "audit_outputs", "demo_stages")


def _load_commands() -> None:
    for mod in pkgutil.iter_modules(__path__):
        if not mod.name.startswith("_") and mod.name not in _NOT_COMMANDS:
            importlib.import_module(f"{__name__}.{mod.name}")


def _hoist_global_flags(args: list[str]) -> list[str]:
    """Move -v/-q from anywhere (before a bare ``--``) to the front, where the root group reads them."""
    flags, rest = [], []
    for i, a in enumerate(args):
        if a == "--":
            rest.extend(args[i:])
            break
        (flags if a in _GLOBAL_FLAGS else rest).append(_GLOBAL_FLAGS.get(a, a) if a in _GLOBAL_FLAGS else a)
    return list(dict.fromkeys(flags)) + rest


def _err(line: str) -> None:
    click.echo(line, err=True)


def main(argv: list[str] | None = None) -> int:
    """Run ``appeal`` with ``argv`` (default ``sys.argv[1:]``); returns the exit status."""
    args = _hoist_global_flags(list(sys.argv[1:] if argv is None else argv))
    verbose = "--verbose" in args
    keep_heap_pad()  # large arrays made and dropped in loops reuse their pages (appeal.allocator)
    try:
        _load_commands()
        rv = cli.main(args=args, prog_name="appeal", standalone_mode=False)
        return rv if isinstance(rv, int) else 0
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.exceptions.Abort:
        _err("appeal: aborted")
        return 130
    except click.ClickException as exc:
        cmd = exc.ctx.command_path if getattr(exc, "ctx", None) else "appeal"
        _err(f"{cmd}: error: {exc.format_message()} (see '{cmd} --help')".replace("\n", " "))
        return 2
    except AppealInputError as exc:
        for line in exc.lines:
            _err(line)
        return 2
    except KeyboardInterrupt:
        _err("appeal: interrupted")
        return 130
    except Exception as exc:  # noqa: BLE001 - the one place internal errors are reported
        if verbose:
            traceback.print_exc()
        msg = f"{type(exc).__name__}: {exc}".splitlines()[0]
        _err(f"appeal: internal error: {msg}" + ("" if verbose else " (run with -v for the traceback)"))
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

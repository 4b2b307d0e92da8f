"""``appeal run``: present a protocol to a participant (or a simulated one) and record the data."""

from __future__ import annotations

import shlex
from pathlib import Path

import click
from click.core import ParameterSource

from appeal_cli.groups import CONTEXT, cli


@cli.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal run protocols/exp2_stylisation.yaml --participant 01
  appeal run protocols/erp_stylisation.yaml --participant 07 --session 2 --out data/sub-07/ses-2/beh
  appeal run protocols/erp_stylisation.yaml --participant 07 --session 2 --out data/sub-07/ses-2/beh --resume
  appeal run protocols/exp3_expressions.yaml --participant 01 --stimuli my_faces/factors.csv --windowed
  appeal run protocols/erp_stylisation.yaml --participant 07 --trigger-backend file   # no EEG hardware
  xvfb-run -a appeal run protocols/exp2_stylisation.yaml --participant 99 --simulate default --out sim/99
  appeal run protocols/erp_stylisation.yaml --participant 98 --simulate model.yaml --no-window --out sim/98""")
@click.argument("protocol", type=click.Path(path_type=Path))
@click.option("--participant", required=True, metavar="ID", help="Participant label, letters and digits (BIDS sub-ID).")
@click.option("--session", type=int, default=1, show_default=True, metavar="N", help="Session number.")
@click.option("--out", type=click.Path(path_type=Path), default=None, metavar="DIR",
              help="Session folder [default: data/sub-ID/ses-N/beh]; must be new or empty unless --resume/--force.")
@click.option("--resume", is_flag=True, help="Continue a crashed or aborted session at its next trial, same order.")
@click.option("--force", is_flag=True, help="Replace an existing session folder.")
@click.option("--stimuli", type=click.Path(path_type=Path), default=None, metavar="PATH",
              help="Use this manifest/factor-table CSV (or a folder holding manifest.csv) instead of the protocol's.")
@click.option("--simulate", default=None, metavar="MODEL",
              help="A simulated participant answers: 'default' or a participant-model YAML. Time is virtual "
                   "(each screen flipped once, the clock advanced by its frames), so sessions run in seconds.")
@click.option("--realtime", is_flag=True, help="With --simulate: flip every frame, paced to the refresh rate.")
@click.option("--no-window", "no_window", is_flag=True, help="With --simulate: no PsychoPy window at all.")
@click.option("--windowed", is_flag=True, help="A window instead of full screen.")
@click.option("--seed", type=int, default=None, metavar="S",
              help="Seed of trial order and jitter [default: derived from protocol, participant and session].")
@click.option("--refresh-hz", "refresh_hz", type=float, default=None, metavar="HZ",
              help="Refresh rate to convert seconds to frames [default: protocol's, else measured, else 60].")
@click.option("--screenshots", type=click.Path(path_type=Path), default=None, metavar="DIR",
              help="Save the first frame of every kind of screen as PNG into DIR.")
@click.option("--trigger-backend", "trigger_backend", type=click.Choice(["parallel", "serial", "lsl", "file"]),
              default=None, help="Send the protocol's trigger codes through this backend instead of its own "
                                 "(file: only the trigger log, e.g. to rehearse an EEG session without the hardware).")
@click.option("--trigger-address", "trigger_address", default=None, metavar="ADDR",
              help="Port of the parallel/serial backend instead of the protocol's (e.g. 0xD010, /dev/ttyUSB0).")
@click.pass_context
def run(ctx: click.Context, protocol: Path, participant: str, session: int, out: Path | None, resume: bool,
        force: bool, stimuli: Path | None, simulate: str | None, realtime: bool, no_window: bool, windowed: bool,
        seed: int | None, refresh_hz: float | None, screenshots: Path | None, trigger_backend: str | None,
        trigger_address: str | None) -> None:
    """Run one session of PROTOCOL (a `kind: protocol` YAML) in a PsychoPy window.

    \b
    Every completed trial is appended to DIR/sub-ID_ses-N_task-TASK_beh.tsv and fsync'ed
    before the next begins; a crash loses at most the trial in progress and --resume
    continues at the next trial in the same order. Beside it: a JSON sidecar (protocol
    hash, versions, refresh rate, screen, seed), the flip log, the trigger log,
    participants.tsv (demographics, apart from the ratings) and report/index.html
    (intended vs shown frames, dropped frames, ISI, trigger-to-flip offsets, trials per
    condition). Escape aborts (resumable).
    """
    from experiments.session import run_session

    if simulate is not None and no_window and screenshots is not None:
        from appeal.errors import AppealInputError

        raise AppealInputError("--screenshots needs a window (drop --no-window)")
    folder = out if out is not None else Path("data") / f"sub-{participant}" / f"ses-{session}" / "beh"
    try:
        res = run_session(protocol, participant, session=session, out=out, stimuli=stimuli, simulate=simulate,
                          windowed=windowed, resume=resume, force=force, seed=seed, realtime=realtime,
                          window=not no_window, screenshot_dir=screenshots, refresh_hz=refresh_hz,
                          triggers={"backend": trigger_backend, "address": trigger_address})
    except BaseException:
        if _crashed_sidecar(folder):
            click.echo(f"Continue with: {resume_command(ctx, folder)}", err=True)
        raise
    click.echo(f"{res.status}: {res.completed}/{res.n_trials} trials -> {res.beh}")
    if res.report is not None:
        click.echo(f"Session report: {res.report}")
    if res.status == "aborted":
        click.echo(f"Continue with: {resume_command(ctx, res.out)}", err=True)


#: Options the continuation command sets itself (or must not repeat).
_NOT_REPEATED = {"out", "resume", "force"}


def resume_command(ctx: click.Context, out: Path) -> str:
    """The ``appeal run ... --resume`` command that continues this session, pasteable as printed.

    Every option given on the command line (stimuli, screen, timing, triggers, simulation, ...)
    is repeated with its value, ``--out`` names the session folder; ``--force`` is dropped.
    Words are quoted for the shell.

    Parameters
    ----------
    ctx : click.Context
        The ``appeal run`` invocation.
    out : Path
        The session folder.

    Returns
    -------
    str
        The command line.
    """
    words = ["appeal", "run", str(ctx.params["protocol"])]
    for param in ctx.command.params:
        if not isinstance(param, click.Option) or param.name in _NOT_REPEATED:
            continue
        source = ctx.get_parameter_source(param.name)
        if param.name not in ("participant", "session") and source in (None, ParameterSource.DEFAULT):
            continue
        value = ctx.params[param.name]
        flag = max(param.opts, key=len)
        if param.is_flag:
            words += [flag] if value else []
        elif value is not None:
            words += [flag, str(value)]
    return shlex.join([*words, "--out", str(out), "--resume"])


def _crashed_sidecar(folder: Path) -> bool:
    import json

    for side in folder.glob("sub-*_beh.json"):
        try:
            if json.loads(side.read_text()).get("Status") == "crashed":
                return True
        except (OSError, ValueError):
            continue
    return False

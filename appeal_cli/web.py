"""``appeal export web`` and ``appeal import web``: the same protocol as an online browser study."""

from __future__ import annotations

from pathlib import Path

import click

from appeal_cli.groups import CONTEXT, export_, import_


@export_.command(name="web", context_settings=CONTEXT, epilog="""\b
Examples:
  appeal export web protocols/exp2_stylisation.yaml --out site/exp2
  appeal export web protocols/exp3_expressions.yaml --out site/exp3 --participants 60 \\
      --completion-url "https://app.prolific.com/submissions/complete?cc=C1A2B3"
  appeal export web protocols/exp2_stylisation.yaml --out site/exp2 --data-url /save   # POST the data here
  python -m http.server -d site/exp2 8000     # then open http://127.0.0.1:8000/?participant=01
\b
Participants open index.html?participant=ID (lists 01..N are the lab runner's lists for those
labels); from Prolific, PROLIFIC_PID, STUDY_ID and SESSION_ID are read from the URL into the
data and another id gets list hash(id) mod N. Each finished trial is kept in the browser (a
reload continues at the next trial); at the end the _beh.tsv downloads (and is POSTed to
--data-url), then the completion code is shown or the participant sent to --completion-url.""")
@click.argument("protocol", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True, metavar="DIR",
              help="The study folder (new or empty unless --force); serve it with any static web server.")
@click.option("--participants", type=int, default=20, show_default=True, metavar="N",
              help="Trial lists for participants 01..N (each the lab runner's list for that label).")
@click.option("--session", type=int, default=1, show_default=True, metavar="N", help="Session number.")
@click.option("--stimuli", type=click.Path(path_type=Path), default=None, metavar="PATH",
              help="Use this manifest/factor table instead of the protocol's (as appeal run --stimuli).")
@click.option("--data-url", default=None, metavar="URL", help="POST the finished data file here (JATOS/Pavlovia-style).")
@click.option("--completion-url", default=None, metavar="URL", help="Send participants here at the end (e.g. Prolific).")
@click.option("--completion-code", default=None, metavar="CODE", help="Show this code at the end.")
@click.option("--no-fullscreen", is_flag=True, help="Do not ask for full screen before the first trial.")
@click.option("--force", is_flag=True, help="Replace an existing study folder.")
def export_web_cmd(protocol: Path, out: Path, participants: int, session: int, stimuli: Path | None,
                   data_url: str | None, completion_url: str | None, completion_code: str | None,
                   no_fullscreen: bool, force: bool) -> None:
    """Export PROTOCOL (a rating or classification `kind: protocol`) as a static browser study.

    \b
    The folder holds index.html, the study script (jsPsych, copied from npm with its licence),
    the images resized to the protocol's screen geometry and the trial lists. Passive viewing
    (ERP) protocols and protocols with EEG triggers are refused: a browser has no EEG.
    """
    from experiments.web import export_web

    res = export_web(protocol, out, participants=participants, session=session, stimuli=stimuli, data_url=data_url,
                     completion_url=completion_url, completion_code=completion_code, fullscreen=not no_fullscreen,
                     force=force)
    n = sorted(set(res.n_trials.values()))
    click.echo(f"{res.index}: {len(res.participants)} participant lists ({'/'.join(map(str, n))} trials), "
               f"{res.n_images} images" + (f", {res.n_clips} clips" if res.n_clips else ""))


@import_.command(name="web", context_settings=CONTEXT, epilog="""\b
Examples:
  appeal import web ~/Downloads/sub-*_task-exp2_beh.tsv --protocol protocols/exp2_stylisation.yaml --out data
  appeal import web server_data/*.tsv --protocol protocols/exp3_expressions.yaml --out data --force
  appeal analyze ratings protocols/analysis/exp2_ratings.yaml --out results/exp2   # reads data/ as usual""")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--protocol", type=click.Path(path_type=Path), required=True, metavar="PROTOCOL",
              help="The protocol the study was exported from (columns and lists are checked against it).")
@click.option("--out", type=click.Path(path_type=Path), default=Path("data"), show_default=True, metavar="DIR",
              help="Data folder: each session goes to DIR/sub-ID/ses-N/beh/.")
@click.option("--stimuli", type=click.Path(path_type=Path), default=None, metavar="PATH",
              help="The manifest/factor table the study was exported with, if not the protocol's "
                   "(the participants' trial lists are rebuilt from it to check the rows).")
@click.option("--force", is_flag=True, help="Replace sessions imported before.")
def import_web_cmd(files: tuple[Path, ...], protocol: Path, out: Path, stimuli: Path | None, force: bool) -> None:
    """Import browser session files (FILES: sub-ID_ses-N_task-TASK_beh.tsv) into the BIDS layout.

    \b
    A file from a browser is untrusted until checked, and every file is checked before anything
    is written: UTF-8 text of a size the protocol's trials explain, ending in a line end (a
    truncated download is refused); the export's columns; every cell parsed to its type (BIDS
    labels, numbers in range, the protocol's scale points and choices); one participant, list and
    seed; the protocol's sha256; and every row the trial the participant's exported list has
    there (rebuilt from the protocol and its stimuli). One bad file: one line naming the file,
    the line and the column, and nothing is written. Each session is then written with a JSON
    sidecar and a timing report (intended vs shown frames at the browser's measured refresh
    rate), so the rating analysis reads it like a lab session; text a spreadsheet would run as
    a formula is written neutralised ('=...).
    """
    from experiments.web import import_web

    for s in import_web(list(files), protocol, out, force=force, stimuli=stimuli):
        state = "complete" if s.complete else "incomplete"
        click.echo(f"sub-{s.participant}: {s.trials} trials ({state}) -> {s.beh}")

"""``appeal import web``: browser session files into the lab's BIDS layout, all or nothing.

A browser session (downloaded by the participant or POSTed to the study's server) is the lab
runner's ``_beh.tsv`` plus :data:`experiments.web.export.WEB_COLUMNS`. It is hostile input until
checked: :func:`experiments.web.session_file.read_session_file` checks each file (its bytes, its
header, every cell, and every row against the participant's exported list). Only when every file
given has passed, and every path the import will write resolves inside ``--out`` (no ``..``, no
symbolic link out of it), is anything written: each session as
``OUT/sub-ID/ses-N/beh/sub-ID_ses-N_task-TASK_beh.tsv`` with a JSON sidecar and the session report
(intended vs shown frames at the browser's refresh rate), so ``appeal analyze ratings`` reads it
unchanged. The files are first written into a staging folder inside ``OUT`` and then moved into
place, so a failure while writing leaves nothing half-written. The participant's file is only
read, never changed; the imported copy has text a spreadsheet would run as a formula neutralised.
"""

from __future__ import annotations

import os
import shutil
import statistics
import tempfile
from dataclasses import dataclass
from pathlib import Path

from appeal.atomic import atomic_write_text
from appeal.errors import AppealInputError
from appeal.outputs import remove_inside, require_inside
from appeal.provenance import now_iso
from experiments.datafile import format_cell, write_sidecar
from experiments.session import column_descriptions, session_paths
from experiments.web.export import WEB_DESCRIPTIONS
from experiments.web.session_file import ImportContext, SessionFile, import_context, read_session_file

__all__ = ["ImportedSession", "import_web"]


@dataclass
class ImportedSession:
    """One imported browser session."""

    source: Path
    beh: Path
    sidecar: Path
    report: Path | None
    participant: str
    trials: int
    complete: bool


def _session_text(found: SessionFile, columns: list[str]) -> str:
    """The checked rows as a session file, every cell through :func:`format_cell` (formulas neutralised)."""
    lines = ["\t".join(columns), *("\t".join(format_cell(r[c]) for c in columns) for r in found.rows)]
    return "\n".join(lines) + "\n"


def _sidecar(found: SessionFile, ctx: ImportContext) -> dict:
    rows = found.rows
    desc = column_descriptions(ctx.protocol, ctx.columns)
    for c, text in WEB_DESCRIPTIONS.items():
        desc[c] = {"Description": text}
    return {
        "TaskName": ctx.protocol.task, "Protocol": str(ctx.protocol_file.resolve()), "ProtocolName": ctx.protocol.name,
        "ProtocolSHA256": ctx.protocol_sha256, "participant_id": found.participant, "Session": found.session,
        "Seed": found.seed, "List": found.list, "RefreshRate": _refresh(found), "TimingMode": "browser",
        "Browser": rows[0]["browser"], "Source": str(found.source.resolve()), "SourceSHA256": found.sha256,
        "Imported": now_iso(), "Started": rows[0]["started"], "NumberOfTrials": found.n_list,
        "CompletedTrials": len(rows), "Status": "complete" if found.complete else "incomplete",
        "Parts": len({r["part"] for r in rows}), "Columns": desc,
    }


def _refresh(found: SessionFile) -> float:
    return statistics.median(float(r["refresh_hz"]) for r in found.rows)


def _planned(sessions: list[SessionFile], root: Path, ctx: ImportContext, force: bool) -> list[dict[str, Path]]:
    """Each session's destination paths, every one checked to resolve inside ``root``."""
    seen: dict[tuple[str, int], Path] = {}
    planned = []
    for s in sessions:
        key = (s.participant, s.session)
        if key in seen:
            raise AppealInputError(f"{seen[key]}, {s.source}: two files of participant {s.participant}, "
                                   f"session {s.session} (import one of them)")
        seen[key] = s.source
        folder = root / f"sub-{s.participant}" / f"ses-{s.session}" / "beh"
        paths = session_paths(folder, s.participant, s.session, ctx.protocol.task)
        for what in ("beh", "sidecar", "report"):
            require_inside(root, paths[what], f"the imported session's {what}")
        if (paths["beh"].exists() or paths["beh"].is_symlink()) and not force:
            raise AppealInputError(f"{paths['beh']}: already imported (--force replaces it)")
        planned.append(paths)
    return planned


def _stage(found: SessionFile, folder: Path, ctx: ImportContext, report: bool) -> dict[str, Path]:
    """Write one session's files into the staging ``folder`` (same layout as its destination)."""
    from experiments.report import write_session_report

    paths = session_paths(folder, found.participant, found.session, ctx.protocol.task)
    folder.mkdir(parents=True)
    atomic_write_text(paths["beh"], _session_text(found, ctx.columns))
    write_sidecar(paths["sidecar"], _sidecar(found, ctx))
    if report:
        write_session_report(paths, _refresh(found))
    return paths


def _move_into_place(staged: dict[str, Path], dest: dict[str, Path], root: Path, report: bool) -> None:
    dest["beh"].parent.mkdir(parents=True, exist_ok=True)
    for what in ("beh", "sidecar", "report"):  # the folders now exist: checked again, links included
        require_inside(root, dest[what], f"the imported session's {what}")
    remove_inside(root, dest["report"], "the imported session's report")
    os.replace(staged["beh"], dest["beh"])
    os.replace(staged["sidecar"], dest["sidecar"])
    if report:
        os.replace(staged["report"], dest["report"])


def import_web(files: list[str | Path], protocol_file: str | Path, out: str | Path, *, force: bool = False,
               report: bool = True, stimuli: str | Path | None = None,
               context: ImportContext | None = None) -> list[ImportedSession]:
    """Import browser session files of ``protocol_file`` into ``out`` (a BIDS data folder), all or nothing.

    Parameters
    ----------
    files : list of path-like
        ``sub-*_beh.tsv`` files written by an exported study (only read).
    protocol_file : path-like
        The protocol the study was exported from (its sha256 must be the one the files carry).
    out : path-like
        The data folder; each session goes to ``sub-ID/ses-N/beh/``.
    force : bool
        Replace sessions already imported.
    report : bool
        Write each session's timing report.
    stimuli : path-like, optional
        The stimulus manifest or factor table the study was exported with, when not the
        protocol's (``appeal export web --stimuli``): the participants' lists are rebuilt from it.
    context : ImportContext, optional
        The protocol's checks, when already built (:func:`experiments.web.session_file.import_context`).

    Returns
    -------
    list of ImportedSession

    Raises
    ------
    AppealInputError
        One line for the first problem of any file; then nothing has been written.
    """
    ctx = context or import_context(protocol_file, stimuli)
    out = Path(out).expanduser()
    if out.exists() and not out.is_dir():
        raise AppealInputError(f"{out}: --out must be a folder, but a file of that name exists")
    sessions = [read_session_file(f, ctx) for f in files]
    root = out.resolve()
    planned = _planned(sessions, root, ctx, force)
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise AppealInputError(f"{out}: cannot create the data folder ({exc.strerror})") from None
    staging = Path(tempfile.mkdtemp(prefix=".appeal-import-", dir=root))
    try:
        staged = [_stage(s, staging / str(k), ctx, report) for k, s in enumerate(sessions)]
        for src, dest in zip(staged, planned):
            _move_into_place(src, dest, root, report)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return [ImportedSession(source=s.source, beh=p["beh"], sidecar=p["sidecar"], report=p["report"] if report else None,
                            participant=s.participant, trials=len(s.rows), complete=s.complete)
            for s, p in zip(sessions, planned)]

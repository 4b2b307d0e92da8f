"""``appeal import web``: browser session files into the lab's BIDS layout.

A browser session (downloaded by the participant or POSTed to the study's server) is the lab
runner's ``_beh.tsv`` plus :data:`experiments.web.export.WEB_COLUMNS`. Each file is checked
against the protocol (same columns, trials in the order of the participant's list, one
participant and session per file) and written as
``OUT/sub-ID/ses-N/beh/sub-ID_ses-N_task-TASK_beh.tsv`` with a JSON sidecar and the session
report (intended vs shown frames at the browser's refresh rate), so ``appeal analyze ratings``
reads it unchanged.
"""

from __future__ import annotations

import shutil
import statistics
from dataclasses import dataclass
from pathlib import Path

from appeal.atomic import atomic_write_text
from appeal.errors import AppealInputError
from appeal.provenance import file_sha256, now_iso
from experiments.datafile import read_completed, write_sidecar
from experiments.session import column_descriptions, default_seed, load_protocol, session_paths
from experiments.web.export import WEB_DESCRIPTIONS, web_columns

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


def _has_clip_columns(path: Path) -> bool:
    """Whether a session file's header has the clip columns (a study whose stimuli include clips)."""
    with open(path, encoding="utf-8") as fh:
        return "clip_frames" in fh.readline().rstrip("\n").split("\t")


def _one(rows: list[dict[str, str]], column: str, source: Path) -> str:
    values = sorted({r[column] for r in rows})
    if len(values) != 1:
        raise AppealInputError(f"{source}: column '{column}': expected one value in a session file (found {', '.join(values[:5])})")
    return values[0]


def _check(rows: list[dict[str, str]], source: Path, protocol_name: str) -> tuple[str, int]:
    """The participant and session of one file's rows, checked (one of each, trials 1..n, the list's seed)."""
    if not rows:
        raise AppealInputError(f"{source}: no trials (a header only)")
    participant, session = _one(rows, "participant_id", source), int(_one(rows, "session", source))
    trials = [int(r["trial"]) for r in rows]
    if trials != list(range(1, len(trials) + 1)):
        raise AppealInputError(f"{source}: column 'trial': expected 1, 2, 3, ... in order (a lost or repeated trial?); "
                               f"found {', '.join(map(str, trials[:8]))}{' ...' if len(trials) > 8 else ''}")
    slot, seed = _one(rows, "list", source), _one(rows, "seed", source)
    if seed != str(default_seed(protocol_name, slot, session)):
        raise AppealInputError(f"{source}: column 'seed': {seed} is not the seed of list {slot} of protocol "
                               f"'{protocol_name}' (exported from another protocol?)")
    return participant, session


def import_web(files: list[str | Path], protocol_file: str | Path, out: str | Path, *, force: bool = False,
               report: bool = True) -> list[ImportedSession]:
    """Import browser session files of ``protocol_file`` into ``out`` (a BIDS data folder).

    Parameters
    ----------
    files : list of path-like
        ``sub-*_beh.tsv`` files written by an exported study.
    protocol_file : path-like
        The protocol the study was exported from (its columns and trial count are checked).
    out : path-like
        The data folder; each session goes to ``sub-ID/ses-N/beh/``.
    force : bool
        Replace sessions already imported.
    report : bool
        Write each session's timing report.

    Returns
    -------
    list of ImportedSession
    """
    protocol_file = Path(protocol_file)
    protocol = load_protocol(protocol_file)
    out = Path(out)
    checked = []
    for f in map(Path, files):
        if not f.is_file():
            raise AppealInputError(f"{f}: no such file")
        if f.suffix != ".tsv":
            raise AppealInputError(f"{f}: expected a browser session file sub-ID_ses-N_task-{protocol.task}_beh.tsv")
        columns = web_columns(protocol, clips=_has_clip_columns(f))
        rows = read_completed(f, columns)
        participant, session = _check(rows, f, protocol.name)
        paths = session_paths(out / f"sub-{participant}" / f"ses-{session}" / "beh", participant, session, protocol.task)
        if paths["beh"].exists() and not force:
            raise AppealInputError(f"{paths['beh']}: already imported (--force replaces it)")
        checked.append((f, rows, participant, session, paths))
    seen = [(c[2], c[3]) for c in checked]
    dup = sorted({s for s in seen if seen.count(s) > 1})
    if dup:
        raise AppealInputError(f"{', '.join(str(c[0]) for c in checked if (c[2], c[3]) == dup[0])}: "
                               f"two files of participant {dup[0][0]}, session {dup[0][1]}")
    done = []
    for f, rows, participant, session, paths in checked:
        desc = column_descriptions(protocol, list(rows[0]))
        for c, text in WEB_DESCRIPTIONS.items():
            desc[c] = {"Description": text}
        paths["beh"].parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(paths["beh"], f.read_text(encoding="utf-8"))
        hz = statistics.median(float(r["refresh_hz"]) for r in rows)
        n, n_list = len(rows), int(rows[0]["list_trials"])
        complete = n == n_list
        sidecar = {
            "TaskName": protocol.task, "Protocol": str(protocol_file.resolve()), "ProtocolName": protocol.name,
            "ProtocolSHA256": file_sha256(protocol_file), "participant_id": participant, "Session": session,
            "Seed": int(rows[0]["seed"]), "List": rows[0]["list"], "RefreshRate": hz, "TimingMode": "browser",
            "Browser": rows[0]["browser"], "Source": str(f.resolve()), "SourceSHA256": file_sha256(f),
            "Imported": now_iso(), "Started": rows[0]["started"], "NumberOfTrials": n_list,
            "CompletedTrials": n, "Status": "complete" if complete else "incomplete",
            "Parts": len({r["part"] for r in rows}), "Columns": desc,
        }
        write_sidecar(paths["sidecar"], sidecar)
        rep = None
        if report:
            from experiments.report import write_session_report

            if paths["report"].exists():
                shutil.rmtree(paths["report"])
            rep = write_session_report(paths, hz)
        done.append(ImportedSession(source=f, beh=paths["beh"], sidecar=paths["sidecar"], report=rep,
                                    participant=participant, trials=n, complete=complete))
    return done

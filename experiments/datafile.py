"""Session data that cannot be lost: a BIDS-style ``_beh.tsv`` written row by row (flush + fsync).

Each completed trial is one line, appended, flushed and fsync'ed before the next trial
starts, so a crash (even SIGKILL) loses at most the trial in progress. :func:`read_completed`
reads the rows back for ``--resume`` (a torn last line is cut off). The JSON sidecar and the
demographics file are written atomically.
"""

from __future__ import annotations

import json
import math
import os
import threading
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from appeal.atomic import atomic_write_text
from appeal.cells import neutralise
from appeal.errors import AppealInputError
from appeal.text_bytes import decoded

__all__ = ["session_stem", "format_cell", "TsvWriter", "read_completed", "read_sidecar", "write_sidecar", "write_demographics", "NA"]

#: How missing values are written (BIDS convention; pandas reads it as NaN).
NA = "n/a"


def session_stem(participant: str, session: int, task: str) -> str:
    """``sub-<id>_ses-<n>_task-<task>`` (the BIDS entity prefix of every session file)."""
    return f"sub-{participant}_ses-{session}_task-{task}"


def format_cell(value: Any) -> str:
    """A value as a session file's cell: ``n/a`` for None and NaN, ``1``/``0`` for booleans, numbers
    to 6 decimals, text on one line with a spreadsheet formula neutralised (:mod:`appeal.cells`)."""
    if value is None:
        return NA
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        if math.isnan(value):
            return NA
        return f"{value:.6f}".rstrip("0").rstrip(".") if abs(value) < 1e9 else repr(value)
    text = str(value)
    if "\t" in text or "\n" in text or "\r" in text:
        text = text.replace("\t", " ").replace("\n", " ").replace("\r", " ")
    return neutralise(text)


class TsvWriter:
    """Append rows to a tab-separated file, each flushed to the OS before returning, and fsync'ed.

    Parameters
    ----------
    path : str | Path
        The file; created with a header line when new or empty.
    columns : sequence of str
        Column order. Rows are mappings; missing keys are written as ``n/a``.
    fsync : {"sync", "background", "off"} or bool
        ``"sync"`` (or True): ``os.fsync`` after every row before returning. ``"background"``:
        every row is written and flushed before returning (so it survives a crash or SIGKILL of
        the process at once) and a helper thread fsyncs it to the disk right after (power-loss
        safe a few ms later), so the trial loop never waits for the disk. ``"off"`` (or
        False): flush only.
    """

    def __init__(self, path: str | Path, columns: Sequence[str], *, fsync: bool | str = "sync"):
        self.path = Path(path)
        self.columns = list(columns)
        self.mode = {True: "sync", False: "off"}.get(fsync, fsync) if isinstance(fsync, bool) else fsync
        if self.mode not in ("sync", "background", "off"):
            raise ValueError(f"fsync must be sync, background or off (got {fsync!r})")
        new = not self.path.exists() or self.path.stat().st_size == 0
        self._fh = open(self.path, "a", encoding="utf-8", newline="\n")  # noqa: SIM115 - kept open for the session
        self._pending = threading.Event()
        self._stop = False
        self._thread = None
        if self.mode == "background":
            self._thread = threading.Thread(target=self._syncer, name=f"fsync-{self.path.name}", daemon=True)
            self._thread.start()
        if new:
            self._write_line("\t".join(self.columns))

    def _syncer(self) -> None:
        fd = self._fh.fileno()
        while True:
            self._pending.wait()
            self._pending.clear()
            os.fsync(fd)
            if self._stop:
                return

    def _write_line(self, line: str) -> None:
        self._fh.write(line + "\n")
        self._fh.flush()
        if self.mode == "sync":
            os.fsync(self._fh.fileno())
        elif self.mode == "background":
            self._pending.set()

    def write(self, row: Mapping[str, Any]) -> None:
        """Append one row and make it durable."""
        self._write_line("\t".join(format_cell(row.get(c)) for c in self.columns))

    def write_many(self, rows: Sequence[Mapping[str, Any]]) -> None:
        """Append several rows with one flush (and fsync)."""
        if rows:
            self._write_line("\n".join("\t".join(format_cell(r.get(c)) for c in self.columns) for r in rows))

    def close(self) -> None:
        """Wait for the last fsync and close the file."""
        if self._thread is not None:
            self._stop = True
            self._pending.set()
            self._thread.join()
            self._thread = None
        if not self._fh.closed:
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self._fh.close()

    def __enter__(self) -> TsvWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_completed(path: str | Path, columns: Sequence[str] | None = None) -> list[dict[str, str]]:
    """The complete rows of a session TSV (a torn last line from a crash is removed from the file).

    Parameters
    ----------
    path : str | Path
        The ``_beh.tsv``.
    columns : sequence of str, optional
        The expected header; a different one is an error (the protocol changed).

    Returns
    -------
    list of dict
        One dict of strings per complete row.
    """
    path = Path(path)
    if not path.exists():
        return []
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        cut = data.rfind(b"\n") + 1
        with open(path, "r+b") as fh:
            fh.truncate(cut)
            fh.flush()
            os.fsync(fh.fileno())
        data = data[:cut]
    lines = decoded(data, str(path), "the session file as the runner wrote it").splitlines()
    if not lines:
        return []
    header = lines[0].split("\t")
    if columns is not None and header != list(columns):
        raise AppealInputError(f"{path}: header differs from what this protocol writes "
                               f"(the protocol changed since the session started?); expected {len(columns)} columns "
                               f"{', '.join(columns[:6])}..., found {', '.join(header[:6])}...")
    rows = []
    for n, line in enumerate(lines[1:], start=2):
        parts = line.split("\t")
        if len(parts) != len(header):
            raise AppealInputError(f"{path}:{n}: expected {len(header)} tab-separated values, found {len(parts)}")
        rows.append(dict(zip(header, parts)))
    return rows


def read_sidecar(path: str | Path) -> dict[str, Any]:
    """A session's JSON sidecar (one-line error when it is not a JSON object)."""
    path = Path(path)
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise AppealInputError(f"{path}: cannot read the session sidecar ({str(exc).splitlines()[0][:80]})") from None
    if not isinstance(record, dict):
        raise AppealInputError(f"{path}: expected a JSON object (the session sidecar), found {type(record).__name__}")
    return record


def write_sidecar(path: str | Path, record: Mapping[str, Any]) -> Path:
    """Write the session's JSON sidecar atomically."""
    return atomic_write_text(path, json.dumps(record, indent=2, default=str) + "\n")


def write_demographics(path: str | Path, participant: str, answers: Mapping[str, Any]) -> Path:
    """Write (or update) the participant's row in a demographics TSV kept apart from the ratings."""
    path = Path(path)
    rows: dict[str, dict[str, str]] = {}
    cols = ["participant_id", *answers]
    if path.exists():
        for r in read_completed(path):
            rows[r["participant_id"]] = r
            cols += [c for c in r if c not in cols]
    rows[participant] = {"participant_id": participant, **{k: format_cell(v) for k, v in answers.items()}}
    text = "\t".join(cols) + "\n" + "".join("\t".join(r.get(c, NA) for c in cols) + "\n" for r in rows.values())
    return atomic_write_text(path, text)

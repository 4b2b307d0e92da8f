"""A browser session file read as hostile input: every byte, line and cell checked before it is used.

A ``_beh.tsv`` from an online study reaches the lab from an anonymous browser (downloaded and
mailed, or POSTed to ``--data-url``), so anyone taking part can edit it first. Nothing in it is
trusted until :func:`read_session_file` has checked, in this order:

1. the file itself: a regular file, no larger than a session of the protocol can be
   (:attr:`ImportContext.max_bytes`: the list's trials times the widest cells), UTF-8 without
   a byte-order mark, no NUL byte, no control character but the tab between cells, and ending in
   a line end (a file without one was cut off in transit);
2. the header: exactly the columns the export writes (:func:`experiments.web.export.web_columns`);
3. every cell, parsed to its column's type (:func:`cell_rules`): BIDS labels for the participant
   and list, whole numbers and finite numbers in range, the protocol's scale points and choice
   values, ``n/a`` only where the browser writes it, ISO 8601 times, the protocol's sha256;
   free text (the user agent, the recruitment site's URL parameters) length-limited;
4. the rows together: one participant, session, list, seed and protocol hash; trials 1, 2, 3 ...
   in order; the seed the lab runner gives that list; and every row the trial the exported list
   has at that position (phase, block, repetition, stimulus, factor levels): the importer
   rebuilds each list from the protocol and its stimuli, so a stimulus the export did not
   contain, a duplicated, lost or reordered trial, or another protocol's file is refused.

Each refusal is one line naming the file, the line and the column. The rows come back as the
checked strings; text a spreadsheet would run as a formula is neutralised when they are written
(:func:`experiments.datafile.format_cell`).
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import re
from dataclasses import dataclass, field
from pathlib import Path

from appeal.errors import AppealInputError
from appeal.labels import MAX_LABEL, MAX_SESSION, label_problem, shown
from appeal.text_bytes import decoded
from appeal.levels import level_key
from appeal.provenance import file_sha256
from experiments.clips import CLIP_COLUMNS
from experiments.datafile import format_cell
from experiments.protocol_schema import ClassificationSpec, LikertSpec, Protocol
from experiments.session import default_seed, load_protocol
from experiments.stimuli import StimulusSet, session_stimuli
from experiments.trials import Trial, build_trials
from experiments.web.export import web_columns

__all__ = ["Cell", "cell_rules", "ImportContext", "import_context", "SessionFile", "read_session_file",
           "MAX_TEXT", "MAX_PARAMETER"]

#: The longest user agent accepted (real ones are 100-300 characters).
MAX_TEXT = 1024
#: The longest recruitment-site URL parameter accepted (Prolific's ids are 24 characters).
MAX_PARAMETER = 256
#: Widest number cell (JavaScript writes ``1.7976931348623157e+308`` at most).
_NUMBER_WIDTH = 32
_NA = "n/a"
_INT = re.compile(r"-?[0-9]{1,15}")
_NUMBER = re.compile(r"-?[0-9]{1,20}(\.[0-9]{1,20})?([eE][-+]?[0-9]{1,3})?")
_SHA256 = re.compile(r"[0-9a-f]{64}")
_ISO = re.compile(r"[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:[0-9]{2}:[0-9]{2}(\.[0-9]{1,9})?(Z|[+-][0-9]{2}:[0-9]{2})")
#: Characters no cell may hold: C0/C1 controls (the tab separates cells), and the Unicode marks
#: that reorder or hide text when it is shown (bidirectional overrides and isolates, the BOM).
_FORBIDDEN = re.compile("[\x00-\x08\x0a-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069\ufeff]")


@dataclass(frozen=True)
class Cell:
    """How the cells of one column are checked.

    Attributes
    ----------
    kind : str
        ``"int"`` / ``"number"`` (in ``lo..hi``), ``"label"`` (BIDS), ``"choice"`` (one of
        ``choices``), ``"text"`` (free text), ``"trial"`` (compared with the exported list),
        ``"iso"`` (an ISO 8601 time), ``"sha256"`` or ``"na"`` (``n/a`` only: the browser has
        no such value).
    na : bool
        ``n/a`` is accepted too.
    lo, hi : float, optional
        Bounds of a number.
    choices : tuple of str
        The accepted values of a choice.
    width : int
        The most characters a cell may have.
    """

    kind: str
    na: bool = False
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] = ()
    width: int = _NUMBER_WIDTH

    def problem(self, text: str) -> str | None:
        """What is wrong with ``text`` as this column's cell (``expected ...``), or None."""
        if text == _NA and (self.na or self.kind == "na"):
            return None
        if len(text) > self.width:
            return f"expected at most {self.width} characters, found {len(text)}"
        if self.kind == "na":
            return "expected n/a (the browser writes no value here)"
        if self.kind in ("int", "number"):
            return self._number_problem(text)
        if self.kind == "label":
            return label_problem(text)
        if self.kind == "choice":
            return None if text in self.choices else f"expected one of {', '.join(self.choices)}{self._or_na}"
        if self.kind == "sha256":
            return None if _SHA256.fullmatch(text) else "expected a sha256 (64 hexadecimal digits)"
        if self.kind == "iso":
            return None if _iso_time(text) else "expected an ISO 8601 time (2026-01-31T12:00:00.000Z)"
        if self.kind in ("text", "trial"):
            return None if text or self.na else "expected a value"
        raise ValueError(f"unknown cell kind {self.kind!r}")

    @property
    def _or_na(self) -> str:
        return " or n/a" if self.na else ""

    def _number_problem(self, text: str) -> str | None:
        whole = self.kind == "int"
        if not (_INT if whole else _NUMBER).fullmatch(text):
            what = "a whole number" if whole else "a number"
            return f"expected {what}{self._range}{self._or_na}"
        value = float(text)
        if value != value or value in (float("inf"), float("-inf")):
            return f"expected a finite number{self._range}"
        if (self.lo is not None and value < self.lo) or (self.hi is not None and value > self.hi):
            return f"expected {'a whole number' if whole else 'a number'}{self._range}{self._or_na}"
        return None

    @property
    def _range(self) -> str:
        lo, hi = (None if v is None else f"{int(v)}" if float(v).is_integer() else f"{v:g}" for v in (self.lo, self.hi))
        if lo is not None and hi is not None:
            return f" from {lo} to {hi}"
        if lo is not None:
            return f" >= {lo}"
        return f" <= {hi}" if hi is not None else ""


def _iso_time(text: str) -> bool:
    if not _ISO.fullmatch(text):
        return False
    try:
        _dt.datetime.fromisoformat(text)
    except ValueError:
        return False
    return True


def _scale(spec: LikertSpec, extra: tuple[str, ...] = ()) -> Cell:
    return Cell("choice", na=True, choices=(*(str(v) for v in range(1, spec.points + 1)), *extra))


def _response_rules(spec: LikertSpec | ClassificationSpec) -> dict[str, Cell]:
    seconds = Cell("number", na=True, lo=0, hi=1e6)
    if isinstance(spec, LikertSpec):
        return {f"response_{spec.name}": _scale(spec), f"rt_{spec.name}": seconds}
    rules = {f"response_{spec.name}": Cell("choice", na=True, choices=tuple(level_key(c.value) for c in spec.choices),
                                           width=max(len(level_key(c.value)) for c in spec.choices)),
             f"rt_{spec.name}": seconds}
    if spec.factor is not None:
        rules[f"correct_{spec.name}"] = Cell("choice", na=True, choices=("0", "1"))
    if spec.intensity is not None:
        skip = () if spec.skip_value is None else (str(spec.skip_value),)
        rules[f"response_{spec.intensity.name}"] = _scale(spec.intensity, skip)
        rules[f"rt_{spec.intensity.name}"] = seconds
    return rules


def cell_rules(protocol: Protocol, columns: list[str]) -> dict[str, Cell]:
    """The check of every column of a browser session file of ``protocol``.

    Parameters
    ----------
    protocol : Protocol
        The protocol the study was exported from.
    columns : list of str
        The file's columns (:func:`experiments.web.export.web_columns`).

    Returns
    -------
    dict of str to Cell
        One rule per column; a column this function does not know is an error (a new column must
        say how it is checked).
    """
    count = Cell("int", lo=0, hi=1e9)
    count_na = Cell("int", na=True, lo=0, hi=1e9)
    seconds = Cell("number", na=True, lo=0, hi=1e7)
    pixels = Cell("int", lo=0, hi=1e5)
    trial_text = Cell("trial", width=1024)
    rules: dict[str, Cell] = {
        "participant_id": Cell("label", width=MAX_LABEL), "session": Cell("int", lo=1, hi=MAX_SESSION),
        "part": Cell("int", lo=1, hi=1e6), "trial": Cell("int", lo=1, hi=1e6), "phase": trial_text,
        "block": Cell("trial", na=True, width=1024), "repetition": Cell("int", lo=0, hi=1e6), "stimulus": trial_text,
        "fixation_frames": count_na, "fixation_onset_s": seconds, "onset_frame": count, "onset_s": seconds,
        "offset_s": seconds, "duration_frames": count, "shown_frames": count, "shown_s": seconds,
        "dropped_frames": count, "dropped_flag": Cell("choice", na=True, choices=("0", "1")), "repeat_of": Cell("na"),
        "trigger": Cell("na"), "trigger_s": Cell("na"), "trigger_flip_ms": Cell("na"),
        "list": Cell("label", width=MAX_LABEL), "list_trials": Cell("int", lo=1, hi=1e6), "seed": Cell("int", lo=0, hi=2 ** 31),
        "browser": Cell("text", width=MAX_TEXT), "screen_width": pixels, "screen_height": pixels,
        "window_width": pixels, "window_height": pixels, "refresh_hz": Cell("number", lo=1, hi=1000),
        "intended_s": Cell("number", lo=0, hi=1e6), "focus_losses": count, "fullscreen_losses": count,
        "recruitment_pid": Cell("text", na=True, width=MAX_PARAMETER),
        "study_id": Cell("text", na=True, width=MAX_PARAMETER), "session_id": Cell("text", na=True, width=MAX_PARAMETER),
        "started": Cell("iso", width=40), "protocol_sha256": Cell("sha256", width=64),
    }
    rules.update({c: count_na for c in CLIP_COLUMNS})
    rules.update({c: seconds for c in ("clip_fps", "clip_flips_per_frame", "clip_onset_s", "clip_apex_s")})
    rules["clip_preload_ms"] = Cell("number", na=True, lo=0, hi=1e9)
    rules.update({f: Cell("trial", width=1024) for f in protocol.stimuli.factors})
    for spec in protocol.responses:
        rules.update(_response_rules(spec))
    unknown = [c for c in columns if c not in rules]
    if unknown:
        raise ValueError(f"no check for the session-file column(s) {', '.join(unknown)}")
    return {c: rules[c] for c in columns}


@dataclass
class ImportContext:
    """What checking a protocol's browser session files needs, built once per import.

    Attributes
    ----------
    protocol, protocol_file, protocol_sha256
        The protocol the study was exported from, its file and the file's sha256.
    full, main : StimulusSet
        Its stimuli (the whole set and the main trials' selection), to rebuild the trial lists.
    columns : list of str
        The header a session file must have.
    rules : dict of str to Cell
        The check of each column.
    n_trials : int
        Trials in a list.
    max_bytes : int
        The largest file a session of this protocol can be.
    """

    protocol: Protocol
    protocol_file: Path
    protocol_sha256: str
    full: StimulusSet
    main: StimulusSet
    columns: list[str]
    rules: dict[str, Cell]
    n_trials: int
    max_bytes: int
    _lists: dict[tuple[str, int], list[Trial]] = field(default_factory=dict, repr=False)

    def trial_list(self, slot: str, session: int) -> list[Trial]:
        """The exported trial list of participant slot ``slot`` in ``session`` (the lab runner's)."""
        key = (slot, session)
        if key not in self._lists:
            seed = default_seed(self.protocol.name, slot, session)
            self._lists[key] = build_trials(self.protocol, self.main, seed=seed,
                                            refresh_hz=float(self.protocol.screen.refresh_hz or 60.0),
                                            source=str(self.protocol_file), full_set=self.full)
        return self._lists[key]


def import_context(protocol_file: str | Path, stimuli: str | Path | None = None) -> ImportContext:
    """The :class:`ImportContext` of ``protocol_file`` (its stimuli from the protocol or ``stimuli``).

    Raises
    ------
    AppealInputError
        When the protocol or its stimuli cannot be loaded (the lists cannot be rebuilt without them).
    """
    protocol_file = Path(protocol_file)
    protocol = load_protocol(protocol_file)
    try:
        full, main = session_stimuli(protocol, protocol_file, stimuli)
    except AppealInputError as exc:
        raise AppealInputError(f"{exc.lines[0]} (the importer rebuilds each participant's trial list from the "
                               "protocol's stimuli to check the rows; --stimuli names another copy)") from None
    columns = web_columns(protocol, clips=full.has_clips)
    rules = cell_rules(protocol, columns)
    ctx = ImportContext(protocol, protocol_file, file_sha256(protocol_file), full, main, columns, rules, 0, 0)
    ctx.n_trials = len(ctx.trial_list("01", 1))
    widths = {**{c: r.width for c, r in rules.items()},
              **{f: max(len(str(v)) for v in full.table[f]) for f in protocol.stimuli.factors},
              "stimulus": max(len(s) for s in full.table["stimulus"])}
    line = sum(min(widths[c], rules[c].width) for c in columns) + len(columns)
    ctx.max_bytes = len("\t".join(columns)) + 2 + ctx.n_trials * (line + 1)
    return ctx


@dataclass
class SessionFile:
    """One checked browser session file.

    Attributes
    ----------
    source : Path
        The file.
    rows : list of dict of str to str
        Its rows, every cell checked.
    participant, list, seed, session
        The participant's label, the exported list it was given, that list's seed and the session.
    n_list : int
        Trials in that list (the session is complete when it has as many rows).
    sha256 : str
        The sha256 of the file's bytes as received.
    """

    source: Path
    rows: list[dict[str, str]]
    participant: str
    session: int
    list: str
    seed: int
    n_list: int
    sha256: str

    @property
    def complete(self) -> bool:
        """Whether every trial of the list is in the file."""
        return len(self.rows) == self.n_list


def _read_text(path: Path, ctx: ImportContext) -> tuple[str, bytes]:
    """The file's text and bytes, after the checks on the file as a whole (1 above)."""
    if not path.exists():
        raise AppealInputError(f"{path}: no such file")
    if not path.is_file():
        raise AppealInputError(f"{path}: not a regular file (expected a browser session file "
                               f"sub-ID_ses-N_task-{ctx.protocol.task}_beh.tsv)")
    if path.suffix != ".tsv":
        raise AppealInputError(f"{path}: expected a browser session file sub-ID_ses-N_task-{ctx.protocol.task}_beh.tsv")
    size = path.stat().st_size
    if size > ctx.max_bytes:
        raise AppealInputError(f"{path}: {size} bytes, more than a session of {ctx.protocol.name} can hold "
                               f"({ctx.max_bytes} bytes for {ctx.n_trials} trials): not a session file of this protocol")
    with open(path, "rb") as fh:
        data = fh.read(ctx.max_bytes + 1)
    if len(data) > ctx.max_bytes:
        raise AppealInputError(f"{path}: more than the {ctx.max_bytes} bytes a session of {ctx.protocol.name} can hold")
    if not data:
        raise AppealInputError(f"{path}: empty file (expected a header line and one line per trial)")
    text = decoded(data, str(path), "text (UTF-8) as the browser writes it", bom=False)
    if not text.endswith("\n"):
        raise AppealInputError(f"{path}:{text.count(chr(10)) + 1}: the last line has no line end: the file was cut off "
                               "(a truncated download or upload?); get the participant's file again")
    return text.replace("\r\n", "\n"), data


def _check_header(header: list[str], path: Path, ctx: ImportContext) -> None:
    if header == ctx.columns:
        return
    for k, (found, expected) in enumerate(zip(header, ctx.columns), start=1):
        if found != expected:
            raise AppealInputError(f"{path}:1: column {k}: expected '{expected}', found {shown(found)} (the header "
                                   f"{ctx.protocol.name}'s export writes; exported from another protocol or version?)")
    raise AppealInputError(f"{path}:1: header: expected the {len(ctx.columns)} columns {ctx.protocol.name}'s export "
                           f"writes, found {len(header)}")


def _parse_rows(lines: list[str], path: Path, ctx: ImportContext) -> list[dict[str, str]]:
    """Every row's cells checked against their column's rule (3 above)."""
    rows = []
    rules = [(c, ctx.rules[c]) for c in ctx.columns]
    for number, line in enumerate(lines, start=2):
        bad = _FORBIDDEN.search(line)
        if bad:
            col = ctx.columns[min(line.count("\t", 0, bad.start()), len(ctx.columns) - 1)]
            raise AppealInputError(f"{path}:{number}: column '{col}': a control character (U+{ord(bad.group()):04X}): "
                                   "expected printable text")
        cells = line.split("\t")
        if len(cells) != len(rules):
            raise AppealInputError(f"{path}:{number}: expected {len(rules)} tab-separated cells, found {len(cells)}")
        for (col, rule), text in zip(rules, cells):
            problem = rule.problem(text)
            if problem is not None:
                raise AppealInputError(f"{path}:{number}: column '{col}': {problem}, found {shown(text)}")
        rows.append(dict(zip(ctx.columns, cells)))
    return rows


def _one(rows: list[dict[str, str]], column: str, path: Path) -> str:
    first = rows[0][column]
    for number, row in enumerate(rows, start=2):
        if row[column] != first:
            raise AppealInputError(f"{path}:{number}: column '{column}': expected {shown(first)} as in every row of "
                                   f"a session file, found {shown(row[column])}")
    return first


def _check_session(rows: list[dict[str, str]], path: Path, ctx: ImportContext) -> SessionFile:
    """The rows together and against the exported list (4 above)."""
    participant, slot = _one(rows, "participant_id", path), _one(rows, "list", path)
    session, seed = int(_one(rows, "session", path)), int(_one(rows, "seed", path))
    sha = _one(rows, "protocol_sha256", path)
    for c in ("list_trials", "started"):
        _one(rows, c, path)
    if sha != ctx.protocol_sha256:
        raise AppealInputError(f"{path}:2: column 'protocol_sha256': the session ran a protocol with sha256 {sha[:12]}..., "
                               f"{ctx.protocol_file} has {ctx.protocol_sha256[:12]}... (changed since the export, or "
                               "another protocol: import with the file the study was exported from)")
    if seed != default_seed(ctx.protocol.name, slot, session):
        raise AppealInputError(f"{path}:2: column 'seed': {seed} is not the seed of list {slot} of protocol "
                               f"'{ctx.protocol.name}' in session {session} (exported from another protocol?)")
    parts = 1
    for number, row in enumerate(rows, start=2):
        if int(row["trial"]) != number - 1:
            raise AppealInputError(f"{path}:{number}: column 'trial': expected {number - 1} (trials 1, 2, 3 ... in order), "
                                   f"found {row['trial']} (a lost, repeated or reordered trial?)")
        if int(row["part"]) < parts:
            raise AppealInputError(f"{path}:{number}: column 'part': expected {parts} or more (parts only grow), "
                                   f"found {row['part']}")
        parts = int(row["part"])
    trials = ctx.trial_list(slot, session)
    n_list = int(rows[0]["list_trials"])
    if n_list != len(trials):
        raise AppealInputError(f"{path}:2: column 'list_trials': list {slot} has {len(trials)} trials, found {n_list}")
    if len(rows) > len(trials):
        raise AppealInputError(f"{path}:{len(trials) + 2}: more rows than the {len(trials)} trials of list {slot}")
    for number, (row, t) in enumerate(zip(rows, trials), start=2):
        planned = {"phase": t.phase, "block": t.block, "repetition": str(t.repetition), "stimulus": t.stimulus,
                   **t.factors}
        for col, value in planned.items():
            if row[col] != format_cell(value):
                raise AppealInputError(f"{path}:{number}: column '{col}': expected {shown(value, 80)} (trial {t.trial} "
                                       f"of list {slot}), found {shown(row[col], 80)}: not the exported trial")
    return SessionFile(path, rows, participant, session, slot, seed, n_list, "")


def read_session_file(path: str | Path, ctx: ImportContext) -> SessionFile:
    """Read and check one browser session file of ``ctx.protocol`` (module docstring: what is checked).

    Parameters
    ----------
    path : path-like
        The ``sub-ID_ses-N_task-TASK_beh.tsv`` file; it is only read, never changed.
    ctx : ImportContext
        The protocol's checks (:func:`import_context`).

    Returns
    -------
    SessionFile

    Raises
    ------
    AppealInputError
        One line naming the file, the line and the column of the first problem.
    """
    path = Path(path)
    text, data = _read_text(path, ctx)
    lines = text[:-1].split("\n")
    _check_header(lines[0].split("\t"), path, ctx)
    if len(lines) == 1:
        raise AppealInputError(f"{path}: no trials (a header only)")
    if len(lines) - 1 > ctx.n_trials:
        raise AppealInputError(f"{path}:{ctx.n_trials + 2}: more rows than the {ctx.n_trials} trials of a list of "
                               f"{ctx.protocol.name}")
    found = _check_session(_parse_rows(lines[1:], path, ctx), path, ctx)
    found.sha256 = hashlib.sha256(data).hexdigest()
    return found

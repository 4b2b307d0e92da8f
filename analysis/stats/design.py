"""Long-format rating tables → a checked subject × cell array (the input of every test here).

Every statistic in :mod:`analysis.stats` works on a :class:`Design`: one row per subject,
one column per within-subject cell (the within factors crossed, the first factor varying
slowest), plus the between-subject group of each subject. :func:`prepare_design` builds it
from a tidy table and raises :class:`~appeal.errors.AppealInputError` with one line per
problem (missing columns, non-numeric or out-of-scale values with their row numbers, a
subject missing cells, repeated trials without ``aggregate``, one-level factors, a DV
without variance).
"""

from __future__ import annotations

import glob
import itertools
import re
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from appeal.errors import AppealInputError
from appeal.text_bytes import decoded
from appeal.logs import logger

__all__ = ["Design", "prepare_design", "read_table", "read_ratings", "factor_levels", "rows_text"]

_MAX_LISTED = 8


@dataclass
class Design:
    """A complete repeated-measures design.

    Attributes
    ----------
    Y : ndarray, shape (n_subjects, n_cells)
        The DV per subject and within cell; cells are the within factors crossed in
        C order (the first factor varies slowest).
    subjects : list of str
        Subject ids in row order.
    within : dict of str to list of str
        Within factors and their level labels, in the order given.
    between : dict of str to list of str
        Between factors and their level labels, in the order given.
    group : ndarray of int, shape (n_subjects,)
        Index of each subject's between cell (the between factors crossed, C order);
        all zero without between factors.
    dropped : list of str
        Subjects removed by ``drop_incomplete``.
    dv, subject : str
        Column names, for messages and reports.
    source : str
        Where the data came from (used in error messages).
    n_rows_per_cell : ndarray of int, shape (n_subjects, n_cells)
        How many rows were averaged into each value.
    """

    Y: np.ndarray
    subjects: list[str]
    within: dict[str, list[str]]
    between: dict[str, list[str]]
    group: np.ndarray
    dv: str
    subject: str
    source: str = "<data>"
    dropped: list[str] = field(default_factory=list)
    n_rows_per_cell: np.ndarray | None = None

    @property
    def n(self) -> int:
        """Number of subjects."""
        return self.Y.shape[0]

    @property
    def shape(self) -> tuple[int, ...]:
        """Number of levels of each within factor."""
        return tuple(len(v) for v in self.within.values())

    @property
    def between_shape(self) -> tuple[int, ...]:
        """Number of levels of each between factor."""
        return tuple(len(v) for v in self.between.values())

    @property
    def n_groups(self) -> int:
        """Number of between cells (1 without between factors)."""
        return int(np.prod(self.between_shape)) if self.between else 1

    def cell_labels(self) -> list[tuple[str, ...]]:
        """The level labels of every within cell, in column order."""
        return list(itertools.product(*self.within.values()))

    def group_labels(self) -> list[tuple[str, ...]]:
        """The level labels of every between cell, in group-index order."""
        return list(itertools.product(*self.between.values())) if self.between else [()]

    def long(self) -> pd.DataFrame:
        """The design back as a tidy table (one row per subject and cell)."""
        cells = self.cell_labels()
        groups = self.group_labels()
        rows = []
        for i, s in enumerate(self.subjects):
            g = groups[self.group[i]]
            for j, c in enumerate(cells):
                rows.append((s, *g, *c, self.Y[i, j]))
        return pd.DataFrame(rows, columns=[self.subject, *self.between, *self.within, self.dv])


# --------------------------------------------------------------------------- reading
#: The largest table read (bytes; of a ``.gz`` file, once decompressed). A session file is a few
#: hundred kB; a long table of a million ratings ~100 MB.
MAX_TABLE_BYTES = 256 * 2 ** 20

_TEXT_SUFFIXES = {".csv": ",", ".csv.gz": ",", ".tsv": "\t", ".tsv.gz": "\t", ".txt": "\t"}


def _size_text(n: int) -> str:
    return f"{n // 2 ** 20} MB" if n >= 2 ** 20 else f"{n} bytes"


def _kind_of(path: Path) -> str | None:
    """What ``path`` is when it is not a regular file (``a folder``, ``a pipe (FIFO)`` ...), else None."""
    import stat

    try:
        mode = path.stat().st_mode
    except OSError:
        return "missing"
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a pipe (FIFO)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a device"


def _read_bytes(path: Path, gz: bool) -> bytes:
    """The file's bytes (decompressed for ``gz``), at most :data:`MAX_TABLE_BYTES`; a one-line error beyond."""
    import gzip
    import zlib

    limit = MAX_TABLE_BYTES
    if not gz and path.stat().st_size > limit:
        raise AppealInputError(f"{path}: the table is larger than {_size_text(limit)} (expected a data table; split "
                               "it into per-session files)")
    try:
        with (gzip.open(path, "rb") if gz else open(path, "rb")) as fh:
            data = fh.read(limit + 1)
    except (OSError, EOFError, zlib.error) as exc:
        why = getattr(exc, "strerror", None) or (str(exc).splitlines() or [type(exc).__name__])[0]
        raise AppealInputError(f"{path}: cannot read the file ({why})") from None
    if len(data) > limit:
        raise AppealInputError(f"{path}: the table is larger than {_size_text(limit)}"
                               + (" once decompressed" if gz else "") + " (expected a data table; split it into "
                               "per-session files)")
    return data


def _text_of(path: Path, data: bytes) -> str:
    """The bytes of a CSV/TSV as text: one-line errors for binary data, text that is not UTF-8, an empty file."""
    text = decoded(data, str(path), "UTF-8 CSV/TSV text")
    if not text.strip():
        raise AppealInputError(f"{path}: the file is empty (expected a header row and data rows)")
    return text


def _longer_row(text: str, sep: str) -> str:
    """Where the first row with more fields than the header is (the message of a ragged table)."""
    import csv
    import io

    reader = csv.reader(io.StringIO(text), delimiter=sep)
    header = next(reader, [])
    for row in reader:
        if len(row) > len(header):
            return (f"line {reader.line_num}: expected at most {len(header)} fields (the header's), "
                    f"found {len(row)}")
    return f"rows with more fields than the header's {len(header)}"


def read_table(path: str | Path, text_columns: Sequence[str] = (), *, all_text: bool = False) -> pd.DataFrame:
    """Read one long-format table (CSV, TSV or Parquet; chosen by the file suffix).

    ``text_columns`` are read as text (a BIDS participant label ``01`` stays ``01``); ``all_text``
    reads every cell as the text it is (``n/a`` and empty cells too). The file may
    come from anyone (an online participant's session), so it is read as hostile: it must be a
    regular file (not a folder, pipe or device) of at most :data:`MAX_TABLE_BYTES` (a ``.gz`` once
    decompressed); a CSV/TSV must be UTF-8 text without NUL bytes, with a header and rows of at
    most as many fields. Each problem is one line naming the file.

    Raises
    ------
    AppealInputError
        When the file is missing, not a regular file, too large, of an unknown type, not text,
        empty or cannot be parsed.
    """
    import io

    path = Path(path)
    kind = _kind_of(path)
    if kind == "missing":
        raise AppealInputError(f"{path}: file not found")
    if kind is not None:
        raise AppealInputError(f"{path}: expected a data file, got {kind}")
    suffix = "".join(path.suffixes[-2:]).lower() if path.suffix.lower() == ".gz" else path.suffix.lower()
    if suffix not in _TEXT_SUFFIXES and suffix not in (".parquet", ".pq"):
        raise AppealInputError(f"{path}: unknown table type '{suffix}' (expected .csv, .tsv or .parquet)")
    if suffix in _TEXT_SUFFIXES:
        text = _text_of(path, _read_bytes(path, suffix.endswith(".gz")))
    elif path.stat().st_size > MAX_TABLE_BYTES:
        raise AppealInputError(f"{path}: the table is larger than {_size_text(MAX_TABLE_BYTES)} (expected a data "
                               "table; split it into per-session files)")
    try:
        if suffix in _TEXT_SUFFIXES:
            sep = _TEXT_SUFFIXES[suffix]
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", pd.errors.ParserWarning)
                # index_col=False: a first row longer than the header is not taken as index columns
                dtype = str if all_text else {c: str for c in text_columns}
                df = pd.read_csv(io.StringIO(text), sep=sep, dtype=dtype, index_col=False,
                                 keep_default_na=not all_text)
            if any(issubclass(w.category, pd.errors.ParserWarning) for w in caught):
                raise AppealInputError(f"{path}: {_longer_row(text, sep)}")
        else:
            df = pd.read_parquet(path)
    except AppealInputError:
        raise
    except Exception as exc:  # noqa: BLE001 - parser errors become one input line
        msg = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise AppealInputError(f"{path}: cannot read table ({msg})") from None
    df.attrs["source"] = str(path)
    return df


_SUB_ENTITY = re.compile(r"(?:^|[_/])sub-([A-Za-z0-9]+)")


def read_ratings(paths: str | Path | Sequence[str | Path], subject: str = "participant_id") -> pd.DataFrame:
    """Read rating data: one table, or a glob / list of per-session files (BIDS ``*_beh.tsv``).

    Files are concatenated. When a file has no ``subject`` column, the subject comes from
    its ``sub-<id>`` file-name entity. A column ``source_file`` records where each row came
    from, and ``source_row`` the row number inside that file (1 = first row after the header).

    Raises
    ------
    AppealInputError
        When nothing matches, or a file has neither the subject column nor a sub- entity.
    """
    if isinstance(paths, (str, Path)):
        text = str(paths)
        files = sorted(glob.glob(text)) if any(ch in text for ch in "*?[") else [text]
        if not files:
            raise AppealInputError(f"{text}: data: no file matches this pattern")
    else:
        files = [str(p) for p in paths]
        if not files:
            raise AppealInputError("data: no files given")
    frames = []
    for f in files:
        df = read_table(f, text_columns=[subject])
        if subject not in df.columns:
            m = _SUB_ENTITY.search(Path(f).name) or _SUB_ENTITY.search(str(f))
            if not m:
                raise AppealInputError(f"{f}: subject: no column '{subject}' and no 'sub-<id>' in the file name")
            df[subject] = m.group(1)
        df["source_file"] = str(f)
        df["source_row"] = np.arange(1, len(df) + 1)
        frames.append(df)
    out = pd.concat(frames, ignore_index=True) if len(frames) > 1 else frames[0]
    out.attrs["source"] = files[0] if len(files) == 1 else f"{files[0]} (+{len(files) - 1} more files)"
    return out


def keep_rows(data: pd.DataFrame, rows: dict[str, Sequence]) -> pd.DataFrame:
    """Rows whose column ``c`` holds one of ``rows[c]`` (columns absent from ``data`` are ignored).

    Values are compared as text, so ``main`` matches whether the column was read as text or not.
    """
    mask = np.ones(len(data), dtype=bool)
    for col, values in rows.items():
        if col in data.columns:
            mask &= data[col].astype(str).isin([str(v) for v in values]).to_numpy()
    out = data.loc[mask].reset_index(drop=True)
    out.attrs.update(data.attrs)
    return out


# --------------------------------------------------------------------------- checks
def rows_text(rows: Sequence[int]) -> str:
    """'rows 3, 7, 9' with at most a few listed."""
    rows = list(rows)
    shown = ", ".join(str(r) for r in rows[:_MAX_LISTED])
    more = f" and {len(rows) - _MAX_LISTED} more" if len(rows) > _MAX_LISTED else ""
    return f"row{'s' if len(rows) > 1 else ''} {shown}{more}"


def _row_numbers(data: pd.DataFrame, mask: np.ndarray) -> list[str]:
    """Human row numbers of the True rows (file:row when several files were read)."""
    idx = np.flatnonzero(mask)
    if "source_row" in data.columns and "source_file" in data.columns and data["source_file"].nunique() > 1:
        sub = data.iloc[idx]
        return [f"{Path(f).name}:{r}" for f, r in zip(sub["source_file"], sub["source_row"])]
    if "source_row" in data.columns:
        return [str(int(r)) for r in data["source_row"].to_numpy()[idx]]
    return [str(i + 1) for i in idx]


def level_key(value: object) -> tuple:
    """What identifies a factor level across files: its number when it reads as one (the runner
    writes shape 1.0 as ``1``, a study file says ``1.0``), else its text."""
    if not isinstance(value, (bool, np.bool_)):
        try:
            return ("n", float(value))
        except (TypeError, ValueError):
            pass
    return ("s", str(value))


def factor_levels(values: pd.Series, order: Sequence | None = None) -> list:
    """The levels of a factor column: ``order`` if given (matched by :func:`level_key`),
    categories, else sorted values."""
    present = pd.unique(values.dropna())
    if order is not None:
        order = list(order)
        given = {level_key(o) for o in order}
        missing = [v for v in present if level_key(v) not in given]
        if missing:
            raise ValueError(f"values {', '.join(map(str, missing[:_MAX_LISTED]))} are not among the given levels")
        have = {level_key(p) for p in present}
        return [o for o in order if level_key(o) in have]
    if isinstance(values.dtype, pd.CategoricalDtype):
        return [c for c in values.cat.categories if c in set(present)]
    try:
        return sorted(present)
    except TypeError:
        return sorted(present, key=str)


def _check_columns(data: pd.DataFrame, source: str, named: Mapping[str, Sequence[str]]) -> None:
    problems = []
    cols = [str(c) for c in data.columns]
    for role, names in named.items():
        for name in names:
            if name not in data.columns:
                import difflib

                close = difflib.get_close_matches(name, cols, n=1)
                hint = f"did you mean '{close[0]}'?" if close else f"columns: {', '.join(cols[:12])}"
                problems.append(f"{source}: {role}: column '{name}' not found ({hint})")
    if problems:
        raise AppealInputError(problems)


def prepare_design(
    data: pd.DataFrame,
    dv: str,
    subject: str,
    within: Sequence[str],
    between: Sequence[str] = (),
    aggregate: str | None = None,
    drop_incomplete: bool = False,
    *,
    scale: tuple[float, float] | None = None,
    levels: Mapping[str, Sequence] | None = None,
    source: str | None = None,
    min_within: int = 1,
) -> Design:
    """Check a long-format table and build the subject × cell :class:`Design`.

    Parameters
    ----------
    data : DataFrame
        One row per trial (or per subject and cell).
    dv : str
        The dependent-variable column (numeric).
    subject : str
        The subject-id column.
    within, between : sequence of str
        Within- and between-subject factor columns.
    aggregate : {"mean", None}
        ``"mean"`` averages repeated rows of a subject × cell; None makes them an error.
    drop_incomplete : bool
        Drop subjects that miss a cell (listed in ``Design.dropped``) instead of raising.
    scale : (low, high) or None
        Allowed range of the DV (e.g. ``(1, 7)`` for a 7-point Likert scale).
    levels : mapping of str to sequence, optional
        Level order per factor (default: categorical order, else sorted).
    source : str, optional
        Name used in error messages (default ``data.attrs["source"]`` or ``<data>``).
    min_within : int
        How many within factors are required.

    Returns
    -------
    Design

    Raises
    ------
    AppealInputError
        One line per problem, naming the source, the field and what was expected.
    """
    src = source or data.attrs.get("source", "<data>")
    within, between = list(within), list(between)
    levels = dict(levels or {})
    if len(within) < min_within:
        raise AppealInputError(f"{src}: within: at least {min_within} within-subject factor(s) expected (got {len(within)})")
    names = [subject, dv, *within, *between]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise AppealInputError(f"{src}: factors: each column may have one role only (used twice: {', '.join(dup)})")
    _check_columns(data, src, {"dv": [dv], "subject": [subject], "within": within, "between": between})
    if aggregate not in (None, "mean"):
        raise AppealInputError(f"{src}: aggregate: expected 'mean' or none (got {aggregate!r})")
    problems: list[str] = []

    raw = data[dv]
    if pd.api.types.is_numeric_dtype(raw.dtype):
        values = raw.to_numpy(dtype=float)
    else:
        values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
        blank = raw.isna().to_numpy() | raw.astype(str).str.strip().isin(["", "n/a", "NA", "nan", "NaN"]).to_numpy()
        bad = np.isnan(values) & ~blank
        if bad.any():
            examples = ", ".join(repr(v) for v in pd.unique(raw[bad])[:3])
            problems.append(f"{src}: {dv}: non-numeric values in {rows_text(_row_numbers(data, bad))} (e.g. {examples}); expected numbers")
    if scale is not None:
        lo, hi = scale
        out = ~np.isnan(values) & ((values < lo) | (values > hi))
        if out.any():
            examples = ", ".join(f"{v:g}" for v in pd.unique(values[out])[:3])
            problems.append(f"{src}: {dv}: values outside the scale {lo:g}..{hi:g} in {rows_text(_row_numbers(data, out))} (e.g. {examples})")
    for col in [subject, *within, *between]:
        miss = data[col].isna().to_numpy()
        if miss.any():
            problems.append(f"{src}: {col}: empty values in {rows_text(_row_numbers(data, miss))}; expected a level in every row")
    if problems:
        raise AppealInputError(problems)

    keep = ~np.isnan(values)
    if not keep.any():
        raise AppealInputError(f"{src}: {dv}: no numeric values")
    if not keep.all():
        logger.info("%s: %d rows without a %s value are ignored", src, int((~keep).sum()), dv)
    y = values[keep]

    # factor codes via factorize (fast), mapped onto the level order
    fac_levels: dict[str, list] = {}
    codes: dict[str, np.ndarray] = {}
    for col in [*between, *within]:
        raw_codes, uniques = pd.factorize(data[col].to_numpy()[keep])
        try:
            lv = factor_levels(pd.Series(uniques, dtype=data[col].dtype if isinstance(data[col].dtype, pd.CategoricalDtype) else None),
                               levels.get(col))
        except ValueError as exc:
            problems.append(f"{src}: levels.{col}: {exc}")
            continue
        if len(lv) < 2:
            got = f"only '{lv[0]}'" if lv else "none"
            problems.append(f"{src}: {col}: a factor needs at least 2 levels (got {got})")
        pos = {level_key(v): i for i, v in enumerate(lv)}
        lut = np.array([pos[level_key(u)] for u in uniques], dtype=np.int64)
        fac_levels[col] = lv
        codes[col] = lut[raw_codes]
    if problems:
        raise AppealInputError(problems)

    subj_codes, subj_uniques = pd.factorize(data[subject].to_numpy()[keep])
    subj_str = [str(u) for u in subj_uniques]
    subjects_all = sorted(subj_str)
    rank = np.empty(len(subj_str), dtype=np.int64)
    rank[np.argsort(subj_str, kind="stable")] = np.arange(len(subj_str))
    si = rank[subj_codes]
    n_s = len(subjects_all)

    # between factors: constant within subject
    if between:
        mixed_s = np.zeros(n_s, dtype=bool)
        for col in between:
            lo_c = np.full(n_s, np.iinfo(np.int64).max)
            hi_c = np.full(n_s, -1)
            np.minimum.at(lo_c, si, codes[col])
            np.maximum.at(hi_c, si, codes[col])
            mixed_s |= lo_c != hi_c
        if mixed_s.any():
            who = ", ".join(subjects_all[i] for i in np.flatnonzero(mixed_s)[:_MAX_LISTED])
            raise AppealInputError(f"{src}: between: subjects {who} have more than one level of a between factor ({', '.join(between)})")

    shape = tuple(len(fac_levels[c]) for c in within)
    n_cells = int(np.prod(shape))
    ci = np.ravel_multi_index(tuple(codes[c] for c in within), shape)
    counts = np.bincount(si * n_cells + ci, minlength=n_s * n_cells).reshape(n_s, n_cells)
    sums = np.bincount(si * n_cells + ci, weights=y, minlength=n_s * n_cells).reshape(n_s, n_cells)

    cell_labels = list(itertools.product(*(map(str, fac_levels[c]) for c in within)))

    def cell_text(j: int) -> str:
        return ", ".join(f"{f}={lv}" for f, lv in zip(within, cell_labels[j]))

    if aggregate is None and (counts > 1).any():
        i, j = np.argwhere(counts > 1)[0]
        n_rep = int((counts > 1).sum())
        raise AppealInputError(
            f"{src}: {dv}: {n_rep} subject x cell combinations have more than one row "
            f"(e.g. subject {subjects_all[i]}, {cell_text(j)}: {counts[i, j]} rows); "
            f"expected one row per subject and cell, or aggregate: mean to average repeated trials")

    missing = counts == 0
    dropped: list[str] = []
    if missing.any():
        bad_subj = np.flatnonzero(missing.any(axis=1))
        if not drop_incomplete:
            lines = []
            for i in bad_subj[:_MAX_LISTED]:
                cells = np.flatnonzero(missing[i])
                listed = "; ".join(cell_text(j) for j in cells[:4]) + (f"; and {len(cells) - 4} more" if len(cells) > 4 else "")
                lines.append(f"{subjects_all[i]} ({listed})")
            more = f" and {len(bad_subj) - _MAX_LISTED} more subjects" if len(bad_subj) > _MAX_LISTED else ""
            raise AppealInputError(
                f"{src}: {dv}: {len(bad_subj)} subject(s) miss cells of the within design: {' | '.join(lines)}{more}; "
                "expected every subject in every cell (drop them with drop_incomplete, or use the mixed model)")
        dropped = [subjects_all[i] for i in bad_subj]
        logger.warning("%s: dropped %d incomplete subject(s): %s", src, len(dropped), ", ".join(dropped))

    keep_s = ~missing.any(axis=1)
    Y = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)[keep_s]
    subjects = [s for s, k in zip(subjects_all, keep_s) if k]
    if len(subjects) < 2:
        raise AppealInputError(f"{src}: {subject}: at least 2 complete subjects expected (got {len(subjects)})")

    if between:
        bshape = tuple(len(fac_levels[c]) for c in between)
        first_row = np.full(n_s, -1)
        first_row[si[::-1]] = np.arange(len(si))[::-1]
        bcodes = [codes[c][first_row][keep_s] for c in between]
        group = np.ravel_multi_index(tuple(bcodes), bshape)
        n_groups = int(np.prod(bshape))
        present = np.bincount(group, minlength=n_groups)
        if (present == 0).any():
            empty = [", ".join(f"{f}={lv}" for f, lv in zip(between, lab))
                     for lab, k in zip(itertools.product(*(map(str, fac_levels[c]) for c in between)), present) if k == 0]
            raise AppealInputError(f"{src}: between: no complete subject in group(s) {'; '.join(empty)}; expected every between cell to be filled")
        if len(subjects) - n_groups < 1:
            raise AppealInputError(f"{src}: {subject}: {len(subjects)} subjects in {n_groups} groups leave no error df; expected more subjects")
    else:
        group = np.zeros(len(subjects), dtype=int)

    if np.nanvar(Y) == 0:
        raise AppealInputError(f"{src}: {dv}: the DV has zero variance (every value is {Y.flat[0]:g}); expected varying responses")

    return Design(
        Y=Y, subjects=subjects,
        within={c: [str(v) for v in fac_levels[c]] for c in within},
        between={c: [str(v) for v in fac_levels[c]] for c in between},
        group=np.asarray(group, dtype=int), dv=dv, subject=subject, source=str(src), dropped=dropped,
        n_rows_per_cell=counts[keep_s],
    )

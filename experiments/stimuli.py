"""Stimulus sets: a grid ``manifest.csv`` or a folder of images plus a factor table."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from appeal.cells import formula_like
from appeal.errors import AppealInputError
from appeal.labels import shown
from appeal.levels import level_key, order_levels
from experiments.clips import clip_frame_files, rate_problem
from experiments.protocol_schema import Protocol, Selection, StimulusSource

__all__ = ["protocol_input_problems", "StimulusSet", "load_stimuli", "select_stimuli", "session_stimuli",
           "clip_rate_problems", "IMAGE_SUFFIXES", "CLIP_TABLE_COLUMNS"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".gif")


@dataclass(frozen=True)
class StimulusSet:
    """Images with their factor levels.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per image: ``stimulus`` (the file as written in the table), ``path``
        (absolute) and one string column per factor (levels compared as text). Clip rows
        (a table with a ``frames`` column) have ``path`` = their folder of PNG frames and
        :data:`CLIP_TABLE_COLUMNS` (``frames``, ``n_frames``, ``fps``, ``onset_frame``,
        ``apex_frame``; None in still rows).
    factors : list of str
        The factor columns, in protocol order.
    source : Path
        The manifest or factor table the set came from.
    """

    table: pd.DataFrame
    factors: list[str]
    source: Path
    order: dict[str, list[str]] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.table)

    def levels(self, factor: str) -> list[str]:
        """The levels of ``factor``: in the protocol's declared order, else natural order."""
        return order_levels(self.table[factor], self.order.get(factor, ()))

    @property
    def has_clips(self) -> bool:
        """Whether any row is a clip (a folder of PNG frames, :mod:`experiments.clips`)."""
        return "frames" in self.table and bool(self.table["frames"].notna().any())


def _read_table(path: Path, what: str) -> pd.DataFrame:
    if not path.is_file():
        raise AppealInputError(f"{path}: {what} not found")
    sep = "\t" if path.suffix.lower() == ".tsv" else ","
    try:
        df = pd.read_csv(path, sep=sep, dtype=str, keep_default_na=False)
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise AppealInputError(f"{path}: cannot read {what} as a table ({str(exc).splitlines()[0]})") from None
    df.columns = [str(c).strip() for c in df.columns]
    return df


def load_stimuli(source: StimulusSource, *, override: str | Path | None = None, protocol_file: str | Path = "protocol",
                 apply_select: bool = True) -> StimulusSet:
    """Load the stimulus table a protocol names (or ``override``, as given by ``--stimuli``).

    Parameters
    ----------
    source : StimulusSource
        The protocol's ``stimuli`` section (factors, selection, paths).
    override : str | Path | None
        A manifest/factor-table CSV (images relative to it) or a folder holding
        ``manifest.csv`` (or ``factors.csv``); replaces the protocol's source.
    protocol_file : str | Path
        Named in error messages.
    apply_select : bool
        Apply ``source.select`` (False: the whole table, for anchors/end items).

    Returns
    -------
    StimulusSet
        The selected images, every file checked to exist.

    Raises
    ------
    AppealInputError
        Missing files or columns, empty selections (one line per problem).
    """
    if override is not None:
        override = Path(override).expanduser().resolve()
        if override.is_dir():
            cands = [override / n for n in ("manifest.csv", "factors.csv", "manifest.tsv", "factors.tsv")]
            found = [c for c in cands if c.is_file()]
            if not found:
                raise AppealInputError(f"{override}: --stimuli folder has no manifest.csv or factors.csv "
                                       "(a table with a 'file' column and one column per factor)")
            table_path, image_root = found[0], override
        else:
            table_path, image_root = override, override.parent
        what = "--stimuli table"
    elif source.manifest is not None:
        table_path, image_root = Path(source.manifest), Path(source.manifest).parent
        what = "stimulus manifest"
        if not table_path.is_file():
            hint = (f" (render it first: appeal stimuli grid {source.grid} --out {table_path.parent})"
                    if source.grid is not None else "")
            raise AppealInputError(f"{protocol_file}: stimuli.manifest: file not found: {table_path}{hint}")
    else:
        table_path, image_root = Path(source.table), Path(source.folder)
        what = "factor table"
        if not image_root.is_dir():
            raise AppealInputError(f"{protocol_file}: stimuli.folder: folder not found: {image_root}")
    df = _read_table(table_path, what)
    problems = []
    if "file" not in df.columns:
        problems.append(f"{table_path}: file: column missing (expected a 'file' column naming each image)")
    missing = [f for f in source.factors if f not in df.columns]
    if missing:
        problems.append(f"{table_path}: {', '.join(missing)}: factor column(s) missing "
                        f"(columns: {', '.join(df.columns)})")
    if problems:
        raise AppealInputError(problems)
    if df.empty:
        raise AppealInputError(f"{table_path}: no rows (expected one row per image)")
    out = pd.DataFrame({"stimulus": df["file"].astype(str)})
    out["path"] = [str((image_root / f).resolve()) for f in out["stimulus"]]
    for f in source.factors:
        out[f] = [level_key(v) for v in df[f]]
    _refuse_formulas(out, ["stimulus", *source.factors], table_path)
    clip = _clip_rows(df, table_path)
    stills = out["path"][~clip]
    absent = [p for p in stills if not Path(p).is_file()]
    if absent:
        more = f" and {len(absent) - 3} more" if len(absent) > 3 else ""
        raise AppealInputError(f"{table_path}: file: {len(absent)} image(s) not found: {', '.join(absent[:3])}{more}")
    bad = [p for p in stills if Path(p).suffix.lower() not in IMAGE_SUFFIXES]
    if bad:
        raise AppealInputError(f"{table_path}: file: not an image ({', '.join(IMAGE_SUFFIXES)}): {bad[0]}")
    if clip.any():
        out = _with_clip_columns(out, df, clip, image_root, table_path)
    dup = out["stimulus"][out["stimulus"].duplicated()].tolist()
    if dup:
        raise AppealInputError(f"{table_path}: file: listed twice: {dup[0]}")
    order = {f: [level_key(v) for v in vs] for f, vs in source.levels.items()}
    sset = StimulusSet(out.reset_index(drop=True), list(source.factors), table_path, order)
    if not apply_select:
        return sset
    selected = select_stimuli(sset, source.select)
    if not len(selected):
        raise AppealInputError(f"{protocol_file}: stimuli.select: selects none of the {len(sset)} images in {table_path}")
    return selected


def _refuse_formulas(out: pd.DataFrame, columns: list[str], table_path: Path) -> None:
    """A one-line error for a file name or level a spreadsheet would run as a formula (the data
    files write such text neutralised, and a resumed session could no longer match it)."""
    for c in columns:
        bad = out[c].map(formula_like)
        if bad.any():
            i = int(bad.to_numpy().argmax())
            field = "file" if c == "stimulus" else c
            raise AppealInputError(f"{table_path}: line {i + 2}: {field}: {shown(out[c].iloc[i])} starts like a "
                                   "spreadsheet formula (=, +, -, @); expected a name that does not")


#: What a clip row of a stimulus table adds to :attr:`StimulusSet.table` (None for still images).
CLIP_TABLE_COLUMNS = ("frames", "n_frames", "fps", "onset_frame", "apex_frame")


def _clip_rows(df: pd.DataFrame, table_path: Path) -> pd.Series:
    """Which rows are clips: those with a ``frames`` folder (a table with ``frames`` needs ``fps``)."""
    if "frames" not in df.columns:
        if "fps" in df.columns:
            raise AppealInputError(f"{table_path}: frames: column missing (a table with 'fps' holds clips: "
                                   "expected a 'frames' column naming each clip's folder of PNG frames)")
        return pd.Series(False, index=df.index)
    if "fps" not in df.columns:
        raise AppealInputError(f"{table_path}: fps: column missing (expected each clip's frame rate beside 'frames')")
    return df["frames"].astype(str).str.strip() != ""


def _whole(text: str, field: str, where: str, lo: int, hi: int) -> tuple[int | None, str | None]:
    """``text`` as a whole number in ``lo..hi``, or the one-line problem naming ``where`` and ``field``."""
    try:
        value = float(text)
    except ValueError:
        return None, f"{where}: {field}: expected a whole number {lo}..{hi} (got {text!r})"
    if not value.is_integer() or not lo <= value <= hi:
        return None, f"{where}: {field}: expected a whole number {lo}..{hi} (got {text})"
    return int(value), None


def _clip_row(row: Mapping[str, str], folder: Path, where: str) -> tuple[dict[str, Any], list[str]]:
    """One clip row's columns (frames folder, counts, rate, onset and apex) and its problems."""
    files = clip_frame_files(folder)
    if isinstance(files, str):
        return {}, [f"{where}: frames: {files}"]
    n = len(files)
    problems = []
    try:
        fps = float(row["fps"])
    except ValueError:
        fps = float("nan")
    if not 0 < fps <= 1000:
        problems.append(f"{where}: fps: expected a frame rate > 0 (got {row['fps']!r})")
    given = str(row.get("n_frames", "")).strip()
    if given:
        count, problem = _whole(given, "n_frames", where, 1, 10 ** 6)
        if problem is None and count != n:
            problem = f"{where}: n_frames: {count} in the table but {n} frames in {folder}"
        problems += [problem] if problem else []
    marks = {}
    for name, default in (("onset_frame", 0), ("apex_frame", n - 1)):
        text = str(row.get(name, "")).strip()
        marks[name], problem = _whole(text, name, where, 0, n - 1) if text else (default, None)
        problems += [problem] if problem else []
    return {"frames": str(folder), "n_frames": n, "fps": fps, **marks}, problems


def _with_clip_columns(out: pd.DataFrame, df: pd.DataFrame, clip: pd.Series, image_root: Path,
                       table_path: Path) -> pd.DataFrame:
    """``out`` with :data:`CLIP_TABLE_COLUMNS` (checked; ``path`` of a clip row = its frames folder)."""
    values: dict[str, list[Any]] = {c: [None] * len(df) for c in CLIP_TABLE_COLUMNS}
    problems: list[str] = []
    for i, (is_clip, row) in enumerate(zip(clip, df.to_dict("records"))):
        if not is_clip:
            continue
        folder = (image_root / str(row["frames"]).strip()).resolve()
        cols, bad = _clip_row(row, folder, f"{table_path}: line {i + 2} ({row['file']})")
        problems += bad
        for c, v in cols.items():
            values[c][i] = v
    if problems:
        more = [f"{table_path}: ... {len(problems) - 10} more problem(s) with clips"] if len(problems) > 10 else []
        raise AppealInputError(problems[:10] + more)
    out = out.copy()
    for c, vs in values.items():
        out[c] = pd.Series(vs, index=out.index, dtype=object)
    out.loc[clip.to_numpy(), "path"] = [v for v, is_clip in zip(values["frames"], clip) if is_clip]
    return out


def clip_rate_problems(sset: StimulusSet, refresh_hz: float) -> list[str]:
    """One line per clip frame rate of ``sset`` that ``refresh_hz`` is no whole multiple of."""
    if not sset.has_clips:
        return []
    clips = sset.table[sset.table["frames"].notna()]
    out = []
    for fps, group in clips.groupby("fps", sort=True):
        problem = rate_problem(float(fps), refresh_hz, str(sset.source), group["stimulus"].iloc[0], len(group))
        if problem:
            out.append(problem)
    return out


def _where_mask(table: pd.DataFrame, where: Mapping[str, Any]) -> pd.Series:
    mask = pd.Series(True, index=table.index)
    for factor, levels in where.items():
        wanted = {level_key(v) for v in (levels if isinstance(levels, list) else [levels])}
        mask &= table[factor].isin(wanted)
    return mask


def _match_key(level: str) -> str:
    """Levels compared by ``match`` (no declared order): their trailing number (s2 ~ m2 ~ 2)."""
    m = re.search(r"(\d+(?:\.\d+)?)$", level)
    return level_key(m.group(1)) if m else level


def select_stimuli(sset: StimulusSet, selection: Selection | None) -> StimulusSet:
    """The subset of ``sset`` a :class:`Selection` keeps (``where`` levels, ``match``-ing factors)."""
    if selection is None:
        return sset
    table = sset.table
    mask = _where_mask(table, selection.where)
    for factor, levels in selection.exclude.items():
        mask &= ~_where_mask(table, {factor: levels})
    if selection.match:
        def keys(f: str) -> pd.Series:
            if f in sset.order:  # declared order: the level's position
                pos = {v: str(i) for i, v in enumerate(sset.order[f])}
                return table[f].map(lambda v: pos.get(v, f"?{v}"))
            return table[f].map(_match_key)
        first = keys(selection.match[0])
        for other in selection.match[1:]:
            mask &= keys(other) == first
    return StimulusSet(table[mask].reset_index(drop=True), sset.factors, sset.source, sset.order)


def session_stimuli(protocol: Protocol, protocol_file: str | Path,
                    override: str | Path | None = None) -> tuple[StimulusSet, StimulusSet]:
    """A session's stimuli: the whole set (anchors, practice and end items select from it) and
    the main trials' selection (``stimuli.select``), which must not be empty.

    Raises
    ------
    AppealInputError
        When the selection keeps no image (or the set cannot be loaded).
    """
    full = load_stimuli(protocol.stimuli, override=override, protocol_file=protocol_file, apply_select=False)
    main = select_stimuli(full, protocol.stimuli.select)
    if not len(main):
        raise AppealInputError(f"{protocol_file}: stimuli.select: selects none of the {len(full)} images in {full.source}")
    return full, main


def protocol_input_problems(protocol: Protocol, source: str | Path) -> list[str]:
    """Problems with the inputs a protocol needs to run: its stimuli (missing manifest,
    folder, table or image files, missing factor columns, empty selections, clip frame folders,
    and clip frame rates that do not divide ``screen.refresh_hz`` when the protocol gives it).

    ``appeal validate`` reports these after the schema checks. They are kept out of the
    schema because a protocol is normally written before its stimuli are rendered.
    """
    try:
        sset = load_stimuli(protocol.stimuli, protocol_file=source)
    except AppealInputError as exc:
        return exc.lines
    if protocol.screen.refresh_hz is not None:
        return clip_rate_problems(sset, protocol.screen.refresh_hz)
    return []

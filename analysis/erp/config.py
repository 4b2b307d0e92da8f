"""Reading an ERP config: the validated model, its event map, its recordings and subjects."""

from __future__ import annotations

import glob
import re
from dataclasses import dataclass, field
from pathlib import Path

from appeal.errors import AppealInputError, StudyFileError
from appeal.labels import shown
from appeal.levels import level_value, order_levels
from appeal.studyfile import load_study_file, load_yaml
from appeal.triggers import trigger_table

from analysis.erp_schema import ErpConfig, ProtocolEvents

__all__ = ["EventMap", "load_erp_config", "read_protocol_codes", "read_protocol_levels", "event_map",
           "find_recordings", "recording_problems", "subject_id", "SUBJECT_ID"]

#: File types the pipeline reads (MNE readers).
RECORDING_SUFFIXES = (".bdf", ".edf", ".fif", ".vhdr", ".set", ".fif.gz")


def load_erp_config(path: str | Path) -> ErpConfig:
    """Load and validate an ERP config file (``kind: erp``).

    Raises
    ------
    StudyFileError
        One ``FILE: field: message`` line per problem.
    """
    return load_study_file(path, ErpConfig)


def read_protocol_codes(path: str | Path) -> dict[int, dict[str, object]]:
    """The ``triggers.codes`` section of a runner protocol: code -> factor levels.

    The section is a list of mappings ``{code: 11, character: c1, stylisation: 0, emotion: angry}``,
    validated by the rules the runner sends them by (:func:`appeal.triggers.trigger_table`) and
    levels typed by :func:`appeal.levels.level_value`. Only this section is read; the rest of the
    protocol is not interpreted here (the analysis does not need :mod:`experiments`).

    Raises
    ------
    StudyFileError
        When the section is missing or an entry is not valid (see ``trigger_table``).
    """
    path = Path(path)
    codes = _protocol_section(path, "triggers", "codes")
    try:
        table = trigger_table(codes if codes is not None else [])
    except ValueError as exc:
        raise StudyFileError(f"{path}: triggers.{exc}" if str(exc).startswith("codes[") else f"{path}: triggers.codes: {exc}") from None
    return {code: {f: level_value(v) for f, v in levels.items()} for code, levels in table.items()}


def read_protocol_levels(path: str | Path) -> dict[str, list]:
    """The ``stimuli.levels`` section of a runner protocol: factor -> its levels in the declared order.

    The runner orders a factor's levels this way (:func:`appeal.levels.order_levels`); the
    analysis orders contrasts and figures the same way unless the ERP config gives ``levels``.

    Returns
    -------
    dict
        factor -> declared levels (empty when the protocol declares none).

    Raises
    ------
    StudyFileError
        When the section is not a mapping of factor to a list of levels.
    """
    path = Path(path)
    section = _protocol_section(path, "stimuli", "levels")
    if section is None:
        return {}
    if not isinstance(section, dict) or not all(isinstance(v, list) for v in section.values()):
        raise StudyFileError(f"{path}: stimuli.levels: expected a mapping of factor to a list of levels "
                             f"(got {section!r})")
    return {str(f): list(v) for f, v in section.items()}


def _protocol_section(path: Path, part: str, key: str) -> object:
    """``doc[part][key]`` of a protocol YAML file, or None where either is absent."""
    doc = load_yaml(path)
    section = doc.get(part) if isinstance(doc, dict) else None
    return section.get(key) if isinstance(section, dict) else None


@dataclass(frozen=True)
class EventMap:
    """Trigger codes and the condition cells they belong to.

    Attributes
    ----------
    codes : dict
        code -> {factor: level} over the analysed ``factors``.
    factors : list of str
        The condition factors (columns of ``amplitudes.csv``).
    levels : dict
        factor -> ordered levels (the order of contrasts and figures).
    ignore : tuple of int
        Codes present in recordings that are not events of interest.
    """

    codes: dict[int, dict[str, object]]
    factors: list[str]
    levels: dict[str, list]
    ignore: tuple[int, ...] = ()
    unknown: str = "error"
    cells: list[tuple] = field(default_factory=list)

    def cell_of(self, code: int) -> tuple:
        """The cell (tuple of levels in ``factors`` order) of a code."""
        return tuple(self.codes[code][f] for f in self.factors)

    def cell_name(self, cell: tuple) -> str:
        """A readable name: ``stylisation=0/emotion=angry``."""
        return "/".join(f"{f}={v}" for f, v in zip(self.factors, cell))


def event_map(cfg: ErpConfig, source: str | Path = "config") -> EventMap:
    """Resolve the config's ``events`` (inline or from a protocol) into an :class:`EventMap`.

    Raises
    ------
    StudyFileError
        When ``factors`` or ``levels`` name factors/levels the event map does not have.
    """
    declared: dict[str, list] = {}
    if isinstance(cfg.events, ProtocolEvents):
        raw = read_protocol_codes(cfg.events.protocol)
        declared = read_protocol_levels(cfg.events.protocol)
    else:
        raw = {int(k): {str(f): level_value(v) for f, v in d.items()} for k, d in cfg.events.items()}
    all_factors: list[str] = []
    for levels in raw.values():
        for f in levels:
            if f not in all_factors:
                all_factors.append(f)
    factors = list(cfg.factors) if cfg.factors else all_factors
    problems = []
    for f in factors:
        missing = [c for c, d in raw.items() if f not in d]
        if missing:
            problems.append(f"{source}: factors: factor {f!r} is not given for codes {missing[:5]} "
                            f"(factors in the event map: {', '.join(all_factors)})")
    if problems:
        raise StudyFileError(problems)
    codes = {c: {f: d[f] for f in factors} for c, d in raw.items()}
    levels: dict[str, list] = {}
    for f in factors:
        seen = list(dict.fromkeys(d[f] for d in codes.values()))
        if f in cfg.levels:
            given = [level_value(v) for v in cfg.levels[f]]
            extra = [v for v in seen if v not in given]
            if extra or len(given) != len(set(given)):
                raise StudyFileError(f"{source}: levels.{f}: expected each of {seen} exactly once (got {given})")
            levels[f] = [v for v in given if v in seen]
        else:
            levels[f] = order_levels(seen, declared.get(f, ()))
    for f in cfg.levels:
        if f not in factors:
            raise StudyFileError(f"{source}: levels.{f}: not a factor (expected one of: {', '.join(factors)})")
    import itertools

    present = {tuple(d[f] for f in factors) for d in codes.values()}
    cells = [c for c in itertools.product(*(levels[f] for f in factors)) if c in present]
    return EventMap(codes=codes, factors=factors, levels=levels, ignore=tuple(cfg.ignore_codes),
                    unknown=cfg.unknown_codes, cells=cells)


def _expand(pattern: Path) -> list[Path]:
    """Files of one ``recordings`` entry: a glob, or a BIDS root walked for ``*_eeg.*``."""
    if pattern.is_dir():
        found = [f for f in sorted(pattern.rglob("*_eeg.*"))
                 if "".join(f.suffixes[-2:]).lower().endswith(RECORDING_SUFFIXES)]
        return [f for f in found if f.suffix.lower() != ".fdt"]
    return [Path(f) for f in sorted(glob.glob(str(pattern)))]


def _patterns(cfg: ErpConfig) -> list[tuple[str, Path]]:
    """``(field, pattern)`` for each entry of ``recordings``."""
    if isinstance(cfg.recordings, list):
        return [(f"recordings[{i}]", Path(p)) for i, p in enumerate(cfg.recordings)]
    return [("recordings", Path(cfg.recordings))]


def recording_problems(cfg: ErpConfig, source: str | Path = "config") -> list[str]:
    """One ``FILE: recordings: ...`` line for each entry of ``recordings`` that finds no file.

    ``appeal validate`` reports these (the schema alone cannot know), and
    :func:`find_recordings` stops on them before a run.
    """
    problems = []
    for where, pat in _patterns(cfg):
        if _expand(pat):
            continue
        if pat.is_dir():
            problems.append(f"{source}: {where}: folder {pat} holds no *_eeg.* recordings "
                            f"(expected a BIDS root with BDF/EDF/FIF/BrainVision/EEGLAB files)")
        else:
            problems.append(f"{source}: {where}: pattern {pat} matches no file "
                            f"(expected a glob of BDF/EDF/FIF/BrainVision/EEGLAB files or a BIDS root)")
    return problems


def find_recordings(cfg: ErpConfig, source: str | Path = "config") -> list[Path]:
    """The recording files: expand globs, or walk a BIDS root for ``*_eeg.*`` files.

    Raises
    ------
    AppealInputError
        When an entry of ``recordings`` matches nothing (one line per entry).
    """
    problems = recording_problems(cfg, source)
    if problems:
        raise AppealInputError(problems)
    files: list[Path] = []
    for _, pat in _patterns(cfg):
        files.extend(f for f in _expand(pat) if f not in files)
    return files


#: What a subject id may hold: letters, digits, spaces, ``-``, ``_`` and ``.``, starting with a letter
#: or digit. Ids come from file names (other labs' included) and end up in tables, figures (where
#: ``$`` would start TeX), log lines and messages; no path is built from them.
SUBJECT_ID = re.compile(r"\w[\w .-]*")


def subject_id(path: Path, pattern: str) -> str:
    """Subject id from a file name: the first group of ``pattern``, else the file's stem.

    Raises
    ------
    AppealInputError
        When the id is empty or holds other characters than :data:`SUBJECT_ID` allows
        (control characters, ``$``, ``/`` ...): one line naming the file.
    """
    m = re.search(pattern, path.name)
    if m:
        found = m.group(1) if m.groups() else m.group(0)
    else:
        found = path.name.split(".")[0]
    if not found or not SUBJECT_ID.fullmatch(found):
        raise AppealInputError(
            f"{path}: subject id: expected letters, digits, spaces, '-', '_' or '.' (from subject_pattern "
            f"{shown(pattern)}, else the file name), got {shown(found or '')}; rename the file or adjust subject_pattern")
    return found

"""Channel names: renaming a recording's labels, and 10-5 positions mapped onto other layouts.

BioSemi recordings label their electrodes by position (A1-A32, B1-B32, ...); MNE's
``biosemi16/32/64`` montages name the same positions in 10-20 terms, in BioSemi's order
(:func:`biosemi_positional_map`, applied with ``channels: {rename: biosemi16}``).

The thesis (§7.3) names its clusters in the 10-5 system (PO9h, TP7h, CPPz ...); BioSemi caps
with 128 electrodes are labelled A1-D32. Both MNE layouts ``spherical_1005`` and
``biosemi128`` place the electrodes on the same idealised sphere, so the nearest electrode
is the one with the smallest angle between the two position vectors. The mapping for
BioSemi 128 is shipped as ``analysis/data/biosemi128_from_1005.csv`` (regenerate it with
:func:`nearest_channel_table`; a test checks the shipped file against the function).
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Iterable, Mapping, Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from appeal.errors import AppealInputError
from appeal.labels import shown

__all__ = [
    "BIOSEMI128_MAP_FILE",
    "biosemi_labels",
    "biosemi_positional_map",
    "channel_name_problem",
    "rename_channels",
    "make_montage",
    "nearest_channel_table",
    "biosemi128_map",
    "resolve_cluster",
]

#: The shipped 10-5 -> BioSemi 128 table (columns ``name_1005``, ``biosemi128``, ``angle_deg``).
BIOSEMI128_MAP_FILE = Path(__file__).resolve().parent.parent / "data" / "biosemi128_from_1005.csv"

#: Characters no channel name may hold: line breaks, tabs, escapes and other control characters
#: (C1 ones included: a header's Latin-1 bytes 0x80-0x9f decode to them).
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")

#: MNE renamed ``standard_1005`` to ``colin27_1005``; older names still work through this map.
_RENAMED = {"standard_1005": "colin27_1005", "standard_1020": "colin27_1020"}


def make_montage(name: str):
    """An MNE built-in montage by name (accepting the older ``standard_*`` names).

    Parameters
    ----------
    name : str
        A name from :func:`mne.channels.get_builtin_montages`.

    Returns
    -------
    mne.channels.DigMontage
        The montage.

    Raises
    ------
    AppealInputError
        When MNE has no montage of that name.
    """
    import mne

    builtin = mne.channels.get_builtin_montages()
    real = _RENAMED.get(name, name) if _RENAMED.get(name) in builtin else name
    if real not in builtin:
        import difflib

        close = difflib.get_close_matches(name, builtin, n=1)
        hint = f"did you mean '{close[0]}'?" if close else "expected an MNE montage name such as biosemi128, or none"
        raise AppealInputError(f"montage: unknown montage {name!r} ({hint})")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        return mne.channels.make_standard_montage(real)


def biosemi_labels(n: int) -> list[str]:
    """BioSemi's positional electrode labels: A1-A32, B1-B32, ... (``n`` of them)."""
    return [f"{chr(ord('A') + i // 32)}{i % 32 + 1}" for i in range(n)]


def biosemi_positional_map(layout: str) -> dict[str, str]:
    """BioSemi's positional labels -> the electrode names of an MNE ``biosemi*`` montage.

    MNE lists the electrodes of its BioSemi montages in BioSemi's order (the 64-channel
    ``test.bdf`` of MNE's test data is labelled Fp1, AF7, AF3 ... in exactly this order), so
    the i-th label A1, A2, ... B1 ... is the montage's i-th electrode. For biosemi128 and
    larger the montage's names are the labels themselves.

    Parameters
    ----------
    layout : str
        ``biosemi16``, ``biosemi32``, ``biosemi64``, ``biosemi128``, ``biosemi160`` or ``biosemi256``.

    Returns
    -------
    dict
        ``{"A1": "Fp1", "A2": "Fp2", ...}`` for biosemi16.
    """
    names = make_montage(layout).ch_names
    return dict(zip(biosemi_labels(len(names)), names))


def channel_name_problem(names: Mapping[int, str], what: str = "channel") -> str | None:
    """Why a recording's channel names cannot be analysed (one phrase), or None when they can.

    Names end up in tables, figures and messages, and the pipeline matches them to the
    config's without regard to case (montages, clusters), so each must be non-empty,
    printable (no control characters: MNE keeps NUL padding, tabs and escapes in EDF labels)
    and different from every other one ignoring case (MNE would append ``-0``, ``-1`` to
    exact duplicates, and its BDF reader takes the first of ``status``/``Status`` as the
    trigger channel). Other text (Latin-1 letters, ``=HYPERLINK(...)``) is a name like any
    other: tables are written through :func:`appeal.cells.write_table`.

    Parameters
    ----------
    names : mapping of int to str
        Number (1-based, as messages count) -> name.
    what : str
        What a number counts, for the phrase (``signal`` in an EDF header).

    Returns
    -------
    str | None
        ``label of signal 3: expected ..., got ...`` naming the first problem.
    """
    seen: dict[str, int] = {}
    for number, name in names.items():
        if not name.strip():
            return f"label of {what} {number}: expected a channel name, got an empty label"
        if _CONTROL.search(name):
            return f"label of {what} {number}: expected printable text, got {shown(name)} (control characters)"
        first = seen.setdefault(name.lower(), number)
        if first != number:
            return (f"labels of {what}s {first} and {number}: expected each channel name once (names are matched "
                    f"ignoring case), got {shown(names[first])} and {shown(name)}")
    return None


def rename_channels(raw, rename: Mapping[str, str] | str, path: str | Path = "") -> dict[str, str]:
    """Rename the recording's channels in place (the config's ``channels.rename``).

    Labels of the mapping that the recording does not have are skipped, so a config for
    A1-labelled files also reads files already labelled with the new names.

    Parameters
    ----------
    raw : mne.io.Raw
        The recording.
    rename : mapping or str
        ``{old: new}``, or a BioSemi layout name (see :func:`biosemi_positional_map`).
    path : path-like
        The recording, for messages.

    Returns
    -------
    dict
        The renames applied.

    Raises
    ------
    AppealInputError
        When a new name is already the name (ignoring case) of another channel of the recording.
    """
    mapping = biosemi_positional_map(rename) if isinstance(rename, str) else dict(rename)
    applied = {old: new for old, new in mapping.items() if old in raw.ch_names and old != new}
    kept = {c.lower() for c in raw.ch_names if c not in applied}  # names are matched ignoring case
    clash = [f"{old} -> {new}" for old, new in applied.items() if new.lower() in kept]
    if clash:
        raise AppealInputError(f"{path}: channels.rename: {clash[0]}: the recording already has a channel "
                               f"{clash[0].split(' -> ')[1]} (expected new names that are not in the recording)")
    if applied:
        raw.rename_channels(applied, verbose="error")
    return applied


def _unit_positions(montage) -> tuple[list[str], np.ndarray]:
    pos = montage.get_positions()["ch_pos"]
    names = list(pos)
    xyz = np.array([pos[n] for n in names], float)
    # both idealised layouts are spheres centred on the origin: compare directions
    return names, xyz / np.linalg.norm(xyz, axis=1, keepdims=True)


def nearest_channel_table(
    names: Iterable[str] | None = None,
    target: str = "biosemi128",
    source: str = "spherical_1005",
) -> pd.DataFrame:
    """For each position of ``source``, the electrode of ``target`` nearest to it.

    Parameters
    ----------
    names : iterable of str | None
        The ``source`` positions to map (default: all of them).
    target : str
        MNE montage whose labels are wanted (default BioSemi 128).
    source : str
        MNE montage holding the named positions (default the spherical 10-5 layout).

    Returns
    -------
    pandas.DataFrame
        Columns ``name_1005``, ``<target>`` (the label) and ``angle_deg`` (angle between the
        two positions seen from the sphere's centre).
    """
    src_names, src = _unit_positions(make_montage(source))
    tgt_names, tgt = _unit_positions(make_montage(target))
    wanted = list(names) if names is not None else src_names
    index = {n.lower(): i for i, n in enumerate(src_names)}
    rows = []
    for name in wanted:
        i = index.get(name.lower())
        if i is None:
            raise AppealInputError(f"channel {name!r}: not a position of the {source} layout")
        cos = np.clip(tgt @ src[i], -1.0, 1.0)
        j = int(np.argmax(cos))
        rows.append((src_names[i], tgt_names[j], float(np.degrees(np.arccos(cos[j])))))
    return pd.DataFrame(rows, columns=["name_1005", target, "angle_deg"])


@lru_cache(maxsize=1)
def biosemi128_map() -> dict[str, str]:
    """The shipped 10-5 name -> BioSemi 128 label map (keys lower-case)."""
    table = pd.read_csv(BIOSEMI128_MAP_FILE, comment="#")
    return {str(a).lower(): str(b) for a, b in zip(table["name_1005"], table["biosemi128"])}


def resolve_cluster(
    names: Sequence[str], ch_names: Sequence[str], montage: str | None, *, where: str
) -> list[str]:
    """The recording's channels for a cluster written with recording labels or 10-5 names.

    A name that is a channel of the recording is kept. Otherwise, with the ``biosemi128``
    montage, a 10-5 name is mapped through the shipped table; with another named montage, the
    10-5 name maps to the montage's nearest electrode. Duplicates are dropped (several
    10-5 positions may share one BioSemi electrode).

    Parameters
    ----------
    names : sequence of str
        Labels as written in the config.
    ch_names : sequence of str
        The recording's EEG channel names.
    montage : str | None
        The montage name of the config (``None`` for ``montage: none``).
    where : str
        The config field, for error messages (``components.N170.clusters.left``).

    Returns
    -------
    list of str
        Channel names of the recording, in the order given.

    Raises
    ------
    AppealInputError
        When a name is neither a channel nor a mappable 10-5 position.
    """
    have = {c.lower(): c for c in ch_names}
    out: list[str] = []
    missing: list[str] = []
    for name in names:
        if name.lower() in have:
            ch = have[name.lower()]
        else:
            if montage == "biosemi128":
                label = biosemi128_map().get(name.lower())
            elif montage:
                try:
                    label = nearest_channel_table([name], target=montage)[montage].iloc[0]
                except AppealInputError:
                    label = None
            else:
                label = None
            ch = have.get(label.lower()) if label else None
            if ch is None:
                missing.append(name if label is None else f"{name} (= {label})")
                continue
        if ch not in out:
            out.append(ch)
    if missing:
        raise AppealInputError(
            f"{where}: channels not in the recording: {', '.join(missing)} "
            f"(expected recording labels or 10-5 names mappable with montage {montage or 'none'})"
        )
    return out

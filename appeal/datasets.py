"""The third-party datasets the project uses: a registry, where they live, and ``data:`` references.

The registry (``appeal/assets/datasets.json``, rebuilt by ``scripts/make_data_registry.py``)
lists, per dataset, its folder in the data tree, licence, credit, upstream and every file with
its size, the sha256 of its content (``.gz`` files: of the decompressed bytes) and the URL of
the same bytes upstream (pinned to a commit), where there is one. A file the curator converted
names how it is made from its upstream source instead: decoded from a Draco-compressed glTF
(``decode``), or written from the registry itself (``text``, a few bytes with no upstream copy).

Data trees (each laid out like ``shared/data``), in the order they are searched:

1. ``$APPEAL_DATA``, if set (then nothing else is searched);
2. the user cache (``$XDG_CACHE_HOME/appeal-lab/data``, default ``~/.cache/appeal-lab/data``),
   where ``appeal data fetch`` writes;
3. ``shared/data`` beside the checkout (the developers' copy).

A study file names a dataset instead of a path: ``data:ict-facekit`` is the dataset's folder,
``data:menpo3d-james/james.obj`` a file in it (:func:`resolve_reference`).

A *dataset group* names several datasets laid out alike as one set (:data:`DATASET_GROUPS`):
``data:london-frl-all/neutral_front`` is the ``neutral_front`` folder of both London-set
datasets. Where a command takes a list of inputs, :func:`expand_inputs` turns group references
and glob patterns (``data:london-frl-all/neutral_front/*.jpg``) into the paths they name.
"""

from __future__ import annotations

import functools
import glob
import json
import os
from dataclasses import dataclass
from pathlib import Path

from appeal.assets import DATA_ENV, asset_path, repo_root
from appeal.errors import AppealInputError

__all__ = ["DATA_PREFIX", "DATASET_GROUPS", "DataFile", "Dataset", "data_roots", "dataset", "dataset_names",
           "expand_inputs", "find_dataset", "fetch_root", "group_members", "resolve_reference", "resolve_references",
           "user_cache_dir"]

#: Prefix of a dataset reference in study files.
DATA_PREFIX = "data:"

#: Dataset groups: one name for datasets whose folders are laid out alike (one image set).
DATASET_GROUPS: dict[str, tuple[str, ...]] = {
    "london-frl-all": ("london-frl", "london-frl-more"),  # the 87 public London-set identities
}


@dataclass(frozen=True)
class DataFile:
    """One file of a dataset.

    Attributes
    ----------
    path : str
        Relative to the dataset's folder.
    sha256 : str
        Of the file's content (decompressed for ``gzip`` files).
    size : int
        Bytes as stored.
    url : str or None
        Where upstream serves the same content (None: from a mirror only).
    gzip : bool
        Stored gzip-compressed (upstream serves it uncompressed).
    docs : bool
        Documentation only: not needed to use the dataset.
    decode : dict or None
        The upstream source is converted after download: ``{"from": "draco-glb", "comment",
        "mtllib", "material"}`` decodes a Draco-compressed binary glTF into an OBJ
        (:mod:`appeal.draco_glb`). The sha256 is of the decoded file.
    text : str or None
        The whole content, written by ``appeal data fetch`` itself (a curator's small file,
        e.g. a material library, with no upstream copy).
    """

    path: str
    sha256: str
    size: int
    url: str | None = None
    gzip: bool = False
    docs: bool = False
    decode: dict | None = None
    text: str | None = None

    @property
    def upstream(self) -> bool:
        """Whether it can be fetched without a mirror."""
        return self.url is not None or self.text is not None


@dataclass(frozen=True)
class Dataset:
    """A registered dataset (see the module docstring)."""

    name: str
    folder: str
    description: str
    licence: str
    credit: str
    upstream: str
    files: tuple[DataFile, ...]

    @property
    def size(self) -> int:
        """Bytes of all its files as stored."""
        return sum(f.size for f in self.files)

    @property
    def fetch_command(self) -> str:
        """The command that gets it."""
        return f"appeal data fetch {self.name}"


@functools.lru_cache(maxsize=1)
def _registry() -> dict[str, Dataset]:
    raw = json.loads(asset_path("datasets.json").read_text(encoding="utf-8"))
    return {name: Dataset(name, d["folder"], d["description"], d["licence"], d["credit"], d["upstream"],
                          tuple(DataFile(**f) for f in d["files"])) for name, d in raw.items()}


def dataset_names() -> list[str]:
    """Names of the registered datasets."""
    return list(_registry())


def dataset(name: str) -> Dataset:
    """The registered dataset ``name`` (one-line error listing the names otherwise)."""
    reg = _registry()
    if name not in reg:
        raise AppealInputError(f"unknown dataset '{name}' (expected one of: {', '.join(reg)}; see appeal data list)")
    return reg[name]


def group_members(name: str) -> tuple[str, ...]:
    """The datasets a name stands for: a group's members, or the dataset itself (checked)."""
    if name in DATASET_GROUPS:
        return DATASET_GROUPS[name]
    if name not in _registry():
        known = ", ".join([*_registry(), *DATASET_GROUPS])
        raise AppealInputError(f"unknown dataset '{name}' (expected one of: {known}; see appeal data list)")
    return (name,)


def user_cache_dir() -> Path:
    """The user cache's data tree (``$XDG_CACHE_HOME/appeal-lab/data``)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "appeal-lab" / "data"


def fetch_root() -> Path:
    """The data tree ``appeal data fetch`` writes to: ``$APPEAL_DATA``, else the user cache."""
    env = os.environ.get(DATA_ENV)
    return Path(env).expanduser() if env else user_cache_dir()


def data_roots() -> list[Path]:
    """Data trees searched for a dataset, in order (see the module docstring)."""
    if os.environ.get(DATA_ENV):
        return [fetch_root()]
    return [user_cache_dir(), repo_root().parent / "shared" / "data"]


def _complete(ds: Dataset, root: Path) -> bool:
    folder = root / ds.folder
    return all((folder / f.path).is_file() for f in ds.files if not f.docs)


def find_dataset(name: str) -> Path | None:
    """The folder of dataset ``name`` in the first data tree that has all its files, or None."""
    ds = dataset(name)
    for root in data_roots():
        if _complete(ds, root):
            return (root / ds.folder).resolve()
    return None


def resolve_reference(ref: str, missing_ok: bool = False) -> Path:
    """The path a ``data:NAME[/sub/path]`` reference names.

    Parameters
    ----------
    ref : str
    missing_ok : bool
        For a dataset not on this machine, return where ``appeal data fetch`` would put it
        instead of raising.

    Raises
    ------
    AppealInputError
        Unknown dataset, or a dataset not on this machine (the message says how to fetch it).
    """
    name, _, sub = ref[len(DATA_PREFIX):].partition("/")
    if name in DATASET_GROUPS:
        raise AppealInputError(f"{ref}: '{name}' is a group of datasets ({', '.join(DATASET_GROUPS[name])}), not one "
                               "folder (expected a dataset here; groups name image sets where a command takes a list)")
    ds = dataset(name)
    folder = find_dataset(name)
    if folder is None and missing_ok:
        folder = fetch_root() / ds.folder
    if folder is None:
        where = ", ".join(str(r) for r in data_roots())
        raise AppealInputError(f"{ref}: dataset '{name}' is not on this machine (looked in {where}); "
                               f"fetch it with: {ds.fetch_command}")
    return folder / sub if sub else folder


def resolve_references(ref: str, missing_ok: bool = False) -> list[Path]:
    """The paths a ``data:NAME[/sub/path]`` reference names: one, or one per member of a group
    (:data:`DATASET_GROUPS`). Errors as :func:`resolve_reference`."""
    name, _, sub = ref[len(DATA_PREFIX):].partition("/")
    return [resolve_reference(f"{DATA_PREFIX}{member}" + (f"/{sub}" if sub else ""), missing_ok)
            for member in group_members(name)]


def expand_inputs(items) -> list[Path]:
    """Input paths with ``data:`` references (groups included) resolved and glob patterns expanded.

    Parameters
    ----------
    items : iterable of str or Path
        Plain paths, ``data:NAME/sub/path`` references, and patterns with ``*``, ``?`` or ``[``
        in either (each pattern's matches sorted by name).

    Raises
    ------
    AppealInputError
        An unknown or missing dataset, or a pattern that matches nothing (one line naming it).
    """
    out: list[Path] = []
    for item in map(str, items):
        paths = resolve_references(item) if item.startswith(DATA_PREFIX) else [Path(item)]
        if not glob.has_magic(item) or all(p.exists() for p in paths):  # a file named "a[1].png" is itself
            out += paths
            continue
        matches = [Path(m) for p in paths for m in sorted(glob.glob(str(p)))]
        if not matches:
            raise AppealInputError(f"{item}: the pattern matches no file (looked in {', '.join(map(str, paths))})")
        out += matches
    return out

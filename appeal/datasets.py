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
"""

from __future__ import annotations

import functools
import json
import os
from dataclasses import dataclass
from pathlib import Path

from appeal.assets import DATA_ENV, asset_path, repo_root
from appeal.errors import AppealInputError

__all__ = ["DATA_PREFIX", "DataFile", "Dataset", "data_roots", "dataset", "dataset_names", "find_dataset",
           "fetch_root", "resolve_reference", "user_cache_dir"]

#: Prefix of a dataset reference in study files.
DATA_PREFIX = "data:"


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
    ds = dataset(name)
    folder = find_dataset(name)
    if folder is None and missing_ok:
        folder = fetch_root() / ds.folder
    if folder is None:
        where = ", ".join(str(r) for r in data_roots())
        raise AppealInputError(f"{ref}: dataset '{name}' is not on this machine (looked in {where}); "
                               f"fetch it with: {ds.fetch_command}")
    return folder / sub if sub else folder

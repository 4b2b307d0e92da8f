"""Download and check the registered datasets (:mod:`appeal.datasets`): ``appeal data fetch|verify``.

Each file is downloaded over HTTP(S) into ``FILE.part`` next to its place in the data tree,
resumed with a ``Range`` request when a ``.part`` is left from an interrupted fetch, checked
against the registry's sha256 and only then moved into place, so a data tree never holds a
half-written or unchecked file under its real name. Files already there with the right content
are not downloaded again; a corrupted one is fetched anew. Sources: the file's upstream URLs
(a Draco-compressed glTF is decoded into the OBJ the registry checks, see
:mod:`appeal.draco_glb`; a curator's few-byte file is written from the registry's own text),
or a mirror of the whole data tree (``base_url``: ``BASE/FOLDER/FILE``, e.g. a lab's server or a
test's loopback server).
"""

from __future__ import annotations

import gzip
import hashlib
import os
import shutil
import sys
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

from appeal.atomic import atomic_write_bytes
from appeal.datasets import DataFile, Dataset, dataset, fetch_root
from appeal.errors import AppealInputError
from appeal.progress import progress_enabled

__all__ = ["MIRROR_ENV", "FetchReport", "content_sha256", "fetch_dataset", "verify_dataset"]

#: Environment variable naming a mirror of the data tree (used when ``--url`` is not given).
MIRROR_ENV = "APPEAL_DATA_URL"
_CHUNK = 1 << 16
_TIMEOUT_S = 30


def content_sha256(path: Path, gz: bool = False) -> str:
    """sha256 of a file's content (of the decompressed bytes when ``gz``)."""
    h = hashlib.sha256()
    with (gzip.open(path, "rb") if gz else open(path, "rb")) as f:
        for block in iter(lambda: f.read(_CHUNK), b""):
            h.update(block)
    return h.hexdigest()


def _state(path: Path, f: DataFile) -> str:
    if not path.is_file():
        return "missing"
    try:
        return "ok" if content_sha256(path, f.gzip) == f.sha256 else "corrupt"
    except (OSError, EOFError, gzip.BadGzipFile):
        return "corrupt"


def verify_dataset(name: str, root: Path | None = None) -> list[tuple[str, str]]:
    """``(file, state)`` for every file of dataset ``name`` in the data tree ``root`` (default:
    :func:`appeal.datasets.fetch_root`); state is ``ok``, ``missing`` or ``corrupt``."""
    ds = dataset(name)
    folder = (root or fetch_root()) / ds.folder
    return [(f.path, _state(folder / f.path, f)) for f in ds.files]


@dataclass
class FetchReport:
    """What :func:`fetch_dataset` did: files downloaded, already there, and their folder."""

    dataset: Dataset
    folder: Path
    downloaded: list[str]
    present: list[str]


def _source(ds: Dataset, f: DataFile, base_url: str | None) -> str | None:
    """Where ``f`` comes from: the mirror, else its upstream URL (None: the registry's own text)."""
    if base_url:
        return f"{base_url.rstrip('/')}/{ds.folder}/{f.path}"
    if not f.upstream:
        raise AppealInputError(f"{ds.name}: {f.path} has no public upstream copy ({ds.upstream}); fetch it from a "
                               f"mirror of the data tree: {ds.fetch_command} --url URL (or set {MIRROR_ENV})")
    return f.url


def _download(src: str, part: Path, bar: object | None) -> None:
    """``src`` into ``part``, continuing a partial ``part`` with a Range request."""
    have = part.stat().st_size if part.exists() else 0
    req = urllib.request.Request(src, headers={"User-Agent": "appeal-lab", **({"Range": f"bytes={have}-"} if have else {})})
    with urllib.request.urlopen(req, timeout=_TIMEOUT_S) as resp:
        resumed = have and resp.status == 206
        if bar is not None and resumed:
            bar.update(have)
        with open(part, "ab" if resumed else "wb") as out:
            for block in iter(lambda: resp.read(_CHUNK), b""):
                out.write(block)
                if bar is not None:
                    bar.update(len(block))


class _SourceFailed(Exception):
    """The source of a file failed; ``args[0]`` says how, ``offline`` when it could not be reached."""

    def __init__(self, why: str, offline: bool = False) -> None:
        super().__init__(why)
        self.offline = offline


def _decoded(f: DataFile, part: Path, src: str) -> Path:
    """The file made from a downloaded upstream source (``f.decode``), next to ``part``."""
    from appeal.draco_glb import ObjStyle, decode_draco_glb, obj_bytes

    spec = dict(f.decode or {})
    if spec.pop("from", None) != "draco-glb":
        raise _SourceFailed(f"{f.path}: the registry names an unknown decoder {f.decode!r} (expected from: draco-glb)")
    out = part.with_name(part.name.removesuffix(".part") + ".decoded-part")
    try:
        out.write_bytes(obj_bytes(decode_draco_glb(part.read_bytes(), name=src), ObjStyle(**spec)))
    except AppealInputError as exc:
        raise _SourceFailed(f"{f.path} from {exc}") from None
    finally:
        part.unlink(missing_ok=True)
    return out


def _fetch_from(ds: Dataset, f: DataFile, dest: Path, src: str, base_url: str | None, bar: object | None) -> None:
    """Download ``f`` from ``src``, make it (decode, gzip) and check it; only then move it to ``dest``."""
    part = dest.with_name(dest.name + ".part")
    try:
        _download(src, part, bar)
    except urllib.error.HTTPError as exc:
        if not (exc.code == 416 and part.exists()):  # 416: the partial file is already whole
            raise _SourceFailed(f"cannot download {f.path} from {src} (HTTP {exc.code} {exc.reason})") from None
    except (urllib.error.URLError, OSError, ValueError) as exc:
        reason = getattr(exc, "reason", None) or exc
        raise _SourceFailed(f"cannot download {f.path} from {src} ({reason})", offline=True) from None
    if f.decode and not base_url:
        part = _decoded(f, part, src)
    upstream_raw = f.gzip and not base_url  # upstream serves the uncompressed file
    got = content_sha256(part, f.gzip and not upstream_raw) if part.is_file() else ""
    if got != f.sha256:
        part.unlink(missing_ok=True)
        raise _SourceFailed(f"{f.path} from {src} has sha256 {got[:12]}..., expected {f.sha256[:12]}... (a corrupted "
                            f"download, or the source changed); the partial file was removed")
    if upstream_raw:
        packed = dest.with_name(dest.name + ".gz-part")
        with open(part, "rb") as src_f, gzip.GzipFile(packed, "wb", mtime=0) as out:
            shutil.copyfileobj(src_f, out)
        part.unlink()
        part = packed
    os.replace(part, dest)


def _write_text(ds: Dataset, f: DataFile, dest: Path) -> None:
    """A file the registry holds whole (``f.text``), checked like a download."""
    data = (f.text or "").encode("utf-8")
    if hashlib.sha256(data).hexdigest() != f.sha256:
        raise AppealInputError(f"{ds.name}: the registry's text of {f.path} does not match its sha256 "
                               f"(expected {f.sha256[:12]}...); the registry is damaged, reinstall appeal-lab")
    atomic_write_bytes(dest, data)


def _fetch_file(ds: Dataset, f: DataFile, dest: Path, base_url: str | None, bar: object | None) -> None:
    """One file of ``ds`` into ``dest``, from the mirror, else upstream (or the registry's own text)."""
    dest.parent.mkdir(parents=True, exist_ok=True)
    src = _source(ds, f, base_url)
    if src is None:
        return _write_text(ds, f, dest)
    try:
        _fetch_from(ds, f, dest, src, base_url, bar)
    except _SourceFailed as exc:
        hint = "check the connection and " if exc.offline else ""
        raise AppealInputError(f"{ds.name}: {exc}; {hint}retry: {ds.fetch_command}") from None


def fetch_dataset(name: str, *, base_url: str | None = None, root: Path | None = None) -> FetchReport:
    """Download what is missing or corrupted of dataset ``name`` into the data tree.

    Parameters
    ----------
    name : str
        A registered dataset (``appeal data list``).
    base_url : str, optional
        A mirror of the data tree (default: ``$APPEAL_DATA_URL``, else each file's upstream URL).
    root : Path, optional
        The data tree (default :func:`appeal.datasets.fetch_root`).

    Returns
    -------
    FetchReport

    Raises
    ------
    AppealInputError
        One line naming the dataset, the file, the source and the command to retry.
    """
    from tqdm.auto import tqdm

    ds = dataset(name)
    base_url = base_url or os.environ.get(MIRROR_ENV) or None
    folder = (root or fetch_root()) / ds.folder
    todo, present = [], []
    for f in ds.files:
        (present if _state(folder / f.path, f) == "ok" else todo).append(f)
    # documentation files without a source are skipped rather than failing the dataset
    todo = [f for f in todo if not (f.docs and not f.upstream and not base_url)]
    for f in todo:
        _source(ds, f, base_url)  # every file has a source before anything is downloaded
    # sizes are of the stored files: upstream serves some uncompressed or Draco-compressed
    raw = any(f.gzip or f.decode for f in todo) and not base_url
    bar = tqdm(total=None if raw else sum(f.size for f in todo), unit="B", unit_scale=True, desc=name, file=sys.stderr,
               disable=not progress_enabled() or not todo, leave=False)
    try:
        for f in todo:
            _fetch_file(ds, f, folder / f.path, base_url, bar)
    finally:
        bar.close()
    return FetchReport(ds, folder, [f.path for f in todo], [f.path for f in present])

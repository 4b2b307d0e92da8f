"""A folder laid out like the upstream servers the registry names, made from ``shared/data``.

``appeal data fetch`` without a mirror downloads every file from its registered upstream URLs
(``https://raw.githubusercontent.com/OWNER/REPO/COMMIT/PATH``). The tests serve this folder on
the loopback server and point those URLs at it, so the real upstream path runs offline: each
file sits at its URL's path in the form upstream serves it — uncompressed where the data tree
keeps it gzipped, and a Draco-compressed binary glTF where the data tree holds the OBJ decoded
from one. A file the registry writes itself (``text``) is not served.
"""

from __future__ import annotations

import gzip
import json
import struct
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np

from appeal.datasets import DataFile, dataset

#: Draco unique ids the test glTF gives its attributes (not DracoPy's own numbering, so a
#: decoder that ignores the extension's attribute table reads the wrong data).
POSITION_ID, TEXCOORD_ID = 7, 11


def draco_glb_of_obj(obj: Path) -> bytes:
    """A binary glTF whose one primitive is the OBJ's mesh, Draco-compressed.

    Positions and texture coordinates are stored losslessly (positions as a generic attribute
    with its own unique id; a quantised copy under Draco's position id as a decoy), the order of
    vertices and faces preserved, so decoding gives the OBJ's float32 values exactly.
    """
    import DracoPy

    rows = [ln.split() for ln in obj.read_text().splitlines()]
    v = np.array([r[1:4] for r in rows if r and r[0] == "v"], dtype=np.float32)
    vt = np.array([r[1:3] for r in rows if r and r[0] == "vt"], dtype=np.float64)
    f = np.array([[int(x.split("/")[0]) - 1 for x in r[1:4]] for r in rows if r and r[0] == "f"], dtype=np.uint32)
    buf = DracoPy.encode(v, f, quantization_bits=11, preserve_order=True,
                         generic_attributes={POSITION_ID: v, TEXCOORD_ID: vt.astype(np.float32)})
    doc = {"asset": {"version": "2.0", "generator": "appeal-lab tests"},
           "buffers": [{"byteLength": len(buf)}], "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(buf)}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "extensions": {
               "KHR_draco_mesh_compression": {"bufferView": 0,
                                              "attributes": {"POSITION": POSITION_ID, "TEXCOORD_0": TEXCOORD_ID}}}}]}],
           "extensionsUsed": ["KHR_draco_mesh_compression"], "extensionsRequired": ["KHR_draco_mesh_compression"]}
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    binary = buf + b"\0" * (-len(buf) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return (b"glTF" + struct.pack("<II", 2, total) + struct.pack("<I", len(text)) + b"JSON" + text
            + struct.pack("<I", len(binary)) + b"BIN\0" + binary)


def url_path(url: str) -> str:
    """The path part of an upstream URL (``/OWNER/REPO/COMMIT/PATH``)."""
    return urlsplit(url).path


def upstream_tree(shared_data: Path, dest: Path, names: list[str]) -> Path:
    """Lay out the upstream copies of datasets ``names`` under ``dest``; returns ``dest``."""
    for name in names:
        ds = dataset(name)
        for f in ds.files:
            if f.text is not None or f.url is None:
                continue
            src = shared_data / ds.folder / f.path
            out = dest / url_path(f.url).lstrip("/")
            out.parent.mkdir(parents=True, exist_ok=True)
            if f.decode:
                out.write_bytes(draco_glb_of_obj(src))
            elif f.gzip:
                out.write_bytes(gzip.decompress(src.read_bytes()))
            elif not out.exists():
                out.symlink_to(src)
    return dest


def pointed_at(f: DataFile, base: str) -> DataFile:
    """``f`` with its upstream URL moved to the loopback server at ``base``."""
    from dataclasses import replace

    return replace(f, url=base + url_path(f.url) if f.url else None)

"""Decode a Draco-compressed binary glTF (``.glb``) mesh into a Wavefront OBJ.

Upstream, the Lee Perry-Smith scan is three.js's ``LeePerrySmith.glb``: one mesh whose
primitive is compressed with ``KHR_draco_mesh_compression``. ``appeal data fetch`` downloads
it and writes the OBJ the study files read, byte for byte the file the data tree's curator
decoded (checked against the registry's sha256). Google's Draco decoder does the decoding,
through the ``DracoPy`` wheel; this module only reads the glTF container and writes the OBJ.

The attributes are taken by the Draco unique ids the extension names (``POSITION``,
``TEXCOORD_0``), as glTF specifies; the node's transform is not applied (the OBJ is the mesh in
its own coordinates, as the curator's copy is).
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass

import numpy as np

from appeal.errors import AppealInputError

__all__ = ["DecodedMesh", "ObjStyle", "decode_draco_glb", "glb_chunks", "obj_bytes"]

_GLB_MAGIC = b"glTF"
_JSON_CHUNK = 0x4E4F534A
_BIN_CHUNK = 0x004E4942
_DRACO = "KHR_draco_mesh_compression"


@dataclass(frozen=True)
class DecodedMesh:
    """Triangles with one texture coordinate per vertex (glTF shares one index for both)."""

    points: np.ndarray  #: (n, 3) float32
    uv: np.ndarray  #: (n, 2) float32, as glTF stores them (origin top-left)
    faces: np.ndarray  #: (m, 3) int, 0-based


@dataclass(frozen=True)
class ObjStyle:
    """How the OBJ is written: a first comment line, its material library and material.

    The curator's OBJ keeps glTF's texture v (the renderers read it with that convention) as
    ``1 - (1 - v)`` computed in float32, the round trip its converter made: it moves 14 of
    Lee Perry-Smith's 9,223 values by one unit in the sixth decimal, and the registry's sha256
    is of those bytes.
    """

    comment: str
    mtllib: str
    material: str


def glb_chunks(data: bytes, name: str = "glb") -> tuple[dict, bytes]:
    """The JSON document and the binary chunk of a binary glTF file.

    Raises
    ------
    AppealInputError
        Not a glTF 2.0 binary, or a truncated one (the message names ``name``).
    """
    if len(data) < 20 or data[:4] != _GLB_MAGIC:
        raise AppealInputError(f"{name}: not a binary glTF file (expected the magic 'glTF', got {data[:4]!r})")
    version, length = struct.unpack_from("<II", data, 4)
    if version != 2:
        raise AppealInputError(f"{name}: expected a glTF 2.0 binary, got glTF version {version}")
    if length > len(data):
        raise AppealInputError(f"{name}: truncated glTF binary ({len(data)} of its {length} bytes)")
    doc, binary, at = None, b"", 12
    while at + 8 <= length:
        size, kind = struct.unpack_from("<II", data, at)
        chunk = data[at + 8:at + 8 + size]
        if kind == _JSON_CHUNK:
            doc = json.loads(chunk.decode("utf-8"))
        elif kind == _BIN_CHUNK:
            binary = chunk
        at += 8 + size
    if doc is None:
        raise AppealInputError(f"{name}: the glTF binary has no JSON chunk")
    return doc, binary


def decode_draco_glb(data: bytes, mesh: int = 0, primitive: int = 0, name: str = "glb") -> DecodedMesh:
    """Decode one Draco-compressed primitive of a binary glTF file.

    Parameters
    ----------
    data : bytes
        The ``.glb`` file.
    mesh, primitive : int
        Which primitive (default: the first of the first mesh).
    name : str
        For error messages (the file or URL).

    Returns
    -------
    DecodedMesh
    """
    import DracoPy

    doc, binary = glb_chunks(data, name)
    try:
        prim = doc["meshes"][mesh]["primitives"][primitive]
        draco = prim["extensions"][_DRACO]
        view = doc["bufferViews"][draco["bufferView"]]
    except (KeyError, IndexError, TypeError):
        raise AppealInputError(f"{name}: meshes[{mesh}].primitives[{primitive}] is not compressed with "
                               f"{_DRACO}") from None
    if view.get("buffer", 0) != 0:
        raise AppealInputError(f"{name}: the Draco data lies in buffer {view['buffer']}, expected the binary chunk (0)")
    start = view.get("byteOffset", 0)
    try:
        decoded = DracoPy.decode(binary[start:start + view["byteLength"]])
    except Exception as exc:  # DracoPy raises its own failure types
        raise AppealInputError(f"{name}: Draco cannot decode the compressed mesh ({exc})") from None
    by_id = {a["unique_id"]: np.asarray(a["data"]) for a in decoded.attributes}
    wanted = draco.get("attributes", {})
    missing = [k for k in ("POSITION", "TEXCOORD_0") if wanted.get(k) not in by_id]
    if missing:
        raise AppealInputError(f"{name}: the Draco mesh lacks {', '.join(missing)} (expected both)")
    faces = np.asarray(decoded.faces, dtype=np.int64).reshape(-1, 3)
    return DecodedMesh(by_id[wanted["POSITION"]].astype(np.float32), by_id[wanted["TEXCOORD_0"]].astype(np.float32),
                       faces)


def obj_bytes(mesh: DecodedMesh, style: ObjStyle) -> bytes:
    """The mesh as OBJ text: ``v %.6f``, ``vt %.6f`` and ``f a/a b/b c/c`` lines (1-based)."""
    one = np.float32(1)
    uv = np.column_stack([mesh.uv[:, 0], one - (one - mesh.uv[:, 1])])
    idx = mesh.faces + 1
    lines = [f"# {style.comment}", f"mtllib {style.mtllib}", f"usemtl {style.material}"]
    lines += ["v %.6f %.6f %.6f" % tuple(p) for p in mesh.points.tolist()]
    lines += ["vt %.6f %.6f" % tuple(t) for t in uv.tolist()]
    lines += ["f %d/%d %d/%d %d/%d" % (a, a, b, b, c, c) for a, b, c in idx.tolist()]
    return ("\n".join(lines) + "\n").encode("ascii")

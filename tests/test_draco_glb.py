"""appeal.draco_glb: a Draco-compressed binary glTF decoded into the OBJ the registry checks."""

from __future__ import annotations

import hashlib
import json
import struct

import numpy as np
import pytest

from appeal.datasets import dataset
from appeal.draco_glb import ObjStyle, decode_draco_glb, glb_chunks, obj_bytes
from appeal.errors import AppealInputError
from upstream_tree import draco_glb_of_obj


def _style() -> ObjStyle:
    spec = next(f for f in dataset("leeperrysmith").files if f.path == "LeePerrySmith.obj").decode
    return ObjStyle(**{k: v for k, v in spec.items() if k != "from"})


def test_the_scan_round_trips_through_draco_byte_for_byte(shared_data):
    obj = shared_data / "meshes/leeperrysmith/LeePerrySmith.obj"
    mesh = decode_draco_glb(draco_glb_of_obj(obj))
    assert mesh.points.shape == (9223, 3) and mesh.uv.shape == (9223, 2) and mesh.faces.shape == (17684, 3)
    assert mesh.points.dtype == np.float32 and mesh.faces.min() == 0
    out = obj_bytes(mesh, _style())
    assert out == obj.read_bytes()
    assert hashlib.sha256(out).hexdigest() == next(f.sha256 for f in dataset("leeperrysmith").files
                                                   if f.path == "LeePerrySmith.obj")


def _glb(doc: dict, binary: bytes = b"") -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I", len(text)) + b"JSON" + text
    if binary:
        body += struct.pack("<I", len(binary)) + b"BIN\0" + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


@pytest.mark.parametrize("data, why", [
    (b"<html>Not Found</html>", "not a binary glTF file"),
    (b"glTF" + struct.pack("<II", 1, 40) + b"\0" * 28, "expected a glTF 2.0 binary, got glTF version 1"),
    (b"glTF" + struct.pack("<II", 2, 400) + b"\0" * 28, "truncated glTF binary (40 of its 400 bytes)"),
    (_glb({"meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}]}),
     "meshes[0].primitives[0] is not compressed with KHR_draco_mesh_compression"),
    (_glb({"bufferViews": [{"buffer": 0, "byteLength": 8}], "meshes": [{"primitives": [{"extensions": {
        "KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}}]}]}, b"\1" * 8),
     "Draco cannot decode"),
])
def test_what_is_not_a_draco_glb_gets_one_line_naming_it(data, why):
    with pytest.raises(AppealInputError) as exc:
        decode_draco_glb(data, name="https://example.org/head.glb")
    msg = str(exc.value)
    assert msg.startswith("https://example.org/head.glb: ") and why in msg and "\n" not in msg


def test_glb_chunks_reads_the_json_and_the_binary(shared_data):
    doc, binary = glb_chunks(draco_glb_of_obj(shared_data / "meshes/leeperrysmith/LeePerrySmith.obj"))
    assert "KHR_draco_mesh_compression" in doc["extensionsRequired"]
    assert len(binary) >= doc["bufferViews"][0]["byteLength"]

"""Mesh I/O: vertex order, quads, UV seams, parts, regions, round trips and bad files."""

from __future__ import annotations

import gzip

import numpy as np
import pytest

from appeal.errors import AppealInputError
from stimulus_engine.geometry.ict_topology import ict_regions
from stimulus_engine.geometry.mesh_io import (
    load_mesh,
    load_parts,
    mesh_uv_layout,
    save_mesh,
    select_region,
    texture_image,
)

QUAD_OBJ = """# two quads sharing an edge, with a UV seam at vertex 2
mtllib missing.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0 0
v 2 1 0
vt 0 0
vt 0.5 0
vt 0.5 1
vt 0 1
vt 1 0
vt 1 1
vt 0.6 1
g left
usemtl skin
f 1/1 2/2 3/3 4/4
g right
usemtl skin
f 2/2 5/5 6/6 3/7
"""


@pytest.fixture
def quad_obj(tmp_path):
    p = tmp_path / "quads.obj"
    p.write_text(QUAD_OBJ)
    return p


def test_quads_fan_triangulated_order_kept(quad_obj):
    m = load_mesh(quad_obj)
    assert m.vertices.shape == (6, 3)
    np.testing.assert_array_equal(m.vertices[4], [2, 0, 0])
    np.testing.assert_array_equal(m.faces, [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]])
    # all normals point +z (orientation kept by the fan)
    assert np.allclose(m.face_normals[:, 2], 1.0)


def test_uv_seam_kept_per_corner(quad_obj):
    m = load_mesh(quad_obj)
    uv, fuv = mesh_uv_layout(m)
    # vertex 2 has UV (0.5, 1) in the left quad and (0.6, 1) in the right one
    np.testing.assert_allclose(uv[fuv[3, 2]], [0.6, 1.0])
    np.testing.assert_allclose(uv[fuv[0, 2]], [0.5, 1.0])
    np.testing.assert_allclose(m.visual.uv[2], [0.5, 1.0])  # first corner wins per vertex
    assert texture_image(m) is None


def test_parts_by_group(quad_obj):
    parts = load_parts(quad_obj)
    assert sorted(parts) == ["left", "right"]
    np.testing.assert_array_equal(parts["right"].metadata["vertex_ids"], [1, 2, 4, 5])
    assert len(parts["right"].faces) == 2


@pytest.mark.parametrize("ext", ["obj", "obj.gz", "ply", "glb"])
def test_round_trip(quad_obj, tmp_path, ext):
    m = load_mesh(quad_obj)
    out = save_mesh(m, tmp_path / f"out.{ext}")
    back = load_mesh(out)
    np.testing.assert_allclose(back.vertices, m.vertices, atol=1e-6)
    np.testing.assert_array_equal(back.faces, m.faces)
    assert getattr(back.visual, "uv", None) is not None


def test_select_region_keeps_inside_faces(quad_obj):
    m = load_mesh(quad_obj)
    sub, ids = select_region(m, [1, 2, 4, 5])
    np.testing.assert_array_equal(ids, [1, 2, 4, 5])
    np.testing.assert_array_equal(sub.faces, [[0, 2, 3], [0, 3, 1]])
    uv, fuv = mesh_uv_layout(sub)
    np.testing.assert_allclose(uv[fuv[1, 2]], [0.6, 1.0])


@pytest.mark.parametrize(
    "content, expected",
    [
        ("", "mesh file is empty"),
        ("v 0 0 0\nv 1 0 0\n", "no faces"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "face refers to vertex 9, but the file has 3 vertices"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "line 4: face needs at least 3 vertices"),
        ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "finite"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 x 3\n", "integer indices (got 'x')"),
    ],
)
def test_bad_obj_one_line_errors(tmp_path, content, expected):
    p = tmp_path / "bad.obj"
    p.write_text(content)
    with pytest.raises(AppealInputError) as e:
        load_mesh(p)
    assert expected in str(e.value)
    assert str(p) in str(e.value)
    assert len(e.value.lines) == 1


def test_missing_and_unsupported(tmp_path):
    with pytest.raises(AppealInputError, match="mesh file not found"):
        load_mesh(tmp_path / "nope.obj")
    p = tmp_path / "a.xyz"
    p.write_text("1 2 3")
    with pytest.raises(AppealInputError, match="unsupported mesh format '.xyz'"):
        load_mesh(p)
    g = tmp_path / "broken.obj.gz"
    g.write_bytes(b"not gzip at all")
    with pytest.raises(AppealInputError, match="cannot read mesh file"):
        load_mesh(g)


def test_missing_texture_flagged(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl a\nmap_Kd gone.png\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    m = load_mesh(tmp_path / "m.obj")
    assert m.metadata["texture_missing"] is True
    assert m.metadata["texture_path"].endswith("gone.png")


def test_gz_equals_plain(tmp_path):
    (tmp_path / "a.obj").write_text(QUAD_OBJ)
    (tmp_path / "a.obj.gz").write_bytes(gzip.compress(QUAD_OBJ.encode()))
    a, b = load_mesh(tmp_path / "a.obj"), load_mesh(tmp_path / "a.obj.gz")
    np.testing.assert_array_equal(a.faces, b.faces)


def test_region_errors(quad_obj):
    m = load_mesh(quad_obj)
    with pytest.raises(AppealInputError, match="vertex index 99 is out of range"):
        select_region(m, [0, 99])
    with pytest.raises(AppealInputError, match="no triangle"):
        select_region(m, [0, 4])


def test_real_ict_and_james(shared_data):
    d = shared_data / "meshes"
    ict = load_mesh(d / "ict-facekit" / "generic_neutral_mesh.obj.gz")
    assert ict.vertices.shape == (26719, 3)
    parts = load_parts(d / "ict-facekit" / "generic_neutral_mesh.obj.gz")
    assert {"M_Face", "M_Teeth", "M_ScleraLeft", "M_IrisRight"} <= set(parts)
    assert len(parts["M_Face"].vertices) == 9409  # README: Face [0:9408]
    regions = ict_regions(d / "ict-facekit" / "vertex_indices.json")
    assert len(regions["landmarks"]) == 68 and regions["landmarks"][0] == 1225
    face, ids = select_region(ict, regions["face"])
    np.testing.assert_array_equal(face.vertices, ict.vertices[:9409])
    james = load_mesh(d / "menpo3d-james" / "james.obj")
    assert james.vertices.shape == (6393, 3)
    assert texture_image(james).size == (2400, 1600)

"""Mesh input/output on trimesh: OBJ (also ``.obj.gz``), PLY and GLB, with UVs and textures.

Every loader keeps the file's vertex order (``process=False`` semantics): vertex ``i`` of the
returned :class:`trimesh.Trimesh` is the ``i``-th ``v`` line of an OBJ file, so vertex indices
from a model's documentation (e.g. the ICT face kit's landmark list) stay valid. Polygons are
fan-triangulated (a quad ``a b c d`` becomes ``a b c`` and ``a c d``), which keeps orientation.

UVs: OBJ files store texture coordinates per face corner, so one vertex on a UV seam can have
several UVs. ``mesh.visual.uv`` holds one UV per vertex (that of the first corner using the
vertex); the exact per-corner layout is kept in ``mesh.metadata["face_uv"]`` (faces × 3 indices)
and ``mesh.metadata["uv_coords"]`` (K × 2), which :mod:`stimulus_engine.correspondence.texture_transfer`
uses so that seams are handled exactly.

Bad files raise :class:`appeal.errors.AppealInputError` with a one-line message naming the file.

The OBJ text itself (parsing and writing) is :mod:`stimulus_engine.geometry.obj_format`; ICT Face
Model regions are in :mod:`stimulus_engine.characters.ict`.
"""

from __future__ import annotations

import gzip
import io
import json
import os
from pathlib import Path

import numpy as np
import trimesh

from appeal.atomic import atomic_write_bytes, atomic_write_text
from appeal.errors import AppealInputError
from appeal.logs import logger
from stimulus_engine.geometry.obj_format import ObjData, obj_text, parse_mtl, parse_obj, texture_for

__all__ = [
    "MESH_SUFFIXES",
    "build_trimesh",
    "load_mesh",
    "load_parts",
    "validate_surface",
    "save_mesh",
    "select_region",
    "mesh_uv_layout",
    "read_json",
    "texture_image",
]

#: File name endings :func:`load_mesh` reads.
MESH_SUFFIXES = (".obj", ".obj.gz", ".ply", ".glb", ".gltf", ".off", ".stl")

def _suffix(path: Path) -> str:
    name = path.name.lower()
    for s in (".obj.gz",):
        if name.endswith(s):
            return s
    return path.suffix.lower()


def _check_exists(path: Path) -> None:
    if not path.exists():
        raise AppealInputError(f"{path}: mesh file not found")
    if path.is_dir():
        raise AppealInputError(f"{path}: expected a mesh file, got a folder")
    if path.stat().st_size == 0:
        raise AppealInputError(f"{path}: mesh file is empty")
    suffix = _suffix(path)
    if suffix not in MESH_SUFFIXES:
        raise AppealInputError(
            f"{path}: unsupported mesh format '{suffix or path.name}' (expected one of "
            f"{', '.join(MESH_SUFFIXES)})"
        )


# --------------------------------------------------------------------------------------------
# Meshes from arrays (OBJ text: stimulus_engine.geometry.obj_format)
# --------------------------------------------------------------------------------------------


def _per_vertex_uv(n_vertices: int, faces: np.ndarray, face_uv: np.ndarray, uv: np.ndarray):
    out = np.zeros((n_vertices, 2))
    # The first corner using each vertex wins (reverse assignment so earliest writes last).
    fv = faces.ravel()[::-1]
    ft = face_uv.ravel()[::-1]
    out[fv] = uv[ft]
    return out


def build_trimesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    uv_coords: np.ndarray | None,
    face_uv: np.ndarray | None,
    image,
    metadata: dict,
) -> trimesh.Trimesh:
    """A :class:`trimesh.Trimesh` in the given vertex order, with the exact UV layout kept.

    With ``uv_coords`` (K, 2) and ``face_uv`` (F, 3), ``visual.uv`` gets one UV per vertex (the
    first corner's) and ``metadata["uv_coords"/"face_uv"]`` the per-corner layout; ``image``
    (PIL, optional) becomes the texture; ``metadata`` is copied into the mesh's.
    """
    visual = None
    if uv_coords is not None and face_uv is not None:
        uv = _per_vertex_uv(len(vertices), faces, face_uv, uv_coords)
        material = trimesh.visual.material.SimpleMaterial(image=image) if image is not None else None
        visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, visual=visual, process=False)
    mesh.metadata.update(metadata)
    if uv_coords is not None and face_uv is not None:
        mesh.metadata["uv_coords"] = uv_coords
        mesh.metadata["face_uv"] = face_uv
    return mesh


def _load_obj(path: Path) -> tuple[trimesh.Trimesh, ObjData]:
    data = parse_obj(path)
    image, tex_path, missing = None, None, False
    if data.mtllibs:
        mats = parse_mtl(path, data.mtllibs)
        image, tex_path, missing = texture_for(path, mats, data.materials)
    meta: dict = {"source_path": str(path)}
    if tex_path is not None:
        meta["texture_path"] = str(tex_path)
        if missing:
            meta["texture_missing"] = True
            logger.warning("%s: map_Kd: texture file %s not found", path, tex_path)
    mesh = build_trimesh(data.vertices, data.faces, data.uv_coords, data.face_uv, image, meta)
    return mesh, data


# --------------------------------------------------------------------------------------------
# Other formats through trimesh
# --------------------------------------------------------------------------------------------


def _load_trimesh_any(path: Path):
    try:
        return trimesh.load(str(path), process=False, maintain_order=True)
    except AppealInputError:
        raise
    except Exception as exc:  # trimesh raises many types for malformed files
        raise AppealInputError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from None


def _from_trimesh(mesh: trimesh.Trimesh, path: Path) -> trimesh.Trimesh:
    faces = np.asarray(mesh.faces, dtype=np.int64)
    verts = np.asarray(mesh.vertices, dtype=np.float64)
    uv = getattr(mesh.visual, "uv", None)
    image = None
    if uv is not None:
        image = texture_image(mesh)
        uv = np.asarray(uv, dtype=np.float64)
    meta = {"source_path": str(path)}
    if uv is not None and len(uv) == len(verts):
        return build_trimesh(verts, faces, uv, faces.copy(), image, meta)
    out = trimesh.Trimesh(vertices=verts, faces=faces, process=False)
    if getattr(mesh.visual, "kind", None) == "vertex":
        out.visual.vertex_colors = mesh.visual.vertex_colors
    out.metadata.update(meta)
    return out


def _scene_parts(scene: trimesh.Scene, path: Path) -> dict[str, trimesh.Trimesh]:
    parts: dict[str, trimesh.Trimesh] = {}
    for node in scene.graph.nodes_geometry:
        transform, geom_name = scene.graph[node]
        geom = scene.geometry[geom_name]
        if not isinstance(geom, trimesh.Trimesh):
            continue
        m = _from_trimesh(geom, path)
        if not np.allclose(transform, np.eye(4)):
            m.vertices = trimesh.transform_points(m.vertices, transform)
        name = str(node) if node not in parts else f"{node}_{len(parts)}"
        parts[name] = m
    return parts


def validate_surface(mesh: trimesh.Trimesh, name: str | os.PathLike) -> trimesh.Trimesh:
    """``mesh`` if it is a surface: triangles, finite coordinates and some area.

    Raises
    ------
    AppealInputError
        One line starting with ``name`` (the file, or the mesh's role).
    """
    if len(mesh.vertices) == 0 or len(mesh.faces) == 0:
        raise AppealInputError(f"{name}: mesh has no triangles (expected a surface mesh)")
    v = np.asarray(mesh.vertices, dtype=np.float64)
    if not np.all(np.isfinite(v)):
        raise AppealInputError(f"{name}: vertex coordinates must be finite numbers (found NaN/inf)")
    if float(mesh.area) <= 1e-12 * float(np.sum((v.max(axis=0) - v.min(axis=0)) ** 2)):
        raise AppealInputError(f"{name}: mesh has no area (every triangle is degenerate; expected a surface mesh)")
    return mesh


# --------------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------------


def load_mesh(path: str | os.PathLike) -> trimesh.Trimesh:
    """Load a triangle mesh, keeping the file's vertex order.

    Parameters
    ----------
    path : path-like
        ``.obj``, ``.obj.gz``, ``.ply``, ``.glb``/``.gltf`` (also ``.off``, ``.stl``).

    Returns
    -------
    trimesh.Trimesh
        Vertices in file order; polygons fan-triangulated; ``visual.uv`` and the texture image
        (``visual.material.image``) when the file has them. ``metadata`` holds
        ``source_path``, ``texture_path`` (when one is referenced), ``texture_missing`` (when
        the referenced image does not exist), and for OBJ files the exact per-corner UV layout
        ``uv_coords``/``face_uv``. Multi-part GLB scenes are concatenated (use
        :func:`load_parts` to keep them apart).

    Raises
    ------
    AppealInputError
        Missing, empty, unsupported or malformed files (one line naming the file).
    """
    path = Path(path)
    _check_exists(path)
    if _suffix(path) in (".obj", ".obj.gz"):
        mesh, _ = _load_obj(path)
        return validate_surface(mesh, path)
    loaded = _load_trimesh_any(path)
    if isinstance(loaded, trimesh.Scene):
        parts = _scene_parts(loaded, path)
        if not parts:
            raise AppealInputError(f"{path}: scene holds no triangle meshes")
        if len(parts) == 1:
            return validate_surface(next(iter(parts.values())), path)
        mesh = trimesh.util.concatenate(list(parts.values()))
        mesh.metadata["source_path"] = str(path)
        return validate_surface(mesh, path)
    if not isinstance(loaded, trimesh.Trimesh):
        raise AppealInputError(f"{path}: expected a triangle mesh (got {type(loaded).__name__})")
    return validate_surface(_from_trimesh(loaded, path), path)


def load_parts(path: str | os.PathLike) -> dict[str, trimesh.Trimesh]:
    """Load a multi-part head as named parts (e.g. skin, eyes, teeth).

    OBJ files are split by their ``g``/``o`` groups, or by ``usemtl`` materials when they have
    no groups (the ICT face kit names its parts by material: ``M_Face``, ``M_Teeth``, ...).
    GLB/GLTF scenes are split by node. A file without parts gives ``{"mesh": whole}``.

    Parameters
    ----------
    path : path-like
        A mesh file (see :func:`load_mesh`).

    Returns
    -------
    dict of str to trimesh.Trimesh
        Each part keeps only its own vertices, in their original relative order;
        ``part.metadata["vertex_ids"]`` maps them to the whole file's vertex indices.
    """
    path = Path(path)
    _check_exists(path)
    if _suffix(path) in (".obj", ".obj.gz"):
        mesh, data = _load_obj(path)
        validate_surface(mesh, path)
        if data.groups and (data.face_group >= 0).any():
            labels, names = data.face_group, data.groups
        elif data.materials and (data.face_material >= 0).any():
            labels, names = data.face_material, data.materials
        else:
            return {"mesh": mesh}
        parts: dict[str, trimesh.Trimesh] = {}
        for k in np.unique(labels):
            name = names[k] if k >= 0 else "default"
            face_ids = np.flatnonzero(labels == k)
            used = np.unique(mesh.faces[face_ids])
            sub, _ = select_region(mesh, used, faces=face_ids)
            parts[name] = sub
        return parts
    loaded = _load_trimesh_any(path)
    if isinstance(loaded, trimesh.Scene):
        parts = _scene_parts(loaded, path)
        if not parts:
            raise AppealInputError(f"{path}: scene holds no triangle meshes")
        return parts
    return {"mesh": load_mesh(path)}


def mesh_uv_layout(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray] | None:
    """The exact UV layout: ``(uv_coords (K, 2), face_uv (F, 3))``, or None without UVs.

    Uses the per-corner layout of OBJ files when present, else the per-vertex
    ``mesh.visual.uv`` with the mesh's own faces.
    """
    if "uv_coords" in mesh.metadata and "face_uv" in mesh.metadata:
        fuv = np.asarray(mesh.metadata["face_uv"])
        if len(fuv) == len(mesh.faces):
            return np.asarray(mesh.metadata["uv_coords"], dtype=np.float64), fuv
    uv = getattr(mesh.visual, "uv", None)
    if uv is None or len(uv) != len(mesh.vertices):
        return None
    return np.asarray(uv, dtype=np.float64), np.asarray(mesh.faces)


def texture_image(mesh: trimesh.Trimesh):
    """The mesh's texture image (PIL), or None.

    trimesh gives every :class:`~trimesh.visual.TextureVisuals` without a material a 2x2
    one-colour placeholder (``trimesh.visual.material.empty_material``); that is not a texture
    and is reported as None.
    """
    mat = getattr(mesh.visual, "material", None)
    if mat is None:
        return None
    img = getattr(mat, "image", None)
    if img is None:
        img = getattr(mat, "baseColorTexture", None)
    if img is None or (img.size[0] <= 2 and img.size[1] <= 2):
        return None
    return img


def select_region(
    mesh: trimesh.Trimesh, vertex_ids, faces: np.ndarray | None = None
) -> tuple[trimesh.Trimesh, np.ndarray]:
    """The sub-mesh spanned by a vertex set (e.g. an ICT region), UVs and texture kept.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The whole mesh.
    vertex_ids : array-like of int
        Vertex indices of the region (any order; duplicates ignored).
    faces : array of int, optional
        Face indices to keep; by default every face whose three vertices are in the set.

    Returns
    -------
    sub : trimesh.Trimesh
        The region, vertices in increasing original index; ``sub.metadata["vertex_ids"]``
        holds those original indices.
    vertex_ids : ndarray of int
        The same original indices (``sub.vertices == mesh.vertices[vertex_ids]``).
    """
    ids = np.unique(np.asarray(vertex_ids, dtype=np.int64).ravel())
    n = len(mesh.vertices)
    if ids.size == 0:
        raise AppealInputError("region: vertex set is empty (expected vertex indices)")
    if ids[0] < 0 or ids[-1] >= n:
        bad = ids[(ids < 0) | (ids >= n)][0]
        raise AppealInputError(
            f"region: vertex index {int(bad)} is out of range (mesh has {n} vertices)"
        )
    remap = np.full(n, -1, dtype=np.int64)
    remap[ids] = np.arange(len(ids))
    if faces is None:
        keep = np.all(remap[mesh.faces] >= 0, axis=1)
        face_ids = np.flatnonzero(keep)
    else:
        face_ids = np.asarray(faces, dtype=np.int64)
    if face_ids.size == 0:
        raise AppealInputError("region: no triangle has all its vertices in the vertex set")
    new_faces = remap[mesh.faces[face_ids]]
    layout = mesh_uv_layout(mesh)
    uv_coords = face_uv = None
    image = None
    if layout is not None:
        uv_coords, fuv = layout
        face_uv = fuv[face_ids]
        image = texture_image(mesh)
    meta = {k: v for k, v in mesh.metadata.items() if k not in ("uv_coords", "face_uv")}
    meta["vertex_ids"] = ids
    sub = build_trimesh(mesh.vertices[ids], new_faces, uv_coords, face_uv, image, meta)
    return sub, ids


def read_json(path: str | os.PathLike, what: str):
    """Parse a JSON file; a missing file or bad JSON is a one-line :class:`AppealInputError`."""
    p = Path(path)
    if not p.exists():
        raise AppealInputError(f"{p}: {what} not found")
    try:
        return json.loads(p.read_text())
    except json.JSONDecodeError as exc:
        raise AppealInputError(f"{p}: not valid JSON ({exc.msg} at line {exc.lineno})") from None


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------


def save_mesh(mesh: trimesh.Trimesh, path: str | os.PathLike) -> Path:
    """Write a mesh (vertex order kept), atomically.

    ``.obj`` / ``.obj.gz`` are written by this module with the exact UV layout; a texture
    image is written beside an ``.obj`` as ``<stem>.png`` with a ``<stem>.mtl``. ``.ply``,
    ``.glb`` and ``.stl``/``.off`` go through trimesh's exporters.

    Returns
    -------
    Path
        The written file.
    """
    path = Path(path)
    suffix = _suffix(path)
    if suffix not in MESH_SUFFIXES or suffix == ".gltf":
        raise AppealInputError(
            f"{path}: cannot write mesh format '{suffix}' (expected .obj, .obj.gz, .ply, .glb, "
            ".off or .stl)"
        )
    if not path.parent.exists():
        raise AppealInputError(f"{path}: output folder {path.parent} does not exist")
    if suffix in (".obj", ".obj.gz"):
        image = texture_image(mesh)
        mtl_name = None
        if image is not None and suffix == ".obj":
            stem = path.name[: -len(suffix)]
            mtl_name = f"{stem}.mtl"
            png = io.BytesIO()
            image.save(png, format="PNG")
            atomic_write_bytes(path.parent / f"{stem}.png", png.getvalue())
            atomic_write_text(
                path.parent / mtl_name,
                f"newmtl material_0\nKd 1 1 1\nKa 0 0 0\nKs 0 0 0\nmap_Kd {stem}.png\n",
            )
        text = obj_text(mesh.vertices, mesh.faces, mesh_uv_layout(mesh), mtl_name)
        if suffix == ".obj.gz":
            atomic_write_bytes(path, gzip.compress(text.encode("utf-8"), mtime=0))
        else:
            atomic_write_text(path, text)
        return path
    data = trimesh.exchange.export.export_mesh(mesh, file_obj=None, file_type=suffix[1:])
    if isinstance(data, str):
        data = data.encode("utf-8")
    atomic_write_bytes(path, data)
    return path

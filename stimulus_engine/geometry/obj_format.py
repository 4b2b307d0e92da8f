"""The Wavefront OBJ format: OBJ and MTL text to arrays and back (no trimesh).

:func:`parse_obj` reads positions, the exact per-corner UV layout, groups and materials;
:func:`parse_mtl` and :func:`texture_for` find the ``map_Kd`` texture; :func:`obj_text` writes
a mesh. :mod:`stimulus_engine.geometry.mesh_io` builds meshes from them.
"""

from __future__ import annotations

import gzip
import io
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError
from appeal.logs import logger

__all__ = ["ObjData", "obj_text", "parse_mtl", "parse_obj", "texture_for"]


class ObjData:
    """Raw OBJ content: positions, corner UV indices, per-face part labels and materials."""

    def __init__(self) -> None:
        self.vertices: np.ndarray = np.zeros((0, 3))
        self.uv_coords: np.ndarray | None = None
        self.faces: np.ndarray = np.zeros((0, 3), dtype=np.int64)
        self.face_uv: np.ndarray | None = None
        self.face_group: np.ndarray = np.zeros(0, dtype=np.int64)
        self.face_material: np.ndarray = np.zeros(0, dtype=np.int64)
        self.groups: list[str] = []
        self.materials: list[str] = []
        self.mtllibs: list[str] = []


def _read_text(path: Path) -> str:
    try:
        if path.name.lower().endswith(".obj.gz"):
            with gzip.open(path, "rb") as fh:
                raw = fh.read()
        else:
            raw = path.read_bytes()
    except (OSError, EOFError) as exc:
        raise AppealInputError(f"{path}: cannot read mesh file ({exc})") from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def parse_obj(path: Path) -> ObjData:
    """Parse an OBJ (``.obj``/``.obj.gz``) file: polygons fan-triangulated, file vertex order kept.

    Raises
    ------
    AppealInputError
        Unreadable or malformed files (one line naming the file and line).
    """
    text = _read_text(path)
    v: list[str] = []
    vt: list[str] = []
    corners_v: list[int] = []
    corners_t: list[int] = []
    poly_sizes: list[int] = []
    poly_group: list[int] = []
    poly_mat: list[int] = []
    groups: dict[str, int] = {}
    materials: dict[str, int] = {}
    mtllibs: list[str] = []
    cur_group = -1
    cur_mat = -1
    any_missing_t = False
    for lineno, line in enumerate(text.splitlines(), start=1):
        if not line or line[0] == "#":
            continue
        head, _, rest = line.partition(" ")
        if head == "v":
            v.append(rest)
        elif head == "vt":
            vt.append(rest)
        elif head == "f":
            items = rest.split()
            if len(items) < 3:
                raise AppealInputError(
                    f"{path}: line {lineno}: face needs at least 3 vertices (got '{line.strip()}')"
                )
            for it in items:
                parts = it.split("/")
                try:
                    vi = int(parts[0])
                    ti = int(parts[1]) if len(parts) > 1 and parts[1] else 0
                except ValueError:
                    raise AppealInputError(
                        f"{path}: line {lineno}: face entries must be integer indices "
                        f"(got '{it}')"
                    ) from None
                # OBJ indices are 1-based; negative ones count back from the current end.
                vi = vi - 1 if vi > 0 else len(v) + vi
                if ti == 0:
                    any_missing_t = True
                    ti = -1
                else:
                    ti = ti - 1 if ti > 0 else len(vt) + ti
                corners_v.append(vi)
                corners_t.append(ti)
            poly_sizes.append(len(items))
            poly_group.append(cur_group)
            poly_mat.append(cur_mat)
        elif head in ("g", "o"):
            name = rest.strip() or f"group{len(groups)}"
            cur_group = groups.setdefault(name, len(groups))
        elif head == "usemtl":
            name = rest.strip()
            cur_mat = materials.setdefault(name, len(materials))
        elif head == "mtllib":
            mtllibs.append(rest.strip())
    data = ObjData()
    if not v:
        raise AppealInputError(f"{path}: no vertices ('v' lines) found; expected an OBJ mesh")
    if not poly_sizes:
        raise AppealInputError(f"{path}: no faces ('f' lines) found; expected a polygon mesh")
    try:
        verts = np.loadtxt(io.StringIO("\n".join(v)), dtype=np.float64, ndmin=2, usecols=(0, 1, 2))
    except ValueError as exc:
        raise AppealInputError(f"{path}: vertex lines must hold 3 numbers ({exc})") from None
    if not np.all(np.isfinite(verts)):
        raise AppealInputError(f"{path}: vertex coordinates must be finite numbers (found NaN/inf)")
    cv = np.asarray(corners_v, dtype=np.int64)
    ct = np.asarray(corners_t, dtype=np.int64)
    bad = (cv < 0) | (cv >= len(verts))
    if bad.any():
        raise AppealInputError(
            f"{path}: face refers to vertex {int(cv[bad][0]) + 1}, but the file has "
            f"{len(verts)} vertices"
        )
    sizes = np.asarray(poly_sizes, dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    # Fan triangulation: polygon (p0 .. pk-1) -> (p0, pj, pj+1), j = 1 .. k-2.
    n_tri = sizes - 2
    poly_of_tri = np.repeat(np.arange(len(sizes)), n_tri)
    j = np.arange(n_tri.sum()) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri) + 1
    base = starts[poly_of_tri]
    corner_idx = np.stack([base, base + j, base + j + 1], axis=1)
    data.vertices = verts
    data.faces = cv[corner_idx]
    if vt and not any_missing_t:
        uvs = np.loadtxt(io.StringIO("\n".join(vt)), dtype=np.float64, ndmin=2, usecols=(0, 1))
        if ((ct < 0) | (ct >= len(uvs))).any():
            raise AppealInputError(
                f"{path}: face refers to a texture coordinate beyond the {len(uvs)} 'vt' lines"
            )
        data.uv_coords = uvs
        data.face_uv = ct[corner_idx]
    elif vt:
        logger.warning("%s: some faces have no texture coordinates; UVs ignored", path)
    data.face_group = np.asarray(poly_group, dtype=np.int64)[poly_of_tri]
    data.face_material = np.asarray(poly_mat, dtype=np.int64)[poly_of_tri]
    data.groups = list(groups)
    data.materials = list(materials)
    data.mtllibs = mtllibs
    return data


def parse_mtl(obj_path: Path, mtllibs: list[str]) -> dict[str, dict[str, str]]:
    """Material name -> {key: value} from the OBJ's mtllib files (missing libs are logged)."""
    out: dict[str, dict[str, str]] = {}
    for lib in mtllibs:
        mpath = (obj_path.parent / lib).resolve()
        if not mpath.exists():
            logger.warning("%s: material library '%s' not found; materials ignored", obj_path, lib)
            continue
        current: dict[str, str] | None = None
        for line in mpath.read_text(errors="replace").splitlines():
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            key, _, val = line.partition(" ")
            if key == "newmtl":
                current = out.setdefault(val.strip(), {"_mtl": str(mpath)})
            elif current is not None:
                current[key] = val.strip()
    return out


def texture_for(obj_path: Path, mats: dict[str, dict[str, str]], names: list[str]):
    """First ``map_Kd`` image among the used materials: (image or None, path or None, missing)."""
    from PIL import Image

    for name in names or list(mats):
        m = mats.get(name)
        if not m or "map_Kd" not in m:
            continue
        rel = m["map_Kd"].split()[-1]
        tpath = (Path(m["_mtl"]).parent / rel).resolve()
        if not tpath.exists():
            return None, tpath, True
        try:
            img = Image.open(tpath)
            img.load()
        except OSError as exc:
            raise AppealInputError(f"{tpath}: map_Kd: cannot read texture image ({exc})") from None
        return img, tpath, False
    return None, None, False


def obj_text(vertices: np.ndarray, faces: np.ndarray, layout: tuple[np.ndarray, np.ndarray] | None,
             mtl_name: str | None) -> str:
    """OBJ text of a triangle mesh: ``v`` lines in order, the exact UV layout ``(uv, face_uv)`` if given."""
    buf = io.StringIO()
    buf.write("# written by Appeal Lab (stimulus_engine.geometry.mesh_io)\n")
    if mtl_name:
        buf.write(f"mtllib {mtl_name}\nusemtl material_0\n")
    np.savetxt(buf, np.asarray(vertices), fmt="v %.8g %.8g %.8g")
    faces1 = np.asarray(faces, dtype=np.int64) + 1
    if layout is not None:
        uv, fuv = layout
        np.savetxt(buf, uv, fmt="vt %.8g %.8g")
        fuv1 = np.asarray(fuv, dtype=np.int64) + 1
        inter = np.stack([faces1, fuv1], axis=2).reshape(len(faces1), 6)
        np.savetxt(buf, inter, fmt="f %d/%d %d/%d %d/%d")
    else:
        np.savetxt(buf, faces1, fmt="f %d %d %d")
    return buf.getvalue()

"""Render a stimulus grid: characters × shapes × materials × expressions × lighting × shading.

:func:`run_grid` plans every image (with a hash of everything that determines its pixels),
prepares the shared inputs once in this process (stylised shapes with expressions carried over by
deformation transfer, stylised albedos) into ``DIR/.cache``, renders the images that are not
already up to date in parallel worker processes (one OpenGL context each; Dask when a scheduler
is given), and writes:

``DIR/manifest.csv``
    One row per image: ``file`` (relative to DIR), the factors ``character``, ``shape`` (level
    0 = realistic .. 1 = cartoon), ``shape_label`` (``realistic``, ``shape0.5``, ``cartoon``:
    what file names and contact sheets say), ``stylisation`` (the thesis's level number, the
    same way round in every grid: 0 = the grid's most stylised shape level, counting up towards
    the realistic end; photographs above all, see :meth:`GridFile.stylisation_index`), ``material``, ``expression``
    (canonical), ``emotion`` (as written in the grid), ``lighting``, ``shading``; the input
    hashes ``geometry_hash``, ``albedo_hash``, ``maps_hash`` (normal and specular maps, ``none``
    without), ``input_hash``; ``camera``; ``seconds``; ``status``.
``DIR/landmarks.csv``
    3D landmarks of every (character, shape, expression) geometry (for neoteny measures).
``DIR/contact_sheet.png`` (+ ``contact_sheet_expressions.png``, ``contact_sheet_lighting.png``)
    Rows = character × shape level, columns = materials (thesis Fig. 6.11), for the first
    expression/lighting/shading; and the same rows against expressions (and lighting/shading).
    Only the cells the grid has: with ``pair_materials_with_shapes`` the first sheet has one row
    per character and one column per shape+material pair.

A re-run over the same folder (``--resume``) skips images whose ``input_hash`` and file are
unchanged.
"""

from __future__ import annotations

import functools
import hashlib
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from PIL import Image

from appeal.atomic import atomic_write_bytes, atomic_write_text
from appeal.errors import AppealInputError
from appeal.logs import logger
from stimulus_engine.expressions import apply_expression, resolve_expression
from stimulus_engine.ict import load_ict_rig
from stimulus_engine.rig import FaceRig
from stimulus_engine.grid_schema import CharacterSpec, GridFile, MaterialSpec, shape_label

__all__ = ["GRID_VERSION", "RenderItem", "plan_grid", "run_grid"]

#: Bumped when the rendering code changes what pixels come out (part of every input hash).
GRID_VERSION = "grid-7"


def _sha(*parts: object) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p if isinstance(p, bytes) else json.dumps(p, sort_keys=True, default=str).encode())
        h.update(b"\0")
    return h.hexdigest()[:20]


@dataclass(frozen=True)
class RenderItem:
    """Everything a worker needs to render one image (paths and settings; picklable)."""

    file: str
    out_dir: str
    rig_npz: str
    geometry_npy: str
    albedo_png: str
    lighting: str
    shading: str
    camera: tuple
    width: int
    height: int
    shadows: bool
    background: tuple
    normal_png: str = ""
    specular_png: str = ""


# --------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------


def _file_sha(path: object) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _base_rig(c: CharacterSpec) -> tuple[FaceRig, str]:
    """The character's own rig (ICT identity or procedural head) and a hash of its inputs."""
    if c.procedural is not None:
        from stimulus_engine.procedural_head import procedural_head

        p = c.procedural
        return procedural_head(p.seed, texture_size=p.texture_size, resolution=p.resolution), _sha("procedural", p.model_dump())
    assert c.ict is not None
    rig = load_ict_rig(c.ict, c.identity)
    files = sorted(Path(c.ict).glob("*.obj*"))
    sig = [(f.name, f.stat().st_size, int(f.stat().st_mtime)) for f in files]
    return rig, _sha("ict", c.identity, sig)


def _character_rig(c: CharacterSpec, cache: Path, source: str) -> tuple[FaceRig, str, FaceRig]:
    """The rig of a character, a hash of its inputs, and the rig its expressions come from.

    For a ``mesh`` character the base rig is corresponded onto the mesh (cached in
    ``cache/mesh``, keyed by the inputs' hash); expressions are then carried over from the base
    rig by deformation transfer.
    """
    base, base_hash = _base_rig(c)
    if c.mesh is None:
        return base, base_hash, base
    from dataclasses import replace

    m = c.mesh
    files = {"file": m.file, "texture": m.texture, "normal_map": m.normal_map, "specular_map": m.specular_map}
    h = _sha(GRID_VERSION, "mesh", base_hash, *[_file_sha(f) if f else None for f in files.values()],
             m.model_dump(mode="json", exclude=set(files)))
    p = cache / "mesh" / f"{h}.npz"
    if p.exists():
        d = np.load(p)
        masks = {k[5:]: d[k] for k in d.files if k.startswith("mask_")}
        maps = {k[4:]: d[k] for k in d.files if k.startswith("map_")}
        rig = replace(base.with_vertices(d["vertices"], name=c.name),
                      texture=d["texture"] if "texture" in d.files else None, texture_masks=masks, texture_maps=maps)
        return rig, h, base
    import io

    from stimulus_engine.mesh_character import correspond_rig
    from stimulus_engine.ict import ict_regions
    from stimulus_engine.mesh_io import load_mesh

    where = f"{source}: characters.{c.name}.mesh"
    region = None
    if m.region == "front":
        from stimulus_engine.mesh_character import front_region

        region = front_region(base)
    elif m.region is not None:
        regions = ict_regions(Path(c.ict) / "vertex_indices.json")
        if m.region not in regions or m.region == "landmarks":
            names = ", ".join(k for k in regions if k != "landmarks")
            raise AppealInputError(f"{where}: region: unknown ICT region '{m.region}' (expected one of: {names})")
        region = regions[m.region]
    mesh = load_mesh(m.file)
    texture = _load_texture(m.texture) if m.texture is not None else None
    maps = {kind: _load_map(path, kind, None, f"{where}.{kind}_map")
            for kind, path in (("normal", m.normal_map), ("specular", m.specular_map)) if path is not None}
    landmarks = {k: (list(v) if isinstance(v, tuple) else v) for k, v in m.landmarks.items()}
    logger.info("%s: corresponding %s onto %s", c.name, base.name, m.file)
    mc = correspond_rig(base, mesh, landmarks, region=region, texture=texture, texture_size=m.texture_size,
                        name=c.name, where=where, maps=maps)
    logger.info("%s: correspondence metrics %s", c.name,
                {k: round(v, 5) for k, v in mc.metrics.items() if isinstance(v, float)})
    buf = io.BytesIO()
    extra = {} if mc.rig.texture is None else {"texture": mc.rig.texture}
    np.savez(buf, vertices=mc.rig.vertices, **extra, **{f"mask_{k}": v for k, v in mc.rig.texture_masks.items()},
             **{f"map_{k}": v for k, v in mc.rig.texture_maps.items()})
    p.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(p, buf.getvalue())
    return mc.rig, h, base


def _load_texture(path: Path) -> np.ndarray:
    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"))
    except OSError as exc:
        raise AppealInputError(f"{path}: cannot read the texture image ({exc})".splitlines()[0]) from None


def _load_map(path: Path, kind: str, size: tuple[int, int] | None, where: str) -> np.ndarray:
    """A normal or specular map file, checked (channels, size, tangent space) before any rendering."""
    from stimulus_engine.materials import check_map

    try:
        with Image.open(path) as im:
            arr = np.asarray(im if im.mode in ("L", "RGB", "RGBA", "LA", "I;16") else im.convert("RGB"))
    except OSError as exc:
        raise AppealInputError(f"{where}: {path}: cannot read the image ({exc})".splitlines()[0]) from None
    if arr.ndim == 3 and arr.shape[2] == 2:  # LA
        arr = arr[..., 0]
    try:
        return check_map(arr, kind, size)
    except ValueError as exc:
        raise AppealInputError(f"{where}: {path.name}: {exc}") from None


def _npz_cached(path: Path, compute: object) -> dict[str, np.ndarray]:
    """``compute()`` (a dict of arrays), kept in ``path`` so a re-run (``--resume``) reads it back."""
    import io

    if path.exists():
        with np.load(path) as d:
            return {k: d[k] for k in d.files}
    out = compute()  # type: ignore[operator]
    buf = io.BytesIO()
    np.savez(buf, **out)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())
    return out


def _painted_albedo(rig: FaceRig, rig_hash: str, seed: int, cache: Path) -> tuple[np.ndarray, dict]:
    """The albedo painted by code on a rig without texture, cached in ``cache/painted``."""
    from stimulus_engine.materials import rig_albedo

    def paint() -> dict[str, np.ndarray]:
        img, masks = rig_albedo(rig, seed=seed)
        return {"albedo": img, **{f"mask_{k}": v for k, v in masks.items()}}

    d = _npz_cached(cache / "painted" / f"{_sha(GRID_VERSION, rig_hash, 'albedo', seed)}.npz", paint)
    return d["albedo"], {k[5:]: v for k, v in d.items() if k.startswith("mask_")}


def _albedo_source(c: CharacterSpec, rig: FaceRig, grid_name: str, rig_hash: str = "",
                   cache: Path | None = None) -> tuple[np.ndarray, dict]:
    from stimulus_engine.materials import rig_albedo

    if c.texture is not None:
        if rig.uv is None:
            raise AppealInputError(f"{grid_name}: characters.{c.name}.texture: the mesh has no UVs, "
                                   "so a texture cannot be applied (expected a mesh with texture coordinates)")
        return _load_texture(c.texture), {}
    if rig.uv is None and rig.texture is None:
        raise AppealInputError(f"{grid_name}: characters.{c.name}: the mesh has no UVs, so no albedo texture can be "
                               "painted (expected a mesh with texture coordinates)")
    if rig.texture is None and cache is not None:
        return _painted_albedo(rig, rig_hash, c.texture_seed, cache)
    return rig_albedo(rig, seed=c.texture_seed)


def _camera_for(rig: FaceRig, shape_vertices: np.ndarray, grid: GridFile) -> tuple:
    """Same face size and eye position for every shape: framed on the shape's neutral landmarks."""
    from stimulus_engine.render import face_camera

    lm = rig.landmark_points(shape_vertices)
    eye = (lm["eye_left"] + lm["eye_right"]) / 2
    length = float(np.linalg.norm(lm["forehead_top"] - lm["chin"]))
    r = grid.render
    cam = face_camera(eye, length, yfov_deg=r.yfov_deg, eye_row=r.eye_row, face_fraction=r.face_fraction)
    return (cam.position, cam.target, cam.yfov_deg, cam.up)


def _save_npy(path: Path, arr: np.ndarray) -> None:
    import io

    if path.exists():
        return
    buf = io.BytesIO()
    np.save(buf, arr)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())


def _save_rig(path: Path, rig: FaceRig) -> None:
    import io

    if path.exists():
        return
    buf = io.BytesIO()
    np.savez(buf, faces=rig.faces, face_part=rig.face_part, part_names=np.array(rig.part_names),
             uv=rig.uv if rig.uv is not None else np.zeros((0, 2)),
             face_uv=rig.face_uv if rig.face_uv is not None else np.zeros((0, 3), np.int64),
             **{f"part_texture_{k}": t for k, t in rig.part_textures.items()})
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())


# --------------------------------------------------------------------------------------------
# Planning
# --------------------------------------------------------------------------------------------


def plan_grid(grid: GridFile, out: Path, *, source: str = "grid") -> tuple[pd.DataFrame, list[RenderItem], pd.DataFrame]:
    """Prepare the inputs of every image in ``out/.cache`` and list the images.

    Everything that can be wrong with the inputs is found here, before any rendering.

    Returns
    -------
    manifest : DataFrame
        One row per image (``seconds`` and ``status`` still empty).
    items : list of RenderItem
        One per rendered image, in manifest order (photographs need no rendering).
    landmarks : DataFrame
        Long table: character, shape, expression, landmark, x, y, z.
    """
    from stimulus_engine.materials import albedo_hash, maps_hash, rig_detail_maps, stylise_albedo, stylise_map
    from stimulus_engine.stylise import stylise

    cache = out / ".cache"
    rigs: dict[str, tuple[FaceRig, str, FaceRig]] = {c.name: _character_rig(c, cache, source) for c in grid.characters}
    specs = {c.name: c for c in grid.characters}
    albedo_src = {c.name: _albedo_source(c, rigs[c.name][0], source, rigs[c.name][1], cache) for c in grid.characters}
    mats = grid.material_specs()
    for m in mats:
        if m.from_character is None:
            continue
        a = rigs[m.from_character][0]
        for c in grid.characters:
            b = rigs[c.name][0]
            if b.uv is None or a.uv is None or a.uv.shape != b.uv.shape or not np.allclose(a.uv, b.uv):
                raise AppealInputError(
                    f"{source}: materials.{m.name}: characters '{c.name}' and '{m.from_character}' do not share a UV "
                    "layout (expected corresponded meshes; transfer the texture with the correspondence first)")
    rows, items, lm_rows = [], [], []
    r = grid.render
    stylisation = grid.stylisation_index()
    geom_cache: dict[tuple, tuple[Path, str]] = {}
    albedo_cache: dict[tuple, tuple[Path, str]] = {}

    def albedo_for(char: str, m: MaterialSpec) -> tuple[Path, str]:
        src = m.from_character or char
        key = (src, m.style)
        if key not in albedo_cache:
            img, masks = albedo_src[src]
            styl = stylise_albedo(img, m.style, masks)
            h = albedo_hash(styl)
            p = cache / "albedo" / f"{h}.png"
            if not p.exists():
                from stimulus_engine.render import save_png

                save_png(styl, p)
            albedo_cache[key] = (p, h)
        return albedo_cache[key]

    maps_cache: dict[tuple, tuple[str, str, str]] = {}

    def maps_for(char: str, m: MaterialSpec) -> tuple[str, str, str]:
        """(normal PNG or "", specular PNG or "", maps hash): the material's files, else the
        albedo character's own maps, else painted by code (procedural_maps); stylised like the albedo."""
        src = m.from_character or char
        key = (src, m.name)
        if key in maps_cache:
            return maps_cache[key]
        img, masks = albedo_src[src]
        size = img.shape[:2]
        own = rigs[src][0].texture_maps
        painted = None
        found = {}
        for kind, path in (("normal", m.normal_map), ("specular", m.specular_map)):
            if path is not None:
                found[kind] = _load_map(path, kind, size, f"{source}: materials.{m.name}.{kind}_map")
            elif kind in own:
                found[kind] = own[kind]
            elif m.procedural_maps:
                if rigs[src][0].uv is None:
                    raise AppealInputError(f"{source}: materials.{m.name}.procedural_maps: character '{src}' has no "
                                           "UVs (expected a mesh with texture coordinates)")
                if painted is None:
                    seed = specs[src].texture_seed
                    painted = _npz_cached(
                        cache / "painted" / f"{_sha(GRID_VERSION, rigs[src][1], 'maps', seed, size)}.npz",
                        lambda: dict(zip(("normal", "specular"), rig_detail_maps(rigs[src][0], size=size[0],
                                                                                seed=seed))))
                    painted = (painted["normal"], painted["specular"])
                found[kind] = painted[0] if kind == "normal" else painted[1]
            if kind in found and found[kind].shape[:2] != size:
                raise AppealInputError(f"{source}: materials.{m.name}: the {kind} map of '{src}' is "
                                       f"{found[kind].shape[1]} x {found[kind].shape[0]}, expected {size[1]} x {size[0]} "
                                       "like its albedo")
        out = {}
        for kind, arr in found.items():
            styl = stylise_map(arr, kind, m.style, masks if all(np.shape(v) == size for v in masks.values()) else {})
            h = albedo_hash(styl)
            path = cache / "maps" / f"{kind}_{h}.png"
            if not path.exists():
                from stimulus_engine.render import save_png

                save_png(styl if styl.ndim == 3 else np.repeat(styl[..., None], 3, axis=2), path)
            out[kind] = (str(path), styl)
        maps_cache[key] = (out["normal"][0] if "normal" in out else "", out["specular"][0] if "specular" in out else "",
                           maps_hash(out["normal"][1] if "normal" in out else None,
                                     out["specular"][1] if "specular" in out else None))
        return maps_cache[key]

    for c in grid.characters:
        rig, rig_hash, expr_rig = rigs[c.name]
        rig_npz = cache / "rigs" / f"{_sha(GRID_VERSION, rig_hash)}.npz"
        _save_rig(rig_npz, rig)
        for pos, level in enumerate(grid.shapes):
            si, label = stylisation[level], shape_label(level)
            shape_v = stylise(rig, level)
            cam = _camera_for(rig, shape_v, grid)
            mat_list = [mats[pos]] if grid.pair_materials_with_shapes else mats
            for expr in grid.expressions:
                canon = resolve_expression(expr)
                gkey = (c.name, level, canon)
                if gkey not in geom_cache:
                    gh = _sha(GRID_VERSION, rig_hash, level, canon, r.intensity)
                    gp = cache / "geometry" / f"{gh}.npy"
                    if not gp.exists():
                        # the rig's own blendshapes on its own neutral; deformation transfer onto a
                        # stylised shape or a corresponded mesh character
                        plain = level == 0 and expr_rig is rig
                        try:
                            v = apply_expression(expr_rig, canon, r.intensity, target=None if plain else shape_v)
                        except ValueError as exc:  # a recipe shape the rig lacks
                            raise AppealInputError(f"{source}: characters.{c.name}: {exc}") from None
                        _save_npy(gp, v.astype(np.float32))
                    v = np.load(gp)
                    for name, pt in rig.landmark_points(v.astype(np.float64)).items():
                        lm_rows.append({"character": c.name, "shape": level, "stylisation": si, "expression": canon,
                                        "landmark": name, "x": pt[0], "y": pt[1], "z": pt[2]})
                    geom_cache[gkey] = (gp, gh)
                gp, gh = geom_cache[gkey]
                for m in mat_list:
                    ap, ah = albedo_for(c.name, m)
                    npng, spng, mh = maps_for(c.name, m)
                    for light in grid.lighting:
                        for shading in grid.shading:
                            fname = f"images/{c.name}_{label}_{m.name}_{expr}_{light}_{shading}.png"
                            extra = () if mh == "none" else (mh,)  # hashes without maps as before
                            ih = _sha(GRID_VERSION, gh, ah, light, shading, cam, r.model_dump(), *extra)
                            items.append(RenderItem(fname, str(out), str(rig_npz), str(gp), str(ap), light, shading,
                                                    cam, r.width, r.height, r.shadows, tuple(r.background),
                                                    npng, spng))
                            rows.append({"file": fname, "character": c.name, "shape": level, "shape_label": label,
                                         "stylisation": si,
                                         "material": m.name, "material_style": m.style,
                                         "material_from": m.from_character or c.name, "expression": canon,
                                         "emotion": expr, "lighting": light, "shading": shading,
                                         "geometry_hash": gh, "albedo_hash": ah, "maps_hash": mh,
                                         "input_hash": ih,
                                         "camera": _camera_text(cam), "width": r.width, "height": r.height})
    for p in grid.photographs:
        for expr in grid.expressions:
            src = p.files[expr]
            fname = f"images/{p.character}_photo_{expr}.png"
            ih = _sha(GRID_VERSION, "photo", hashlib.sha256(Path(src).read_bytes()).hexdigest(), r.width, r.height)
            rows.append({"file": fname, "character": p.character, "shape": "photograph",
                         "shape_label": "photograph", "stylisation": len(grid.shapes), "material": "photograph", "material_style": "photograph",
                         "material_from": p.character, "expression": resolve_expression(expr), "emotion": expr,
                         "lighting": "photograph", "shading": "photograph", "geometry_hash": "", "albedo_hash": "",
                         "maps_hash": "",
                         "input_hash": ih, "camera": f"photo:{Path(src).name}", "width": r.width, "height": r.height,
                         "_photo": str(src)})
    return pd.DataFrame(rows), items, pd.DataFrame(lm_rows)


def _camera_text(cam: tuple) -> str:
    from stimulus_engine.render import CameraSpec

    return CameraSpec(tuple(cam[0]), tuple(cam[1]), cam[2], tuple(cam[3])).describe()


# --------------------------------------------------------------------------------------------
# Rendering (runs in worker processes)
# --------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=8)
def _rig_static(path: str) -> FaceRig:
    d = np.load(path)
    uv = d["uv"] if len(d["uv"]) else None
    fuv = d["face_uv"] if len(d["face_uv"]) else None
    textures = {k[len("part_texture_"):]: d[k] for k in d.files if k.startswith("part_texture_")}
    return FaceRig(name=Path(path).stem, vertices=np.zeros((0, 3)), faces=d["faces"], uv=uv, face_uv=fuv,
                   face_part=d["face_part"], part_names=tuple(str(x) for x in d["part_names"]), landmarks={},
                   part_textures=textures)


@functools.lru_cache(maxsize=16)
def _albedo_image(path: str) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def _map_image(path: str, kind: str) -> np.ndarray | None:
    """A prepared map from the cache (specular maps are stored as grey RGB), or None."""
    if not path:
        return None
    img = _albedo_image(path)
    return img if kind == "normal" else _grey(path)


@functools.lru_cache(maxsize=16)
def _grey(path: str) -> np.ndarray:
    return np.ascontiguousarray(_albedo_image(path)[..., 0])


def render_item(item: RenderItem) -> float:
    """Render one grid image to ``item.out_dir/item.file``; returns the seconds it took."""
    from stimulus_engine.materials import rig_render_parts
    from stimulus_engine.render import CameraSpec, render_mesh, save_png

    t0 = time.perf_counter()
    rig = _rig_static(item.rig_npz)
    v = np.load(item.geometry_npy).astype(np.float64)
    parts = rig_render_parts(rig, v, _albedo_image(item.albedo_png), shading=item.shading,
                             normal_map=_map_image(item.normal_png, "normal"),
                             specular_map=_map_image(item.specular_png, "specular"))
    pos, target, yfov, up = item.camera
    cam = CameraSpec(tuple(pos), tuple(target), yfov, tuple(up))
    img = render_mesh(parts, width=item.width, height=item.height, lighting=item.lighting, camera=cam,
                      background=item.background, shadows=item.shadows)
    save_png(img, Path(item.out_dir) / item.file)
    return time.perf_counter() - t0


def _place_photo(src: str, dst: Path, width: int, height: int, background: tuple) -> None:
    """Letterbox a photograph into the stimulus size on the grid's background."""
    from stimulus_engine.render import save_png

    with Image.open(src) as im:
        im = im.convert("RGB")
        scale = min(width / im.width, height / im.height)
        im = im.resize((max(1, round(im.width * scale)), max(1, round(im.height * scale))), Image.LANCZOS)
    canvas = Image.new("RGB", (width, height), tuple(int(round(b * 255)) for b in background))
    canvas.paste(im, ((width - im.width) // 2, (height - im.height) // 2))
    save_png(np.asarray(canvas), dst)


# --------------------------------------------------------------------------------------------
# The command's body
# --------------------------------------------------------------------------------------------


def _previous_hashes(out: Path) -> dict[str, str]:
    p = out / "manifest.csv"
    if not p.exists():
        return {}
    try:
        old = pd.read_csv(p, dtype=str)
    except (OSError, ValueError, pd.errors.ParserError):
        return {}
    if not {"file", "input_hash", "status"} <= set(old.columns):
        return {}
    old = old[old["status"].isin(["rendered", "up to date"])]
    return dict(zip(old["file"], old["input_hash"]))


def sheet_layout(cells: pd.DataFrame, rows: list[str], col: str) -> tuple[list[int | None], int, dict]:
    """Arrange the manifest rows ``cells`` (one per image) on a contact sheet.

    Rows are the distinct values of the columns ``rows``, columns those of ``col``. When every
    row × column combination has an image this is a table (row and column labels); when the grid
    does not have them all (e.g. materials paired with shapes) the images are laid out as a list
    with a caption each, so that no cell stands for an image the grid does not have.

    Returns
    -------
    order : list of int or None
        Index labels of ``cells`` in row-major order (None only pads the last row of a list).
    ncols : int
    labels : dict
        ``row_labels`` and ``col_labels`` (table) or ``labels`` (list), for :func:`contact_sheet`.
    """
    row_keys = list(dict.fromkeys(zip(*(cells[r] for r in rows))))
    cols = list(dict.fromkeys(cells[col]))
    where = {(*key, c): idx for idx, key, c in zip(cells.index, zip(*(cells[r] for r in rows)), cells[col])}
    if len(where) == len(row_keys) * len(cols):
        order: list[int | None] = [where[(*key, c)] for key in row_keys for c in cols]
        return order, len(cols), {"row_labels": [" ".join(map(str, k)) for k in row_keys],
                                  "col_labels": [str(c) for c in cols]}
    order = list(where.values())
    captions = [" ".join(map(str, k)) for k in where]
    ncols = min(len(order), max(len(cols), 1))
    return order, ncols, {"labels": captions}


def _sheets(out: Path, manifest: pd.DataFrame, grid: GridFile) -> list[Path]:
    from stimulus_engine.render import contact_sheet, save_png

    planned = manifest[manifest["shape"] != "photograph"]
    ok = planned["status"].isin(["rendered", "up to date"])
    if not ok.any():
        return []
    first = planned[ok].iloc[0]
    paired = grid.pair_materials_with_shapes
    paths = []

    def sheet(sub: pd.DataFrame, rows: list[str], col: str, name: str, title: str) -> None:
        order, ncols, labels = sheet_layout(sub, rows, col)
        imgs = [None if i is None or not ok[i] else np.asarray(Image.open(out / sub.at[i, "file"]).convert("RGB"))
                for i in order]
        if all(im is None for im in imgs):
            return
        arr = contact_sheet(imgs, ncols, thumb_width=220, title=title, **labels)
        paths.append(save_png(arr, out / name))

    def where(**eq: str) -> pd.DataFrame:
        sel = planned
        for k, v in eq.items():
            if not (paired and k == "material"):  # paired: each shape level has its own material
                sel = sel[sel[k] == v]
        return sel.copy()

    shape_rows = ["character", "shape_label"]
    sel = where(expression=first.expression, lighting=first.lighting, shading=first.shading)
    if paired:
        sel["shape_material"] = sel["shape_label"] + " / " + sel["material"]
        sheet(sel, ["character"], "shape_material", "contact_sheet.png",
              f"{grid.name}: character (rows) x shape / material pairs (columns), {first.emotion}, {first.lighting}, "
              f"{first.shading}")
    else:
        sheet(sel, shape_rows, "material", "contact_sheet.png",
              f"{grid.name}: shape (rows) x material (columns), {first.emotion}, {first.lighting}, {first.shading}")
    sel = where(material=first.material, lighting=first.lighting, shading=first.shading)
    sheet(sel, shape_rows, "emotion", "contact_sheet_expressions.png",
          f"{grid.name}: shape (rows) x expression (columns), {'paired material' if paired else first.material}, "
          f"{first.lighting}, {first.shading}")
    if len(grid.lighting) > 1 or len(grid.shading) > 1:
        sel = where(material=first.material, expression=first.expression)
        sel["light_shading"] = sel["lighting"] + "/" + sel["shading"]
        sheet(sel, shape_rows, "light_shading", "contact_sheet_lighting.png",
              f"{grid.name}: shape (rows) x lighting/shading (columns), "
              f"{'paired material' if paired else first.material}, {first.emotion}")
    return paths


def run_grid(grid: GridFile, out: Path, *, n_jobs: int | None = None, scheduler: str | None = None,
             source: str = "grid") -> tuple[pd.DataFrame, list[Path]]:
    """Render ``grid`` into ``out`` (see the module docstring for the files written).

    Parameters
    ----------
    grid : GridFile
    out : Path
        Output folder (prepared by the caller, e.g. :func:`appeal.outputs.output_run`).
    n_jobs : int, optional
        Local worker processes (default: all cores; 1 = in this process).
    scheduler : str, optional
        Dask scheduler address.
    source : str
        The grid file's name, for error messages.

    Returns
    -------
    manifest : DataFrame
    sheets : list of Path
        The contact sheets written.
    """
    from appeal.parallel import parallel_map

    out = Path(out)
    manifest, items, landmarks = plan_grid(grid, out, source=source)
    previous = _previous_hashes(out)
    status = {}
    todo = []
    for it, row in zip(items, manifest[manifest["shape"] != "photograph"].itertuples()):
        if previous.get(it.file) == row.input_hash and (out / it.file).exists():
            status[it.file] = ("up to date", float("nan"))
        else:
            todo.append(it)
    logger.info("%s: %d images, %d up to date, %d to render", grid.name, len(manifest), len(status), len(todo))
    res = parallel_map(render_item, todo, n_jobs=n_jobs, scheduler=scheduler, desc="rendering",
                       labels=[t.file for t in todo])
    failed = {f.index: f.error for f in res.failures}
    for i, (it, secs) in enumerate(zip(todo, res.results)):
        status[it.file] = (f"failed: {failed[i]}", float("nan")) if i in failed else ("rendered", float(secs))
    for idx in manifest.index[manifest["shape"] == "photograph"]:
        t0 = time.perf_counter()
        f = manifest.at[idx, "file"]
        _place_photo(manifest.at[idx, "_photo"], out / f, grid.render.width, grid.render.height,
                     grid.render.background)
        status[f] = ("rendered", time.perf_counter() - t0)
    manifest["seconds"] = [round(status[f][1], 4) for f in manifest["file"]]
    manifest["status"] = [status[f][0] for f in manifest["file"]]
    manifest = manifest.drop(columns=[c for c in manifest.columns if c.startswith("_")])
    atomic_write_text(out / "manifest.csv", manifest.to_csv(index=False))
    atomic_write_text(out / "landmarks.csv", landmarks.to_csv(index=False))
    atomic_write_text(out / "grid.json", json.dumps(grid.model_dump(mode="json"), indent=2))
    sheets = _sheets(out, manifest, grid)
    if res.failures:
        logger.warning(res.summary())
    return manifest, sheets


def item_dict(item: RenderItem) -> dict:
    """A RenderItem as a plain dict (for logs)."""
    return asdict(item)

"""The grid's input cache (``DIR/.cache``): content keys and the files kept between runs.

Every prepared input (a corresponded mesh character, a painted albedo or map set, an
expression's geometry, a stylised albedo or map, a rig's topology) is written once under a name
made from a hash of everything it depends on (:func:`sha`, with :data:`GRID_VERSION`), so a
re-run (``--resume``) reads it back and an image whose input hash is unchanged is not rendered
again. Files are written atomically: a crash leaves no half-written cache entry.
"""

from __future__ import annotations

import functools
import hashlib
import io
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from appeal.atomic import atomic_write_bytes
from stimulus_engine.characters.rig import FaceRig
from stimulus_engine.parts.body import body_arrays, body_from_arrays
from stimulus_engine.parts.hair import hair_arrays, hair_from_arrays
from stimulus_engine.parts.surround import surround_arrays, surround_from_arrays

__all__ = ["GRID_VERSION", "file_sha", "load_rig", "npz_cached", "save_npy", "save_npz", "save_png_once", "save_rig", "sha"]

#: Bumped when the rendering code changes what pixels come out (part of every input hash).
GRID_VERSION = "grid-50"  # 50: the bust's neck textured (its colour around the neck with a fine mottle as strong as the skin's above it); 49: the eyeballs centred in their openings in each image before aiming, the rig (and the hair and bust fitted to it) as ICT placed them; 48: the eye's catch-light a small window, a scan's dark painted iris lifted to grey 68; 47: an ICT rig's eyeballs centred in their lids' openings (looking ahead); 46: characters from one photograph (photo:), their surround drawn unlit; 45: the garment goes on 6 iod below the bust's cut across the chest, a designed cartoon on its character's neck, its hair fitted to each designed level's head; 44: a dark painted iris lifted to grey 85, the Cycles toon highlight 0.03; 43: the eyes, lashes and hair stylised along the scale (stylisation.eyes, .hair), toon shading; 42: the painted material family, eyes 1.3x at the cartoon end; 41: a scan's upper incisors shown between parted lips; 40: the bust's neck extended up at the sides and back; 39: half the white hair highlight; 38: pyrender anti-aliased by supersampling (render.supersample, default 1.5); 37: hair cards blended back to front, strand edges softened; 36: no dips in the collar's edge; 35: a scan's lids drawn with a margin from the rim back onto the eyeball; 34: the inside of a mesh character's lips drawn as mucosa in its lips' shade; 33: a scan fades into its neck's colour toward its border, the neck coloured from skin texels only; 32: the inside of the mouth lit at least 0.55 (teeth 0.7), as Cycles bounces light in; 31: Kajiya-Kay strand highlights on pyrender hair; 30: the eye-occlusion shell drawn as the lids' shadow and the caruncle, one glint per eye; 29: the bust neck coloured from 0.1 iod above its border; 28: Cycles draws hair strands as curves with the Principled Hair BSDF; 27: the ICT rig's lacrimal fluid drawn as the lids' wet line; 26: a scan's collar edge hidden from mask 0.2, the bust neck coloured from 0.35 iod above its border; 25: the garment drawn on both sides, Cycles cuts alpha-tested hair out; 24: the neck's own texture coordinates at the neckline; 23: a soft oval vignette with the head framing; 22: a hair style per character (MakeHuman's eight), locks hang by their offsets, a style over a scan's own hair; 21: a crew neckline at the base of the neck, the character's neck on under the garment, a scan's collar cut in a clean line; 20: a bust (neck, shoulders, garment) under every head, head-and-shoulders framing; 19: lash cards follow their roots; 18: eyeball sclera lit to SCLERA_LEVEL; 17: a mesh character's lashes seated on its lids; 16: painted-eye remnants inpainted on scan lids; 15: eyeballs kept behind the lids; 14: teeth, gums and tongue behind a scan's lips, the mouth lit through its opening, glossy corneas; 13: eyes aimed at the gaze target, scan eyeballs by their painted pupils; 12: render engine, samples and seed in the hash; skin shading


def sha(*parts: object) -> str:
    """Short hash (20 hex digits) of ``parts``: bytes as they are, anything else as sorted JSON."""
    h = hashlib.sha256()
    for p in parts:
        h.update(p if isinstance(p, bytes) else json.dumps(p, sort_keys=True, default=str).encode())
        h.update(b"\0")
    return h.hexdigest()[:20]


def file_sha(path: object) -> str:
    """SHA-256 of a file's bytes (hex)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _write(path: Path, save: Callable[[io.BytesIO], None]) -> None:
    buf = io.BytesIO()
    save(buf)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())


def npz_cached(path: Path, compute: Callable[[], dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """``compute()`` (a dict of arrays), kept in ``path`` so a re-run (``--resume``) reads it back."""
    if path.exists():
        with np.load(path) as d:
            return {k: d[k] for k in d.files}
    out = compute()
    save_npz(path, out)
    return out


def save_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` to ``path`` (``.npz``, uncompressed), atomically."""
    _write(path, lambda buf: np.savez(buf, **arrays))


def save_npy(path: Path, arr: np.ndarray) -> None:
    """Write ``arr`` to ``path`` (``.npy``) unless it is already there."""
    if not path.exists():
        _write(path, lambda buf: np.save(buf, arr))


def save_png_once(arr: np.ndarray, path: Path) -> Path:
    """Write the image ``arr`` to ``path`` unless it is already there (content-named files)."""
    if not path.exists():
        from stimulus_engine.render import save_png

        save_png(arr, path)
    return path


def save_rig(path: Path, rig: FaceRig) -> None:
    """Write a rig's topology (faces, parts, UVs, part textures) for the render workers, once."""
    if path.exists():
        return
    _write(path, lambda buf: np.savez(
        buf, faces=rig.faces, face_part=rig.face_part, part_names=np.array(rig.part_names),
        uv=rig.uv if rig.uv is not None else np.zeros((0, 2)),
        face_uv=rig.face_uv if rig.face_uv is not None else np.zeros((0, 3), np.int64),
        **{f"part_texture_{k}": t for k, t in rig.part_textures.items()}, **hair_arrays(rig.hair),
        **body_arrays(rig.body), **surround_arrays(rig.surround)))


@functools.lru_cache(maxsize=8)
def load_rig(path: str) -> FaceRig:
    """The topology written by :func:`save_rig` as a rig without vertices (cached per process)."""
    d = np.load(path)
    uv = d["uv"] if len(d["uv"]) else None
    fuv = d["face_uv"] if len(d["face_uv"]) else None
    textures = {k[len("part_texture_"):]: d[k] for k in d.files if k.startswith("part_texture_")}
    return FaceRig(name=Path(path).stem, vertices=np.zeros((0, 3)), faces=d["faces"], uv=uv, face_uv=fuv,
                   face_part=d["face_part"], part_names=tuple(str(x) for x in d["part_names"]), landmarks={},
                   part_textures=textures, hair=hair_from_arrays(d), body=body_from_arrays(d),
                   surround=surround_from_arrays(d))

"""A grid's design (``design:``): the artist's head corresponded once, each character's own cartoon.

The grid only orchestrates: the correspondence and the features are
:mod:`stimulus_engine.characters.design`, the cartoon and the morphs
:mod:`stimulus_engine.stylisation.designed_shape`. The design in the rig's topology is kept in
``.cache/design`` (a few seconds to make); :func:`grid_characters` gives every character its cartoon
and :func:`shape_vertices` is the neutral of any shape level, designed or analytic.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError
from appeal.logs import logger
from stimulus_engine.grid.cache import GRID_VERSION, file_sha, npz_cached, sha
from stimulus_engine.grid.characters import Character, load_character
from stimulus_engine.grid.schema import DesignSpec, GridFile

__all__ = ["drawn_rig", "grid_characters", "load_design", "shape_vertices"]

#: Changes whenever a design's correspondence or features change (part of its cache key).
DESIGN_VERSION = "design-1"


def load_design(spec: DesignSpec, ict: Path, cache: Path, source: str) -> np.ndarray:
    """The design of ``spec`` in the topology of the ICT model in ``ict`` (its mean face's frame), cached."""
    from stimulus_engine.characters.design import correspond_design, design_head
    from stimulus_engine.characters.ict import load_ict_rig
    from stimulus_engine.geometry.mesh_io import load_parts

    where = f"{source}: design.{spec.name}"
    files = sorted(Path(ict).glob("*.obj*"))
    key = sha(GRID_VERSION, DESIGN_VERSION, file_sha(spec.file), spec.landmarks,
              [(f.name, f.stat().st_size) for f in files])

    def make() -> dict[str, np.ndarray]:
        mean = load_ict_rig(ict, "generic_neutral_mesh")
        parts = load_parts(spec.file)
        points = _landmark_points(spec, where)
        head = design_head(parts, points, where)
        design = correspond_design(mean, head, dict(zip(spec.landmarks, map(tuple, points))), name=spec.name,
                                   where=where)
        logger.info("%s: corresponded with the rig (fit %.3f of its size; eyes %.2fx, nose %.2fx, mouth %.2fx)",
                    where, design.metrics.get("hausdorff_rel", float("nan")), design.metrics["scale_eye_right"],
                    design.metrics["scale_nose"], design.metrics["scale_mouth"])
        return {"vertices": design.vertices, "mean": mean.vertices}

    return npz_cached(cache / "design" / f"{key}.npz", make)["vertices"]


def _landmark_points(spec: DesignSpec, where: str) -> np.ndarray:
    """The landmarks as points (a vertex index counts in the file as :func:`load_mesh` reads it whole)."""
    from stimulus_engine.geometry.mesh_io import load_mesh

    whole = None
    out = []
    for name, p in spec.landmarks.items():
        if isinstance(p, int):
            whole = whole if whole is not None else load_mesh(spec.file)
            if not 0 <= p < len(whole.vertices):
                raise AppealInputError(f"{where}: landmarks.{name}: vertex {p} is not in the file "
                                       f"(it has {len(whole.vertices)})")
            out.append(np.asarray(whole.vertices[p], np.float64))
        else:
            out.append(np.asarray(p, np.float64))
    return np.asarray(out)


def _basis(ict: Path, more: Path, cache: Path) -> np.ndarray:
    """The ICT identity components of the face kit and ``more`` (float32, cached: 100 files to read)."""
    from stimulus_engine.characters.ict import ict_identity_basis

    files = sorted(f for d in (Path(ict), Path(more)) for f in d.glob("identity*.obj*"))
    key = sha(GRID_VERSION, "identity-basis", [(f.name, f.stat().st_size) for f in files])
    return npz_cached(cache / "design" / f"basis_{key}.npz",
                      lambda: {"basis": ict_identity_basis(ict, more).astype(np.float32)})["basis"].astype(np.float64)


def grid_characters(grid: GridFile, cache: Path, source: str) -> dict[str, Character]:
    """The grid's characters by name, each loaded once; with a ``design``, each with its own cartoon
    (:func:`~stimulus_engine.stylisation.designed_shape.own_cartoon`)."""
    chars = {c.name: load_character(c, cache, source, grid.render) for c in grid.characters}
    if grid.design is None:
        return chars
    from stimulus_engine.characters.ict import load_ict_rig
    from stimulus_engine.characters.mesh_character import front_region
    from stimulus_engine.stylisation.designed_shape import (
        model_identity,
        on_character,
        own_cartoon,
    )

    d = grid.design
    per_rig: dict[str, tuple] = {}  # characters on one ICT model share its design, mean face and components

    def model_of(ict: Path) -> tuple:
        if str(ict) not in per_rig:
            mean = load_ict_rig(ict, "generic_neutral_mesh", shapes=[])
            basis = _basis(ict, d.identity_model, cache) if d.identity > 0 else None
            per_rig[str(ict)] = (load_design(d, ict, cache, source), mean, front_region(mean), basis)
        return per_rig[str(ict)]

    out = {}
    for name, ch in chars.items():
        design, mean, region, basis = model_of(ch.spec.ict)
        if design.shape != ch.rig.vertices.shape:
            raise AppealInputError(f"{source}: design.{d.name}: character '{name}' is not in the ICT rig's topology "
                                   f"({len(ch.rig.vertices)} vertices, the design {len(design)})")
        face, reference = ch.rig.vertices, mean.vertices  # the face as the model explains it, in the mean's frame
        if basis is not None:
            face, _ = model_identity(basis, mean.vertices, ch.rig.vertices, region)
            reference = face
        cartoon = own_cartoon(ch.rig, mean.vertices, face, design, d.identity)
        cartoon = on_character(ch.rig, cartoon, reference, ch.rig.vertices, region)
        out[name] = replace(ch, cartoon=cartoon, eyes_ahead=d.eyes_ahead,
                            rig_hash=sha(ch.rig_hash, "design", d.name, d.identity, str(d.identity_model),
                                         d.eyes_ahead, np.ascontiguousarray(cartoon).tobytes()))
    return out


def shape_vertices(ch: Character, level: float) -> np.ndarray:
    """The character's neutral at shape ``level``: the morph toward its cartoon when the grid has a
    design, else the analytic operator (:func:`~stimulus_engine.stylisation.shape.stylise`)."""
    if ch.cartoon is None:
        from stimulus_engine.stylisation.shape import stylise

        return stylise(ch.rig, level)
    from stimulus_engine.stylisation.designed_shape import designed_shape

    return designed_shape(ch.rig, ch.rig.vertices, ch.cartoon, level, ch.eyes_ahead)


def drawn_rig(ch: Character, level: float, vertices: np.ndarray):
    """The rig drawn at shape ``level`` (its neutral ``vertices``): as loaded, but on a designed level
    its hair fitted again to that level's head (:func:`~stimulus_engine.parts.hair.fit_hair`).

    Hair is bound to the realistic head's skin with fixed offsets, which hold while a head changes
    a little; a design's cranium is half as large again, and the realistic fit's cards, spanning a
    larger curve, left the skin showing between them (8.6 % of Lee Perry-Smith's hair vertices
    under his cartoon's skin, measured, against 1.6 % at the realistic level)."""
    if ch.cartoon is None or ch.rig.hair is None or level == 0.0:
        return ch.rig
    from stimulus_engine.parts.hair import fit_hair

    hair = ch.rig.hair
    refit = fit_hair(ch.rig.with_vertices(vertices), ch.spec.hair_style or "short", hair.colour)
    return replace(ch.rig, hair=replace(refit, texture=hair.texture, massed=hair.massed))

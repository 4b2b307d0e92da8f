"""The images of a grid, from the grid file alone (pure: no files read, nothing computed).

:func:`plan_images` lists every rendered image in manifest order (characters, shape levels,
expressions, materials, lighting, shading; with ``pair_materials_with_shapes`` each shape level
wears only its own material), :func:`plan_photos` the photographs, and
:func:`material_sources` the distinct (albedo character, material) pairs the images wear, so
each material is prepared once.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from stimulus_engine.characters.expressions import resolve_expression
from stimulus_engine.grid.schema import GridFile, MaterialSpec, shape_label

__all__ = ["PlannedImage", "PlannedPhoto", "material_sources", "plan_images", "plan_photos"]


@dataclass(frozen=True)
class PlannedImage:
    """One rendered image of a grid: its file and the levels of every factor.

    Attributes
    ----------
    file : str
        Relative to the output folder (``images/<character>_<shape label>_<material>_<emotion>_<lighting>_<shading>.png``).
    character : str
    shape : float
        Stylisation level (0 realistic .. 1 cartoon).
    shape_label : str
        :func:`stimulus_engine.grid.schema.shape_label` of ``shape``.
    stylisation : int
        :meth:`GridFile.stylisation_index` of ``shape``.
    material : MaterialSpec
    albedo_from : str
        The character whose albedo (and maps) the material stylises.
    emotion : str
        The expression as written in the grid.
    expression : str
        Its canonical name.
    lighting, shading : str
    """

    file: str
    character: str
    shape: float
    shape_label: str
    stylisation: int
    material: MaterialSpec
    albedo_from: str
    emotion: str
    expression: str
    lighting: str
    shading: str


@dataclass(frozen=True)
class PlannedPhoto:
    """One photograph of a grid, placed as an image of the top stylisation level."""

    file: str
    character: str
    emotion: str
    expression: str
    source: Path


def plan_images(grid: GridFile) -> list[PlannedImage]:
    """Every rendered image of ``grid``, in manifest order (an animated grid's cells: each clip's
    apex; with ``animation.expression`` a recipe name, that is every cell's ``expression``)."""
    mats = grid.material_specs()
    stylisation = grid.stylisation_index()
    anim = grid.animation
    named = anim is not None and anim.expression != "cell"  # every cell animates that expression
    out = []
    for c in grid.characters:
        for pos, level in enumerate(grid.shape_levels()):
            label = shape_label(level)
            for expr in grid.expressions:
                canon = resolve_expression(anim.expression if named else expr)
                for m in [mats[pos]] if grid.pair_materials_with_shapes else mats:
                    for light in grid.lighting:
                        for shading in grid.shading:
                            out.append(PlannedImage(
                                f"images/{c.name}_{label}_{m.name}_{expr}_{light}_{shading}.png", c.name, level, label,
                                stylisation[level], m, m.from_character or c.name, expr, canon, light, shading))
    return out


def plan_photos(grid: GridFile) -> list[PlannedPhoto]:
    """Every photograph of ``grid`` (one per photographed character and expression), in manifest order."""
    return [PlannedPhoto(f"images/{p.character}_photo_{expr}.png", p.character, expr, resolve_expression(expr),
                         Path(p.files[expr]))
            for p in grid.photographs for expr in grid.expressions]


def material_sources(images: list[PlannedImage]) -> list[tuple[str, MaterialSpec]]:
    """The distinct (albedo character, material) pairs worn by ``images``, in first-use order."""
    seen: dict[tuple[str, str], tuple[str, MaterialSpec]] = {}
    for im in images:
        seen.setdefault((im.albedo_from, im.material.name), (im.albedo_from, im.material))
    return list(seen.values())

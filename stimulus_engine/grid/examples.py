"""Small grid files on the real james scan, for benchmarks, tests and trying things out.

:func:`james_grid` writes a grid file whose one character is menpo3d's textured james scan drawn
as itself on the ICT rig (the character of the shipped grids), at the realistic level with its
original material, neutral: only the lighting, shading and render settings vary.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

__all__ = ["james_grid"]


def james_grid(path: str | Path, data: str | Path, *, lighting: Sequence[str] = ("direct_hard",),
               shading: Sequence[str] = ("pbr",), shapes: Sequence[float] = (0.0,),
               materials: Sequence[str] = ("original",), render: str = "{width: 1024, height: 768}") -> Path:
    """Write the grid file to ``path`` and return it.

    Parameters
    ----------
    path : path-like
        The grid file to write.
    data : path-like
        The third-party data folder (``../shared/data``: ``meshes/ict-facekit`` and
        ``meshes/menpo3d-james``).
    lighting, shading, shapes, materials : sequences
        The grid's factors.
    render : str
        The ``render:`` mapping, in YAML flow style.
    """
    def flow(values) -> str:
        return "[" + ", ".join(str(v) for v in values) + "]"

    path = Path(path)
    path.write_text(f"""kind: grid
name: {path.stem}
characters:
  - name: james
    ict: {data}/meshes/ict-facekit
    identity: identity000
    mesh: {{file: {data}/meshes/menpo3d-james/james.obj, topology: scan, region: front}}
shapes: {flow(shapes)}
materials: {flow(materials)}
expressions: [neutral]
lighting: {flow(lighting)}
shading: {flow(shading)}
render: {render}
""")
    return path

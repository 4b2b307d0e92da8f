"""A tiny procedural-head grid file shared by the tests that render one (two shapes x neutral/happy, 96 x 72)."""

TINY_GRID = """kind: grid
name: still
characters:
  - name: a
    procedural: {seed: 3, texture_size: 128, resolution: 32}
shapes: [0.0, 1.0]
materials: [original]
expressions: [neutral, happy]
lighting: [flat]
shading: [pbr]
render: {width: 96, height: 72}
"""


def render_tiny_grid(root, name: str = "still"):
    """:data:`TINY_GRID` rendered into ``root/name`` (pyrender, one process); returns that folder."""
    from pathlib import Path

    from appeal.studyfile import load_study_file
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile

    root = Path(root)
    (root / f"{name}.yaml").write_text(TINY_GRID)
    run_grid(load_study_file(root / f"{name}.yaml", GridFile), root / name, n_jobs=1)
    return root / name

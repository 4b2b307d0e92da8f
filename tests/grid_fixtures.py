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

"""Benchmark: how far each expression moves the face at each shape level of a grid (default Exp. 2).

    python benchmarks/expression_levels.py [GRID.yaml] [--cache /tmp/exp2_cache] [--transfer METHOD]

Loads the grid, keeps one material (``original``), its first lighting and shading and no
photographs, prepares it (:func:`stimulus_engine.grid.prepare.prepare_grid`: characters,
stylised shapes, posed geometry; no rendering) into a temporary folder with a persistent
``--cache`` (the first load of a corresponded scan takes minutes, then seconds), and prints
:func:`stimulus_engine.grid.expression_measures.expression_measures` (character x expression x
measure x shape level, in face lengths), the judged measures' agreement across levels and, per
expression, the judged measure whose levels differ most from the realistic one.

``--transfer METHOD`` overrides the grid's ``expression_transfer`` (how an expression is carried
onto a stylised shape: ``aligned``, ``deformation_transfer`` or ``rbf``).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from appeal.studyfile import load_study_file  # noqa: E402
from stimulus_engine.grid.expression_measures import (  # noqa: E402
    expression_measures,
    expression_spread,
    level_agreement,
)
from stimulus_engine.grid.prepare import prepare_grid  # noqa: E402
from stimulus_engine.grid.schema import GridFile  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def with_transfer(grid: GridFile, method: str | None) -> tuple[GridFile, str]:
    """``grid`` with ``expression_transfer`` set to ``method`` (None: as the file says), and what was used."""
    if method is None:
        return grid, grid.expression_transfer
    from pydantic import TypeAdapter

    value = TypeAdapter(GridFile.model_fields["expression_transfer"].annotation).validate_python(method)
    return grid.model_copy(update={"expression_transfer": value}), value


def one_look(grid: GridFile) -> GridFile:
    """``grid`` with one material, its first lighting and shading and no photographs: the
    landmarks depend on shape and expression only."""
    return grid.model_copy(update={"materials": ["original"], "pair_materials_with_shapes": False,
                                   "lighting": grid.lighting[:1], "shading": grid.shading[:1], "photographs": []})


def grid_landmarks(grid: GridFile, cache: Path, source: str) -> pd.DataFrame:
    """The grid's long landmark table, prepared in a temporary folder with ``cache``."""
    with tempfile.TemporaryDirectory() as tmp:
        _, _, landmarks = prepare_grid(grid, Path(tmp), source=source, cache=cache)
    return landmarks


def print_tables(table: pd.DataFrame) -> None:
    """The measures (a column per shape level), the judged agreement, and the spread per expression."""
    wide = table.pivot_table(index=["character", "expression", "measure"], columns="shape", values="value",
                             sort=False)
    print("\nexpression measures (face lengths; columns: shape level)")
    print(wide.to_string(float_format=lambda v: f"{v:+.4f}"))
    agreement = level_agreement(table)
    print("\nagreement across levels (judged measures)")
    cols = ["character", "expression", "measure", "realistic", "ratio", "largest_relative_difference", "at_shape"]
    print(agreement[agreement["judged"]][cols].to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print("\nnot judged (realistic magnitude under the fraction of the expression's largest)")
    unjudged = agreement[~agreement["judged"]][cols[:4] + ["share"]]
    print(unjudged.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print("\nlargest relative difference from the realistic level, per expression")
    print(expression_spread(agreement).to_string(index=False, float_format=lambda v: f"{v:.4f}"))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("grid", nargs="?", type=Path, default=ROOT / "protocols/grids/exp2_stylisation.yaml")
    ap.add_argument("--cache", type=Path, default=Path("/tmp/exp2_cache"),
                    help="persistent input cache (characters, shapes, geometry); default /tmp/exp2_cache")
    ap.add_argument("--transfer", metavar="METHOD", default=None,
                    help="override the grid's expression_transfer (aligned, deformation_transfer, rbf)")
    ap.add_argument("--csv", type=Path, default=None, help="also write the measures table here")
    args = ap.parse_args()
    grid, used = with_transfer(one_look(load_study_file(args.grid, GridFile)), args.transfer)
    print(f"grid {grid.name}: {len(grid.characters)} characters x {len(grid.shape_levels())} shape levels x "
          f"{len(grid.expressions)} expressions; expression transfer: {used}; cache {args.cache}")
    t0 = time.perf_counter()
    landmarks = grid_landmarks(grid, args.cache, args.grid.name)
    print(f"prepared in {time.perf_counter() - t0:.1f} s")
    table = expression_measures(landmarks)
    if args.csv is not None:
        table.to_csv(args.csv, index=False)
    print_tables(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

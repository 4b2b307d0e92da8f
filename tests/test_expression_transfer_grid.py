"""The shipped Exp. 2 grid's expressions reach every stylisation level (issues 31 and 48).

Geometry only (no rendering): the grid prepared with one material, its landmarks measured
(:mod:`stimulus_engine.grid.expression_measures`). On the analytic shape operator, today's
deformation transfer let the judged measures drift 16–24 % between the realistic and the cartoon
level; the aligned transfer keeps each expression's measures within 15 % of the realistic level.
Toward the grid's design the aligned transfer moves each level at least as far as the realistic
one (a cartoon's features are smaller and its face wider: stylised shapes read as more intense,
thesis §6.5), so no judged measure fades.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest

from appeal.studyfile import load_study_file
from stimulus_engine.grid.expression_measures import expression_measures, expression_spread, level_agreement
from stimulus_engine.grid.prepare import prepare_grid
from stimulus_engine.grid.schema import GridFile

GRID = Path(__file__).resolve().parents[1] / "protocols" / "grids" / "exp2_stylisation.yaml"


@pytest.fixture(scope="module")
def exp2(shared_data, tmp_path_factory):
    grid = load_study_file(GRID, GridFile)
    return grid.model_copy(update={"materials": ["original"], "lighting": grid.lighting[:1], "photographs": []}), \
        tmp_path_factory.mktemp("exp2_cache")


def _spread(grid: GridFile, cache: Path):
    with tempfile.TemporaryDirectory() as tmp:
        _, _, landmarks = prepare_grid(grid, Path(tmp), source=GRID.name, cache=cache)
    return expression_spread(level_agreement(expression_measures(landmarks)))


@pytest.mark.timeout(1200)
def test_shipped_exp2_grid_moves_the_face_equally_at_every_level(exp2):
    grid, cache = exp2
    assert grid.expression_transfer == "aligned" and grid.design is not None
    grid = grid.model_copy(update={"design": None})  # the analytic operator, as issue 31 measured it
    aligned = _spread(grid, cache)
    today = _spread(grid.model_copy(update={"expression_transfer": "deformation_transfer"}), cache)
    print("aligned\n", aligned.to_string(), "\ndeformation transfer\n", today.to_string())
    assert len(aligned) == 8  # 2 characters x 4 expressions
    assert (aligned["largest_relative_difference"] < 0.15).all()
    assert (today["largest_relative_difference"] > 0.15).all()  # what the aligned transfer fixes


@pytest.mark.timeout(1200)
def test_shipped_exp2_expressions_do_not_fade_toward_the_design(exp2):
    grid, cache = exp2
    with tempfile.TemporaryDirectory() as tmp:
        _, _, landmarks = prepare_grid(grid, Path(tmp), source=GRID.name, cache=cache)
    table = expression_measures(landmarks)
    agreement = level_agreement(table)
    judged = agreement[agreement["judged"]].set_index(["character", "expression", "measure"])
    rows = table.set_index(["character", "expression", "measure"]).loc[judged.index]
    relative = rows["value"] / judged["realistic"].reindex(rows.index)
    print(relative.groupby(level=[0, 1]).describe().to_string())
    assert len(judged.index.unique(level="expression")) == 4 and relative.notna().all()
    assert (relative >= 0.9).all(), relative[relative < 0.9]

"""The renderer comparison sheet: one scan character, three renderers, a photograph."""

from __future__ import annotations

import pytest

from appeal.errors import AppealInputError
from appeal.studyfile import load_study_file
from stimulus_engine.grid.engine_sheet import SHEET_EXPRESSIONS, SHEET_LIGHTING, engine_grid, engine_sheet, variants_for
from stimulus_engine.grid.schema import GridFile


def _grid(shared_data, tmp_path) -> GridFile:
    from stimulus_engine.grid.examples import james_grid

    # a grid with other factors than the sheet's: the sheet replaces them
    p = james_grid(tmp_path / "g.yaml", shared_data, lighting=("flat",), shading=("phong",), shapes=(0.0, 1.0),
                   materials=("original", "flat"), render="{width: 320, height: 240}")
    return load_study_file(p, GridFile)


def test_variants_and_cut_down_grid(shared_data, tmp_path):
    assert [v[:2] for v in variants_for(["pyrender"])] == [("pyrender", "pbr"), ("pyrender", "skin")]
    assert [v[:2] for v in variants_for(["pyrender", "cycles"])][-1] == ("cycles", "pbr")
    g = engine_grid(_grid(shared_data, tmp_path), "pyrender", shading="skin")
    assert g.n_images() == len(SHEET_EXPRESSIONS) * len(SHEET_LIGHTING)
    assert g.shading == ["skin"] and g.shapes == [0.0] and g.material_specs()[0].name == "original"
    with pytest.raises(AppealInputError, match="--character: 'nobody' is not in the grid"):
        engine_grid(g, "pyrender", "nobody")


def test_sheet_of_the_pyrender_variants_beside_a_photo(shared_data, tmp_path):
    grid = _grid(shared_data, tmp_path)
    photo = shared_data / "faces2d" / "london-frl" / "neutral_front" / "001_03.jpg"
    sheet = engine_sheet(grid, tmp_path / "out", photo, engines=("pyrender",), thumb_width=160, n_jobs=1)
    assert (tmp_path / "out" / "pyrender-pbr").is_dir() and (tmp_path / "out" / "pyrender-skin").is_dir()
    rows = len(SHEET_EXPRESSIONS) * len(SHEET_LIGHTING)
    assert sheet.shape[1] >= 3 * 160 and sheet.shape[0] >= rows * 120

"""Dense continua in grid files (issue 34): ``shapes``/``materials`` ``{levels: N, spacing: even}``,
evenly spaced by value from ``from`` to ``to``, never measured; the shipped realism-continuum grid."""

from __future__ import annotations

import re
from collections import Counter

import pytest

from appeal.studyfile import StudyFileError, validate_data
from stimulus_engine.grid.continuum import needs_measuring, pins, spaced_by_value
from stimulus_engine.grid.plan import material_sources, plan_images
from stimulus_engine.grid.schema import GridFile, MaterialContinuum, ShapeContinuum

BASE = {"kind": "grid", "name": "dense", "characters": [{"name": "a", "procedural": {"seed": 1}}],
        "shapes": [0.0, 1.0], "materials": ["original"], "expressions": ["neutral"]}
EVEN41 = [round(k / 40, 4) for k in range(41)]


def _grid(**change: object) -> GridFile:
    return validate_data({**BASE, **change}, GridFile, source="g.yaml")


def test_41_even_shape_levels_are_exactly_k_over_40():
    grid = _grid(shapes={"from": 0, "to": 1, "levels": 41, "spacing": "even"})
    assert grid.shape_levels() == EVEN41
    assert grid.shape_levels()[:3] == [0.0, 0.025, 0.05] and grid.shape_levels()[-1] == 1.0
    # from / to default to 0 and 1; cartoon_first lists the same values the other way round
    assert _grid(shapes={"levels": 41, "spacing": "even"}).shape_levels() == EVEN41
    assert _grid(shapes={"levels": 41, "spacing": "even", "order": "cartoon_first"}).shape_levels() == EVEN41[::-1]
    # a part of the scale, rounded to 4 decimals; up to 101 levels
    assert _grid(shapes={"from": 0.2, "to": 0.4, "levels": 5, "spacing": "even"}).shape_levels() == \
        [0.2, 0.25, 0.3, 0.35, 0.4]
    third = _grid(shapes={"from": 0, "to": 1 / 3, "levels": 3, "spacing": "even"})
    assert third.shape_levels() == [0.0, 0.1667, 0.3333]
    assert len(set(_grid(shapes={"levels": 101, "spacing": "even"}).shape_levels())) == 101


def test_the_default_spacing_is_still_measured_and_unchanged():
    shapes = _grid(shapes={"levels": 5}).shapes
    assert isinstance(shapes, ShapeContinuum) and shapes.spacing == "measured"
    assert shapes.values() == [0.0, 0.25, 0.5, 0.75, 1.0]
    mats = _grid(materials={"levels": 4}).materials
    assert isinstance(mats, MaterialContinuum) and mats.spacing == "measured"
    assert [m.name for m in mats.specs()] == ["original", "paint1", "paint2", "paint3"]
    # the pins a run prints name no spacing or ends (a pinned grid reads as before)
    spec = _grid(shapes={"levels": 3})
    assert pins(spec, spec.model_copy(update={"shapes": [0.0, 0.31, 1.0]})) == \
        {"shapes": {"levels": 3, "measured": [0.0, 0.31, 1.0]}}


def test_even_materials_are_painted_amounts_spaced_by_value():
    specs = _grid(materials={"levels": 41, "spacing": "even"}).material_specs()
    assert [m.amount for m in specs] == EVEN41 and {m.style for m in specs} == {"painted"}
    assert [m.name for m in specs[:3]] + [specs[-1].name] == ["original", "paint1", "paint2", "paint40"]
    part = _grid(materials={"levels": 3, "spacing": "even", "from": 0.5, "order": "painted_first"}).material_specs()
    assert [(m.name, m.amount) for m in part] == [("paint2", 1.0), ("paint1", 0.75), ("paint0", 0.5)]


@pytest.mark.parametrize(("change", "line"), [
    ({"shapes": {"levels": 41}},
     "g.yaml: shapes.levels: expected at most 12 with spacing: measured, which renders every level to measure it "
     "(spacing: even allows up to 101) (got 41)"),
    ({"materials": {"levels": 13}}, "g.yaml: materials.levels: expected at most 12 with spacing: measured"),
    ({"shapes": {"levels": 102, "spacing": "even"}}, "g.yaml: shapes.levels: must be <= 101 (got 102)"),
    ({"shapes": {"levels": 1, "spacing": "even"}}, "g.yaml: shapes.levels: must be >= 2 (got 1)"),
    ({"shapes": {"levels": 5, "spacing": "even", "from": 0.6, "to": 0.4}},
     "g.yaml: shapes.to: expected a value above from, 0.6 (got 0.4)"),
    ({"shapes": {"levels": 5, "spacing": "even", "from": 0.5, "to": 0.5}},
     "g.yaml: shapes.to: expected a value above from, 0.5 (got 0.5)"),
    ({"materials": {"levels": 5, "spacing": "even", "from": 0.9, "to": 0.1}},
     "g.yaml: materials.to: expected a value above from, 0.9 (got 0.1)"),
    ({"shapes": {"levels": 5, "spacing": "even", "from": -0.1}},
     "g.yaml: shapes.from: expected a value within 0..1 (got -0.1)"),
    ({"materials": {"levels": 5, "spacing": "even", "to": 1.5}},
     "g.yaml: materials.to: expected a value within 0..1 (got 1.5)"),
    ({"shapes": {"levels": 5, "from": 0.2}}, "g.yaml: shapes.from: expected 0 with spacing: measured"),
    ({"shapes": {"levels": 3, "spacing": "even", "measured": [0.0, 0.5, 1.0]}},
     "g.yaml: shapes.measured: expected no measured levels with spacing: even"),
    ({"materials": {"levels": 3, "spacing": "even", "measured": {"a": [0.0, 0.5, 1.0]}}},
     "g.yaml: materials.measured: expected no measured levels with spacing: even"),
    ({"shapes": {"levels": 101, "spacing": "even", "from": 0.5, "to": 0.501}},
     "g.yaml: shapes.levels: expected levels that differ at 4 decimals"),
    ({"shapes": {"levels": 5, "spacing": "evenly"}}, "g.yaml: shapes.spacing: expected 'measured' or 'even'"),
])
def test_bad_continua_are_one_line_errors_naming_the_field(change, line):
    with pytest.raises(StudyFileError) as err:
        _grid(**change)
    assert str(err.value).startswith(line), str(err.value)
    assert "\n" not in str(err.value)


def test_a_dense_paired_grid_plans_one_image_per_level_with_unique_readable_files():
    grid = _grid(shapes={"levels": 41, "spacing": "even"}, materials={"levels": 41, "spacing": "even"},
                 pair_materials_with_shapes=True, expressions=["neutral", "happiness"],
                 characters=[{"name": "a", "procedural": {}}, {"name": "b", "procedural": {"seed": 2}}])
    images = plan_images(grid)
    assert len(images) == 2 * 41 * 2 == grid.n_images()
    assert len({im.file for im in images}) == len(images)
    assert {im.shape for im in images} == set(EVEN41)
    assert Counter(im.shape_label for im in images)["shape0.025"] == 4
    assert {im.shape_label for im in images if im.shape in (0.0, 1.0)} == {"realistic", "cartoon"}
    assert "images/a_shape0.025_paint1_neutral_gi_soft_pbr.png" in {im.file for im in images}
    # material k with shape k: the painted amount is the shape's value
    assert all(im.material.amount == im.shape for im in images)
    # the manifest's stylisation numbers the 41 levels from the cartoon (0) to the realistic end (40)
    assert {im.shape: im.stylisation for im in images} == {v: 40 - k for k, v in enumerate(EVEN41)}
    assert len(material_sources(images)) == 2 * 41


def test_even_spacing_is_written_out_by_value_and_never_measured(tmp_path, monkeypatch):
    """The grid workflow's measuring step (``prepare.measured_grid``, which ``run_grid`` and
    ``prepare_grid`` call first) on even continua: the levels by value, no character loaded, no
    probe rendered, nothing cached, nothing to pin."""
    from stimulus_engine.grid import continuum, prepare

    def never(*args: object, **kwargs: object) -> None:
        raise AssertionError("a spacing: even continuum was measured")

    monkeypatch.setattr(prepare, "_probe_images", never)
    monkeypatch.setattr(prepare, "_characters", never)
    monkeypatch.setattr(continuum, "_refined", never)
    spec = _grid(shapes={"levels": 41, "spacing": "even", "order": "cartoon_first"},
                 materials={"levels": 41, "spacing": "even", "order": "painted_first"}, pair_materials_with_shapes=True)
    assert not needs_measuring(spec) and needs_measuring(_grid(shapes={"levels": 3}))
    done = prepare.measured_grid(spec, tmp_path)
    assert done.shapes == EVEN41[::-1]
    assert [m.amount for m in done.materials] == EVEN41[::-1] and done.materials[0].name == "paint40"
    assert not needs_measuring(done) and not (tmp_path / ".cache").exists()
    assert plan_images(done) == plan_images(spec)  # written out, the same images
    assert pins(spec, done) == {}
    # each measuring function on its own skips an even continuum too
    assert continuum.even_shapes(spec, tmp_path, never).shapes == EVEN41[::-1]
    assert [m.amount for m in continuum.even_materials(spec, tmp_path, never).materials] == EVEN41[::-1]
    assert spaced_by_value(_grid()) == _grid()  # listed levels as they are


def test_the_shipped_realism_continuum_validates_and_plans_its_header_count(capsys):
    from appeal.assets import protocols_dir
    from appeal.studyfile import load_study_file
    from appeal_cli import main

    path = protocols_dir() / "grids" / "realism_continuum.yaml"
    assert main(["validate", str(path)]) == 0, capsys.readouterr()
    grid = load_study_file(path, GridFile)
    assert grid.shapes.spacing == "even" and grid.materials.spacing == "even" and grid.pair_materials_with_shapes
    assert grid.shape_levels() == [round(k / 20, 4) for k in range(21)]
    images = plan_images(grid)
    assert len(images) == len({im.file for im in images}) == 21 * 3 == grid.n_images()
    header = " ".join(ln for ln in path.read_text(encoding="utf-8").splitlines() if ln.startswith("#"))
    assert re.search(r"= 63 images", header)
    assert not needs_measuring(grid)


@pytest.mark.render
def test_a_tiny_even_grid_renders_its_levels_by_value_without_measuring(tmp_path):
    """``run_grid`` end to end on a small procedural head: the manifest's shapes and paired painted
    amounts are the even values, and no continuum measurement was cached."""
    import pandas as pd

    from stimulus_engine.grid import run_grid

    grid = _grid(characters=[{"name": "a", "procedural": {"seed": 1, "texture_size": 128, "resolution": 32}}],
                 shapes={"levels": 3, "spacing": "even", "from": 0.25, "to": 0.75},
                 materials={"levels": 3, "spacing": "even"}, pair_materials_with_shapes=True,
                 render={"width": 96, "height": 72})
    manifest, _ = run_grid(grid, tmp_path, n_jobs=1)
    assert manifest["status"].eq("rendered").all() and len(manifest) == 3
    assert list(manifest["shape"]) == [0.25, 0.5, 0.75]
    assert list(manifest["shape_label"]) == ["shape0.25", "shape0.5", "shape0.75"]
    assert list(manifest["material_amount"]) == [0.0, 0.5, 1.0] and list(manifest["stylisation"]) == [2, 1, 0]
    assert not (tmp_path / ".cache" / "continuum").exists()
    assert pd.read_csv(tmp_path / "manifest.csv")["file"].is_unique

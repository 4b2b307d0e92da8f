"""The grid planner (pure: a GridFile -> the images to render), paired and unpaired grids."""

from __future__ import annotations

from collections import Counter

import pytest

from appeal.studyfile import validate_data
from stimulus_engine.grid.plan import material_sources, plan_images, plan_photos
from stimulus_engine.grid.schema import GridFile

SPEC = {
    "kind": "grid",
    "name": "g",
    "characters": [{"name": "a", "procedural": {"seed": 1}}, {"name": "b", "procedural": {"seed": 2}}],
    "shapes": [0.0, 0.5, 1.0],
    "materials": ["original", "flat", {"name": "from_b", "style": "blur25", "from_character": "b"}],
    "expressions": ["neutral", "happy"],
    "lighting": ["flat", "gi_soft"],
    "shading": ["pbr", "phong"],
}


def _grid(**change: object) -> GridFile:
    return validate_data({**SPEC, **change}, GridFile, source="g.yaml")


def test_unpaired_grid_is_the_full_product_in_manifest_order():
    grid = _grid()
    images = plan_images(grid)
    assert len(images) == 2 * 3 * 3 * 2 * 2 * 2 == grid.n_images()
    assert len({im.file for im in images}) == len(images)
    first = images[0]
    assert (first.file, first.character, first.shape, first.shape_label, first.stylisation, first.material.name,
            first.albedo_from, first.emotion, first.expression, first.lighting, first.shading) == (
        "images/a_realistic_original_neutral_flat_pbr.png", "a", 0.0, "realistic", 2, "original", "a", "neutral",
        "neutral", "flat", "pbr")
    # shading varies fastest, then lighting, material, expression, shape, character
    assert [(im.lighting, im.shading) for im in images[:4]] == [("flat", "pbr"), ("flat", "phong"),
                                                                ("gi_soft", "pbr"), ("gi_soft", "phong")]
    assert [im.material.name for im in images[:12:4]] == ["original", "flat", "from_b"]
    assert images[12].emotion == "happy" and images[12].expression == "happiness"
    assert Counter(im.character for im in images) == {"a": 72, "b": 72}
    assert Counter(im.material.name for im in images) == {"original": 48, "flat": 48, "from_b": 48}
    assert {im.albedo_from for im in images if im.material.name == "from_b"} == {"b"}
    assert {(im.character, im.albedo_from) for im in images if im.material.name == "flat"} == {("a", "a"), ("b", "b")}
    assert [(src, m.name) for src, m in material_sources(images)] == [
        ("a", "original"), ("a", "flat"), ("b", "from_b"), ("b", "original"), ("b", "flat")]


def test_paired_grid_gives_each_shape_its_own_material():
    grid = _grid(pair_materials_with_shapes=True, shapes=[1.0, 0.0, 0.5])
    images = plan_images(grid)
    assert len(images) == 2 * 3 * 1 * 2 * 2 * 2 == grid.n_images()
    assert {(im.shape, im.material.name) for im in images} == {(1.0, "original"), (0.0, "flat"), (0.5, "from_b")}
    assert Counter(im.shape_label for im in images) == {"cartoon": 16, "realistic": 16, "shape0.5": 16}
    assert {im.shape: im.stylisation for im in images} == {1.0: 0, 0.5: 1, 0.0: 2}
    assert [(src, m.name) for src, m in material_sources(images)] == [
        ("a", "original"), ("a", "flat"), ("b", "from_b"), ("b", "original"), ("b", "flat")]


def test_photographs_are_planned_after_the_rendered_images(tmp_path):
    files = {e: tmp_path / f"{e}.png" for e in ("neutral", "happy")}
    for f in files.values():
        f.write_bytes(b"")
    grid = validate_data({**SPEC, "photographs": [{"character": "a", "files": {k: str(v) for k, v in files.items()}}]},
                         GridFile, source="g.yaml", base_dir=tmp_path)
    photos = plan_photos(grid)
    assert [(p.file, p.expression, p.source.name) for p in photos] == [
        ("images/a_photo_neutral.png", "neutral", "neutral.png"), ("images/a_photo_happy.png", "happiness", "happy.png")]
    assert len(plan_images(grid)) + len(photos) == grid.n_images()


def test_every_character_has_one_kind_with_a_rig_builder():
    from stimulus_engine.grid.characters import CHARACTER_KINDS, character_kind

    grid = validate_data({**SPEC, "characters": [{"name": "p", "procedural": {"seed": 1}}, {"name": "i", "ict": "k"}],
                          "materials": ["original"]},
                         GridFile, source="g.yaml", check_paths=False)
    assert [character_kind(c) for c in grid.characters] == ["procedural", "ict"]
    assert set(CHARACTER_KINDS) == {"photo", "ict", "procedural"}


#: Images per shipped grid as the thesis designs them (§6.3.1 Exp. 1a: 3 shapes x 3 materials x 5
#: expressions; §6.3.2 Exp. 1b: 3 baseline characters x 2 shadings x 3 lightings x 5 expressions;
#: §6.3.3 Exp. 1c: 3 shapes x 5 materials, neutral; §6.4 Exp. 2: 2 characters x 5 x 5 x 5 expressions;
#: §7.3 / Fig. 7.4 ERP: 2 characters x 6 stylisation levels x 3 emotions).
THESIS_IMAGES = {"exp1a_shape_material": 45, "exp1b_shading_lighting": 90, "exp1c_texture": 15,
                 "exp2_stylisation": 250, "erp_stylisation": 36}


@pytest.mark.parametrize("name", sorted(THESIS_IMAGES))
def test_shipped_grid_counts_match_the_thesis_and_their_header(name):
    import re

    from appeal.assets import protocols_dir
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid.plan import plan_images, plan_photos

    path = protocols_dir() / "grids" / f"{name}.yaml"
    grid = load_study_file(path, GridFile)
    assert len(plan_images(grid)) + len(plan_photos(grid)) == THESIS_IMAGES[name]
    header = " ".join(line for line in path.read_text(encoding="utf-8").splitlines() if line.startswith("#"))
    assert re.search(rf"= {THESIS_IMAGES[name]} images", header), f"{path.name}: the header states another count"

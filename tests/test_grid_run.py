"""Grids end to end on the procedural head: manifest, files, determinism, up-to-date skipping, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from appeal_cli import main
from appeal.errors import StudyFileError
from appeal.studyfile import load_study_file
from stimulus_engine.grid import prepare_grid, run_grid, sheet_layout
from stimulus_engine.grid.schema import GridFile

GRID = """kind: grid
name: tiny
characters:
  - name: a
    procedural: {seed: 1, texture_size: 128, resolution: 32}
  - name: b
    procedural: {seed: 2, texture_size: 128, resolution: 32}
shapes: [0.0, 1.0]
materials: [original, flat, {name: from_b, style: original, from_character: b}]
expressions: [neutral, happy]
lighting: [flat]
shading: [pbr]
render: {width: 96, height: 72}
"""


def _grid(tmp_path: Path, text: str = GRID) -> tuple[Path, GridFile]:
    p = tmp_path / "g.yaml"
    p.write_text(text)
    return p, load_study_file(p, GridFile)


def test_grid_manifest_files_and_resume(tmp_path):
    _, grid = _grid(tmp_path)
    out = tmp_path / "out"
    manifest, sheets = run_grid(grid, out, n_jobs=1)
    assert len(manifest) == 2 * 2 * 3 * 2 == grid.n_images()
    for col in ("file", "character", "shape", "stylisation", "material", "expression", "emotion", "lighting",
                "shading", "geometry_hash", "albedo_hash", "input_hash", "camera", "seconds"):
        assert col in manifest.columns
    assert set(manifest["emotion"]) == {"neutral", "happy"} and set(manifest["expression"]) == {"neutral", "happiness"}
    assert (manifest["status"] == "rendered").all()
    assert all((out / f).exists() for f in manifest["file"])
    assert [s.name for s in sheets] == ["contact_sheet.png", "contact_sheet_expressions.png", "continuum.png",
                                       "expression_measures.png"]
    on_disk = pd.read_csv(out / "manifest.csv")
    assert list(on_disk["file"]) == list(manifest["file"])
    # the material from another character differs from a's own albedo, but not from b's
    row = manifest.set_index(["character", "material"])["albedo_hash"]
    assert row[("a", "from_b")].iloc[0] != row[("a", "original")].iloc[0]
    assert row[("a", "from_b")].iloc[0] == row[("b", "original")].iloc[0]
    # a re-run skips everything; a changed input re-renders only what it affects
    again, _ = run_grid(grid, out, n_jobs=1)
    assert (again["status"] == "up to date").all()
    changed = grid.model_copy(update={"expressions": ["neutral", "sad"]})
    third, _ = run_grid(changed, out, n_jobs=1)
    assert set(third.loc[third["status"] == "rendered", "emotion"]) == {"sad"}
    assert set(third.loc[third["status"] == "up to date", "emotion"]) == {"neutral"}


def test_two_renders_of_a_grid_are_byte_identical_and_framing_is_consistent(tmp_path):
    _, grid = _grid(tmp_path)
    small = grid.model_copy(update={"characters": grid.characters[:1], "materials": ["flat"]})
    m1, _ = run_grid(small, tmp_path / "o1", n_jobs=2)
    m2, _ = run_grid(small, tmp_path / "o2", n_jobs=1)
    for f in m1["file"]:
        assert (tmp_path / "o1" / f).read_bytes() == (tmp_path / "o2" / f).read_bytes()
    # eyes at the same image row for every shape level: the camera target differs, the framing rule does not
    assert m1["camera"].nunique() == 2


def test_stylisation_index_and_paired_materials(tmp_path):
    text = GRID.replace("materials: [original, flat, {name: from_b, style: original, from_character: b}]",
                        "materials: [original, flat]\npair_materials_with_shapes: true")
    _, grid = _grid(tmp_path, text)
    manifest, sheets = run_grid(grid, tmp_path / "o", n_jobs=1)
    assert len(manifest) == 2 * 2 * 2
    # stylisation 0 = the most stylised level (shape 1.0, paired with flat), as in the thesis
    pairs = set(zip(manifest["stylisation"], manifest["shape_label"], manifest["material"]))
    assert pairs == {(1, "realistic", "original"), (0, "cartoon", "flat")}
    # the contact sheets show the 2 characters x 2 pairs the grid has: no empty (red) cells
    assert [p.name for p in sheets] == ["contact_sheet.png", "contact_sheet_expressions.png", "continuum.png",
                                       "expression_measures.png"]
    for p in sheets:
        img = np.asarray(Image.open(p).convert("RGB")).astype(int)
        red = (img[..., 0] == 200) & (img[..., 1] == 0) & (img[..., 2] == 0)
        assert red.sum() == 0, p.name


def test_sheet_layout_is_a_table_when_complete_and_a_list_otherwise():
    full = pd.DataFrame({"character": ["a", "a", "b", "b"], "shape_label": ["realistic"] * 4,
                         "material": ["flat", "original"] * 2})
    order, ncols, labels = sheet_layout(full, ["character", "shape_label"], "material")
    assert order == [0, 1, 2, 3] and ncols == 2
    assert labels == {"row_labels": ["a realistic", "b realistic"], "col_labels": ["flat", "original"]}
    # materials paired with shapes: 2 of the 4 shape x material cells exist
    paired = pd.DataFrame({"character": ["a", "a"], "shape_label": ["cartoon", "realistic"],
                           "material": ["flat", "original"]})
    order, ncols, labels = sheet_layout(paired, ["character", "shape_label"], "material")
    assert order == [0, 1] and ncols == 2
    assert labels == {"labels": ["a cartoon flat", "a realistic original"]}


def test_level_labels_mean_the_same_whatever_order_the_shapes_are_listed_in(tmp_path):
    """``s0`` used to be the first listed shape: realistic in one grid, cartoon in another."""
    _, grid = _grid(tmp_path, GRID.replace("materials: [original, flat, {name: from_b, style: original, "
                                           "from_character: b}]", "materials: [flat]"))
    up, _, _ = prepare_grid(grid.model_copy(update={"shapes": [0.0, 0.5, 1.0]}), tmp_path / "up")
    down, _, _ = prepare_grid(grid.model_copy(update={"shapes": [1.0, 0.5, 0.0]}), tmp_path / "down")
    for m in (up, down):
        table = m.drop_duplicates("shape").set_index("shape")
        assert table["stylisation"].to_dict() == {1.0: 0, 0.5: 1, 0.0: 2}
        assert table["shape_label"].to_dict() == {1.0: "cartoon", 0.5: "shape0.5", 0.0: "realistic"}
    assert sorted(up["file"]) == sorted(down["file"])
    assert any("_realistic_" in f for f in up["file"]) and not any("_s0_" in f for f in up["file"])


@pytest.mark.parametrize("change, message", [
    ("expressions: [neutral, happy]|expressions: [neutral, smug]", "unknown expression 'smug'"),
    ("materials: [original, flat, {name: from_b, style: original, from_character: b}]|materials: [gold]",
     "unknown material 'gold'"),
    ("from_character: b}|from_character: zed}", "from_character 'zed' is not a character"),
    ("shapes: [0.0, 1.0]|shapes: []", "shapes: list should have at least 1 item"),
    ("shapes: [0.0, 1.0]|shapes: [0.0, 1.5]", "stylisation levels must be within 0..1"),
    ("    procedural: {seed: 2, texture_size: 128, resolution: 32}|    ict: /nonexistent/ict",
     "characters[1].ict"),
])
def test_bad_grids_give_one_line_errors(tmp_path, change, message):
    old, new = change.split("|")
    assert old in GRID
    p = tmp_path / "bad.yaml"
    p.write_text(GRID.replace(old, new))
    with pytest.raises(StudyFileError) as exc:
        load_study_file(p, GridFile)
    assert any(message in line and str(p) in line for line in exc.value.lines), exc.value.lines


def test_missing_texture_is_reported_before_rendering(tmp_path, capsys):
    text = GRID.replace("    procedural: {seed: 1, texture_size: 128, resolution: 32}",
                        "    procedural: {seed: 1, texture_size: 128, resolution: 32}\n    texture: skin.png")
    p = tmp_path / "g.yaml"
    p.write_text(text)
    code = main(["stimuli", "grid", str(p), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2
    assert "characters[0].texture" in err and "skin.png" in err
    assert not (tmp_path / "o" / "images").exists()


def test_cli_grid_and_neoteny(tmp_path, capsys):
    p, _ = _grid(tmp_path, GRID.replace("materials: [original, flat, {name: from_b, style: original, "
                                        "from_character: b}]", "materials: [flat]"))
    out = tmp_path / "o"
    assert main(["stimuli", "grid", str(p), "--out", str(out), "--n-jobs", "1"]) == 0
    audit = pd.read_csv(out / "audit" / "audit.csv")  # the grid audits itself (appeal stimuli audit)
    assert list(audit["file"]) == list(pd.read_csv(out / "manifest.csv")["file"])
    assert audit["face_L_mean"].between(1, 99).all() and (out / "audit" / "audit.png").exists()
    # the grid's page: contact sheets and what the audit found to differ, linking its report
    page = (out / "index.html").read_text()
    assert "What differs between levels" in page and "audit/report.html" in page and "contact_sheet.png" in page
    assert (out / "audit" / "design_tests.csv").exists() and (out / "audit" / "report.html").exists()
    assert main(["stimuli", "grid", str(p), "--out", str(tmp_path / "o2"), "--n-jobs", "1", "--no-audit"]) == 0
    assert not (tmp_path / "o2" / "audit").exists() and "Not run (--no-audit)" in (tmp_path / "o2" / "index.html").read_text()
    assert main(["stimuli", "neoteny", str(out / "manifest.csv")]) == 0
    table = pd.read_csv(out / "neoteny" / "neoteny.csv")
    eye = table[(table.measure == "eye_width") & (table.expression == "neutral")].groupby("shape")["value"].mean()
    assert eye[1.0] > eye[0.0] * 1.08  # stylisation makes eyes relatively larger
    assert (out / "neoteny" / "neoteny.png").exists() and (out / "neoteny" / "neoteny.svg").exists()
    capsys.readouterr()
    assert main(["stimuli", "neoteny", str(tmp_path / "nope.csv")]) == 2
    assert "manifest not found" in capsys.readouterr().err
    assert np.isfinite(table["value"]).all()


def test_shipped_grids_and_protocols_number_stylisation_levels_the_same_way():
    """Every shipped grid: stylisation 0 is its most stylised shape level; every protocol that lists
    shape levels lists them in that order (most stylised first, the thesis's s0, s1, ...)."""
    import yaml

    from appeal.assets import protocols_dir

    grids = sorted((protocols_dir() / "grids").glob("*.yaml"))
    assert len(grids) >= 5
    for path in grids:
        grid = load_study_file(path, GridFile)
        index = grid.stylisation_index()
        levels = grid.shape_levels()
        assert [index[lv] for lv in sorted(levels, reverse=True)] == list(range(len(levels))), path.name
    for path in sorted(protocols_dir().glob("*.yaml")):
        stimuli = yaml.safe_load(path.read_text()).get("stimuli", {})
        listed = (stimuli.get("levels") or {}).get("shape")
        if listed is None:
            continue
        grid = load_study_file((path.parent / stimuli["grid"]).resolve(), GridFile)
        index = grid.stylisation_index()
        assert [index[float(lv)] for lv in listed] == sorted(index[float(lv)] for lv in listed), path.name

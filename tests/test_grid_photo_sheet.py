"""The realistic level beside a photograph: the photo framed like the rendering (eyes on its eyes)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from appeal.errors import AppealInputError
from stimulus_engine.grid.photo_sheet import photo_like_render, realism_sheet, realistic_images


def test_picks_each_characters_most_realistic_neutral_original_image():
    m = pd.DataFrame({
        "file": list("abcdefg"), "character": ["c1"] * 4 + ["c2"] * 2 + ["c1"],
        "shape": ["1.0", "0.0", "0.0", "0.0", "0.0", "0.5", "photograph"],
        "stylisation": [0, 2, 2, 2, 2, 1, 3], "expression": ["neutral", "happiness", "neutral", "neutral", "anger", "neutral",
                                                            "neutral"],
        "material_style": ["original", "original", "flat", "original", "original", "original", "photograph"]})
    best = realistic_images(m)
    assert list(best.file) == ["d", "e"]  # photographs are not rendered images; c2 has no neutral at its top level


def test_photo_is_framed_like_the_rendering(shared_data):
    """A photo moved, scaled and turned by a known similarity is brought back onto the original."""
    import cv2

    photo = np.asarray(Image.open(shared_data / "faces2d" / "london-frl" / "neutral_front" / "002_03.jpg").convert("RGB"))
    photo = cv2.resize(photo, (600, 600), interpolation=cv2.INTER_AREA)
    m = cv2.getRotationMatrix2D((300, 300), 8.0, 0.7)
    m[:, 2] += (-40, 25)
    target = cv2.warpAffine(photo, m, (640, 480), borderValue=(128, 128, 128))
    framed = photo_like_render(photo, target, (128, 128, 128))
    assert framed.shape == target.shape
    face = (slice(170, 330), slice(220, 420))  # around the eyes, nose and mouth of the target
    err = np.abs(framed[face].astype(float) - target[face].astype(float)).mean()
    assert err < 12, err  # same face, same place (dlib's points are not exact)
    assert np.abs(photo[:480, :640][face].astype(float) - target[face].astype(float)).mean() > 2 * err


def test_bad_inputs_are_one_line(tmp_path):
    with pytest.raises(AppealInputError, match="manifest not found"):
        realism_sheet(tmp_path / "manifest.csv", ["x.jpg"])
    junk = tmp_path / "junk.csv"
    junk.write_bytes(b"\xff\xfe\x00 not a table")
    with pytest.raises(AppealInputError, match="junk.csv: not a grid manifest"):
        realism_sheet(junk, ["x.jpg"])
    other = tmp_path / "other.csv"
    other.write_text("a,b\n1,2\n")
    with pytest.raises(AppealInputError, match="other.csv: file, character, .*column.s. missing"):
        realism_sheet(other, ["x.jpg"])
    grid = tmp_path / "manifest.csv"
    pd.DataFrame({"file": ["img.png"], "character": ["c"], "shape": ["0.0"], "shape_label": ["realistic"],
                  "stylisation": [0], "material": ["original"], "material_style": ["original"],
                  "expression": ["neutral"]}).to_csv(grid, index=False)
    (tmp_path / "img.png").write_bytes(b"not a png")
    with pytest.raises(AppealInputError, match="manifest.csv: file: .*img.png: not an image"):
        realism_sheet(grid, ["x.jpg"])


def test_sheet_pairs_each_character_with_a_photo(shared_data, tmp_path):
    """Two characters, one photo used for both: a 2 x 2 sheet (a real face stands in for a rendering)."""
    frl = shared_data / "faces2d" / "london-frl" / "neutral_front"
    face = Image.open(frl / "001_03.jpg").convert("RGB").resize((480, 480))
    canvas = Image.new("RGB", (640, 480), (128, 128, 128))
    canvas.paste(face, (80, 0))
    canvas.save(tmp_path / "r.png")
    pd.DataFrame({"file": ["r.png", "r.png"], "character": ["c1", "c2"], "shape": ["0.0", "0.0"],
                  "shape_label": ["realistic"] * 2, "stylisation": [1, 1], "material": ["original"] * 2,
                  "material_style": ["original"] * 2, "expression": ["neutral"] * 2}).to_csv(tmp_path / "manifest.csv",
                                                                                          index=False)
    sheet = realism_sheet(tmp_path / "manifest.csv", [frl / "002_03.jpg"], thumb_width=200)
    assert sheet.ndim == 3 and sheet.shape[0] > 2 * 150 and sheet.shape[1] > 2 * 200

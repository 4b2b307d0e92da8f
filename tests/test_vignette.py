"""The soft oval vignette of the head framing (thesis ERP study): the maths, the grid field's
defaults, and a rendered grid image."""

from __future__ import annotations

import numpy as np
import pytest

from stimulus_engine.render.vignette import face_oval, oval_vignette


def test_the_oval_keeps_the_face_and_fades_to_the_background():
    img = np.full((96, 128, 3), 200, np.uint8)
    oval = face_oval(128, 96, 0.45, 0.70)
    out = oval_vignette(img, oval, (0.0, 0.0, 1.0))
    cx, cy, rx, ry, feather = oval
    assert (out[int(cy), int(cx)] == 200).all()  # the face's middle is untouched
    assert (out[0, 0] == (0, 0, 255)).all() and (out[-1, -1] == (0, 0, 255)).all()  # corners: background
    # along a row through the centre the picture fades monotonically, from the oval's inner edge out
    row = out[int(cy), int(cx):, 0].astype(int)
    assert (np.diff(row) <= 0).all() and row[0] == 200 and row[-1] < 200
    inner = int(cx + (1 - feather) * rx) - int(cx)
    assert (row[:inner - 1] == 200).all()


def test_the_vignette_is_on_by_default_only_with_the_head_framing():
    from stimulus_engine.grid.schema import RenderSettings

    assert RenderSettings.model_validate({"framing": "head"}).vignette is True
    assert RenderSettings.model_validate({}).vignette is False
    assert RenderSettings.model_validate({"framing": "head", "vignette": False}).vignette is False
    assert RenderSettings.model_validate({"vignette": True}).vignette is True


@pytest.mark.render
def test_a_head_framed_grid_image_fades_out_at_its_edges(tmp_path):
    from PIL import Image

    from appeal.studyfile import validate_data
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile

    spec = validate_data({
        "kind": "grid", "name": "v", "characters": [{"name": "p", "procedural": {"resolution": 48}, "body": "none"}],
        "shapes": [0.0], "materials": ["original"], "expressions": ["neutral"], "lighting": ["gi_soft"],
        "shading": ["pbr"], "render": {"width": 128, "height": 96, "framing": "head", "background": [0.0, 0.0, 1.0]},
    }, GridFile, source="v.yaml")
    run_grid(spec, tmp_path, n_jobs=1, source="v.yaml")
    img = np.asarray(Image.open(next((tmp_path / "images").glob("*.png"))).convert("RGB")).astype(int)
    fg = np.abs(img - (0, 0, 255)).sum(axis=2) > 40
    oval = face_oval(128, 96, 0.45, 0.70)
    y, x = np.mgrid[0:96, 0:128]
    outside = np.hypot((x + 0.5 - oval[0]) / oval[2], (y + 0.5 - oval[1]) / oval[3]) > 1.0
    assert not fg[outside].any()  # nothing of the head outside the oval ...
    assert fg[~outside].mean() > 0.5  # ... which the head fills

"""Stylised eyes: a larger, painted iris and a plain white along the stylisation scale."""

from __future__ import annotations

import numpy as np
import pytest

from stimulus_engine.parts.eyes import eyeball_asset, photographic_eye_texture, tint_iris
from stimulus_engine.stylisation.eyes import PAINTED_WHITE, iris_circles, stylised_eye_texture


def _textures() -> dict[str, np.ndarray]:
    """Both layouts: a scan's two-eyed asset (its iris tinted a dark, nearly grey brown, as
    james's painted iris is) and a rig's equal-area eyeball (blue)."""
    _, asset = eyeball_asset()
    return {"scan": tint_iris(asset, np.array([62.0, 52.0, 44.0])),
            "rig": tint_iris(photographic_eye_texture(512), np.array([64.0, 82.0, 107.0]))}


@pytest.mark.parametrize("layout", ["scan", "rig"])
def test_the_iris_grows_by_the_scale_and_paints_flat(layout):
    tex = _textures()[layout]
    found = iris_circles(tex)
    assert len(found) == (2 if layout == "scan" else 1)
    assert stylised_eye_texture(tex, 1.0, 0.0) is tex  # nothing asked: the texture itself
    bigger = iris_circles(stylised_eye_texture(tex, 1.3, 0.0))
    for (x, y, r, p), (x2, y2, r2, p2) in zip(found, bigger):
        assert abs(x2 - x) < 1.5 and abs(y2 - y) < 1.5
        assert abs(r2 - 1.3 * r) <= 3 and abs(p2 - 1.3 * p) <= 2, (r, r2, p, p2)
    painted = stylised_eye_texture(tex, 1.3, 1.0).astype(float)
    h, w = tex.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w]
    for x, y, r, p in [(x, y, 1.3 * r, 1.3 * p) for x, y, r, p in found]:
        d = np.hypot(xx - x, yy - y)
        iris = (d > p + 2) & (d < 0.8 * r)
        before = stylised_eye_texture(tex, 1.3, 0.0).astype(float)
        assert painted[iris].std(axis=0).max() < 0.3 * before[iris].std(axis=0).max()  # fibres gone: flat paint
        assert painted[iris].mean() > 75  # a dark iris (the scan's, tinted near-grey brown) lifted: its colour shows
        white = (d > 1.1 * r) & (d < 1.5 * r)
        assert np.abs(painted[white].mean(axis=0) - PAINTED_WHITE).max() < 8  # a plain white
        rim = (d > 0.9 * r) & (d < r)
        assert painted[rim].mean() < painted[iris].mean()  # a dark rim
    with pytest.raises(ValueError, match="iris_scale"):
        stylised_eye_texture(tex, 0.9, 0.0)


def test_a_grid_stylises_the_eyes_with_its_shape_and_painted_material(tmp_path):
    """The iris scale follows the shape level, the paint a painted material's amount; the
    realistic original image keeps the modelled eyes (and its input hash); stylised_eyes: false
    keeps every level's."""
    from appeal.studyfile import validate_data
    from stimulus_engine.grid.prepare import prepare_grid
    from stimulus_engine.grid.schema import GridFile

    spec = {"kind": "grid", "name": "eyes", "characters": [{"name": "a", "procedural": {"seed": 2, "texture_size": 128,
                                                                                        "resolution": 32}}],
            "shapes": [0.0, 0.5, 1.0], "materials": [{"name": "original", "style": "original"},
                                                     {"name": "paint", "style": "painted", "amount": 0.6}],
            "expressions": ["neutral"], "render": {"width": 64, "height": 48}}
    manifest, items, _ = prepare_grid(validate_data(spec, GridFile, source="eyes.yaml"), tmp_path / "a")
    style = {(m.shape, m.material): it.eye_style for m, it in zip(manifest.itertuples(), items)}
    assert style[0.0, "original"] == () and style[0.0, "paint"] == (1.0, 0.6)
    assert style[0.5, "original"] == (1.15, 0.0) and style[1.0, "paint"] == (1.3, 0.6)
    # the worker draws the cartoon's eyes with the stylised texture: a larger, flat iris
    from stimulus_engine.grid.worker import item_scene

    def eye_texture(k: int) -> np.ndarray:
        parts, _ = item_scene(items[k])
        return np.asarray(next(p for p in parts if p.name == "eye").material.baseColorTexture.source)

    index = {key: k for k, key in enumerate(style)}
    (_, _, r0, _), = iris_circles(eye_texture(index[0.0, "original"]))
    (_, _, r1, _), = iris_circles(eye_texture(index[1.0, "paint"]))
    assert 1.2 < r1 / r0 < 1.4, (r0, r1)
    off = {**spec, "render": {**spec["render"], "stylised_eyes": False}}
    manifest2, items2, _ = prepare_grid(validate_data(off, GridFile, source="eyes.yaml"), tmp_path / "b")
    assert all(it.eye_style == () for it in items2)
    same = manifest2["input_hash"] == manifest["input_hash"]
    assert list(same) == [s == () for s in style.values()]  # only the stylised images changed inputs


def test_painted_lashes_get_a_bold_lid_line_along_their_roots():
    from stimulus_engine.parts.eyelashes import lash_texture
    from stimulus_engine.stylisation.eyes import LID_LINE, bold_lash_texture

    lashes = lash_texture(128)
    assert bold_lash_texture(lashes, 0.0) is lashes
    bold = bold_lash_texture(lashes, 1.0)
    root = bold[-int(0.5 * LID_LINE * 128):]  # the bottom rows: the roots
    assert (root[..., 3] == 255).all() and root[..., :3].max() < 40  # a solid dark line
    assert np.array_equal(bold[: int((1 - LID_LINE) * 128) - 1], lashes[: int((1 - LID_LINE) * 128) - 1])  # tips as they were
    half = bold_lash_texture(lashes, 0.5)
    assert 120 <= int(half[-1, :, 3].min()) <= 135  # half a line: half opaque where no lash was
    with pytest.raises(ValueError, match="paint"):
        bold_lash_texture(lashes, 1.5)


def test_painted_hair_is_drawn_as_masses_and_cycles_draws_its_cards(tmp_path):
    """A painted level's hair texture merges its strands into solid locks with flat grey; a
    rig stored before ``massed`` existed still loads; the scene export grows strand curves for
    strand hair only, the massed hair's cards are what the path tracer draws."""
    import dataclasses

    from stimulus_engine.characters.render_parts import hair_render_part
    from stimulus_engine.parts.hair import hair_arrays, hair_asset, hair_from_arrays
    from stimulus_engine.render import CameraSpec
    from stimulus_engine.render.scene_export import export_scene
    from stimulus_engine.stylisation.hair import hair_mass_texture

    tex = hair_asset("short02").texture
    assert hair_mass_texture(tex, 0.0) is tex
    mass = hair_mass_texture(tex, 1.0)
    inside = tex[..., 3] > 0
    assert (mass[..., 3] >= tex[..., 3]).mean() > 0.99  # the gaps between strands fill in
    assert np.abs(np.diff(mass[..., 0].astype(int), axis=1))[inside[:, 1:]].mean() < \
        0.5 * np.abs(np.diff(tex[..., 0].astype(int), axis=1))[inside[:, 1:]].mean()  # no fibres

    # a hair style's mesh as it is (bound to one rig point at the origin)
    import json

    from stimulus_engine.parts.hair import Hair

    asset = hair_asset("short02")
    m = len(asset.uv)
    hair = Hair(np.zeros((m, 3), int), np.full((m, 3), 1 / 3), asset.anchors + asset.offset, asset.faces, asset.uv,
                asset.texture)
    stored = hair_arrays(hair)
    stored.pop("hair_massed")  # a rig stored before the field was added
    assert hair_from_arrays(stored).massed is False
    cam = CameraSpec((0.0, 0.0, 40.0), (0.0, 0.0, 0.0), 20.0)
    for massed in (False, True):
        h = dataclasses.replace(hair, texture=hair_mass_texture(hair.texture, 1.0) if massed else hair.texture,
                                massed=massed)
        spec = export_scene([hair_render_part(h, np.zeros((1, 3)))], [], 0.3, cam, tmp_path / str(massed),
                            width=32, height=32, background=(0.5, 0.5, 0.5))
        assert json.loads(spec.read_text())["parts"][0].get("strands", False) is (not massed)

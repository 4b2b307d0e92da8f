"""Normal and specular maps, and the Phong (specular-glossiness) shader pyrender 0.1.45 lacks:
tangent-frame convention, specular response, map checks, stylisation, procedural maps, grid
plumbing (one-line errors before rendering, byte-identical re-runs)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from PIL import Image

from appeal_cli import main
from appeal.errors import AppealInputError, StudyFileError
from appeal.studyfile import load_study_file
from stimulus_engine.grid import run_grid
from stimulus_engine.grid.schema import GridFile
from stimulus_engine.characters.skin_maps import FLAT_NORMAL, check_map, rig_detail_maps
from stimulus_engine.stylisation.materials import stylise_albedo, stylise_map
from stimulus_engine.characters.procedural_head import procedural_head
from stimulus_engine.render import LightSpec, RenderPart, render_mesh
from stimulus_engine.render._pyrender import phong_fragment_shader, pyrender
from stimulus_engine.characters.render_parts import _new_material


def _plane() -> trimesh.Trimesh:
    """A unit square in the xy plane facing +z (the camera), UV u = x, v = y."""
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    m = trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)
    m.visual = trimesh.visual.TextureVisuals(uv=(v[:, :2] + 1) / 2)
    return m


def _lit(material: object, direction: tuple[float, float, float], intensity: float = 3.0) -> float:
    """Mean grey level of the plane's centre lit by one directional light (camera frame)."""
    img = render_mesh([RenderPart(_plane(), material=material)], width=64, height=48,
                      lighting=([LightSpec("directional", direction, intensity)], 0.0), shadows=False)
    return float(img[18:30, 26:38].mean())


def _normal_map(nx: float, ny: float) -> np.ndarray:
    n = np.array([nx, ny, 1.0]) / np.linalg.norm([nx, ny, 1.0])
    return np.tile(np.rint((n + 1) / 2 * 255).astype(np.uint8), (16, 16, 1))


def test_phong_shader_patch_fills_the_glossy_branch():
    import os

    with open(os.path.join(os.path.dirname(pyrender.__file__), "shaders", "mesh.frag")) as f:
        original = f.read()
    patched = phong_fragment_shader(original)
    assert "TODO GLOSSY MATERIAL BRDF" in original and "TODO GLOSSY MATERIAL BRDF" not in patched
    assert patched.count("compute_phong(") == 4  # the function + directional, point, spot loops
    assert "sampler2D specular_glossiness_texture;" in patched  # the name pyrender binds
    with pytest.raises(RuntimeError, match="0.1.45"):
        phong_fragment_shader(original.replace("// TODO GLOSSY MATERIAL BRDF", ""))


@pytest.mark.parametrize("shading", ["pbr", "phong"])
def test_normal_map_tangent_frame_is_opengl_convention(shading):
    grey = np.full((16, 16, 3), 180, np.uint8)
    flat = _normal_map(0, 0)
    assert tuple(flat[0, 0]) == FLAT_NORMAL
    from_right, from_top = (-0.6, 0.0, -0.8), (0.0, -0.6, -0.8)  # light travelling from +x / +y
    plain = _new_material(shading, (1, 1, 1, 1), grey, 0.6)
    base = _lit(plain, from_right)
    assert base > 0
    assert abs(_lit(_new_material(shading, (1, 1, 1, 1), grey, 0.6, flat), from_right) - base) < 1.5
    # R > 128 tilts the normal towards +u (= +x here): brighter when lit from +x, darker from -x
    tilt_u = _new_material(shading, (1, 1, 1, 1), grey, 0.6, _normal_map(0.5, 0))
    assert _lit(tilt_u, from_right) > base + 5
    assert _lit(tilt_u, (0.6, 0.0, -0.8)) < base - 5
    # G > 128 tilts it towards +v (= +y): brighter when lit from above
    tilt_v = _new_material(shading, (1, 1, 1, 1), grey, 0.6, _normal_map(0, 0.5))
    assert _lit(tilt_v, from_top) > _lit(plain, from_top) + 5


@pytest.mark.parametrize("shading", ["pbr", "phong"])
def test_specular_map_white_is_shinier_than_black(shading):
    grey = np.full((16, 16, 3), 120, np.uint8)
    head_on = (0.0, 0.0, -1.0)  # mirror direction towards the camera: the highlight is at the centre

    def lit(spec: np.ndarray | None) -> float:
        return _lit(_new_material(shading, (1, 1, 1, 1), grey, 0.6, None, spec), head_on, 0.8)

    lo, mid, hi = (lit(np.full((16, 16), v, np.uint8)) for v in (0, 128, 255))
    none = lit(None)
    assert lo < mid < hi and hi > lo + 10
    assert abs(mid - none) < 4  # mid-grey = the look without a map


def test_phong_and_pbr_differ_and_phong_is_deterministic():
    s = trimesh.creation.icosphere(subdivisions=3)
    imgs = [render_mesh([RenderPart(s, material=_new_material(sh, (0.8, 0.6, 0.5, 1.0), None, 0.62))],
                        width=64, height=48, lighting="direct_hard") for sh in ("pbr", "phong", "phong")]
    assert np.array_equal(imgs[1], imgs[2])
    assert (imgs[1] != 128).any() and np.abs(imgs[0].astype(int) - imgs[1]).max() > 10


def test_check_map_messages():
    with pytest.raises(ValueError, match="expected an RGB tangent-space normal map \\(got a greyscale image\\)"):
        check_map(np.full((8, 8), 200, np.uint8), "normal")
    with pytest.raises(ValueError, match="mostly blue"):
        check_map(np.full((8, 8, 3), 100, np.uint8), "normal")
    with pytest.raises(ValueError, match="greyscale specular map"):
        check_map(np.dstack([np.zeros((8, 8)), np.ones((8, 8)), np.ones((8, 8))]).astype(np.uint8), "specular")
    with pytest.raises(ValueError, match="expected 16 x 16 pixels like the albedo it belongs to \\(got 8 x 8\\)"):
        check_map(np.full((8, 8), 9, np.uint8), "specular", (16, 16))
    with pytest.raises(ValueError, match="8-bit"):
        check_map(np.full((8, 8), 4000, np.uint16), "specular")
    assert check_map(np.full((8, 8, 3), 77, np.uint8), "specular").shape == (8, 8)
    assert check_map(np.dstack([_normal_map(0.1, 0)[:8, :8], np.full((8, 8), 255, np.uint8)]), "normal").shape == (8, 8, 3)


def test_stylise_map_follows_the_albedo_operator():
    rng = np.random.default_rng(0)
    n = rng.normal(0, 0.3, (32, 32, 3))
    n[..., 2] = 1
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    nm = np.rint((n + 1) / 2 * 255).astype(np.uint8)
    assert np.array_equal(stylise_map(nm, "normal", "original"), nm)
    blurred = stylise_map(nm, "normal", "blur50").astype(float) / 255 * 2 - 1
    assert np.allclose(np.linalg.norm(blurred, axis=-1), 1, atol=0.02)  # still unit vectors
    assert blurred[..., 2].mean() > n[..., 2].mean()  # pores softened: closer to flat
    flat = stylise_map(nm, "normal", "flat").astype(int)
    assert np.abs(flat - flat[0, 0]).max() == 0 and flat[0, 0, 2] > 250
    spec = rng.integers(0, 256, (32, 32), dtype=np.uint8)
    assert np.array_equal(stylise_map(spec, "specular", "blur25"),
                          stylise_albedo(np.dstack([spec] * 3), "blur25")[..., 0])


@pytest.mark.parametrize("style", ["original", "blur25", "bilateral", "flat", "painted"])
def test_stylise_material_filters_albedo_and_maps_together_as_each_alone(style):
    """One stack of the albedo's and the maps' channels gives what each texture stylised on its
    own gives, byte for byte (regions, an unused part, a partial amount)."""
    from stimulus_engine.stylisation.materials import paint_masks, stylise_material

    rng = np.random.default_rng(3)
    albedo = rng.integers(0, 256, (60, 90, 3), dtype=np.uint8)
    normal = rng.integers(0, 256, (60, 90, 3), dtype=np.uint8)
    normal[..., 2] = 220
    spec = rng.integers(0, 256, (60, 90), dtype=np.uint8)
    masks = {"lips": (rng.random((60, 90)) > 0.8).astype(np.float32), "unused": np.zeros((60, 90), np.float32)}
    masks["unused"][:9] = 1.0
    masks["lips"][:9] = 0.0  # disjoint, as a scan's regions are
    a, maps = stylise_material(albedo, style, masks, {"normal": normal, "specular": spec}, 0.7)
    assert np.array_equal(a, stylise_albedo(albedo, style, masks, 0.7))
    masks = paint_masks(albedo, masks, style, 0.7)  # the albedo's dark features, the maps' regions too
    assert np.array_equal(maps["normal"], stylise_map(normal, "normal", style, masks, 0.7))
    assert np.array_equal(maps["specular"], stylise_map(spec, "specular", style, masks, 0.7))
    if style not in ("original", "bilateral"):  # the region filters
        assert np.array_equal(a[:9], albedo[:9])  # unused texels stay as they are


def test_procedural_detail_maps():
    rig = procedural_head(seed=3, texture_size=256, resolution=48)
    normal, spec = rig_detail_maps(rig, seed=3)
    assert normal.shape == (256, 256, 3) and spec.shape == (256, 256) and normal.dtype == np.uint8
    again = rig_detail_maps(procedural_head(seed=3, texture_size=256, resolution=48), seed=3)
    assert np.array_equal(again[0], normal) and np.array_equal(again[1], spec)
    n = normal.astype(float) / 255 * 2 - 1
    tilt = np.arccos(np.clip(n[..., 2] / np.linalg.norm(n, axis=-1), -1, 1))
    assert 0.02 < np.sqrt(np.mean(tilt**2)) < 0.12 and tilt.max() < 0.6  # mild pores
    hair = rig.texture_masks["hair"] > 0.99
    dev = np.abs(normal.astype(int) - FLAT_NORMAL).max(axis=-1)
    assert np.percentile(dev[hair], 99) <= 2 < np.percentile(dev[~hair], 50)  # no pores under hair
    from stimulus_engine.characters.skin_maps import bake_surface_points

    pts, valid = bake_surface_points(rig, 256)
    lm = rig.landmark_points()

    def at(p: np.ndarray) -> float:
        d = np.where(valid, np.linalg.norm(pts - p, axis=-1), np.inf)
        return float(spec.flat[np.argmin(d)])

    cheek = (lm["face_left"] + lm["nose_tip"]) / 2
    assert at(lm["nose_tip"]) > at(cheek) + 40  # T-zone shine
    assert spec[rig.texture_masks["lips"] > 0.9].mean() > 180 and spec[hair].mean() < 60


def _grid(tmp_path, materials: str, shading: str = "[pbr]") -> str:
    return f"""kind: grid
name: mapgrid
characters:
  - name: a
    procedural: {{seed: 1, texture_size: 128, resolution: 32}}
  - name: b
    procedural: {{seed: 2, texture_size: 128, resolution: 32}}
shapes: [0.0]
materials: {materials}
expressions: [neutral]
lighting: [direct_hard]
shading: {shading}
render: {{width: 96, height: 72, framing: head}}
"""


def test_grid_with_maps_is_byte_identical_and_carries_maps_across_characters(tmp_path):
    nm = tmp_path / "n.png"
    Image.fromarray(_normal_map(0.3, 0.1)[:1].repeat(128, 0)[:, :1].repeat(128, 1)).save(nm)
    p = tmp_path / "g.yaml"
    p.write_text(_grid(tmp_path, f"[original, {{name: pores, procedural_maps: true}}, "
                                 f"{{name: b_pores, from_character: b, procedural_maps: true}}, "
                                 f"{{name: tilted, normal_map: {nm}}}]", "[pbr, phong]"))
    grid = load_study_file(p, GridFile)
    m1, _ = run_grid(grid, tmp_path / "o1", n_jobs=1, source=str(p))
    m2, _ = run_grid(grid, tmp_path / "o2", n_jobs=1, source=str(p))
    assert (m1["status"] == "rendered").all() and len(m1) == 16
    for f in m1["file"]:
        assert (tmp_path / "o1" / f).read_bytes() == (tmp_path / "o2" / f).read_bytes(), f
    h = m1.drop_duplicates(["character", "material"]).set_index(["character", "material"])["maps_hash"]
    assert h[("a", "original")] == "none" and h[("a", "pores")] != "none"
    assert h[("a", "b_pores")] == h[("b", "pores")] == h[("b", "b_pores")] != h[("a", "pores")]
    img = {(r.material, r.shading): np.asarray(Image.open(tmp_path / "o1" / r.file)).astype(int)
           for r in m1[m1.character == "a"].itertuples()}
    assert np.abs(img[("pores", "pbr")] - img[("original", "pbr")]).max() > 10
    assert np.abs(img[("tilted", "pbr")] - img[("original", "pbr")]).mean() > 1
    assert np.abs(img[("original", "phong")] - img[("original", "pbr")]).max() > 10


def test_grid_map_errors_are_one_line_and_before_rendering(tmp_path, capsys):
    small = tmp_path / "small.png"
    Image.fromarray(np.full((64, 64), 128, np.uint8)).save(small)
    p = tmp_path / "g.yaml"
    p.write_text(_grid(tmp_path, f"[{{name: m, specular_map: {small}}}]"))
    code = main(["stimuli", "grid", str(p), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2
    assert "materials.m.specular_map: small.png: expected 128 x 128 pixels like the albedo" in err
    assert not (tmp_path / "o" / "images").exists()
    p.write_text(_grid(tmp_path, f"[{{name: m, normal_map: {small}}}]"))
    with pytest.raises(AppealInputError, match="normal_map: small.png: expected an RGB tangent-space normal map"):
        run_grid(load_study_file(p, GridFile), tmp_path / "o2", n_jobs=1, source=str(p))
    p.write_text(_grid(tmp_path, "[{name: m, normal_map: missing.png}]"))
    with pytest.raises(StudyFileError) as exc:
        load_study_file(p, GridFile)
    assert any("normal_map" in line and "file not found" in line for line in exc.value.lines), exc.value.lines


def test_region_blur_equals_scipy_normalised_convolution_with_periodic_borders():
    """Each region's blur over its own window (wrapping around the texture's borders) is the
    whole-image normalised convolution of scipy's ``gaussian_filter(mode="wrap")``; texels of
    the ``unused`` mask stay as they are."""
    from scipy.ndimage import gaussian_filter

    from stimulus_engine.stylisation.materials import _region_blur, _regions

    rng = np.random.default_rng(1)
    for h, w in [(40, 56), (33, 33)]:
        f = rng.random((h, w, 3)) * 255
        lips = np.zeros((h, w))
        lips[-6:, :5] = 1.0  # a region across the corner: its window wraps around both borders
        lips[:3, -4:] = 0.5
        unused = np.zeros((h, w))
        unused[10:14, 20:30] = 1.0
        regions = _regions({"lips": lips, "unused": unused}, (h, w))
        for sigma in (0.3, 1.29, 2.225, 6.0):  # incl. the blur25/blur50 sigmas at 1024 px
            ref = f * unused[..., None]
            for wt in regions:
                num = gaussian_filter(f * wt[..., None], sigma=(sigma, sigma, 0), mode="wrap")
                den = gaussian_filter(wt, sigma=sigma, mode="wrap")[..., None]
                ref += wt[..., None] * num / np.maximum(den, 1e-6)
            assert np.abs(_region_blur(f, regions, sigma) - ref).max() < 1e-3

"""The path-traced tier: one scene description, two engines (pyrender and Blender's Cycles).

Tests that render with Cycles need its Python (``make cycles``: ``.venv-cycles`` with the bpy
wheel, which pins numpy < 2); ``make test`` installs it, elsewhere they are skipped with that
reason. Exporting scenes and checking settings needs no Blender.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from appeal_cli import main
from appeal.studyfile import load_study_file
from stimulus_engine.grid import run_grid
from stimulus_engine.grid.schema import GridFile
from stimulus_engine.render import CameraSpec, lighting_preset
from stimulus_engine.render.cycles import cycles_python
from stimulus_engine.render.scene_export import export_scene, world_lights

needs_cycles = pytest.mark.skipif(cycles_python() is None,
                                  reason="Cycles not installed: run 'make cycles' (or set APPEAL_CYCLES_PYTHON)")

GRID = """kind: grid
name: two_engines
characters:
  - name: a
    procedural: {seed: 3, texture_size: 128, resolution: 40}
shapes: [0.0]
materials: [original]
expressions: [neutral]
lighting: [direct_hard]
shading: [pbr]
render: {width: 160, height: 120, engine: ENGINE, samples: 8}
"""


def _grid(tmp_path: Path, engine: str, extra: str = "") -> tuple[Path, GridFile]:
    p = tmp_path / f"{engine}.yaml"
    p.write_text(GRID.replace("ENGINE", engine) + extra)
    return p, load_study_file(p, GridFile)


def test_disc_of_spot_samples_becomes_one_soft_light():
    cam = CameraSpec((0.0, 0.0, 10.0), (0.0, 0.0, 0.0))
    lights, _ = lighting_preset("direct_soft")
    out = world_lights(lights, cam)
    discs = [w for w in out if w["kind"] == "disc"]
    assert len(discs) == 1
    spots = [s for s in lights if s.kind == "spot"]
    assert discs[0]["intensity"] == pytest.approx(sum(s.intensity for s in spots))
    assert 0.1 < discs[0]["radius"] < 0.2 and discs[0]["shadow"]
    assert len(out) == len(lights) - len(spots) + 1


def test_scene_export_writes_parts_materials_and_camera(tmp_path):
    from stimulus_engine.grid.prepare import prepare_grid
    from stimulus_engine.grid.worker import item_scene

    _, grid = _grid(tmp_path, "pyrender")
    _, items, _ = prepare_grid(grid, tmp_path / "out")
    parts, cam = item_scene(items[0])
    lights, ambient = lighting_preset("gi_soft")
    path = export_scene(parts, lights, ambient, cam, tmp_path / "scene", width=160, height=120,
                        background=(0.5, 0.5, 0.5))
    spec = json.loads(path.read_text())
    assert spec["format"] == "appeal-scene/1" and spec["ambient"] == ambient
    assert [p["name"] for p in spec["parts"]] == [p.name for p in parts]
    skin = next(p for p in spec["parts"] if p["name"] == "skin")
    assert (path.parent / skin["texture"]).is_file()
    arrays = np.load(path.parent / "parts.npz")
    k = [p.name for p in parts].index("skin")
    assert arrays[f"v{k}"].shape == parts[k].mesh.vertices.shape and f"uv{k}" in arrays.files
    assert 100 < spec["mm_per_unit"] * np.ptp(arrays[f"v{k}"][:, 0]) < 200  # a head ~150 mm wide
    assert spec["camera"]["yfov_deg"] == cam.yfov_deg


def test_alpha_tested_and_blended_cards_are_cut_out_in_cycles(tmp_path):
    """Hair (alpha-tested, MASK) and lashes (BLEND) take their texture's alpha into the path
    tracer; opaque parts do not (the hair had rendered as a solid dark cap)."""
    from stimulus_engine.render._pyrender import pyrender
    from stimulus_engine.render.scene_export import _material_record

    rgba = np.zeros((4, 4, 4), np.uint8)
    for mode, cut in (("MASK", True), ("BLEND", True), ("OPAQUE", False)):
        mat = pyrender.MetallicRoughnessMaterial(baseColorTexture=pyrender.Texture(source=rgba, source_channels="RGBA"),
                                                 alphaMode=mode, doubleSided=True)
        assert _material_record("hair", mat, tmp_path, 0)["alpha_blend"] is cut, mode
    phong = pyrender.material.SpecularGlossinessMaterial(diffuseTexture=pyrender.Texture(source=rgba, source_channels="RGBA"),
                                                alphaMode="MASK")
    assert _material_record("hair", phong, tmp_path, 1)["alpha_blend"] is True


@pytest.mark.parametrize("field, value, expected", [
    ("engine", "mitsuba", "render.engine"),
    ("samples", 0, "render.samples"),
    ("samples", -5, "render.samples"),
    ("supersample", 5, "render.supersample"),
    ("supersample", 0.5, "render.supersample"),
])
def test_bad_engine_settings_are_one_line_errors_before_rendering(tmp_path, capsys, field, value, expected):
    p = tmp_path / "g.yaml"
    text = GRID.replace("ENGINE", "pyrender").replace("samples: 8", f"samples: {value}" if field == "samples" else "samples: 8")
    if field == "engine":
        text = text.replace("engine: pyrender", f"engine: {value}")
    if field == "supersample":
        text = text.replace("samples: 8", f"samples: 8, supersample: {value}")
    p.write_text(text)
    rc = main(["stimuli", "grid", str(p), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert rc != 0 and len(err.splitlines()) == 1 and expected in err and str(p) in err, err
    assert not (tmp_path / "out").exists()


def test_cycles_not_installed_is_a_one_line_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("APPEAL_CYCLES_PYTHON", str(tmp_path / "no-such-python"))
    p = tmp_path / "g.yaml"
    p.write_text(GRID.replace("ENGINE", "cycles"))
    rc = main(["stimuli", "grid", str(p), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert rc != 0 and len(err.splitlines()) == 1 and "'cycles' is not installed" in err and "make cycles" in err, err
    assert not (tmp_path / "out").exists()


@needs_cycles
def test_both_engines_frame_the_face_identically(tmp_path):
    """Same scene, same camera: the silhouettes (and so the eyes) land on the same pixels."""
    from stimulus_engine.grid.prepare import prepare_grid
    from stimulus_engine.grid.worker import item_scene
    from stimulus_engine.render import render_mesh
    from stimulus_engine.render.cycles import render_cycles

    _, grid = _grid(tmp_path, "pyrender")
    _, items, _ = prepare_grid(grid, tmp_path / "out")
    parts, cam = item_scene(items[0])
    _, depth = render_mesh(parts, width=160, height=120, lighting="direct_hard", camera=cam, return_depth=True)
    red = (1.0, 0.0, 0.0)  # a background no face pixel has: the Cycles silhouette is what differs from it
    img = render_cycles(parts, width=160, height=120, lighting="direct_hard", camera=cam, background=red, samples=4)
    mask_py = depth > 0
    mask_cy = ~np.all(img == np.array([255, 0, 0], np.uint8), axis=-1)
    iou = (mask_py & mask_cy).sum() / (mask_py | mask_cy).sum()
    assert iou > 0.97, iou
    c_py = np.argwhere(mask_py).mean(axis=0)
    c_cy = np.argwhere(mask_cy).mean(axis=0)
    assert np.abs(c_py - c_cy).max() < 0.5, (c_py, c_cy)
    for axis in (0, 1):
        span_py = np.flatnonzero(mask_py.any(axis=1 - axis))
        span_cy = np.flatnonzero(mask_cy.any(axis=1 - axis))
        assert abs(span_py[0] - span_cy[0]) <= 2 and abs(span_py[-1] - span_cy[-1]) <= 2


@needs_cycles
def test_cycles_grid_renders_and_rerenders_identically(tmp_path):
    _, grid = _grid(tmp_path, "cycles")
    m1, _ = run_grid(grid, tmp_path / "one", n_jobs=1)
    m2, _ = run_grid(grid, tmp_path / "two", n_jobs=1)
    assert (m1["status"] == "rendered").all()
    f = m1["file"].iloc[0]
    a = np.asarray(Image.open(tmp_path / "one" / f)).astype(int)
    b = np.asarray(Image.open(tmp_path / "two" / f)).astype(int)
    # fixed seed, fixed sample count, CPU denoiser: the same pixels
    assert np.abs(a - b).max() == 0
    # a face on the 50 % grey background, not an empty frame
    assert (np.abs(a - 128).sum(-1) > 30).mean() > 0.1
    # a different seed gives different noise before denoising: not the same image
    other = grid.model_copy(update={"render": grid.render.model_copy(update={"seed": 7})})
    m3, _ = run_grid(other, tmp_path / "three", n_jobs=1)
    c = np.asarray(Image.open(tmp_path / "three" / m3["file"].iloc[0])).astype(int)
    assert np.abs(a - c).max() > 0


@needs_cycles
def test_hair_is_rendered_as_strands_with_the_principled_hair_bsdf(tmp_path, shared_data):
    """An ICT head with short hair: the exported scene carries strands grown over the hair mesh;
    Cycles builds them as a curves object shaded by the Principled Hair BSDF, and renders them:
    dark strands over the head where the hair is."""
    import subprocess

    from stimulus_engine.grid.prepare import prepare_grid
    from stimulus_engine.grid.worker import export_item_scene, item_scene
    from stimulus_engine.render.cycles import composite

    p = tmp_path / "hair.yaml"
    p.write_text(f"""kind: grid
name: hair
characters:
  - {{name: a, ict: {shared_data / "meshes" / "ict-facekit"}, hair: short02}}
shapes: [0.0]
materials: [original]
expressions: [neutral]
lighting: [gi_soft]
shading: [pbr]
render: {{width: 128, height: 96, engine: cycles, samples: 4}}
""")
    _, items, _ = prepare_grid(load_study_file(p, GridFile), tmp_path / "out")
    scene = export_item_scene(items[0], tmp_path / "scene")
    parts, cam = item_scene(items[0])
    spec = json.loads(scene.read_text())
    k = [r["name"] for r in spec["parts"]].index("hair")
    assert spec["parts"][k]["strands"]
    arrays = np.load(scene.parent / "parts.npz")
    sizes, points = arrays[f"ss{k}"], arrays[f"sp{k}"]
    assert len(sizes) > 10000 and sizes.sum() == len(points) == len(arrays[f"sr{k}"])
    worker = Path(__file__).resolve().parents[1] / "stimulus_engine" / "render" / "cycles_worker.py"
    probe = f"""
import importlib.util, pathlib, bpy
s = importlib.util.spec_from_file_location("w", {str(worker)!r}); w = importlib.util.module_from_spec(s); s.loader.exec_module(w)
w.build_scene(bpy, pathlib.Path({str(scene)!r}), 4, 0, 2)
ob = bpy.context.scene.objects["strands"]
nodes = [n.bl_idname for n in ob.data.materials[0].node_tree.nodes]
print("PROBE", ob.type, len(ob.data.curves), len(ob.data.points), "ShaderNodeBsdfHairPrincipled" in nodes)
bpy.context.scene.render.filepath = {str(tmp_path / "hair.png")!r}
bpy.ops.render.render(write_still=True)
"""
    out = subprocess.run([str(cycles_python()), "-c", probe], capture_output=True, text=True, cwd=tmp_path)
    line = next((ln for ln in out.stdout.splitlines() if ln.startswith("PROBE")), out.stderr[-2000:])
    assert line == f"PROBE CURVES {len(sizes)} {len(points)} True", line
    img = composite(np.asarray(Image.open(tmp_path / "hair.png")), (0.5, 0.5, 0.5)).astype(float)
    # dark strands where the hair mesh is the nearest surface (pyrender's depth of the head with
    # and without it), not the skin's colour
    from stimulus_engine.render import render_mesh

    kw = dict(width=128, height=96, lighting="gi_soft", camera=cam, return_depth=True)
    full = render_mesh(parts, **kw)[1]

    def seen(name: str) -> np.ndarray:
        depth = render_mesh([q for q in parts if q.name == name], **kw)[1]
        return (depth > 0) & (np.abs(depth - full) < 1e-3 * full.max())

    hair, skin = seen("hair"), seen("skin")
    assert hair.sum() > 200 and img[hair].mean() < 0.6 * img[skin].mean(), (hair.sum(), img[hair].mean(), img[skin].mean())


@needs_cycles
@pytest.mark.slow
def test_the_inside_of_an_open_mouth_agrees_between_the_engines(tmp_path):
    """Lee Perry-Smith's surprise (Exp. 2's character, gi_soft, pbr): the teeth and the tongue seen
    through the open mouth are as bright in pyrender (direct light from the front, and the
    bounced light's floor) as in Cycles (four diffuse bounces), within a quarter. With direct
    light only, the tongue was a black hole (6 against 120 grey levels)."""
    import yaml

    from stimulus_engine.grid.prepare import prepare_grid
    from stimulus_engine.grid.worker import item_scene
    from stimulus_engine.render import render_mesh
    from stimulus_engine.render.cycles import render_cycles

    root = Path(__file__).resolve().parents[1]
    grid = yaml.safe_load((root / "protocols/grids/realism_continuum.yaml").read_text())
    grid["characters"] = [c for c in grid["characters"] if c["name"] == "lps"]
    # the scene this comparison was made on: deformation transfer opens the mouth a little wider at
    # the realistic level than the aligned transfer the grid file asks for, so the tongue shows
    grid.update(shapes=[0.0], materials=["original"], expressions=["surprise"], render={"shadows": False},
                expression_transfer="deformation_transfer")
    grid.pop("design", None)  # the realistic level only: no cartoon to make
    path = tmp_path / "mouth.yaml"
    path.write_text(yaml.safe_dump(grid))
    _, items, _ = prepare_grid(load_study_file(path, GridFile), tmp_path / "out")
    parts, cam = item_scene(items[0])
    kw = dict(width=512, height=384, lighting="gi_soft", camera=cam)
    py, full = render_mesh(parts, return_depth=True, shadows=False, **kw)
    cy = render_cycles(parts, samples=16, **kw)
    for name in ("teeth", "tongue"):
        depth = render_mesh([p for p in parts if p.name == name], return_depth=True, shadows=False, **kw)[1]
        seen = (depth > 0) & (np.abs(depth - full) < 1e-4 * full.max())
        assert seen.sum() > 20, name
        a, b = py[seen].astype(float).mean(), cy[seen].astype(float).mean()
        assert 0.75 < a / b < 1.25, (name, a, b)


@needs_cycles
def test_toon_shading_is_cel_shaded_in_cycles_too(tmp_path):
    """``toon`` reaches Cycles as Toon BSDFs (the scene's record says so): a sphere lit from the
    side shows a few flat tones there, where ``skin`` (subsurface scattering) shades it smoothly."""
    import trimesh

    from stimulus_engine.characters.render_parts import _new_material
    from stimulus_engine.render import LightSpec, RenderPart
    from stimulus_engine.render.cycles import render_cycles
    from stimulus_engine.render.scene_export import _material_record

    sphere = trimesh.creation.icosphere(subdivisions=4, radius=10.0)
    cam = CameraSpec((0.0, 0.0, 80.0), (0.0, 0.0, 0.0), 20.0)
    side = ([LightSpec("directional", (-1.0, 0.0, -0.6), 2.0)], 0.3)
    images = {}
    for shading in ("skin", "toon"):
        mat = _new_material(shading, (0.85, 0.62, 0.52, 1.0), None, 0.62, scatter=True)
        assert _material_record("skin", mat, tmp_path, 0)["toon"] is (shading == "toon")
        images[shading] = render_cycles([RenderPart(sphere, material=mat, name="skin")], width=120, height=120,
                                        lighting=side, camera=cam, samples=16)
    ball = np.abs(images["skin"].astype(int) - 128).sum(axis=-1) > 12
    luma = {k: im[..., :3].astype(float) @ np.array([0.299, 0.587, 0.114]) for k, im in images.items()}

    def tones(v: np.ndarray) -> float:  # share of the sphere in its three fullest 6-level bins
        return float(np.sort(np.bincount((v[ball] // 6).astype(int)))[-3:].sum() / ball.sum())

    assert tones(luma["toon"]) > tones(luma["skin"]) + 0.2, (tones(luma["toon"]), tones(luma["skin"]))

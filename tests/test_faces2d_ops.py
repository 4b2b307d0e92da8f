"""``appeal faces align | average | continuum | mask`` on the London FRL photographs (issue 33)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from appeal.errors import AppealInputError
from appeal_cli import main
from cli_errors import one_line_error
from stimulus_engine.faces2d.align import align_face, default_eyes, eye_points, load_faces
from stimulus_engine.faces2d.composite import average_faces, composite_ghosting, pixel_average
from stimulus_engine.faces2d.continuum import continuum
from stimulus_engine.faces2d.mask import apply_mask, face_mask
from stimulus_engine.faces2d.template import Template, read_template, write_template
from stimulus_engine.morphpca.metrics import psnr

SIZE = (300, 400)  # reduced output size (width, height) for speed


@pytest.fixture(scope="module")
def london(shared_data):
    return shared_data / "faces2d" / "london-frl"


@pytest.fixture(scope="module")
def aligned20(london):
    """20 London neutral faces aligned to 300x400 on their mean pupil positions."""
    paths = sorted((london / "neutral_front").glob("*.jpg"))[:20]
    faces = load_faces(paths)
    eyes = default_eyes(faces, SIZE)
    moved = [align_face(f.image, f.points, eyes, SIZE) for f in faces]
    return faces, eyes, [m[0] for m in moved], [m[1] for m in moved]


def test_align_puts_pupils_where_asked(london):
    faces = load_faces(sorted((london / "neutral_front").glob("*.jpg"))[:3])
    target = np.array([[240.0, 350.0], [360.0, 350.0]])
    for f in faces:
        img, pts = align_face(f.image, f.points, target, (600, 800), fill=(0.0, 0.0, 0.0))
        assert img.shape == (800, 600, 3)
        assert np.abs(eye_points(pts) - target).max() < 1.0
        # the image moved with the template: the (dark) pupil is darker than the skin below the eye
        x, y = np.round(target[0]).astype(int)
        assert img[y, x].mean() < img[y + 25, x].mean()
        # uncovered corners get the fill colour
        assert np.allclose(img[0, 0], 0.0) or np.allclose(img[-1, -1], 0.0)


def test_composite_of_20_is_sharp_and_its_template_is_the_mean(aligned20):
    faces, eyes, imgs, pts = aligned20
    comp, mean = average_faces(imgs, pts)
    assert comp.shape == (SIZE[1], SIZE[0], 3)
    np.testing.assert_allclose(mean, np.mean(pts, axis=0), atol=1e-9)
    assert np.abs(eye_points(mean) - eyes).max() < 1.0
    g_comp = composite_ghosting(comp, mean, imgs, pts)
    g_plain = composite_ghosting(pixel_average(imgs), mean, imgs, pts)
    # measured: 0.455 composite (averaging 20 faces cancels unaligned skin/hair detail),
    # 0.667 plain pixel average (doubled, smeared features)
    assert g_comp < 0.5 and g_comp < g_plain - 0.15, (g_comp, g_plain)
    # with texture restored (Tiddeman et al. 2001): measured 0.236
    tex, _ = average_faces(imgs, pts, texture=True)
    g_tex = composite_ghosting(tex, mean, imgs, pts)
    assert g_tex < 0.3 and g_tex < g_comp - 0.1, (g_tex, g_comp)
    # linear-light averaging: same shape, a near-identical image
    lin, mean_lin = average_faces(imgs[:4], pts[:4], colour_space="linear")
    srgb, _ = average_faces(imgs[:4], pts[:4])
    np.testing.assert_allclose(mean_lin, np.mean(pts[:4], axis=0))
    assert 25 < psnr(lin, srgb) < 60


def test_continuum_ends_reproduce_a_and_b_and_the_midpoint_is_the_mean(aligned20):
    _, _, imgs, pts = aligned20
    frames = continuum(imgs[0], pts[0], imgs[1], pts[1], 5)
    assert len(frames) == 5
    assert psnr(frames[0][0], imgs[0]) > 40 and psnr(frames[-1][0], imgs[1]) > 40
    np.testing.assert_allclose(frames[0][1], pts[0])
    np.testing.assert_allclose(frames[2][1], (pts[0] + pts[1]) / 2)
    # the midpoint is neither end
    assert psnr(frames[2][0], imgs[0]) < 30 and psnr(frames[2][0], imgs[1]) < 30


def test_female_male_continuum_from_the_london_composites_has_single_sharp_features(london):
    faces = load_faces([london / "composite" / "f_white.jpg", london / "composite" / "m_white.jpg"])
    eyes = default_eyes(faces, SIZE)
    (a, pa), (b, pb) = (align_face(f.image, f.points, eyes, SIZE) for f in faces)
    frames = continuum(a, pa, b, pb, 5)
    # measured: 0.142, 0.227, 0.223 for the inner steps (0 = as crisp as the two composites)
    for img, pts in frames[1:-1]:
        assert composite_ghosting(img, pts, [a, b], [pa, pb]) < 0.3


@pytest.mark.parametrize("kind", ["oval", "hull"])
def test_mask_is_0_outside_1_inside_with_a_soft_edge(aligned20, kind):
    _, eyes, imgs, pts = aligned20
    m = face_mask(imgs[0].shape[:2], pts[0], kind, feather=12)
    assert m.dtype == np.float32 and m.min() == 0.0 and m.max() == 1.0
    cx, cy = np.round(eyes.mean(0)).astype(int)
    assert m[cy, cx] == 1.0 and m[0, 0] == 0.0 and m[-1, -1] == 0.0
    soft = (m > 0) & (m < 1)
    assert soft.sum() > 0.5 * 12 * 2 * (m == 1).sum() ** 0.5  # a ramp around the outline, not a hard step
    # along a row through the face the edge rises over about `feather` pixels
    row = m[cy]
    ramp = np.flatnonzero((row > 0) & (row < 1))
    assert 6 <= len(ramp) // 2 <= 14
    hard = face_mask(imgs[0].shape[:2], pts[0], kind, feather=0)
    assert set(np.unique(hard)) <= {0.0, 1.0}
    rgba = apply_mask(imgs[0], m, None)
    assert rgba.shape[-1] == 4 and np.array_equal(rgba[..., 3], m)
    on_grey = apply_mask(imgs[0], m, (0.5, 0.5, 0.5))
    assert np.allclose(on_grey[0, 0], 0.5) and np.allclose(on_grey[cy, cx], imgs[0][cy, cx])


def test_cli_writes_images_templates_manifest_and_sheet(london, tmp_path, capsys):
    from PIL import Image

    src = sorted((london / "neutral_front").glob("*.jpg"))[:4]
    out = tmp_path / "aligned"
    assert main(["faces", "align", *map(str, src), "--size", "300x400", "--eyes", "0.4,0.45,0.6,0.45",
                 "--fill", "grey", "--out", str(out)]) == 0
    man = pd.read_csv(out / "manifest.csv")
    assert list(man.columns[:5]) == ["file", "tem", "operation", "inputs", "parameters"]
    assert len(man) == 4 and (man.operation == "align").all()
    assert (out / "contact_sheet.png").is_file()
    for row in man.itertuples():
        assert Image.open(out / row.file).size == (300, 400)
        t = read_template(out / row.tem)
        assert np.abs(eye_points(t.points) - [[120, 180], [180, 180]]).max() < 1.0
    # the aligned folder feeds the next steps
    comp = tmp_path / "comp"
    assert main(["faces", "average", str(out), "--out", str(comp), "--name", "four"]) == 0
    man = pd.read_csv(comp / "manifest.csv")
    assert man.file.tolist() == ["four.png"] and man.n_faces.tolist() == [4]
    assert man.ghosting[0] < man.ghosting_pixel_average[0]
    mean = np.mean([read_template(out / f"{p.stem}.tem").points for p in src], axis=0)
    np.testing.assert_allclose(read_template(comp / "four.tem").points, mean, atol=1e-6)
    cont = tmp_path / "cont"
    assert main(["faces", "continuum", str(out / "001_03.png"), str(out / "002_03.png"), "--steps", "3",
                 "--out", str(cont)]) == 0
    man = pd.read_csv(cont / "manifest.csv")
    assert man.step.tolist() == [0, 1, 2] and man.weight.tolist() == [0.0, 0.5, 1.0]
    assert all((cont / f).is_file() for f in man.tem)
    masked = tmp_path / "masked"
    assert main(["faces", "mask", str(comp / "four.png"), "--kind", "hull", "--fill", "transparent",
                 "--out", str(masked)]) == 0
    assert Image.open(masked / "four.png").mode == "RGBA"
    assert (masked / "contact_sheet.png").is_file() and (masked / "four.tem").is_file()


def test_cli_one_line_errors_name_the_file(london, tmp_path, capsys):
    nf = london / "neutral_front"
    a, b = nf / "001_03.jpg", nf / "002_03.jpg"
    # a template with another point count
    odd = tmp_path / "odd"
    odd.mkdir()
    for p in (a, b):
        (odd / p.name).write_bytes(p.read_bytes())
    t = read_template(nf / "001_03.tem")
    write_template(odd / "001_03.tem", t)
    write_template(odd / "002_03.tem", Template(t.points[:100], t.tail))
    one_line_error(capsys, ["faces", "average", str(odd / "001_03.jpg"), str(odd / "002_03.jpg"),
                             "--out", str(tmp_path / "o1")], "002_03.jpg", "100 points", "189 points")
    # a malformed template
    (odd / "002_03.tem").write_text("189\n1 2\nnot numbers\n")
    one_line_error(capsys, ["faces", "align", str(odd / "002_03.jpg"), "--out", str(tmp_path / "o2")],
                    "002_03.tem")
    # images of different sizes where a step needs one size
    small = tmp_path / "small"
    assert main(["faces", "align", str(b), "--size", "300x400", "--out", str(small)]) == 0
    one_line_error(capsys, ["faces", "average", str(a), str(small / "002_03.png"), "--out", str(tmp_path / "o3")],
                    "002_03.png", "300x400", "1350x1350")
    one_line_error(capsys, ["faces", "continuum", str(a), str(small / "002_03.png"), "--out", str(tmp_path / "o4")],
                    "002_03.png")
    # a face the detector cannot find (no .tem beside it: detection)
    blank = tmp_path / "blank.png"
    from stimulus_engine.render.contact_sheet import save_png

    save_png(np.full((200, 200, 3), 128, np.uint8), blank)
    one_line_error(capsys, ["faces", "mask", str(blank), "--out", str(tmp_path / "o5")], "blank.png", "no face")
    # a photo with a .tem mixed with one without (detected 68 points)
    notem = tmp_path / "notem.jpg"
    notem.write_bytes(b.read_bytes())
    one_line_error(capsys, ["faces", "align", str(a), str(notem), "--out", str(tmp_path / "o6")],
                    "notem.jpg", "template mismatch", "68")
    one_line_error(capsys, ["faces", "align", str(a), "--size", "big", "--out", str(tmp_path / "o7")], "--size")
    one_line_error(capsys, ["faces", "mask", str(a), "--fill", "mauve", "--out", str(tmp_path / "o8")], "mauve")
    with pytest.raises(AppealInputError, match="missing.jpg: image file not found"):
        load_faces([a, tmp_path / "missing.jpg"])


def test_images_named_by_a_dataset_reference_and_a_pattern(tmp_path):
    """`data:` references and globs, as in `appeal faces align "data:london-frl/neutral_front/00[12]_03.jpg"`."""
    from appeal_cli.faces_ops import image_files

    files = image_files([Path("data:london-frl/neutral_front/00[12]_03.jpg")])
    assert [f.name for f in files] == ["001_03.jpg", "002_03.jpg"]
    assert main(["faces", "align", "data:london-frl/neutral_front/00[12]_03.jpg", "--size", "150x200",
                 "--out", str(tmp_path / "a")]) == 0
    assert (tmp_path / "a" / "001_03.tem").is_file()

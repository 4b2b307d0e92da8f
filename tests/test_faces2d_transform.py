"""``appeal faces transform | caricature | symmetrise`` on the London FRL photographs (issue 33)."""

from __future__ import annotations

import csv

import cv2
import numpy as np
import pandas as pd
import pytest

from appeal.errors import AppealInputError
from appeal_cli import main
from cli_errors import one_line_error
from stimulus_engine.faces2d.align import align_face, eye_points, read_face
from stimulus_engine.faces2d.caricature import caricature, caricature_points
from stimulus_engine.faces2d.composite import average_faces, composite_ghosting
from stimulus_engine.faces2d.symmetry import (DLIB_68_MIRROR, FRL_189_MIRROR, asymmetry, check_mirror_map,
                                              derive_mirror_map, mirror_map, mirror_template, reflect_image,
                                              symmetrise, symmetry_reflection)
from stimulus_engine.faces2d.template import Template, read_template, write_template
from stimulus_engine.faces2d.transform import eye_distance, shape_difference, transform

SIDE = 300  # the 1350-px London photos reduced to 300x300 for speed
SCALE = SIDE / 1350


@pytest.fixture(scope="module")
def london(shared_data):
    return shared_data / "faces2d" / "london-frl"


def _small(path):
    """A London photo and its template at SIDE x SIDE."""
    f = read_face(path, detect=False)
    img = cv2.resize(f.image, (SIDE, SIDE), interpolation=cv2.INTER_AREA)
    return img, (f.points + 0.5) * SCALE - 0.5


@pytest.fixture(scope="module")
def faces(london):
    """All 30 neutral London faces (small), their sex, and the faces aligned on fixed pupils."""
    with open(london / "london_info.csv", newline="") as fh:
        sex = {r["face_id"]: r["face_gender"] for r in csv.DictReader(fh)}
    paths = sorted((london / "neutral_front").glob("*.jpg"))
    small = [_small(p) for p in paths]
    eyes = np.array([[0.42, 0.45], [0.58, 0.45]]) * SIDE
    aligned = [align_face(i, p, eyes, (SIDE, SIDE)) for i, p in small]
    return paths, [sex[p.stem[:3]] for p in paths], small, aligned


@pytest.fixture(scope="module")
def prototypes(faces):
    """Female and male composites (the other faces' average_faces), and the average of all."""
    paths, sex, _, aligned = faces

    def comp(keep):
        sel = [a for a, s in zip(aligned, sex) if keep(s)]
        return average_faces([a[0] for a in sel], [a[1] for a in sel])

    return comp(lambda s: s == "female"), comp(lambda s: s == "male"), comp(lambda s: True)


def _sex_features(points):
    """Brow height above the pupils and jaw width, both in eye distances (189-point FRL)."""
    d = eye_distance(points)
    brow = (np.mean(points[:2, 1]) - np.mean(points[71:83, 1])) / d
    jaw = np.linalg.norm(points[126] - points[132]) / d
    return np.array([brow, jaw])


# ------------------------------------------------------------------ transform

def test_transform_weight_zero_returns_the_image(faces, prototypes):
    _, _, small, _ = faces
    (fi, fp), (mi, mp), _ = prototypes
    img, pts = small[0]
    out, q = transform(img, pts, fi, fp, mi, mp)
    np.testing.assert_array_equal(q, pts)
    assert np.abs(out - img).max() < 1e-6


def test_shape_weight_one_moves_the_template_by_b_minus_a_in_the_image_frame(faces, prototypes):
    _, _, small, _ = faces
    (fi, fp), (mi, mp), _ = prototypes
    img, pts = small[3]
    out, q = transform(img, pts, fi, fp, mi, mp, shape=1.0)
    # B - A measured after putting both prototypes' pupils on the face's: the composites (made from
    # faces aligned on the same pupils) share their pupils, so it is mp - fp rotated and scaled
    diff = shape_difference(pts, fp, mp)
    np.testing.assert_allclose(q - pts, diff, atol=1e-9)
    np.testing.assert_allclose(fp[:2], mp[:2], atol=1e-6)
    s = eye_distance(pts) / eye_distance(fp)
    ang = np.arctan2(*(eye_points(pts)[1] - eye_points(pts)[0])[::-1])
    rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    np.testing.assert_allclose(diff, s * (mp - fp) @ rot.T, atol=1e-6)
    assert np.abs(diff).max() > 1.0  # the composites do differ
    np.testing.assert_allclose(q[:2], pts[:2], atol=1e-6)  # pupils coincide in both prototypes
    # the image moved with its template: half way gives half the move
    _, half = transform(img, pts, fi, fp, mi, mp, shape=0.5)
    np.testing.assert_allclose(half - pts, 0.5 * diff, atol=1e-9)
    assert out.shape == img.shape and out.dtype == np.float32
    # prototypes of another size: the same move (they are aligned on the face's pupils first)
    big = cv2.resize(mi, (2 * SIDE, 2 * SIDE), interpolation=cv2.INTER_CUBIC)
    out2, q2 = transform(img, pts, fi, fp, big, (mp + 0.5) * 2 - 0.5, shape=1.0, colour=1.0)
    np.testing.assert_allclose(q2, q, atol=1e-6)
    ref, _ = transform(img, pts, fi, fp, mi, mp, shape=1.0, colour=1.0)
    assert out2.shape == img.shape and float(np.abs(out2 - ref).mean()) < 0.005


def test_female_to_male_transform_moves_sex_typical_features_toward_the_male_prototype(faces, prototypes):
    _, sex, small, _ = faces
    (fi, fp), (mi, mp), _ = prototypes
    f_feat, m_feat = _sex_features(fp), _sex_features(mp)
    assert f_feat[0] > m_feat[0] and f_feat[1] < m_feat[1]  # women: higher brows, narrower jaws
    women = [k for k, s in enumerate(sex) if s == "female"][:4]
    for k in women:
        img, pts = small[k]
        _, q = transform(img, pts, fi, fp, mi, mp, shape=1.0, colour=1.0, texture=1.0)
        before, after = _sex_features(pts), _sex_features(q)
        np.testing.assert_allclose(after - before, m_feat - f_feat, atol=0.02)
    # colour: the masculinised face's skin gets the male composite's darker, redder low frequencies
    img, pts = small[women[0]]
    shape_only, q = transform(img, pts, fi, fp, mi, mp, shape=1.0)
    full, _ = transform(img, pts, fi, fp, mi, mp, shape=1.0, colour=1.0)
    cheek = tuple(np.round(q[[165, 166]].mean(0)).astype(int))
    assert full[cheek[1], cheek[0]].mean() < shape_only[cheek[1], cheek[0]].mean()
    # away from the face (region="face") colour and texture leave the image alone
    np.testing.assert_allclose(full[:10], shape_only[:10], atol=1e-5)


def test_transform_texture_changes_fine_detail_not_the_mean(faces, prototypes):
    _, sex, small, _ = faces
    (fi, fp), (mi, mp), _ = prototypes
    k = sex.index("male")
    img, pts = small[k]
    smooth, _ = transform(img, pts, mi, mp, fi, fp, texture=1.0)  # male -> female: smoother skin
    lap = lambda x: float(np.abs(cv2.Laplacian(cv2.cvtColor(x, cv2.COLOR_RGB2GRAY), cv2.CV_32F)).mean())
    box = (slice(int(pts[129, 1] - 0.6 * eye_distance(pts)), int(pts[129, 1])),
           slice(int(pts[127, 0]), int(pts[131, 0])))  # lower face: stubble
    assert lap(smooth[box]) < 0.9 * lap(img[box])
    assert abs(float(smooth[box].mean()) - float(img[box].mean())) < 0.02


# ------------------------------------------------------------------ caricature

def test_caricature_k0_is_identity_and_k_half_moves_points_1_5_times_away(faces, prototypes):
    _, _, small, _ = faces
    _, _, (ai, ap) = prototypes
    img, pts = small[5]
    same, q0 = caricature(img, pts, ai, ap, 0.0)
    np.testing.assert_array_equal(q0, pts)
    assert np.abs(same - img).max() < 1e-6
    out, q = caricature(img, pts, ai, ap, 0.5)
    avg = pts - shape_difference(pts, ap, pts)  # the average's template in the face's eye frame
    np.testing.assert_allclose(q - avg, 1.5 * (pts - avg), atol=1e-9)
    np.testing.assert_allclose(caricature_points(pts, ap, -0.5) - avg, 0.5 * (pts - avg), atol=1e-9)
    assert np.abs(q[:2] - pts[:2]).max() < 1e-6  # pupils stay
    for k in (-0.5, 0.5):
        o, qk = caricature(img, pts, ai, ap, k, colour=k)
        g = composite_ghosting(o, qk, [img], [pts])
        assert g < 0.25, (k, g)  # single sharp features (0 = as crisp as the photo)


# ------------------------------------------------------------------ symmetry

def test_mirror_maps_are_involutions_with_the_midline_fixed(london):
    for m in (FRL_189_MIRROR, DLIB_68_MIRROR):
        check_mirror_map(m)
        assert np.array_equal(m[m], np.arange(len(m)))
    assert FRL_189_MIRROR[0] == 1 and FRL_189_MIRROR[1] == 0  # the pupils
    fixed = np.flatnonzero(FRL_189_MIRROR == np.arange(189)).tolist()
    assert fixed == [55, 90, 96, 101, 106, 129, 139, 151, 174, 175, 177]
    assert np.flatnonzero(DLIB_68_MIRROR == np.arange(68)).tolist() == [8, 27, 28, 29, 30, 33, 51, 57, 62, 66]
    assert DLIB_68_MIRROR[36] == 45 and DLIB_68_MIRROR[0] == 16 and DLIB_68_MIRROR[48] == 54
    # the stored constant is what the data give (30 London templates; the module used all 87)
    tems = [read_template(p).points for p in sorted((london / "neutral_front").glob("*.tem"))]
    np.testing.assert_array_equal(derive_mirror_map(tems), FRL_189_MIRROR)
    assert mirror_map(189) is FRL_189_MIRROR and mirror_map(68) is DLIB_68_MIRROR
    with pytest.raises(ValueError, match="no left-right mirror map for a 12-point"):
        mirror_map(12)
    with pytest.raises(ValueError, match="own inverse"):
        check_mirror_map([1, 2, 0])


def test_symmetrise_gives_a_symmetric_template_and_image(faces):
    _, _, small, _ = faces
    img, pts = small[4]
    m = FRL_189_MIRROR
    assert asymmetry(pts, m) > 3.0  # a real face is not symmetric
    out, q = symmetrise(img, pts, mode="both")
    assert asymmetry(q, m) <= 0.5
    assert np.abs(mirror_template(q, m) - q).max() <= 0.5
    # the image's reflection about the symmetric face's axis, warped onto the symmetric shape, is itself
    from stimulus_engine.faces2d.warp import warp_to_points

    g = symmetry_reflection(q, m)
    flipped = warp_to_points(reflect_image(out, g), mirror_template(q, m, g), q)
    face = (slice(int(q[:, 1].min()), int(q[129, 1])), slice(int(q[125, 0]), int(q[133, 0])))
    err = float(np.abs(flipped[face] - out[face]).mean())
    before = float(np.abs(warp_to_points(reflect_image(img, symmetry_reflection(pts, m)),
                                         mirror_template(pts, m), pts)[face] - img[face]).mean())
    assert err < 0.01 and err < 0.3 * before, (err, before)
    # shape only keeps the colours; colour only keeps the shape
    _, qs = symmetrise(img, pts, mode="shape")
    np.testing.assert_allclose(qs, q, atol=1e-9)
    oc, qc = symmetrise(img, pts, mode="colour")
    np.testing.assert_array_equal(qc, pts)
    assert composite_ghosting(out, q, [img], [pts]) < 0.25
    assert composite_ghosting(oc, qc, [img], [pts]) < 0.25


def test_symmetrise_works_with_dlib_68_points(faces):
    from stimulus_engine.morphpca.keypoints import detect_landmarks

    _, _, small, _ = faces
    img = small[2][0]
    pts68 = detect_landmarks(img, "003_03")
    assert asymmetry(pts68, DLIB_68_MIRROR) > 1.0
    out, q = symmetrise(img, pts68)
    assert asymmetry(q, DLIB_68_MIRROR) <= 0.5
    assert composite_ghosting(out, q, [img], [pts68]) < 0.25


# ------------------------------------------------------------------ CLI

def _save(folder, name, img, pts, tail=""):
    from stimulus_engine.faces2d.outputs import to_uint8
    from stimulus_engine.render.contact_sheet import save_png

    folder.mkdir(parents=True, exist_ok=True)
    save_png(to_uint8(img), folder / f"{name}.png")
    write_template(folder / f"{name}.tem", Template(np.asarray(pts, np.float64), tail))
    return folder / f"{name}.png"


def test_cli_writes_outputs_manifest_and_sheet(faces, prototypes, london, tmp_path):
    from PIL import Image

    paths, _, small, _ = faces
    (fi, fp), (mi, mp), (ai, ap) = prototypes
    tail = read_template(paths[0].with_suffix(".tem")).tail
    src = tmp_path / "src"
    face = _save(src, "face", *small[0], tail)
    fem, mal, avg = (_save(src, n, i, p, tail) for n, (i, p) in (("female", (fi, fp)), ("male", (mi, mp)),
                                                                  ("average", (ai, ap))))
    out = tmp_path / "t"
    assert main(["faces", "transform", str(face), "--from", str(fem), "--to", str(mal), "--strength", "-0.5,0,0.5",
                 "--texture", "0", "--out", str(out)]) == 0
    man = pd.read_csv(out / "manifest.csv")
    assert list(man.columns[:5]) == ["file", "tem", "operation", "inputs", "parameters"]
    assert man.file.tolist() == ["face_t-0.50.png", "face_t+0.00.png", "face_t+0.50.png"]
    assert (man.operation == "transform").all() and man.strength.tolist() == [-0.5, 0.0, 0.5]
    assert (out / "contact_sheet.png").is_file() and Image.open(out / man.file[0]).size == (SIDE, SIDE)
    q = read_template(out / "face_t+0.50.tem").points
    np.testing.assert_allclose(q, transform(*small[0], fi, fp, mi, mp, shape=0.5)[1], atol=1e-3)
    # a folder as prototype: its composite
    folder = tmp_path / "fem_faces"
    for k in range(3):
        _save(folder, f"f{k}", *faces[3][k], tail)
    assert main(["faces", "transform", str(face), "--from", str(folder), "--to", str(mal),
                 "--out", str(tmp_path / "t2")]) == 0
    out = tmp_path / "c"
    assert main(["faces", "caricature", str(face), "--average", str(avg), "--k", "-0.5,0.5", "--colour",
                 "--out", str(out)]) == 0
    man = pd.read_csv(out / "manifest.csv")
    assert man.file.tolist() == ["face_k-0.50.png", "face_k+0.50.png"] and man.k.tolist() == [-0.5, 0.5]
    assert (out / "contact_sheet.png").is_file() and (out / "face_k+0.50.tem").is_file()
    out = tmp_path / "s"
    assert main(["faces", "symmetrise", str(face), "--mode", "shape", "--mode", "both", "--out", str(out)]) == 0
    man = pd.read_csv(out / "manifest.csv")
    assert man.file.tolist() == ["face_sym-shape.png", "face_sym-both.png"]
    assert (man.asymmetry_after <= 0.5).all() and (man.asymmetry_before > 1).all()
    assert asymmetry(read_template(out / "face_sym-both.tem").points, FRL_189_MIRROR) < 0.01


def test_cli_one_line_errors_name_the_file(faces, prototypes, tmp_path, capsys):
    paths, _, small, _ = faces
    (fi, fp), (mi, mp), _ = prototypes
    src = tmp_path / "src"
    face = _save(src, "face", *small[0])
    fem = _save(src, "female", fi, fp)
    odd = _save(src, "odd", mi, mp[:100])  # another point count
    one_line_error(capsys, ["faces", "transform", str(face), "--from", str(fem), "--to", str(odd),
                             "--out", str(tmp_path / "o1")], "odd.png", "100 points", "189")
    one_line_error(capsys, ["faces", "caricature", str(face), "--average", str(odd), "--out", str(tmp_path / "o2")],
                    "odd.png", "100 points")
    # a prototype without its .tem (the faces have templates: no detection for it)
    notem = src / "notem.png"
    notem.write_bytes(fem.read_bytes())
    one_line_error(capsys, ["faces", "transform", str(face), "--from", str(notem), "--to", str(fem),
                             "--out", str(tmp_path / "o3")], "notem.png", "notem.tem")
    # a folder prototype whose images differ in size (a composite needs one size)
    mixed = tmp_path / "mixed"
    _save(mixed, "a", *small[1])
    _save(mixed, "b", cv2.resize(small[2][0], (200, 200)), small[2][1] * 2 / 3)
    one_line_error(capsys, ["faces", "transform", str(face), "--from", str(mixed), "--to", str(fem),
                             "--out", str(tmp_path / "o4")], "b.png", "200x200", "300x300")
    # symmetrise: a template type without left-right partners
    twelve = _save(tmp_path / "twelve", "face", small[0][0], small[0][1][:12])
    one_line_error(capsys, ["faces", "symmetrise", str(twelve), "--out", str(tmp_path / "o5")],
                    "face.tem", "12-point")
    one_line_error(capsys, ["faces", "caricature", str(face), "--average", str(fem), "--k", "lots",
                             "--out", str(tmp_path / "o6")], "--k", "lots")
    one_line_error(capsys, ["faces", "transform", str(tmp_path / "missing.png"), "--from", str(fem), "--to",
                             str(fem), "--out", str(tmp_path / "o7")], "missing.png")
    with pytest.raises(AppealInputError, match="prototype A: template has 100 points"):
        transform(small[0][0], small[0][1], mi, mp[:100], mi, mp)

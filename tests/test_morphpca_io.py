"""Morph-space PCA at the edges: files, templates, the landmark detector, the CLI, bad input."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from appeal_cli import main
from appeal.errors import AppealInputError
from stimulus_engine.morphpca import (
    detect_faceframe,
    faceframe_from_tem,
    random_identity,
    read_images,
    read_keypoints_csv,
    read_tem,
    register_faces,
    save_image,
    synthetic_set,
    write_keypoints_csv,
)

FRL = "faces2d/london-frl"


@pytest.fixture(scope="module")
def synthetic_dirs(tmp_path_factory):
    root = tmp_path_factory.mktemp("faces")
    for name, seed in (("A", 11), ("B", 12)):
        imgs, _, frames = synthetic_set(random_identity(seed), 8, seed)
        files = [root / name / f"f{i}.png" for i in range(len(imgs))]
        files[0].parent.mkdir()
        for f, im in zip(files, imgs):
            save_image(f, im)
        write_keypoints_csv(root / f"{name}.csv", files, frames)
    return root


def test_read_images_errors(tmp_path):
    colour = np.full((20, 16, 3), 128, np.uint8)
    cv2.imwrite(str(tmp_path / "a.png"), colour)
    cv2.imwrite(str(tmp_path / "b.png"), np.full((22, 16, 3), 9, np.uint8))
    cv2.imwrite(str(tmp_path / "c.png"), colour)
    cv2.imwrite(str(tmp_path / "g.png"), np.full((20, 16), 50, np.uint8))
    (tmp_path / "bad.png").write_text("no image")
    with pytest.raises(AppealInputError) as e:
        read_images([tmp_path / "a.png", tmp_path / "b.png"])
    assert e.value.lines == [f"{tmp_path / 'b.png'}: image size 22x16 differs from a.png's 20x16 (expected all the same "
                             "size; use --size HxW or register by keypoints)"]
    with pytest.raises(AppealInputError) as e:
        read_images([tmp_path / "a.png", tmp_path / "c.png", tmp_path / "g.png"])
    assert e.value.lines == [f"{tmp_path / 'g.png'}: greyscale image among colour ones (expected all images colour, "
                             "or all greyscale)"]
    with pytest.raises(AppealInputError, match=r"bad.png: not a readable image"):
        read_images([tmp_path / "a.png", tmp_path / "bad.png"])
    assert read_images([tmp_path / "a.png", tmp_path / "b.png"], size=(10, 8)).shape == (2, 10, 8, 3)
    grey = read_images([tmp_path / "g.png", tmp_path / "g.png"])
    assert grey.shape == (2, 20, 16, 3) and np.allclose(grey[0, 0, 0], 50 / 255)


def test_keypoints_csv_errors(tmp_path):
    f = tmp_path / "k.csv"
    f.write_text("image,left_eye_x,left_eye_y,right_eye_x,right_eye_y,philtrum_x,philtrum_y\n"
                 "a.png,1,2,3,4,5,6\nb.png,1,2,3,,5,6\n")
    np.testing.assert_array_equal(read_keypoints_csv(f, ["x/a.png"])[0], [[1, 2], [3, 4], [5, 6]])
    with pytest.raises(AppealInputError) as e:
        read_keypoints_csv(f, ["a.png", "b.png", "c.png"])
    assert e.value.lines == [f"{f}: right_eye_y: missing or non-numeric for 'b.png' (expected pixel coordinates)",
                             f"{f}: image: no keypoints for 'c.png' (expected one row per image)"]
    g = tmp_path / "g.csv"
    g.write_text("image,x,y\na.png,1,2\n")
    with pytest.raises(AppealInputError, match="missing column"):
        read_keypoints_csv(g, ["a.png"])
    with pytest.raises(AppealInputError, match="template file not found"):
        read_tem(tmp_path / "none.tem")


def test_tem_faceframe_and_detector_agree_on_real_photos(shared_data):
    folder = shared_data / FRL / "neutral_front"
    names = ["001_03", "005_03", "010_03"]
    for name in names:
        pts = read_tem(folder / f"{name}.tem")
        assert pts.shape == (189, 2)
        tem_frame = faceframe_from_tem(pts, name)
        img = read_images([folder / f"{name}.jpg"])[0]
        det = detect_faceframe(img, name)
        iod = np.linalg.norm(tem_frame[1] - tem_frame[0])
        # dlib eye centres (mean of 6 lid points) vs hand-placed pupils: within 8% of the eye distance
        assert np.abs(det[:2] - tem_frame[:2]).max() < 0.08 * iod, (name, det, tem_frame)
        assert np.abs(det[2] - tem_frame[2]).max() < 0.15 * iod


def test_register_real_faces_puts_pupils_on_canonical_positions(shared_data):
    folder = shared_data / FRL / "neutral_front"
    files = [folder / "001_03.jpg", folder / "002_03.jpg"]
    imgs = read_images(files)
    frames = np.stack([faceframe_from_tem(read_tem(f.with_suffix(".tem"))) for f in files])
    out, moved = register_faces(imgs, frames, (240, 200))
    assert out.shape == (2, 240, 200, 3)
    np.testing.assert_allclose(moved[:, 0], [[70, 96], [70, 96]], atol=1e-6)
    np.testing.assert_allclose(moved[:, 1], [[130, 96], [130, 96]], atol=1e-6)


def test_cli_build_project_avatar_reconstruct(synthetic_dirs, tmp_path, capsys):
    d = synthetic_dirs
    assert main(["-q", "stimuli", "morphpca", "build", str(d / "A"), "--keypoints", str(d / "A.csv"),
                 "--out", str(tmp_path / "mA"), "--holdout", "2", "--json", str(tmp_path / "a.json")]) == 0
    metrics = json.loads((tmp_path / "a.json").read_text())
    assert metrics["n_images"] == 6 and metrics["n_components"] == 5 and metrics["holdout_psnr_db"] > 25
    assert (tmp_path / "mA" / "model.npz").is_file() and (tmp_path / "mA" / "components.png").is_file()
    assert main(["-q", "stimuli", "morphpca", "build", str(d / "B"), "--keypoints", str(d / "B.csv"),
                 "--out", str(tmp_path / "mB")]) == 0
    assert main(["-q", "stimuli", "morphpca", "project", str(d / "A" / "f3.png"), "--from", str(tmp_path / "mA/model.npz"),
                 "--to", str(tmp_path / "mB/model.npz"), "--truth", str(d / "B" / "f3.png"), "--naive",
                 "--out", str(tmp_path / "p"), "--json", str(tmp_path / "p.json")]) == 0
    pm = json.loads((tmp_path / "p.json").read_text())
    assert {"ssim_projection", "ssim_naive", "psnr_projection_db", "psnr_naive_db"} <= set(pm)
    assert (tmp_path / "p" / "projected" / "f3.png").is_file() and (tmp_path / "p" / "naive" / "f3.png").is_file()
    assert main(["-q", "stimuli", "morphpca", "avatar", str(tmp_path / "mA/model.npz"), str(tmp_path / "mB/model.npz"),
                 "--out", str(tmp_path / "av"), "--json", str(tmp_path / "av.json")]) == 0
    assert json.loads((tmp_path / "av.json").read_text())["frames"] == 14
    (tmp_path / "lo.csv").write_text("image,pc1,pc2\nfirst,0,0\nsecond,100,-50\n")
    assert main(["-q", "stimuli", "morphpca", "reconstruct", str(tmp_path / "av/model.npz"), "--loadings",
                 str(tmp_path / "lo.csv"), "--out", str(tmp_path / "r"), "--json", str(tmp_path / "r.json")]) == 0
    assert (tmp_path / "r" / "first.png").is_file() and (tmp_path / "r" / "second.png").is_file()
    capsys.readouterr()


def test_cli_bad_input_one_line_exit_2(synthetic_dirs, tmp_path, capsys):
    d = synthetic_dirs
    one = tmp_path / "one"
    one.mkdir()
    cv2.imwrite(str(one / "x.png"), np.zeros((10, 10, 3), np.uint8))
    partial = tmp_path / "partial.csv"
    partial.write_text("\n".join((d / "A.csv").read_text().splitlines()[:-1]) + "\n")  # no row for f7.png
    cases = [
        (["build", str(one), "--out", str(tmp_path / "o1")], "IMAGES: a model needs at least 2 images (got 1: x.png)"),
        (["build", str(d / "A"), "--keypoints", str(partial), "--out", str(tmp_path / "o2")],
         f"{partial}: image: no keypoints for 'f7.png' (expected one row per image)"),
        (["project", str(d / "A" / "f1.png"), "--from", str(tmp_path / "none.npz"), "--to", str(tmp_path / "none.npz"),
          "--out", str(tmp_path / "o3")],
         f"{tmp_path / 'none.npz'}: model file not found (expected a .npz written by 'appeal stimuli morphpca build')"),
        (["build", str(d / "A"), "--register", "--out", str(tmp_path / "o4")],
         "--register: needs --keypoints FILE, 'tem' or 'detect' (the eye centres to align)"),
    ]
    for args, expected in cases:
        assert main(["-q", "stimuli", "morphpca", *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err[0] == expected and "Traceback" not in "\n".join(err)
    assert not (tmp_path / "o1").exists() and not (tmp_path / "o2").exists()

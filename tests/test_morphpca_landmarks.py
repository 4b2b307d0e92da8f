"""Landmark-guided warp fields on real photographs (London set): spline, refinement, models, bad keypoints."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from appeal.errors import AppealInputError
from appeal_cli import main
from stimulus_engine.morphpca import build_model, faceframe_from_tem, psnr, read_images, read_tem, register_faces
from stimulus_engine.morphpca.flow import grid, warp_image
from stimulus_engine.morphpca.landmark_warp import guided_flow, tps_displacement

FRL = "faces2d/london-frl"


@pytest.fixture(scope="module")
def london(shared_data):
    """The first 8 neutral London photos registered to 240x200 with their 189 template points."""
    folder = shared_data / FRL / "neutral_front"
    files = sorted(folder.glob("*.jpg"))[:8]
    tems = np.stack([read_tem(f.with_suffix(".tem")) for f in files])
    frames = np.stack([faceframe_from_tem(t) for t in tems])
    imgs, _, pts = register_faces(read_images(files), frames, (240, 200), points=tems)
    return files, imgs, pts


def test_spline_hits_the_landmarks_and_holds_the_border():
    from stimulus_engine.morphpca.flow import sample_field

    rng = np.random.default_rng(1)
    gy, gx = np.mgrid[40:201:25, 40:161:25]  # a template-like spread: points ~25 px apart
    src = np.stack([gx.ravel(), gy.ravel()], 1) + rng.uniform(-5, 5, size=(gx.size, 2))
    dst = src + rng.normal(0, 2, size=src.shape)
    d = tps_displacement(src, dst, (240, 200))
    # evaluated on a coarser grid and upsampled: at the landmarks within half a pixel
    at = sample_field(d, src.astype(np.float32)[None])[0]
    assert np.abs(at - (dst - src)).max() < 0.5
    assert np.abs(d[0]).max() < 0.3 and np.abs(d[-1]).max() < 0.3 and np.abs(d[:, 0]).max() < 0.3


def test_guided_flow_recovers_a_known_warp_of_a_real_face(london):
    _, imgs, pts = london
    ref, ref_pts = imgs[0], pts[0]
    rng = np.random.default_rng(0)
    moved = ref_pts + rng.normal(0, 2.5, ref_pts.shape)  # a different face shape, same person
    true = tps_displacement(ref_pts, moved, (240, 200))
    image = warp_image(ref, grid(240, 200) - true)  # approximately ref(x) = image(x + true(x))
    f = guided_flow(ref, image, ref_pts, moved)
    inner = (slice(40, 200), slice(40, 160))
    err = np.linalg.norm(f - true, axis=-1)[inner]
    assert np.median(err) < 0.5 and np.percentile(err, 95) < 1.5
    # optical flow alone from the same images does worse: the landmarks matter
    from stimulus_engine.morphpca.flow import compute_flow

    err_flow = np.linalg.norm(compute_flow(ref, image) - true, axis=-1)[inner]
    assert np.median(err) < np.median(err_flow)


def test_landmark_guided_model_reconstructs_real_photos(london):
    """All components: the training photos come back near-losslessly, far better than with flow alone."""
    _, imgs, pts = london
    n = 6
    guided = build_model(imgs[:n], landmarks=pts[:n])
    flow = build_model(imgs[:n])
    train = np.mean([psnr(a, b) for a, b in zip(guided.reconstruct(guided.loadings), imgs[:n])])
    train_flow = np.mean([psnr(a, b) for a, b in zip(flow.reconstruct(flow.loadings), imgs[:n])])
    assert train >= 32.0 and train > train_flow + 2.0, (train, train_flow)
    assert guided.landmarks.shape == (189, 2) and guided.ref_landmarks.shape == (189, 2)
    # held-out identities are encoded through their landmarks too
    held = guided.reconstruct(guided.project(guided.encode(imgs[n:], pts[n:])))
    held_flow = flow.reconstruct(flow.project(flow.encode(imgs[n:])))
    assert np.mean([psnr(a, b) for a, b in zip(held, imgs[n:])]) > np.mean([psnr(a, b) for a, b in zip(held_flow, imgs[n:])])


def test_model_keeps_its_landmarks_through_save_and_load(london, tmp_path):
    from stimulus_engine.morphpca import load_model, save_model

    _, imgs, pts = london
    m = build_model(imgs[:3], landmarks=pts[:3], refine=False)
    back = load_model(save_model(m, tmp_path / "m.npz"))
    np.testing.assert_allclose(back.landmarks, m.landmarks)
    np.testing.assert_allclose(back.ref_landmarks, m.ref_landmarks)
    assert back.meta["landmark_refine"] is False
    with pytest.raises(AppealInputError, match="built with 189"):
        back.encode(imgs[3], pts[3][:68][None])


def test_cli_build_with_templates_reports_warp_and_holdout(shared_data, tmp_path):
    folder = shared_data / FRL / "neutral_front"
    files = [str(f) for f in sorted(folder.glob("*.jpg"))[:6]]
    assert main(["-q", "stimuli", "morphpca", "build", *files, "--keypoints", "tem", "--register", "--size", "120x100",
                 "--holdout", "2", "--out", str(tmp_path / "m"), "--json", str(tmp_path / "m.json")]) == 0
    m = json.loads((tmp_path / "m.json").read_text())
    assert m["warp"] == "guided" and m["train_psnr_db"] > 30 and "holdout_psnr_db" in m


def _copy_pair(shared_data, tmp_path, name="001_03"):
    src = shared_data / FRL / "neutral_front"
    for ext in (".jpg", ".tem"):
        shutil.copy(src / f"{name}{ext}", tmp_path / f"{name}{ext}")
    return tmp_path / f"{name}.jpg"


def _build(paths, tmp_path, capsys):
    rc = main(["stimuli", "morphpca", "build", *map(str, paths), "--keypoints", "tem", "--register",
               "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    return rc, err


def test_wrong_keypoint_files_give_one_line_errors(shared_data, tmp_path, capsys):
    a = _copy_pair(shared_data, tmp_path, "001_03")
    b = _copy_pair(shared_data, tmp_path, "002_03")
    tem_b = b.with_suffix(".tem")
    good = tem_b.read_text()
    lines = good.split("\n")

    # another template: 68 points where the first image has 189
    pts = read_tem(tem_b)[:68]
    tem_b.write_text("68\n" + "\n".join(f"{x}\t{y}" for x, y in pts) + "\n")
    rc, err = _build([a, b], tmp_path, capsys)
    assert rc != 0 and len(err.splitlines()) == 1 and "002_03.tem" in err and "189" in err, err

    # missing points: the count says 189, fewer follow
    tem_b.write_text("\n".join(lines[:100]) + "\n")
    rc, err = _build([a, b], tmp_path, capsys)
    assert rc != 0 and len(err.splitlines()) == 1 and "002_03.tem" in err, err

    # the template of an image of another size (twice as large)
    tem_b.write_text("189\n" + "\n".join(f"{2 * x}\t{2 * y}" for x, y in read_tem_text(good)) + "\n")
    rc, err = _build([a, b], tmp_path, capsys)
    assert rc != 0 and len(err.splitlines()) == 1 and "002_03.tem" in err and "outside" in err, err
    assert not (tmp_path / "out").exists()  # nothing half-written


def read_tem_text(text: str) -> np.ndarray:
    n = int(text.split("\n")[0])
    return np.array([[float(v) for v in line.split()[:2]] for line in text.split("\n")[1 : 1 + n]])

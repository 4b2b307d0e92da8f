"""SHINE-style equalisation (stimulus_engine.audit.equalise) and ``appeal stimuli equalise``."""

from __future__ import annotations

import doctest
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from appeal.errors import AppealInputError
from stimulus_engine.audit import equalise as E
from grid_fixtures import render_tiny_grid

H, W = 72, 96


def _synthetic(k: int, rng: np.random.Generator) -> np.ndarray:
    """A tinted gradient + stripes + noise; mean and contrast grow with k."""
    y, x = np.mgrid[0:H, 0:W]
    base = 60 + 40 * k + (x / W) * (50 + 30 * k) + 20 * np.sin(y / (5 + k))
    rgb = np.stack([base * (1 + 0.1 * k), base, base * 0.9], -1) + rng.normal(0, 8 + 6 * k, (H, W, 3))
    return np.clip(np.rint(rgb), 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def image_set() -> tuple[list[np.ndarray], list[np.ndarray]]:
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:H, 0:W]
    images = [_synthetic(k, rng) for k in range(3)]
    masks = [((xx - 48) / (30 + 3 * k)) ** 2 + ((yy - 36) / 28) ** 2 <= 1 for k in range(3)]
    return images, masks


def test_doctests():
    res = doctest.testmod(E)
    assert res.failed == 0 and res.attempted > 0


def test_grey_levels_round_trip_exactly():
    g = np.arange(256, dtype=np.uint8)
    assert np.array_equal(E.level_codes(E.grey_levels()), g)
    assert np.all(np.diff(E.grey_levels()) > 0)


@pytest.mark.parametrize("grey", [False, True])
def test_luminance_matching_sets_masked_mean_and_sd(image_set, grey):
    images, masks = image_set
    before = np.array([E.masked_stats(im, m) for im, m in zip(images, masks)])
    assert np.ptp(before[:, 0]) > 10 and np.ptp(before[:, 1]) > 2  # a set that needs matching
    out = E.match_luminance(images, masks, grey=grey)
    after = np.array([E.masked_stats(im, m) for im, m in zip(out, masks)])  # measured on the 8-bit output
    target = before.mean(axis=0)
    assert np.abs(after - target).max() < 0.5
    for im in out:  # the background is 50 % grey
        assert np.all(im[~masks[0] & ~masks[1] & ~masks[2]] == 128)


def test_luminance_matching_to_a_given_target(image_set):
    images, masks = image_set
    out = E.match_luminance(images, masks, target=(50.0, 10.0), background=None)
    for im, o, m in zip(images, out, masks):
        mean, sd = E.masked_stats(o, m)
        assert abs(mean - 50) < 0.5 and abs(sd - 10) < 0.5
        assert np.array_equal(o[~m], im[~m])  # background kept


def test_histogram_matching_is_exact_in_grey(image_set):
    """Tolerance: the normalised 8-bit level histograms of two images differ in no bin by a whole
    pixel of either (1/n_i + 1/n_j): the target counts n_i p_k are rounded to whole pixels."""
    images, masks = image_set
    assert E.histogram_mismatch(images, masks) > 10
    out = E.match_histogram(images, masks, grey=True)
    assert E.histogram_mismatch(out, masks) < 1.0
    for o in out:
        assert np.array_equal(o[..., 0], o[..., 1]) and np.array_equal(o[..., 0], o[..., 2])


def test_histogram_matching_equal_masks_gives_identical_histograms(image_set):
    images, masks = image_set
    same = [masks[0]] * 3
    out = E.match_histogram(images, same, grey=True)
    hists = [np.bincount(E.level_codes(E.lightness(o)[same[0]]), minlength=256) for o in out]
    # the counts differ only where the set's average n * p_k is not a whole number (3 images: thirds)
    assert max(np.abs(hists[0] - h).max() for h in hists) <= 1
    assert sum(np.abs(hists[0] - h).sum() for h in hists) < 0.05 * same[0].sum()


def test_histogram_matching_in_colour_is_close(image_set):
    """In colour the 8-bit rounding of R, G and B moves some pixels to a neighbouring level."""
    images, masks = image_set
    out = E.match_histogram(images, masks)
    assert E.histogram_mismatch(out, masks) < 8
    q = np.linspace(0.01, 0.99, 50)
    quantiles = np.array([np.quantile(E.lightness(o)[m], q) for o, m in zip(out, masks)])
    assert np.ptp(quantiles, axis=0).max() < 1.0  # L* units


@pytest.mark.parametrize("grey", [False, True])
def test_spectrum_matching_rotational_averages_agree(image_set, grey):
    images, masks = image_set
    assert E.spectrum_agreement(images) > 0.1
    out = E.match_spectrum(images, masks, grey=grey)
    assert E.spectrum_agreement(out) <= 0.01  # after background restore and 8-bit rounding
    for o in out:
        assert np.all(o[~masks[0] & ~masks[1] & ~masks[2]] == 128)


def test_ssim_is_one_when_already_matched(image_set):
    images, masks = image_set
    same = [images[0], images[0].copy()]
    out, ssims = E.equalise(same, [masks[0]] * 2, "luminance", background=None)
    assert np.array_equal(out[0], images[0]) and ssims == pytest.approx([1.0, 1.0])
    out, ssims = E.equalise(images, masks, "histogram")
    assert all(0 < s < 1 for s in ssims)


def test_one_line_errors(image_set):
    images, masks = image_set
    small = np.zeros((48, 64, 3), np.uint8)
    with pytest.raises(AppealInputError, match=r"^b.png: 64 x 48, expected 96 x 72 like a.png$"):
        E.check_set([images[0], small], [masks[0], np.ones((48, 64), bool)], names=["a.png", "b.png"])
    with pytest.raises(AppealInputError, match="at least 2 images"):
        E.match_luminance(images[:1], masks[:1])
    with pytest.raises(AppealInputError, match="image 2: the face mask is empty"):
        E.match_histogram(images[:2], [masks[0], np.zeros((H, W), bool)])
    for call in (lambda: E.equalise(images, masks, "blur"),):
        with pytest.raises(AppealInputError) as exc:
            call()
        assert len(exc.value.lines) == 1


# ------------------------------------------------------------------------------ the command
@pytest.fixture(scope="module")
def grid_dir(tmp_path_factory) -> Path:
    return render_tiny_grid(tmp_path_factory.mktemp("eqgrid"), "grid")


def test_cli_writes_equalised_images_and_manifest(grid_dir, tmp_path, capsys):
    from appeal_cli import main

    out = tmp_path / "eq"
    assert main(["stimuli", "equalise", str(grid_dir / "manifest.csv"), "--match", "histogram", "--grey",
                 "--out", str(out)]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert "4 images equalised" in line and "SSIM" in line and "min" in line
    before, after = pd.read_csv(grid_dir / "manifest.csv"), pd.read_csv(out / "manifest.csv")
    assert list(after.columns) == list(before.columns) + ["equalised", "ssim"]
    assert after["file"].tolist() == before["file"].tolist()
    pd.testing.assert_frame_equal(after[before.columns], before)
    assert set(after["equalised"]) == {"histogram (grey)"} and after["ssim"].between(0, 1, inclusive="neither").all()
    imgs = [np.asarray(Image.open(out / f).convert("RGB")) for f in after["file"]]
    bg_after = [np.all(im == 128, axis=2) for im in imgs]
    masks = [~b for b in bg_after]
    assert E.histogram_mismatch(imgs, masks) < 1.0
    assert not any(p.name.startswith(".equalise-") for p in out.iterdir())


def test_cli_errors_are_one_line_and_write_nothing(grid_dir, tmp_path, capsys):
    import shutil

    from appeal_cli import main

    bare = tmp_path / "bare"
    shutil.copytree(grid_dir / "images", bare / "images")
    shutil.copy(grid_dir / "manifest.csv", bare / "manifest.csv")
    out = tmp_path / "eq"
    shutil.copy(grid_dir / "grid.json", bare / "grid.json")
    first = pd.read_csv(bare / "manifest.csv")["file"][1]
    Image.fromarray(np.zeros((48, 64, 3), np.uint8)).save(bare / first)
    assert main(["stimuli", "equalise", str(bare / "manifest.csv"), "--match", "spectrum", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"{first}: 64 x 48, expected 96 x 72 like {pd.read_csv(bare / 'manifest.csv')['file'][0]}"]
    assert not out.exists()


def test_spectrum_matching_of_photographs_with_small_face_masks(shared_data):
    """Real photographs whose landmark-hull masks are a tenth of the picture: the over-relaxed
    sfMatch passes leave them 2 % apart; the preconditioned polish brings them within 1 %."""
    from stimulus_engine.audit.masks import find_landmarks, landmark_face_mask

    files = sorted((shared_data / "faces2d" / "london-frl" / "neutral_front").glob("*.jpg"))[:4]
    images, masks = [], []
    for f in files:
        im = np.asarray(Image.open(f).convert("RGB").resize((450, 450), Image.LANCZOS))
        m = landmark_face_mask(im.shape, find_landmarks(im, f.name))
        images.append(np.where(m[..., None], im, 128).astype(np.uint8))
        masks.append(m)
    assert all(0.05 < m.mean() < 0.15 for m in masks)
    passes = E.match_spectrum(images, masks, grey=True, polish_iterations=0)
    assert E.spectrum_agreement(passes) > 0.01
    out = E.match_spectrum(images, masks, grey=True)
    assert E.spectrum_agreement(out) <= 0.01
    for o, im, m in zip(out, images, masks):
        assert np.all(o[~m] == 128) and E.ssim_lightness(im, o) > 0.95


def test_cli_equalises_photographs_inside_their_landmark_masks(shared_data, tmp_path):
    """A folder of photographs (no grid.json): the faces' masks come from their dlib landmarks."""
    from appeal_cli import main

    folder = tmp_path / "photos"
    folder.mkdir()
    files = sorted((shared_data / "faces2d" / "london-frl" / "neutral_front").glob("*.jpg"))[:3]
    for f in files:
        Image.open(f).convert("RGB").resize((400, 400), Image.LANCZOS).save(folder / f"{f.stem}.png")
    pd.DataFrame({"file": [f"{f.stem}.png" for f in files], "face_id": [f.stem for f in files]}).to_csv(
        folder / "manifest.csv", index=False)
    out = tmp_path / "eq"
    assert main(["stimuli", "equalise", str(folder / "manifest.csv"), "--match", "spectrum", "--grey",
                 "--out", str(out)]) == 0
    result = pd.read_csv(out / "manifest.csv")
    # SSIM to the originals, whose backgrounds became grey: what the matching cost
    assert result["face_id"].tolist() == [f.stem for f in files] and result["ssim"].between(0.3, 1).all()
    images = [np.asarray(Image.open(out / f).convert("RGB")) for f in result["file"]]
    assert E.spectrum_agreement(images) <= 0.01
    assert all(np.mean(np.all(im == 128, axis=2)) > 0.8 for im in images)  # grey outside the faces
    assert json.loads((out / "provenance.json").read_text())["face_masks"] == "landmarks"


def test_cli_matches_faces_and_images_without_a_face(shared_data, tmp_path, capsys):
    """Photographs and objects (no face: matched as whole images, listed in one warning line); with
    --region image every image as a whole. Luminance matching gives every mask the same mean and SD."""
    from skimage import data as skdata

    from appeal_cli import main

    folder = tmp_path / "n170"
    folder.mkdir()
    rows = []
    for f in sorted((shared_data / "faces2d" / "london-frl" / "neutral_front").glob("*.jpg"))[:2]:
        Image.open(f).convert("RGB").resize((400, 400), Image.LANCZOS).save(folder / f"{f.stem}.png")
        rows.append({"file": f"{f.stem}.png", "category": "face"})
    for name in ("coffee", "chelsea"):
        Image.fromarray(getattr(skdata, name)()).resize((400, 400), Image.LANCZOS).save(folder / f"{name}.png")
        rows.append({"file": f"{name}.png", "category": "object"})
    pd.DataFrame(rows).to_csv(folder / "manifest.csv", index=False)
    for region in ("face", "image"):
        out = tmp_path / f"eq_{region}"
        assert main(["stimuli", "equalise", str(folder / "manifest.csv"), "--match", "luminance", "--grey",
                     "--region", region, "--out", str(out)]) == 0
        warned = [line for line in capsys.readouterr().err.splitlines() if "without a face" in line]
        assert (warned and "2 of 4" in warned[0] and "coffee.png, chelsea.png" in warned[0]) if region == "face" \
            else not warned
        images = [np.asarray(Image.open(out / r["file"]).convert("RGB")) for r in rows]
        if region == "face":
            from stimulus_engine.audit.masks import find_landmarks, landmark_face_mask

            originals = [np.asarray(Image.open(folder / r["file"]).convert("RGB")) for r in rows]
            masks = [landmark_face_mask(o.shape, find_landmarks(o, "face")) for o in originals[:2]]
            masks += [np.ones((400, 400), bool)] * 2
            assert all(np.mean(np.all(im == 128, axis=2)) > 0.8 for im in images[:2])  # grey around the faces
        else:
            masks = [np.ones((400, 400), bool)] * 4
        stats = np.array([E.masked_stats(im, m) for im, m in zip(images, masks)])
        # equal within 8-bit rounding and what clips at black or white (the audit flags 2 L*, 0.02 contrast)
        assert np.ptp(stats[:, 0]) < 0.3 and np.ptp(stats[:, 1]) < 1.0, stats
        face_masks = json.loads((out / "provenance.json").read_text())["face_masks"]
        assert face_masks == ("landmarks, 2 whole images" if region == "face" else "whole images")

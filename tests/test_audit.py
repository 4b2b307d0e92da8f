"""The stimulus audit (``appeal stimuli audit``): measures against hand-computed values on
synthetic images, the manifest workflow on a tiny rendered grid, real photographs, one-line errors."""

from __future__ import annotations

import doctest
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from appeal.errors import AppealInputError
from appeal_cli import main
from stimulus_engine.audit import masks as M
from stimulus_engine.audit import measures as X
from stimulus_engine.audit.workflow import FACTOR_COLUMNS, audit_factors, audit_manifest, read_audit_inputs
from grid_fixtures import render_tiny_grid

def _srgb_lightness(v: int) -> float:
    """L* of the grey sRGB level ``v`` by hand: linearise, Y = linear value, L* = 116 Y^(1/3) - 16."""
    c = v / 255
    lin = c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4
    return 116 * lin ** (1 / 3) - 16 if lin > (6 / 29) ** 3 else lin * (29 / 3) ** 3


def _power_noise(alpha: float, h: int = 256, w: int = 256, seed: int = 0) -> np.ndarray:
    """Noise whose amplitude spectrum falls as f^-alpha (random phases, flat within each ring)."""
    f = X.radial_frequency(h, w)
    f[0, 0] = 1.0
    amp = f ** -alpha
    amp[0, 0] = 0.0
    spec = np.fft.fft2(np.random.default_rng(seed).standard_normal((h, w)))
    return np.real(np.fft.ifft2(amp * spec / np.abs(spec)))


# ------------------------------------------------------------------------------ the measures
def test_doctests_of_the_audit_modules():
    res = doctest.testmod(X)
    assert res.failed == 0 and res.attempted >= 3


@pytest.mark.parametrize("level", [0, 60, 128, 200, 255])
def test_uniform_grey_has_its_hand_computed_lightness_and_no_contrast(level):
    lab = X.lab_image(np.full((16, 20, 3), level, np.uint8))
    s = X.colour_stats(lab, np.ones((16, 20), bool))
    assert s["L_mean"] == pytest.approx(_srgb_lightness(level), abs=0.02)
    assert abs(s["a_mean"]) < 0.01 and abs(s["b_mean"]) < 0.01
    assert s["rms_contrast"] == pytest.approx(0.0, abs=1e-9)
    assert X.edge_density(lab[..., 0] / 100, np.ones((16, 20), bool)) == 0.0


def test_two_level_image_has_the_rms_contrast_of_its_two_lightnesses():
    img = np.zeros((10, 10, 3), np.uint8)
    img[:, :5] = 60
    img[:, 5:] = 200
    lo, hi = _srgb_lightness(60), _srgb_lightness(200)
    s = X.colour_stats(X.lab_image(img), np.ones((10, 10), bool))
    assert s["L_mean"] == pytest.approx((lo + hi) / 2, abs=0.02)
    assert s["rms_contrast"] == pytest.approx((hi - lo) / 2 / 100, abs=2e-4)  # two equal halves: sd = half the step
    # a quarter of white: sd of a Bernoulli(1/4) scaled by the step
    img[:, :] = 0
    img[:5, :5] = 255
    s = X.colour_stats(X.lab_image(img), np.ones((10, 10), bool))
    assert s["rms_contrast"] == pytest.approx(np.sqrt(0.25 * 0.75), abs=1e-6)
    # the mask decides: only the white quarter is uniform
    assert X.colour_stats(X.lab_image(img), img[..., 0] > 0)["rms_contrast"] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("alpha", [1.0, 2.0])
@pytest.mark.parametrize("shape", [(256, 256), (192, 256)])
def test_spectrum_slope_recovers_the_exponent_of_power_law_noise(alpha, shape):
    assert X.spectrum_slope(_power_noise(alpha, *shape)) == pytest.approx(-alpha, abs=0.1)


@pytest.mark.parametrize("cycles, band", [(4, "low"), (16, "mid"), (45, "high")])
def test_a_grating_puts_its_energy_in_its_band(cycles, band):
    x = np.arange(128)
    grating = np.tile(np.sin(2 * np.pi * cycles * x / 128), (128, 1))
    shares = X.band_energy(grating)
    assert sum(shares.values()) == pytest.approx(1.0)
    assert shares[band] > 0.97  # the Hann window spreads the line over about +-2 cycles/image


def test_rotational_average_rings_are_one_cycle_per_image():
    f, a = X.rotational_average(np.ones((64, 96)))
    assert f[0] == 1 and f[-1] == 32 and np.allclose(a, 1.0)


def test_edge_density_of_stripes_and_a_checkerboard():
    """Canny marks a step between two pixels on both of them: two edge pixels per boundary."""
    y, x = np.mgrid[0:128, 0:128]
    whole = np.ones((128, 128), bool)
    stripes = ((x // 8) % 2).astype(float)  # 15 vertical boundaries
    assert X.edge_density(stripes, whole) == pytest.approx(15 * 2 / 128, abs=0.01)
    board = (((y // 8) + (x // 8)) % 2).astype(float)
    band = np.zeros_like(whole)  # pixels with a 4-neighbour of the other colour
    band[:, 1:] |= board[:, 1:] != board[:, :-1]
    band[:, :-1] |= board[:, 1:] != board[:, :-1]
    band[1:, :] |= board[1:, :] != board[:-1, :]
    band[:-1, :] |= board[1:, :] != board[:-1, :]
    assert X.edge_density(board, whole) == pytest.approx(band.mean(), abs=0.03)
    on_band = X.edge_density(board, band) * band.sum() / (X.edge_density(board, whole) * whole.sum())
    assert on_band > 0.85  # most edge pixels lie on the boundaries (the rest: diagonals at the corners)
    assert X.edge_density(board, np.zeros_like(whole)) != X.edge_density(board, np.zeros_like(whole))  # NaN


def test_masks_oval_background_hull_and_area():
    oval = M.oval_mask(200, 300, (150, 100, 60, 80))
    assert X.face_area(oval) == pytest.approx(np.pi * 60 * 80 / (200 * 300), rel=0.01)
    img = np.full((4, 4, 3), 128, np.uint8)
    img[0, 0] = (131, 126, 128)
    img[1, 1] = (140, 128, 128)
    bg = M.background_mask(img, (0.5, 0.5, 0.5))
    assert bg[0, 0] and not bg[1, 1] and bg.sum() == 15
    hull = M.landmark_face_mask((50, 50), np.array([[10, 10], [40, 10], [40, 40], [10, 40], [25, 25]]))
    assert hull.sum() == pytest.approx(31 * 31, rel=0.05) and not hull[5, 5] and hull[25, 25]
    assert X.face_area(M.whole_image_mask((7, 9, 3))) == 1.0


# ------------------------------------------------------------------------------ the workflow
@pytest.fixture(scope="module")
def grid_dir(tmp_path_factory) -> Path:
    """The tiny still grid rendered once (pyrender, 96 x 72)."""
    return render_tiny_grid(tmp_path_factory.mktemp("audit"))


def test_a_rendered_grid_gives_a_row_per_image_with_its_factors(grid_dir, tmp_path):
    manifest = pd.read_csv(grid_dir / "manifest.csv")
    table = audit_manifest(grid_dir / "manifest.csv")
    assert len(table) == len(manifest) == 4
    assert list(table["file"]) == list(manifest["file"])
    for c in ("character", "shape", "material", "expression", "lighting", "shading"):
        assert list(table[c]) == list(manifest[c])
    assert set(table["mask"]) == {"rendered"}
    assert table["face_area"].between(0.02, 0.6).all()
    assert (table["face_L_mean"] != table["image_L_mean"]).all()
    assert table["image_L_mean"].between(30, 70).all() and table["spectrum_slope"].between(-3, -0.3).all()
    assert np.allclose(table[["energy_low", "energy_mid", "energy_high"]].sum(axis=1), 1.0)
    assert audit_factors(table) == ["shape", "expression"]
    # the CLI: audit.csv and the figure
    rc = main(["stimuli", "audit", str(grid_dir), "--out", str(tmp_path / "out")])
    assert rc == 0
    written = pd.read_csv(tmp_path / "out" / "audit.csv")
    assert len(written) == 4 and {"face_rms_contrast", "image_L_mean", "spectrum_slope", "iod_px"} <= set(written)
    with Image.open(tmp_path / "out" / "audit.png") as im:
        assert im.size[0] > 300 and im.size[1] > 600


def test_rendered_face_mask_is_the_oval_minus_background(grid_dir):
    import json

    render = json.loads((grid_dir / "grid.json").read_text())["render"]
    with Image.open(next((grid_dir / "images").glob("*.png"))) as im:
        rgb = np.asarray(im.convert("RGB"))
    mask = M.rendered_face_mask(rgb, render["width"], render["height"], render["eye_row"], render["face_fraction"],
                                tuple(render["background"]))
    assert mask.any() and not M.background_mask(rgb, render["background"])[mask].any()
    assert not mask[:, :10].any() and not mask[:, -10:].any()  # the oval is narrower than the picture


def test_photographs_get_landmark_masks_and_eye_positions(tmp_path, shared_data):
    photos = shared_data / "faces2d" / "london-frl" / "neutral_front"
    for name in ("001_03.jpg", "002_03.jpg"):
        shutil.copy(photos / name, tmp_path / name)
    table = audit_manifest(tmp_path)
    assert list(table["file"]) == ["001_03.jpg", "002_03.jpg"] and set(table["mask"]) == {"landmarks"}
    assert table["face_area"].between(0.03, 0.5).all()
    assert (table["eye_left_x"] < table["eye_right_x"]).all()
    assert (abs(table["eye_left_y"] - table["eye_right_y"]) < 0.1 * table["iod_px"]).all()  # frontal, level eyes
    assert table["iod_px"].between(0.1 * 1350, 0.3 * 1350).all()
    assert set(audit_factors(table)) == {"file"} and not set(FACTOR_COLUMNS) & set(table.columns)


# ------------------------------------------------------------------------------ bad input
def _one_line_error(args: list[str], capsys) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


def test_bad_inputs_are_one_line_errors(grid_dir, tmp_path, capsys):
    broken = tmp_path / "broken"
    broken.mkdir()
    pd.read_csv(grid_dir / "manifest.csv").to_csv(broken / "manifest.csv", index=False)  # no images beside it
    err = _one_line_error(["stimuli", "audit", str(broken / "manifest.csv"), "--out", str(tmp_path / "o1")], capsys)
    assert "4 of 4 images missing" in err and not (tmp_path / "o1").exists()
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("no images")
    err = _one_line_error(["stimuli", "audit", str(empty), "--out", str(tmp_path / "o2")], capsys)
    assert "no images" in err
    faceless = tmp_path / "faceless"
    faceless.mkdir()
    Image.fromarray(np.full((120, 160, 3), 128, np.uint8)).save(faceless / "grey.png")
    err = _one_line_error(["stimuli", "audit", str(faceless), "--out", str(tmp_path / "o3")], capsys)
    assert "grey.png" in err and "no face" in err and not (tmp_path / "o3").exists()
    with pytest.raises(AppealInputError, match="not found"):
        read_audit_inputs(tmp_path / "nothing.csv")
    (tmp_path / "plain.csv").write_text("a,b\n1,2\n")
    with pytest.raises(AppealInputError, match="no 'file' column"):
        read_audit_inputs(tmp_path / "plain.csv")

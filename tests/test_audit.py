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


# ------------------------------------------------------------------------------ images without a face
def _grey_png(lstar: np.ndarray, path: Path) -> None:
    """An L* image (0..100) written as the grey sRGB PNG nearest it."""
    from stimulus_engine.audit.equalise import level_codes

    code = level_codes(np.clip(lstar, 0, 100)).astype(np.uint8)
    Image.fromarray(np.repeat(code[..., None], 3, axis=2)).save(path)


def _noise_folder(folder: Path, alphas: list[float]) -> None:
    folder.mkdir()
    for i, alpha in enumerate(alphas):
        z = _power_noise(alpha, 256, 256, seed=i)
        _grey_png(50 + 12 * z / z.std(), folder / f"noise_{alpha:.1f}.png")


def test_audit_of_noise_images_recovers_their_spectrum_slopes(tmp_path, capsys):
    """1/f^alpha noise images (no face): whole-image measures, NaN face measures, one warning line
    naming them, the tables and figures written; the slopes come back within 0.1."""
    alphas = [0.6, 1.0, 1.4, 1.8, 2.0]  # steeper spectra flatten at 8 bits (quantisation noise is white)
    _noise_folder(tmp_path / "noise", alphas)
    out = tmp_path / "audit"
    assert main(["stimuli", "audit", str(tmp_path / "noise"), "--out", str(out)]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "without a face" in line]
    assert len(err) == 1 and "5 of 5 images" in err[0] and "noise_0.6.png" in err[0] and "noise_2.0.png" in err[0]
    table = pd.read_csv(out / "audit.csv").set_index("file")
    for alpha in alphas:
        assert table.loc[f"noise_{alpha:.1f}.png", "spectrum_slope"] == pytest.approx(-alpha, abs=0.1)
    assert set(table["mask"]) == {"none"} and table["warning"].str.contains("no face").all()
    face_cols = [c for c in table.columns if c.startswith("face_")] + ["eye_left_x", "iod_px"]
    assert table[face_cols].isna().all().all() and table["image_L_mean"].between(45, 55).all()
    assert table["image_rms_contrast"].between(0.08, 0.16).all()
    assert (out / "audit.png").stat().st_size > 10_000 and (out / "report.html").is_file()


def _phase_scrambled(rgb: np.ndarray, seed: int) -> np.ndarray:
    """The image's L* with its Fourier phases replaced by those of white noise: the same amplitude
    spectrum, no face (the N170 studies' scrambled control)."""
    from stimulus_engine.audit.equalise import lightness

    lstar = lightness(rgb)
    noise = np.fft.fft2(np.random.default_rng(seed).standard_normal(lstar.shape))
    spec = np.fft.fft2(lstar - lstar.mean())
    out = np.real(np.fft.ifft2(np.abs(spec) * np.exp(1j * np.angle(noise)))) + lstar.mean()
    return out


def test_faces_and_their_controls_are_tested_against_each_other(tmp_path, shared_data, capsys):
    """A manifest of London photographs, their phase-scrambled versions and skimage's photographs
    of objects: ``category`` is a factor, each image an item; faces keep their face measures."""
    from skimage import data as skdata

    from stimulus_engine.audit.equalise import lightness

    photos = shared_data / "faces2d" / "london-frl" / "neutral_front"
    rows = []
    for i, name in enumerate(("001_03.jpg", "002_03.jpg", "003_03.jpg")):
        rgb = np.asarray(Image.open(photos / name).convert("RGB").resize((450, 450)))
        Image.fromarray(rgb).save(tmp_path / f"face_{i}.png")
        _grey_png(_phase_scrambled(rgb, i), tmp_path / f"scrambled_{i}.png")
        rows += [{"file": f"face_{i}.png", "category": "face"}, {"file": f"scrambled_{i}.png", "category": "scrambled"}]
    for name in ("coffee", "rocket", "chelsea"):
        Image.fromarray(getattr(skdata, name)()).save(tmp_path / f"object_{name}.png")
        rows.append({"file": f"object_{name}.png", "category": "object"})
    pd.DataFrame(rows).to_csv(tmp_path / "n170.csv", index=False)
    out = tmp_path / "audit"
    assert main(["stimuli", "audit", str(tmp_path / "n170.csv"), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "6 of 9 images without a face" in err and "face_0.png" not in err.split("without a face")[1]
    table = pd.read_csv(out / "audit.csv")
    faces = table["category"] == "face"
    assert set(table.loc[faces, "mask"]) == {"landmarks"} and table.loc[faces, "face_L_mean"].notna().all()
    assert table.loc[~faces, "face_L_mean"].isna().all() and table["image_L_mean"].notna().all()
    # scrambling keeps the mean L* (and the unwindowed amplitude spectrum; the audit's slope is of the
    # Hann-windowed image, whose scrambled version differs by up to ~0.1)
    by_file = table.set_index("file")
    for i in range(3):
        face, scrambled = by_file.loc[f"face_{i}.png"], by_file.loc[f"scrambled_{i}.png"]
        assert scrambled["image_L_mean"] == pytest.approx(face["image_L_mean"], abs=2.0)  # less what clips at white
    assert table["spectrum_slope"].between(-2.2, -0.6).all()
    assert lightness(np.asarray(Image.open(tmp_path / "scrambled_0.png"))).std() > 5
    tests = pd.read_csv(out / "design_tests.csv").set_index(["factor", "measure"])
    row = tests.loc[("category", "image_L_mean")]
    assert row["test"] == "one-way ANOVA between 9 items" and (row["num_df"], row["den_df"]) == (2, 6)
    assert tests.loc[("category", "face_L_mean"), "test"] == "none: one level has this measure"
    assert set(pd.read_csv(out / "level_means.csv")["level"]) == {"face", "scrambled", "object"}
    assert (out / "flags.png").is_file() and "category" in (out / "report.md").read_text()


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
    (empty / "broken.png").write_bytes(b"not a PNG")
    err = _one_line_error(["stimuli", "audit", str(empty), "--out", str(tmp_path / "o3")], capsys)
    assert "broken.png" in err and "not a readable image" in err and not (tmp_path / "o3").exists()
    with pytest.raises(AppealInputError, match="not found"):
        read_audit_inputs(tmp_path / "nothing.csv")
    (tmp_path / "plain.csv").write_text("a,b\n1,2\n")
    with pytest.raises(AppealInputError, match="no 'file' column"):
        read_audit_inputs(tmp_path / "plain.csv")

"""Fine skin detail where a scan's texture lacks it (stimulus_engine.characters.skin_detail)."""

from __future__ import annotations

import numpy as np
import pytest

from stimulus_engine.characters.skin_detail import DETAIL_TARGET, fine_detail, skin_mottle, with_skin_detail


def _plane(size: int = 256, extent: float = 12.0):
    """A flat skin patch ``extent`` wide (eyes 6 apart: two eye distances) as texel points."""
    u = (np.arange(size) + 0.5) / size * extent
    xx, yy = np.meshgrid(u, u[::-1])
    pts = np.dstack([xx, yy, np.zeros_like(xx)])
    return pts, np.ones((size, size), bool), 6.0


def test_a_flat_texture_gets_detail_up_to_the_target_on_its_skin_only():
    pts, valid, iod = _plane()
    albedo = np.full((*valid.shape, 3), (200, 150, 130), np.uint8)
    skin = np.ones(valid.shape)
    skin[:, :40] = 0.0  # e.g. the lips or brows: not skin
    assert fine_detail(albedo, pts, valid, skin, iod) < 1e-9
    out = with_skin_detail(albedo, pts, valid, skin, iod)
    assert abs(fine_detail(out, pts, valid, skin, iod) - DETAIL_TARGET) < 0.15 * DETAIL_TARGET
    assert np.array_equal(out[:, :30], albedo[:, :30])  # nothing added off the skin
    mean_change = np.abs(out[:, 60:].astype(float).mean(axis=(0, 1)) - albedo[0, 0]).max()
    assert mean_change < 4  # a mottle about the colour, not a shift of it


def test_a_texture_with_enough_detail_is_left_as_it_is():
    pts, valid, iod = _plane()
    rng = np.random.default_rng(0)
    albedo = np.clip(rng.normal(150, 30, (*valid.shape, 3)), 0, 255).astype(np.uint8)
    skin = np.ones(valid.shape)
    assert fine_detail(albedo, pts, valid, skin, iod) > DETAIL_TARGET
    assert np.array_equal(with_skin_detail(albedo, pts, valid, skin, iod), albedo)


def _axis_power(field: np.ndarray) -> float:
    """Mean spectral power within 3 degrees of the image axes over that between 10 and 80 degrees
    (about 1 for an isotropic texture; above it where a square lattice shows)."""
    power = np.abs(np.fft.fftshift(np.fft.fft2(field - field.mean()))) ** 2
    n = field.shape[0]
    y, x = np.mgrid[0:n, 0:n] - n // 2
    r, angle = np.hypot(x, y), np.degrees(np.arctan2(y, x)) % 90
    band = (r > 4) & (r < n // 2 - 2)
    return float(power[band & ((angle < 3) | (angle > 87))].mean() / power[band & (angle > 10) & (angle < 80)].mean())


def test_the_mottle_has_no_lattice():
    """Dots of value noise on one lattice line up along its axes (rows of pores across a cheek);
    the mottle's octaves on turned lattices do not."""
    from stimulus_engine.characters.procedural_head import value_noise3
    from stimulus_engine.characters.skin_detail import MOTTLE_CELLS

    pts, valid, iod = _plane(256, extent=3.0)
    flat = pts.reshape(-1, 3)
    mottle = skin_mottle(flat, iod).reshape(valid.shape)
    assert _axis_power(mottle) < 1.2
    for cell in MOTTLE_CELLS:  # measured 1.6-1.7
        dots = np.clip((value_noise3(flat, cell * iod, 0) - 0.55) / 0.3, 0, 1).reshape(valid.shape)
        assert _axis_power(dots) > 1.4


@pytest.mark.slow
def test_lee_perry_smiths_texture_carries_a_photographs_detail(shared_data, tmp_path):
    """His re-laid 1024-texel JPEG texture (fine detail 0.032) is brought up to the target, the
    lips, brows and hair left as they are; ``skin_detail: false`` keeps it as re-laid."""
    from stimulus_engine.characters.scan_regions import skin_texels
    from stimulus_engine.characters.skin_maps import bake_surface_points
    from stimulus_engine.grid.characters import character_albedo, load_character
    from stimulus_engine.grid.schema import CharacterSpec

    d = shared_data / "meshes"
    mesh = {"file": d / "leeperrysmith" / "LeePerrySmith.obj", "region": "front"}
    plain = load_character(CharacterSpec(name="lps", ict=d / "ict-facekit", mesh={**mesh, "skin_detail": False}),
                           tmp_path / ".cache", "g.yaml")
    kept, masks = character_albedo(plain, "g.yaml", tmp_path / ".cache")
    assert np.array_equal(kept, plain.rig.texture)
    ch = load_character(CharacterSpec(name="lps", ict=d / "ict-facekit", mesh=mesh), tmp_path / ".cache", "g.yaml")
    detailed, _ = character_albedo(ch, "g.yaml", tmp_path / ".cache")
    pts, valid = bake_surface_points(ch.rig, detailed.shape[0])
    lm = ch.rig.landmark_points()
    iod = float(np.linalg.norm(lm["pupil_left"] - lm["pupil_right"]))
    skin = skin_texels(masks, detailed.shape)
    before, after = (fine_detail(a, pts, valid, skin, iod) for a in (kept, detailed))
    assert before < 0.7 * DETAIL_TARGET and abs(after - DETAIL_TARGET) < 0.1 * DETAIL_TARGET, (before, after)
    lips = masks["lips"] > 0.99
    assert np.abs(detailed[lips].astype(int) - kept[lips].astype(int)).max() <= 1

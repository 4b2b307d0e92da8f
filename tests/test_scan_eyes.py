"""Eyes for scans: lid contours, openings cut along them, eyeballs behind the lids."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from stimulus_engine.parts.eyes import eyeball_asset, tint_iris
from stimulus_engine.characters.scan_eyes import PAINTED_IRIS_LEAST
from stimulus_engine.characters.scan_eyes import (
    CLOSED_RATIO, EYEBALL_RATIO, cut_openings, eye_geometry, lid_contour, openness,
)


def _eye_points(cx: float, half_width: float = 1.5, half_height: float = 0.5, z: float = 0.0) -> np.ndarray:
    """Six iBUG-ordered points of an almond eye: corner, two upper, corner, two lower."""
    w, h = half_width, half_height
    return np.array([[cx - w, 0, z], [cx - w / 3, h, z], [cx + w / 3, h, z], [cx + w, 0, z],
                     [cx + w / 3, -h, z], [cx - w / 3, -h, z]])


def _sheet(n: int = 120, size: float = 12.0) -> trimesh.Trimesh:
    """A finely tessellated, slightly domed sheet facing +z (a stand-in for a face's skin)."""
    g = np.linspace(-size / 2, size / 2, n)
    x, y = np.meshgrid(g, g)
    v = np.column_stack([x.ravel(), y.ravel(), 0.02 * (size**2 / 4 - x.ravel() ** 2 - y.ravel() ** 2) / size])
    i = np.arange(n * n).reshape(n, n)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel()
    return trimesh.Trimesh(v, np.vstack([np.column_stack([a, b, d]), np.column_stack([a, d, c])]), process=False)


def test_lid_contour_passes_through_the_six_points_and_keeps_sharp_corners():
    p = _eye_points(0.0)
    c = lid_contour(p, n=8)
    assert c.shape == (48, 3)
    # the curve starts each span at its point: corner, upper points, corner, lower points
    np.testing.assert_allclose(c[[0, 8, 16, 24, 32, 40]], p[[0, 1, 2, 3, 4, 5]], atol=1e-12)
    assert c[1:24, 1].min() >= -1e-9 and c[25:48, 1].max() <= 1e-9  # upper arc above, lower below


def test_openness_tells_open_from_closed_eyes():
    assert openness(_eye_points(0.0, 1.5, 0.5)) == pytest.approx(1.0 / 3.0)
    assert openness(_eye_points(0.0, 1.5, 0.05)) < CLOSED_RATIO


def test_cut_openings_follow_the_contour_without_folds():
    sheet = _sheet()
    contour = lid_contour(_eye_points(-2.5) + [0, 0, 0.1])
    keep, v = cut_openings(sheet.vertices, sheet.faces, [contour], reach=4.0)
    assert 0 < (~keep).sum() < 0.05 * len(keep)
    from stimulus_engine.geometry.polyline2d import inside_polygon as _inside

    kept = sheet.faces[keep]
    assert not _inside(v[kept].mean(axis=1)[:, :2], contour[:, :2]).any()  # nothing kept inside the lids
    # the opening's rim lies on the contour: every hole-boundary vertex is within 1e-9 of it
    m = trimesh.Trimesh(v, kept, process=False)
    edges = m.edges_sorted
    boundary = np.unique(edges[trimesh.grouping.group_rows(edges, require_count=1)])
    rim = boundary[np.linalg.norm(v[boundary, :2] - contour[:, :2].mean(axis=0), axis=1) < 3.0]
    seg = np.linspace(0, 1, 2001)[:, None, None]
    dense = (contour[None] * (1 - seg) + np.roll(contour, -1, axis=0)[None] * seg).reshape(-1, 3)[:, :2]
    d = np.min(np.linalg.norm(v[rim, None, :2] - dense[None], axis=2), axis=1)
    assert len(rim) >= 20 and d.max() < 2e-3
    assert (m.face_normals[:, 2] > 0).all()  # no triangle folded over by moving the rim
    far = np.linalg.norm(sheet.vertices[:, :2] - [-2.5, 0], axis=1) > 3.0
    np.testing.assert_array_equal(v[far], sheet.vertices[far])  # the rest of the sheet untouched


def test_eye_geometry_puts_anatomical_balls_behind_the_lids():
    sheet = _sheet()
    pts = np.vstack([_eye_points(-3.15), _eye_points(3.15)])
    lift = sheet.vertices[:, 2].max()
    eyes = eye_geometry(sheet.vertices, sheet.faces, pts + [0, 0, lift])
    assert len(eyes.balls) == 2 and len(eyes.sockets) == 2
    centres = [b.mean(axis=0) for b in eyes.balls]
    assert centres[0][0] < 0 < centres[1][0]  # the subject's right eye (-x) first
    for ball, p in zip(eyes.balls, pts.reshape(2, 6, 3)):
        from stimulus_engine.parts.eyes import fit_sphere

        c, r = fit_sphere(ball)
        assert r == pytest.approx(EYEBALL_RATIO * 6.3, rel=0.05)
        assert abs(c[0] - p[:, 0].mean()) < 0.05 and abs(c[1]) < 0.05  # centred behind the opening
        assert c[2] < lift - 0.5 * r
    # outside the openings no part of a ball comes through the skin
    from scipy.interpolate import LinearNDInterpolator

    from stimulus_engine.geometry.polyline2d import inside_polygon as _inside

    skin = LinearNDInterpolator(eyes.vertices[:, :2], eyes.vertices[:, 2])
    for ball, p in zip(eyes.balls, pts.reshape(2, 6, 3)):
        out = ~_inside(ball[:, :2], lid_contour(p)[:, :2])
        assert (ball[out, 2] < skin(ball[out, :2])).all()


def test_closed_eyes_are_refused_with_what_to_do():
    sheet = _sheet(40)
    pts = np.vstack([_eye_points(-3.15, 1.5, 0.05), _eye_points(3.15, 1.5, 0.05)])
    with pytest.raises(ValueError, match="closed.*eyes: scan"):
        eye_geometry(sheet.vertices, sheet.faces, pts)


def test_tint_iris_recolours_the_iris_only():
    _, tex = eyeball_asset()
    blue = tint_iris(tex, np.array([60.0, 90.0, 130.0]))
    changed = np.any(blue != tex, axis=-1)
    assert 0.02 < changed.mean() < 0.3  # the iris disks, not the sclera
    assert blue[changed][:, 2].mean() > blue[changed][:, 0].mean()  # now bluish
    assert tex[changed][:, 0].mean() > tex[changed][:, 2].mean()  # was brown


def test_a_dark_painted_iris_is_lifted_to_a_photographed_brown():
    """james's painted iris (mean grey about 50, read off his shaded scan) rendered as a black
    disc; with ``least`` the colour is lifted, hue kept, and a lighter one is left alone."""
    _, tex = eyeball_asset()
    dark = np.array([58.0, 48.0, 44.0])
    plain, lifted = tint_iris(tex, dark), tint_iris(tex, dark, least=PAINTED_IRIS_LEAST)
    iris = np.any(plain != tex, axis=-1)
    ratio = lifted[iris].astype(float).mean(axis=0) / np.maximum(plain[iris].astype(float).mean(axis=0), 1)
    assert np.all(ratio > 1.25) and np.ptp(ratio) < 0.06  # brighter by one factor: the same hue
    light = np.array([120.0, 100.0, 80.0])
    assert np.array_equal(tint_iris(tex, light), tint_iris(tex, light, least=PAINTED_IRIS_LEAST))


def _lip_points(gap: float) -> np.ndarray:
    """iBUG 60-67 of a mouth 5 wide at y = -3: corner, three upper, corner, three lower."""
    x = np.array([-2.5, -1.0, 0.0, 1.0, 2.5, 1.0, 0.0, -1.0])
    bulge = np.array([0, 1, 1, 1, 0, 1, 1, 1]) * gap / 2
    y = -3 + np.where(np.arange(8) < 5, bulge, -bulge)
    return np.column_stack([x, y, np.full(8, 0.5)])


@pytest.mark.parametrize("gap", [0.0, 0.2, 1.2])
def test_cut_lips_separates_upper_from_lower(gap):
    from stimulus_engine.characters.scan_mouth import CLOSED_GAP, cut_lips, lip_arcs

    sheet = _sheet()
    pts = _lip_points(gap)
    keep, v, side = cut_lips(sheet.vertices, sheet.faces, pts)
    kept = sheet.faces[keep]
    s = side[kept]
    assert not ((s == 1).any(axis=1) & (s == -1).any(axis=1)).any()  # no triangle spans the lip line
    assert (side == 1).sum() > 50 and (side == -1).sum() > 50
    assert (trimesh.Trimesh(v, kept, process=False).face_normals[:, 2] > 0).all()
    rim_up = np.unique(kept[(s == 1).any(axis=1)])
    rim_up = rim_up[(side[rim_up] == 1) & ~np.isin(rim_up, sheet.faces[keep & (side[sheet.faces] != 1).any(axis=1)].ravel())]
    upper, lower = lip_arcs(pts)
    if gap < CLOSED_GAP * 5:
        # closed lips: both sides' rims on one line, so neutral shows no slit
        moved = np.flatnonzero(np.any(v != sheet.vertices, axis=1) & (side != 0))
        mid = 0.5 * (upper + lower)
        yline = np.interp(v[moved, 0], mid[:, 0], mid[:, 1])
        on_line = np.abs(v[moved, 1] - yline) < 1e-9
        assert on_line.sum() >= 20
        assert set(side[moved[on_line]]) == {1, -1}
    else:
        from stimulus_engine.geometry.polyline2d import inside_polygon

        opening = np.vstack([upper, lower[::-1][1:-1]])
        assert not inside_polygon(v[kept].mean(axis=1)[:, :2], opening[:, :2]).any()


def test_push_behind_keeps_a_part_behind_the_skin_outside_an_opening():
    from stimulus_engine.geometry.polyline2d import push_behind

    g = np.linspace(-2, 2, 9)
    x, y = np.meshgrid(g, g)
    skin = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    part = np.array([[0.0, 0.0, 0.5], [1.0, 1.0, 0.2], [1.5, -1.0, -0.4]])
    out = push_behind(part, skin, gap=0.1)
    np.testing.assert_allclose(out - part, [[0, 0, -0.6]] * 3)  # the frontmost point ends 0.1 behind
    np.testing.assert_allclose(push_behind(out, skin, gap=0.1), out, atol=1e-12)  # already behind: unchanged
    square = np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0]])
    np.testing.assert_allclose(push_behind(part, skin, opening=square) - part, [[0, 0, -0.2]] * 3)


def test_photographic_eye_texture_puts_the_photographed_iris_at_the_rigs_angle():
    """The MakeHuman photograph re-laid about the gaze axis: pupil dark at the centre, the iris
    (saturated) ending at the requested angle, sclera beyond, the back of the ball dark."""
    from matplotlib.colors import rgb_to_hsv

    from stimulus_engine.parts.eyes import IRIS_ANGLE, photographic_eye_texture

    tex = photographic_eye_texture(256)
    assert tex.shape == (256, 256, 3) and not tex.flags.writeable
    y, x = (np.mgrid[0:256, 0:256] + 0.5) / 256
    r = np.hypot(x - 0.5, y - 0.5) / 0.5
    theta = np.degrees(2 * np.arcsin(np.minimum(r, 1.0)))
    lum = tex @ [0.2126, 0.7152, 0.0722]
    sat = rgb_to_hsv(tex / 255.0)[..., 1]
    assert lum[theta < 4].mean() < 40  # pupil
    assert sat[(theta > 12) & (theta < IRIS_ANGLE - 3)].mean() > 0.35  # iris
    assert sat[(theta > IRIS_ANGLE + 6) & (theta < 60)].mean() < 0.2  # sclera
    assert lum[(theta > IRIS_ANGLE + 6) & (theta < 60)].mean() > 120
    assert lum[theta > 150].mean() < 20  # the back of the ball
    # centred: the iris is round about the UV centre (left/right and up/down halves alike)
    ring = (theta > 12) & (theta < IRIS_ANGLE - 3)
    for a, b in (((x < 0.5) & ring, (x >= 0.5) & ring), ((y < 0.5) & ring, (y >= 0.5) & ring)):
        assert abs(sat[a].mean() - sat[b].mean()) < 0.08


def test_lid_shadow_darkens_the_top_of_the_ball_not_its_middle():
    from stimulus_engine.characters.scan_eyes import lid_shadow

    templates, _ = eyeball_asset()
    grey = np.full((256, 256, 3), 200, np.uint8)
    shaded = lid_shadow(grey, templates, depth=0.4)
    for unit, _, uv in templates:
        d = unit / np.linalg.norm(unit, axis=1, keepdims=True)
        px = shaded[np.clip(np.rint((1 - uv[:, 1]) * 255).astype(int), 0, 255),
                    np.clip(np.rint(uv[:, 0] * 255).astype(int), 0, 255), 0].astype(float)
        top, middle = px[d[:, 1] > 0.6], px[(np.abs(d[:, 1]) < 0.05) & (np.abs(d[:, 0]) < 0.2)]
        assert np.median(middle) == pytest.approx(200, abs=3)
        assert np.median(top) < 0.7 * 200


def test_lash_strip_curls_up_from_the_lid_and_is_longest_towards_the_outer_corner():
    from stimulus_engine.parts.eyelashes import ROWS, lash_strip, lash_texture

    # the subject's right eye (x < 0): inner corner at x = -1, outer at x = -4
    arc = lid_contour(_eye_points(-2.5))[:25]  # the upper arc, corner to corner
    assert arc[0, 0] < arc[-1, 0]
    v, f, uv = lash_strip(arc, width=3.0)
    k = len(arc)
    assert v.shape == (ROWS * k, 3) and f.max() == len(v) - 1 and uv.shape == (len(v), 2)
    root, tip = v[:k], v[-k:]
    np.testing.assert_allclose(root[:, :2], arc[:, :2])  # on the lid margin ...
    assert (root[:, 2] > arc[:, 2]).all()  # ... a little in front of it
    assert (tip[:, 1] > root[:, 1]).all() and (tip[:, 2] > root[:, 2]).all()  # curled up and forward
    length = np.linalg.norm(tip - root, axis=1)
    assert np.argmax(length) < k // 2  # longest on the outer (x = -4, first) half
    assert length[-1] < 0.4 * length.max() and length[0] < 0.9 * length.max()  # short at the corners, inner most
    tex = lash_texture()
    a = tex[..., 3]
    assert 0.03 < (a > 128).mean() < 0.5 and ((a > 0) & (a < 255)).any()  # strands with soft edges
    assert (a[-8:] > 0).mean() > (a[:8] > 0).mean()  # more lash at the root (bottom rows) than the tips


def test_painted_eye_remnants_on_the_lids_are_inpainted():
    """A pale smear (painted sclera, a wet lid rim's glint) next to an eye's opening goes; skin
    texture elsewhere, and dark lash paint, stay."""
    from stimulus_engine.characters.scan_eyes import erase_painted_eyes

    n = 41  # a flat grid mesh over x, y in [-10, 10], UV = the same square
    xs, ys = np.meshgrid(np.linspace(-10, 10, n), np.linspace(-10, 10, n))
    v = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(n * n)])
    uv = (v[:, :2] + 10) / 20
    q = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    faces = np.vstack([np.column_stack([q, q + 1, q + n + 1]), np.column_stack([q, q + n + 1, q + n])])
    rng = np.random.default_rng(0)
    tex = np.clip(np.array([180, 130, 100]) + rng.normal(0, 4, (200, 200, 3)), 0, 255).astype(np.uint8)

    def px(x, y):  # texture pixel of a surface point
        return int(round((1 - (y + 10) / 20) * 199)), int(round((x + 10) / 20 * 199))

    r, c = px(-4, -1.2)  # just under the right eye's opening: a pale glint
    tex[r - 2:r + 3, c - 3:c + 4] = (235, 232, 222)
    r2, c2 = px(-4, -2.0)  # a dark lash line below it, as close to the eye
    tex[r2, c2 - 4:c2 + 5] = (40, 30, 25)
    eye = lambda cx: np.array([[cx - 1.5, 0, 0], [cx - 0.8, 0.6, 0], [cx + 0.8, 0.6, 0],  # noqa: E731
                               [cx + 1.5, 0, 0], [cx + 0.8, -0.6, 0], [cx - 0.8, -0.6, 0]])
    pts = np.vstack([eye(-4.0), eye(4.0)])
    keep = np.ones(len(faces), bool)
    out = erase_painted_eyes(tex, v, faces, uv, faces, keep, pts)
    assert np.abs(out[r, c].astype(int) - (180, 130, 100)).max() < 25  # the glint is skin now
    assert out[r2, c2].max() < 80  # the lash stays dark
    fr, fc = px(8, 8)
    assert np.array_equal(out[fr - 5:fr + 5, fc - 5:fc + 5], tex[fr - 5:fr + 5, fc - 5:fc + 5])  # far away: untouched


@pytest.mark.slow
def test_james_eyes_open_on_the_ball_with_a_wet_margin_not_a_dark_outline(james_scan):
    """Looking at james's eyes from the front (a grid of lines of sight over each opening), what
    one sees inside the lids is the eyeball, the lower lid's wet line and the caruncle in the
    inner corner (``margin``), not the socket: with the socket fanned from the lid rim it lay in
    front of his deep-set balls, 28 % and 34 % of the openings a dark outline round each eye."""
    t = james_scan.scan.topology
    names = np.asarray(t.part_names)
    drawn = ~np.isin(names[t.face_part], ["hidden", "lashes"])
    mesh = trimesh.Trimesh(t.vertices, t.faces[drawn], process=False)
    part = names[t.face_part[drawn]]
    centres = {side: t.vertices[t.landmarks[f"eye_{side}"]].mean(axis=0) for side in ("right", "left")}
    midline = (centres["right"][0] + centres["left"][0]) / 2
    for side, c in centres.items():
        g = np.linspace(-1.3, 1.3, 120)
        x, y = np.meshgrid(c[0] + g, c[1] + 0.5 * g)
        origins = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, t.vertices[:, 2].max() + 1)])
        tri = mesh.ray.intersects_first(origins, np.tile([0.0, 0.0, -1.0], (len(origins), 1)))
        seen, where = part[tri[tri >= 0]], origins[tri >= 0]
        inside = seen != "skin"
        share = {p: float(np.mean(seen[inside] == p)) for p in ("eye", "margin", "socket")}
        assert share["socket"] < 0.05 and 0.03 < share["margin"] < 0.25 and share["eye"] > 0.7, (side, share)
        # the caruncle: the margin is what one sees at the inner corner of the opening
        toward = np.sign(midline - c[0])
        corner = inside & ((where[:, 0] - c[0]) * toward > 0.8 * np.abs(where[inside, 0] - c[0]).max())
        assert np.mean(seen[corner] == "margin") > 0.5, side

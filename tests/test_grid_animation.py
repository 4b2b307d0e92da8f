"""Animated grids (``animation:``) on the procedural head: the weight curve, schema errors, clips
against the still images, the MP4 against its PNG frames, resume, checksums, both engines."""

from __future__ import annotations

import doctest
import hashlib
import typing
from fractions import Fraction
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from appeal.errors import StudyFileError
from appeal.studyfile import load_study_file
from stimulus_engine.grid import run_grid
from stimulus_engine.grid.animation import EASINGS, ClipItem, frame_file, render_clip, weight_curve
from stimulus_engine.grid.schema import AnimationSpec, GridFile
from stimulus_engine.render.clip_video import decode_frames, encode_mp4, psnr, video_info
from grid_fixtures import TINY_GRID

STILL = TINY_GRID
#: The same cells animated: happy at 10 fps, 0.5 s onset, 0.2 s hold -> 8 frames, apex at 5.
ANIMATED = STILL.replace("name: still", "name: clips").replace("expressions: [neutral, happy]",
                                                                "expressions: [happy]") + \
    "animation: {fps: 10, onset: 0.5, hold: 0.2, easing: smoothstep}\n"


def _load(tmp_path: Path, text: str, name: str = "g.yaml") -> GridFile:
    p = tmp_path / name
    p.write_text(text)
    return load_study_file(p, GridFile)


def _png(path: Path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


@pytest.fixture(scope="module")
def rendered(tmp_path_factory) -> dict:
    """The still grid and the animated grid rendered once (pyrender, 96 x 72)."""
    root = tmp_path_factory.mktemp("anim")
    still, clips = _load(root, STILL, "still.yaml"), _load(root, ANIMATED, "clips.yaml")
    still_manifest, _ = run_grid(still, root / "still", n_jobs=1)
    manifest, sheets = run_grid(clips, root / "clips", n_jobs=1)
    return {"root": root, "still": still_manifest, "manifest": manifest, "sheets": sheets, "grid": clips}


# ------------------------------------------------------------------------------ the curve
def test_doctests_of_the_animation_modules():
    import stimulus_engine.grid.animation as animation
    import stimulus_engine.grid.schema as schema
    import stimulus_engine.grid.sheets as sheets
    import stimulus_engine.render.clip_video as clip_video

    for module in (animation, clip_video, schema, sheets):
        res = doctest.testmod(module)
        assert res.failed == 0 and res.attempted > 0, module.__name__


def test_every_easing_of_the_schema_has_a_formula():
    assert set(EASINGS) == set(typing.get_args(AnimationSpec.model_fields["easing"].annotation))


@pytest.mark.parametrize("easing", sorted(EASINGS))
@pytest.mark.parametrize("lead, onset, hold, fps", [(0.0, 1.0, 0.5, 30), (0.25, 0.5, 0.0, 24), (0.1, 0.35, 0.3, 60),
                                                    (1.0, 1.0, 1.0, 1)])
def test_weight_curve_ends_monotone_and_frame_count(easing, lead, onset, hold, fps):
    spec = AnimationSpec(fps=fps, lead=lead, onset=onset, hold=hold, easing=easing)
    w = weight_curve(spec)
    assert len(w) == spec.n_frames == int(np.floor((lead + onset + hold) * fps + 0.5)) + 1
    assert spec.onset_frame == int(np.floor(lead * fps + 0.5))
    assert spec.apex_frame == int(np.floor((lead + onset) * fps + 0.5))
    assert w[0] == 0.0 and w[-1] == 1.0
    assert (w[: spec.onset_frame + 1] == 0).all() and (w[spec.apex_frame:] == 1).all()
    between = w[spec.onset_frame + 1: spec.apex_frame]
    assert ((between > 0) & (between < 1)).all()
    assert (np.diff(w) >= 0).all() and (np.diff(w[spec.onset_frame: spec.apex_frame + 1]) > 0).all()


def test_easings_differ_where_they_should():
    u = np.array([0.25, 0.5, 0.75])
    assert EASINGS["linear"](u).tolist() == [0.25, 0.5, 0.75]
    assert EASINGS["smoothstep"](u)[0] < 0.25 < EASINGS["ease_out"](u)[0]  # slow vs fast start
    assert EASINGS["cosine"](u)[1] == pytest.approx(0.5) and EASINGS["smoothstep"](u)[1] == pytest.approx(0.5)
    assert EASINGS["ease_out"](u)[1] == pytest.approx(0.875)
    # the default clip: 1.5 s at 30 fps, 46 frames, apex at frame 30
    spec = AnimationSpec()
    assert (spec.n_frames, spec.onset_frame, spec.apex_frame) == (46, 0, 30)
    assert weight_curve(spec)[15] == pytest.approx(0.5)


# ------------------------------------------------------------------------------ the schema
@pytest.mark.parametrize("animation, says", [
    ("{fps: 0}", ["animation.fps", "> 0"]),
    ("{fps: 240}", ["animation.fps", "<= 120"]),
    ("{easing: bounce}", ["animation.easing", "linear", "smoothstep", "cosine", "ease_out"]),
    ("{expression: grin}", ["animation.expression", "'cell' or a FACS recipe name", "grin"]),
    ("{onset: 0.01, fps: 30}", ["animation", "onset", "at least 0.0333"]),
    ("{lead: -1}", ["animation.lead", ">= 0"]),
    ("{hold: 100}", ["animation", "at most 60 s"]),
    ("{speed: 2}", ["animation", "unknown key 'speed'"]),
    ("7", ["animation", "AnimationSpec"]),
])
def test_schema_errors_are_one_line(tmp_path, animation, says):
    text = STILL + f"animation: {animation}\n"
    with pytest.raises(StudyFileError) as exc:
        _load(tmp_path, text)
    lines = exc.value.lines
    assert len(lines) == 1 and "\n" not in str(exc.value), lines
    assert lines[0].startswith(str(tmp_path / "g.yaml"))
    for word in says:
        assert word in lines[0], (word, lines[0])


def test_a_named_expression_animates_one_cell_name(tmp_path):
    with pytest.raises(StudyFileError, match=r"animation.expression 'surprise'.*expected one entry in 'expressions'"):
        _load(tmp_path, STILL + "animation: {expression: surprise}\n")
    grid = _load(tmp_path, STILL.replace("[neutral, happy]", "[neutral]") + "animation: {expression: surprise}\n")
    from stimulus_engine.grid.plan import plan_images

    assert {im.expression for im in plan_images(grid)} == {"surprise"}
    assert {im.emotion for im in plan_images(grid)} == {"neutral"}


# ------------------------------------------------------------------------------ the clips
def test_clip_frames_are_the_still_images_at_both_ends(rendered):
    root, m = rendered["root"], rendered["manifest"]
    assert (m["status"] == "rendered").all() and len(m) == 2
    for row in m.itertuples():
        frames = root / "clips" / row.frames
        neutral = _png(root / "still" / f"images/a_{row.shape_label}_original_neutral_flat_pbr.png")
        apex = _png(root / "still" / f"images/a_{row.shape_label}_original_happy_flat_pbr.png")
        assert np.abs(neutral.astype(int) - apex.astype(int)).max() > 20  # the expression shows
        assert (_png(frames / "frame_00000.png") == neutral).all()
        assert (_png(frames / f"frame_{row.apex_frame:05d}.png") == apex).all()
        assert (_png(frames / f"frame_{row.n_frames - 1:05d}.png") == apex).all()  # held
        middle = _png(frames / f"frame_{row.apex_frame // 2:05d}.png")
        assert not (middle == neutral).all() and not (middle == apex).all()
        # the face moves towards the apex frame by frame
        dist = [np.abs(_png(frames / f"frame_{k:05d}.png").astype(int) - apex).mean() for k in range(row.n_frames)]
        assert all(b <= a + 1e-9 for a, b in zip(dist[: row.apex_frame + 1], dist[1: row.apex_frame + 1])), dist


def test_manifest_rows_describe_the_clips(rendered):
    root, m, grid = rendered["root"], rendered["manifest"], rendered["grid"]
    on_disk = pd.read_csv(root / "clips" / "manifest.csv", dtype={"weight_curve": str})
    assert list(on_disk["file"]) == list(m["file"])
    spec = grid.animation
    for row in on_disk.itertuples():
        stem = f"a_{row.shape_label}_original_happy_flat_pbr"
        assert row.file == f"clips/{stem}.mp4" and row.frames == f"clips/{stem}"
        assert (row.n_frames, row.fps, row.onset_frame, row.apex_frame) == (8, 10, 0, 5)
        assert [float(x) for x in row.weight_curve.split(";")] == pytest.approx(weight_curve(spec).round(4).tolist())
        assert sorted(p.name for p in (root / "clips" / row.frames).iterdir()) == \
            [f"frame_{k:05d}.png" for k in range(8)]
        assert row.expression == "happiness" and row.emotion == "happy" and row.material == "original"


def test_checksums_in_the_manifest_match_the_files(rendered):
    root = rendered["root"] / "clips"
    on_disk = pd.read_csv(root / "manifest.csv")
    for row in on_disk.itertuples():
        digests = "".join(hashlib.sha256((root / row.frames / f"frame_{k:05d}.png").read_bytes()).hexdigest()
                          for k in range(row.n_frames))
        assert row.frames_sha256 == hashlib.sha256(digests.encode()).hexdigest()
        assert row.mp4_sha256 == hashlib.sha256((root / row.file).read_bytes()).hexdigest()
    assert on_disk["frames_sha256"].nunique() == len(on_disk)  # the shapes' clips differ


def test_mp4_decodes_to_the_png_frames(rendered):
    root, m = rendered["root"] / "clips", rendered["manifest"]
    for row in m.itertuples():
        info = video_info(root / row.file)
        assert info["codec"] == "h264" and info["all_key_frames"] and info["n_frames"] == row.n_frames
        assert info["fps"] == row.fps and info["time_base"] == Fraction(1, row.fps) and info["pix_fmt"] == "yuv444p"
        decoded = decode_frames(root / row.file)
        assert len(decoded) == row.n_frames
        pngs = [_png(root / row.frames / f"frame_{k:05d}.png") for k in range(row.n_frames)]
        values = [psnr(d, p) for d, p in zip(decoded, pngs)]
        print(f"{row.file}: {len(decoded)} frames, PSNR min {min(values):.2f} dB, mean {np.mean(values):.2f} dB")
        assert min(values) >= 40.0
        # each decoded frame is nearest its own PNG: the order is kept
        assert psnr(decoded[row.apex_frame], pngs[row.apex_frame]) > psnr(decoded[row.apex_frame], pngs[0])


def test_contact_sheets_show_apex_frames_and_a_filmstrip(rendered):
    names = [p.name for p in rendered["sheets"]]
    assert "contact_sheet.png" in names and "filmstrip_a.png" in names
    strip = _png(rendered["root"] / "clips" / "filmstrip_a.png")
    assert strip.shape[1] > 6 * 180  # six frames a row


def test_resume_renders_nothing_then_only_what_changed(rendered, tmp_path):
    import shutil

    grid = rendered["grid"]
    out = tmp_path / "clips"
    shutil.copytree(rendered["root"] / "clips", out)  # a copy to change: the other tests read the original
    before = {p: p.stat().st_mtime_ns for p in out.joinpath("clips").rglob("*") if p.is_file()}
    again, _ = run_grid(grid, out, n_jobs=1)
    assert (again["status"] == "up to date").all()
    assert {p: p.stat().st_mtime_ns for p in out.joinpath("clips").rglob("*") if p.is_file()} == before
    assert list(again["frames_sha256"]) == list(rendered["manifest"]["frames_sha256"])
    # a clip missing a frame is rendered again, the other is kept
    row = again.iloc[0]
    (out / row["frames"] / "frame_00003.png").unlink()
    third, _ = run_grid(grid, out, n_jobs=1)
    assert list(third["status"]) == ["rendered", "up to date"]
    assert (out / row["frames"] / "frame_00003.png").exists()
    assert list(third["frames_sha256"]) == list(rendered["manifest"]["frames_sha256"])  # deterministic
    # another curve is another clip
    eased = grid.model_copy(update={"animation": grid.animation.model_copy(update={"easing": "linear"})})
    fourth, _ = run_grid(eased, out, n_jobs=1)
    assert (fourth["status"] == "rendered").all()
    assert list(fourth["input_hash"]) != list(third["input_hash"])


def test_a_failed_clip_leaves_no_part_of_itself(rendered, tmp_path, monkeypatch):
    import stimulus_engine.grid.animation as animation

    m = rendered["manifest"]
    # a clip item as prepared, pointed at a fresh folder
    from stimulus_engine.grid.prepare import prepare_grid

    _, items, _ = prepare_grid(rendered["grid"], tmp_path, cache=rendered["root"] / "clips" / ".cache")
    item = items[0]
    assert isinstance(item, ClipItem) and item.file == m.iloc[0]["file"]
    calls = []

    def flaky(it):
        calls.append(it.frame)
        if len(calls) == 3:
            raise RuntimeError("the renderer fell over")
        return np.zeros((it.height, it.width, 3), np.uint8)

    monkeypatch.setattr(animation, "render_image", flaky)
    with pytest.raises(RuntimeError, match="fell over"):
        render_clip(item)
    assert not (tmp_path / item.frames).exists() and not (tmp_path / item.file).exists()
    assert not [p for p in (tmp_path / "clips").iterdir()]  # no temporary folder left either
    # frames of one weight are drawn once: 8 frames, 6 distinct weights (0 and the held apex)
    calls.clear()

    def grey(it):
        calls.append(it.frame)
        return np.full((it.height, it.width, 3), it.frame * 20, np.uint8)

    monkeypatch.setattr(animation, "render_image", grey)
    render_clip(item)
    assert calls == [0, 1, 2, 3, 4, 5]
    assert (_png(tmp_path / item.frames / "frame_00007.png") == 100).all()


def test_encode_mp4_refuses_odd_yuv420_and_mixed_sizes(tmp_path):
    frames = [np.full((48, 64, 3), 40 * k, np.uint8) for k in range(3)]
    path = encode_mp4(frames, tmp_path / "x.mp4", 25)
    assert len(decode_frames(path)) == 3 and video_info(path)["time_base"] == Fraction(1, 25)
    with pytest.raises(ValueError, match="even width and height"):
        encode_mp4([np.zeros((47, 64, 3), np.uint8)], tmp_path / "y.mp4", 25, pix_fmt="yuv420p")
    with pytest.raises(ValueError, match="64 x 48"):
        encode_mp4(frames + [np.zeros((50, 64, 3), np.uint8)], tmp_path / "z.mp4", 25)
    assert sorted(f.name for f in tmp_path.iterdir()) == ["x.mp4"]  # no temporary file left either


@pytest.mark.skipif(__import__("stimulus_engine.render.cycles", fromlist=["cycles_python"]).cycles_python() is None,
                    reason="Cycles (.venv-cycles with bpy) is not installed")
def test_a_tiny_cycles_clip(tmp_path):
    text = ANIMATED.replace("render: {width: 96, height: 72}", "render: {width: 64, height: 48, engine: cycles, "
                            "samples: 2}").replace("shapes: [0.0, 1.0]", "shapes: [0.0]")
    text = text.replace("animation: {fps: 10, onset: 0.5, hold: 0.2, easing: smoothstep}",
                        "animation: {fps: 2, onset: 1.0, hold: 0.0}")
    grid = _load(tmp_path, text)
    m, _ = run_grid(grid, tmp_path / "out", n_jobs=1)
    row = m.iloc[0]
    assert row["status"] == "rendered" and row["n_frames"] == 3 and row["weight_curve"] == "0.0000;0.5000;1.0000"
    folder = tmp_path / "out" / row["frames"]
    pngs = [_png(folder / f"frame_{k:05d}.png") for k in range(3)]
    assert pngs[0].shape == (48, 64, 3)
    assert not (pngs[0] == pngs[1]).all() and not (pngs[1] == pngs[2]).all()
    decoded = decode_frames(tmp_path / "out" / row["file"])
    values = [psnr(d, p) for d, p in zip(decoded, pngs)]
    print(f"cycles clip: {len(decoded)} frames, PSNR min {min(values):.2f} dB, {row['seconds'] / 3:.2f} s a frame")
    assert len(decoded) == 3 and min(values) >= 40.0


def test_a_scan_clip_ends_at_its_still_images(tmp_path):
    """A mesh drawn as itself (the shipped james scan) goes through the scan's own chain: its
    surface, eyeballs, teeth and mouth follow the rig frame by frame, and the ends are the stills."""
    from stimulus_engine.data import EMBEDDED_SCAN
    from stimulus_engine.grid.prepare import prepare_grid
    from stimulus_engine.grid.worker import render_item

    text = f"""kind: grid
name: scan_clip
characters:
  - name: james
    procedural: {{seed: 0, texture_size: 128, resolution: 32}}
    mesh: {{file: {EMBEDDED_SCAN}, region: front, topology: scan}}
shapes: [0.0]
materials: [original]
expressions: [surprise]
lighting: [flat]
shading: [pbr]
render: {{width: 96, height: 72, framing: head}}
animation: {{fps: 4, onset: 0.5, hold: 0.0}}
"""
    grid = _load(tmp_path, text)
    m, _ = run_grid(grid, tmp_path / "clips", n_jobs=1)
    row = m.iloc[0]
    assert row["status"] == "rendered" and row["n_frames"] == 3
    # the stills of the same cells, prepared from the same cache (the correspondence made once)
    still = grid.model_copy(update={"animation": None, "expressions": ["neutral", "surprise"]})
    _, items, _ = prepare_grid(still, tmp_path / "still", cache=tmp_path / "clips" / ".cache")
    for it in items:
        render_item(it)
    folder = tmp_path / "clips" / row["frames"]
    neutral, apex = (_png(tmp_path / "still" / it.file) for it in items)
    assert (_png(folder / "frame_00000.png") == neutral).all()
    assert (_png(folder / "frame_00002.png") == apex).all()
    middle = _png(folder / "frame_00001.png")
    assert not (middle == neutral).all() and not (middle == apex).all()


# ------------------------------------------------------------------ a performance in every cell
def _performance_csv(path: Path, rows: list[dict[str, float]], fps: int | None = 10) -> Path:
    import pandas as pd

    df = pd.DataFrame(rows).fillna(0.0)
    df.insert(0, "frame", range(len(df)))
    if fps is not None:
        df.insert(1, "time", [k / fps for k in range(len(df))])
    df.to_csv(path, index=False)
    return path


def test_a_performance_plays_in_every_cell_and_its_frames_are_its_rows(tmp_path, rendered):
    """A weights CSV (what ``appeal stimuli retarget`` writes) as the clip: frame k posed by row k,
    on every shape level through the level's own transfer; a row equal to the happy recipe is the
    happy still image, the neutral rows the neutral still."""
    from stimulus_engine.characters.expressions import expression_weights

    happy = expression_weights("happiness")
    rows = [{}, {k: 0.5 * v for k, v in happy.items()}, dict(happy), {"jawOpen": 0.6}, {}]
    perf = _performance_csv(tmp_path / "take.csv", rows)
    grid = _load(tmp_path, ANIMATED.replace("animation: {fps: 10, onset: 0.5, hold: 0.2, easing: smoothstep}",
                                            f"animation: {{fps: 10, performance: {perf}}}"))
    manifest, _ = run_grid(grid, tmp_path / "out", n_jobs=1)
    assert (manifest["status"] == "rendered").all() and (manifest["n_frames"] == len(rows)).all()
    assert (manifest["apex_frame"] == 2).all() and (manifest["onset_frame"] == 0).all()
    still = rendered["still"].set_index(["shape", "expression"])
    for r in manifest.itertuples():
        folder = tmp_path / "out" / r.frames
        for k, expr in ((0, "neutral"), (2, "happiness"), (4, "neutral")):
            ref = _png(rendered["root"] / "still" / still.loc[(r.shape, expr), "file"])
            assert np.array_equal(_png(folder / frame_file(k)), ref), (r.file, k)
        assert not np.array_equal(_png(folder / frame_file(3)), _png(folder / frame_file(0)))  # the jaw moved
        assert len(decode_frames(tmp_path / "out" / r.file)) == len(rows)
    # how far each frame moves the face: the happy row measures as the happy still, the neutral rows nothing
    frames = pd.read_csv(tmp_path / "out" / "performance_measures.csv")
    stills = pd.read_csv(rendered["root"] / "still" / "expression_measures.csv")
    for shape, g in frames.groupby("shape"):
        happy = stills[(stills["shape"] == shape) & (stills["expression"] == "happiness")].set_index("measure")["value"]
        at = g.set_index(["frame", "measure"])["value"]
        assert np.allclose(at.loc[2].reindex(happy.index), happy, atol=1e-6), shape
        assert np.allclose(at.loc[0], 0.0, atol=1e-9) and np.allclose(at.loc[4], 0.0, atol=1e-9)
        assert np.allclose(at.loc[1].reindex(happy.index), 0.5 * happy, rtol=0.1, atol=2e-4)  # half the weights
    agree = pd.read_csv(tmp_path / "out" / "performance_agreement.csv")
    assert set(agree["shape"]) == {0.0, 1.0} and (agree.loc[agree["shape"] == 0.0, "gain"].dropna() == 1.0).all()


@pytest.mark.parametrize("rows, fps, says", [
    ([{"grin": 1.0}, {}], 10, ["take.csv", "column 'grin'", "not a blendshape of character 'a'"]),
    ([{"jawOpen": 1.0}, {}], 25, ["take.csv", "time: steps at 25 fps", "animation.fps 10"]),
    ([{"jawOpen": 1.0}], 10, ["take.csv", "1 frames", "expected 2.."]),
])
def test_a_bad_performance_is_a_one_line_error_before_rendering(tmp_path, rows, fps, says):
    from appeal.errors import AppealInputError

    perf = _performance_csv(tmp_path / "take.csv", rows, fps)
    grid = _load(tmp_path, ANIMATED.replace("animation: {fps: 10, onset: 0.5, hold: 0.2, easing: smoothstep}",
                                            f"animation: {{fps: 10, performance: {perf}}}"))
    with pytest.raises(AppealInputError) as e:
        run_grid(grid, tmp_path / "out", n_jobs=1)
    msg = str(e.value)
    assert len(msg.splitlines()) == 1 and all(s in msg for s in says), msg
    assert not (tmp_path / "out" / "clips").exists()


def test_a_performance_needs_one_expression_name(tmp_path):
    perf = _performance_csv(tmp_path / "take.csv", [{}, {"jawOpen": 1.0}])
    text = STILL + f"animation: {{performance: {perf}}}\n"
    with pytest.raises(Exception) as e:
        _load(tmp_path, text)
    assert "animation.performance plays one performance in every cell" in str(e.value)

"""Clips in the browser study: `appeal export web` writes each clip's PNG frames, the study preloads
them, decodes them into bitmaps before the trial and draws one per refresh/fps animation frames
(counted, not timed) in headless Chromium; the data file has the lab runner's clip columns."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import yaml
from PIL import Image

from appeal_cli import main
from clip_fixtures import bar_x, make_clip_grid
from experiments.session import load_protocol
from experiments.web import WEB_COLUMNS, export_web, import_web, web_columns
from experiments.runner import beh_columns
from web_participant import StudyServer, answer_until, browser, state, wait_for_file

FACTORS = {"character": ["c1", "c2"], "expression": ["anger", "happiness"]}


def _protocol(tmp_path, **timing):
    manifest = make_clip_grid(tmp_path / "clips", FACTORS, n_frames=8, fps=30, onset_frame=2, apex_frame=6)
    data = {"kind": "protocol", "name": "webclips", "task": "webclips",
            "stimuli": {"manifest": str(manifest), "factors": list(FACTORS)},
            "screen": {"refresh_hz": 60, "window_size": [1280, 1024]},
            "timing": {"stimulus_s": 0.6, "fixation_s": [0.1, 0.2], "on_dropped_frames": "flag", **timing},
            "order": {"repetitions": 3},
            "responses": [{"type": "likert", "name": "appeal", "low": "not at all", "high": "very"}]}
    path = tmp_path / "webclips.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _trials_js(site):
    text = (site / "trials.js").read_text()
    return json.loads(text[text.index("=") + 1:].rstrip().rstrip(";"))


def test_export_writes_every_clip_frame_and_the_clip_plan(tmp_path, capsys):
    proto = _protocol(tmp_path)
    res = export_web(proto, tmp_path / "site", participants=2)
    assert res.n_clips == 4 and res.n_images == 0
    frames = sorted((res.out / "img" / "clips").glob("*/frame_*.png"))
    assert len(frames) == 4 * 8 and {Image.open(f).height for f in frames} == {819}  # 0.8 x 1024
    t = _trials_js(res.out)["01"][0]
    assert t["clip"]["n_frames"] == 8 and t["clip"]["flips_per_frame"] == 2 and t["clip"]["hold_flips"] == 20
    assert t["image"] == t["clip"]["frames"][-1] and all((res.out / f).is_file() for f in t["clip"]["frames"])
    config = (res.out / "config.js").read_text()
    assert "clip_frames_shown" in config and '"clip_end": "hold"' in config
    rep = tmp_path / "repeat.yaml"
    rep.write_text(proto.read_text().replace("on_dropped_frames: flag", "on_dropped_frames: repeat"))
    capsys.readouterr()
    assert main(["export", "web", str(rep), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "timing.on_dropped_frames: repeat" in err[0]


@pytest.mark.slow
def test_chromium_plays_every_frame_for_its_animation_frames(tmp_path):
    proto = _protocol(tmp_path)
    res = export_web(proto, tmp_path / "site", participants=1, fullscreen=False)
    n = res.n_trials["01"]
    shot = tmp_path / "clip.png"
    seen = {}

    def hold_shot(driver):
        """Screenshot a clip while its last frame is held (which frame is up is read from the page)."""
        if not shot.exists():
            held = driver.execute_script("return document.body.dataset.appealClipHold || ''")
            frame = driver.execute_script("return document.body.dataset.appealClipFrame || ''")
            if held and frame:
                driver.save_screenshot(str(shot))
                seen["frame"] = int(frame)
                seen["still_holding"] = bool(driver.execute_script("return document.body.dataset.appealClipHold || ''"))
        return state(driver) == "complete"

    with StudyServer(res.out) as server, browser(tmp_path / "dl") as driver:
        driver.get(server.url + "?participant=01")
        answer_until(driver, hold_shot)
        f = wait_for_file(tmp_path / "dl", "sub-01_*_beh.tsv")
        served = {path.split("?")[0] for _, path in server.handler.served}
    protocol = load_protocol(proto)
    t = pd.read_csv(f, sep="\t")
    assert list(t.columns) == web_columns(protocol, clips=True) == [*beh_columns(protocol, clips=True), *WEB_COLUMNS]
    assert len(t) == n == 12 and t["trial"].tolist() == list(range(1, 13))
    hz = t["refresh_hz"].to_numpy()
    per = np.round(hz / 30)
    assert (np.abs(hz / 30 - per) <= 0.02 * per).all(), hz  # headless Chromium animates at 60 Hz
    # every frame drawn, each for exactly its animation frames, counted; the hold to 0.6 s
    assert (t["clip_frames"] == 8).all() and (t["clip_frames_shown"] == 8).all() and (t["clip_frame_errors"] == 0).all()
    assert (t["clip_flips_per_frame"] == per).all() and (t["clip_flips"] == 8 * per).all()
    assert (t["shown_frames"] == t["duration_frames"]).all()
    assert (t["clip_hold_flips"] == t["duration_frames"] - t["clip_flips"]).all() and (t["clip_hold_flips"] > 0).all()
    assert (t["clip_onset_s"] > t["onset_s"]).all() and (t["clip_apex_s"] > t["clip_onset_s"]).all()
    # the clock-based counts (rAF timestamps) are logged, and the flag follows them
    assert t["clip_dropped_frames"].notna().all() and (t["clip_dropped_frames"] == t["dropped_frames"]).all()
    assert (t["dropped_flag"] == (t["dropped_frames"] > 0).astype(int)).all()
    assert t["clip_preload_ms"].notna().all() and t["response_appeal"].between(1, 7).all()
    # every frame of every clip was fetched from the server
    frames = {"/" + p for trial in _trials_js(res.out)["01"] for p in trial["clip"]["frames"]}
    assert frames <= served
    # the screenshot: the clip's last frame, full height, its bar where the frame has it
    assert seen and seen["frame"] == 7
    im = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    box = np.nonzero(np.abs(im[..., 0] - 128) > 3)
    top, height = box[0].min(), box[0].max() - box[0].min() + 1
    left, width = box[1].min(), box[1].max() - box[1].min() + 1
    assert height == pytest.approx(0.8 * im.shape[0], abs=3) and width == pytest.approx(height, abs=3)
    white = np.nonzero(im[top + height // 2, :, 0] > 240)[0]
    assert white.min() == pytest.approx(left + bar_x(7) * width / 64, abs=4)
    # and the file imports into the lab's layout like a lab session
    done = import_web([f], proto, tmp_path / "data")
    assert done[0].complete

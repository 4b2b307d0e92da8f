"""Nagle et al. §5 from recordings: the mimicry and projection commands read video files (OpenCV).

A neutral↔smile morph sequence of a London-set person (``morph_sequence`` of their neutral and
smiling photos, there and back) written as an .mp4 stands in for a recording."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pandas as pd
import pytest

from appeal_cli import main
from stimulus_engine.morphpca.frame_source import read_frames
from stimulus_engine.morphpca.io import save_model
from stimulus_engine.morphpca.workflow import pair_expression_model

PEOPLE = ("067", "068")


def _write_video(path, frames) -> None:
    h, w = frames.shape[1:3]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 10, (w, h))
    assert vw.isOpened(), "OpenCV cannot write .mp4 here"
    for f in frames:
        vw.write(cv2.cvtColor((f * 255 + 0.5).astype(np.uint8), cv2.COLOR_RGB2BGR))
    vw.release()


@pytest.fixture(scope="module")
def recordings(shared_data, tmp_path_factory):
    """Per person: an expression model (from 8 morph frames), a 12-frame .mp4 (neutral → smile, half back)
    and the same clip reversed."""
    d = shared_data / "faces2d" / "london-frl-more"
    tmp = tmp_path_factory.mktemp("video")
    out = {}
    for p in PEOPLE:
        pair = pair_expression_model(d / "neutral_front" / f"{p}_03.jpg", d / "smiling_front" / f"{p}_08.jpg", n_frames=8)
        save_model(pair.model, tmp / f"{p}.npz")
        clip = np.concatenate([pair.frames, pair.frames[7:3:-1]])
        _write_video(tmp / f"{p}.mp4", clip)
        _write_video(tmp / f"{p}_reversed.mp4", clip[::-1].copy())
        out[p] = (tmp / f"{p}.npz", tmp / f"{p}.mp4", tmp / f"{p}_reversed.mp4", clip)
    return tmp, out


def test_video_frames_are_read_at_the_model_size_with_names(recordings):
    _, rec = recordings
    model, video, _, clip = rec["067"]
    frames = read_frames([video], (120, 100), "--source")
    assert frames.images.shape == (12, 120, 100, 3) and frames.sources == [video]
    assert frames.names[0] == "067_f0000.png" and frames.names[-1] == "067_f0011.png"
    full = read_frames([video])
    assert np.abs(full.images - clip).mean() < 0.03  # mp4 compression only


def _mimicry(tmp, a_model, b_model, source, mimic, name) -> dict:
    out = tmp / name
    assert main(["-q", "stimuli", "morphpca", "mimicry", str(a_model), str(b_model), "--source", str(source),
                 "--mimic", str(mimic), "--out", str(out)]) == 0
    assert len(pd.read_csv(out / "frames.csv")) == 12 and (out / "sheet.png").is_file()
    assert pd.read_csv(out / "loadings_source.csv")["frame"].iloc[3] == f"{source.stem}_f0003.png"
    summary = json.loads((out / "mimicry.json").read_text())
    summary["pc1"] = pd.read_csv(out / "components.csv")["correlation"].iloc[0]  # the smile, over time
    return summary


def test_mimicry_measures_run_from_video_files(recordings):
    tmp, rec = recordings
    a_model, a_video, _, _ = rec["067"]
    b_model, b_video, b_reversed, _ = rec["068"]
    same = _mimicry(tmp, a_model, a_model, a_video, a_video, "same")
    good = _mimicry(tmp, a_model, b_model, a_video, b_video, "good")
    bad = _mimicry(tmp, a_model, b_model, a_video, b_reversed, "bad")
    # the recording mimicking itself: its loadings come back (the mimic's projection weights texture
    # less than the source's orthogonal encoding, so not exactly). Measured: frame correlation 0.99,
    # the smile component's correlation over time 0.90, normalised MI 0.44
    assert same["mean_frame_correlation"] > 0.95 and same["pc1"] > 0.8, same
    # B smiling when A smiles beats B smiling in reverse (measured: frame correlation 0.54 vs 0.44,
    # normalised MI 0.36 vs 0.12); both are far from the recording itself
    assert good["mean_frame_correlation"] > bad["mean_frame_correlation"] + 0.05, (good, bad)
    assert good["mean_normalised_mi"] > bad["mean_normalised_mi"] + 0.1, (good, bad)
    assert same["mean_euclidean"] < 0.5 * good["mean_euclidean"], (same, good)

def test_a_recording_is_reconstructed_and_projected_frame_by_frame(recordings):
    tmp, rec = recordings
    a_model, a_video, _, _ = rec["067"]
    b_model = rec["068"][0]
    out = tmp / "self"
    assert main(["-q", "stimuli", "morphpca", "project", str(a_video), "--from", str(a_model), "--to", str(a_model),
                 "--truth", str(a_video), "--out", str(out), "--json", str(tmp / "self.json")]) == 0
    metrics = json.loads((tmp / "self.json").read_text())
    assert metrics["n_images"] == 12 and metrics["psnr_projection_db"] > 28, metrics  # its own model reconstructs it
    assert (out / "projected" / "067_f0011.png").is_file()
    assert main(["-q", "stimuli", "morphpca", "project", str(a_video), "--from", str(a_model), "--to", str(b_model),
                 "--out", str(tmp / "on_b")]) == 0
    assert len(pd.read_csv(tmp / "on_b" / "loadings.csv")) == 12


def test_a_video_that_cannot_be_read_is_one_line(recordings, tmp_path, capsys):
    _, rec = recordings
    a_model, a_video, _, _ = rec["067"]
    broken = tmp_path / "broken.mp4"
    broken.write_bytes(b"not a video")
    rc = main(["stimuli", "morphpca", "mimicry", str(a_model), str(a_model), "--source", str(a_video), "--mimic",
               str(broken), "--out", str(tmp_path / "m")])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1 and "broken.mp4: no frames could be read" in err[0], err
    assert not (tmp_path / "m").exists()

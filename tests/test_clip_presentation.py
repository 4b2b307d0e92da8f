"""Animated stimuli (clips) in the lab runtime: folders of PNG frames shown frame-locked.

The GUI tests run real PsychoPy windows under Xvfb, in subprocesses. Xvfb has no vsync, so
flip times measure how fast a loaded machine draws, not a display: the tests assert what the
runner controls, by frame COUNTS from the flip log (every clip frame drawn before exactly
``flips_per_frame`` flips, the planned total, triggers on the marked flip), and only check
that PsychoPy's clock-based drop count is logged and agrees with the flip times. A real drop is
made deterministically by a 0.25 s slow draw (``tests/clip_session.py``).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from PIL import Image

from appeal.errors import AppealInputError
from appeal_cli import main
from clip_fixtures import bar_x, make_clip_grid
from experiments import build_trials, load_protocol, load_stimuli, read_completed, run_session
from experiments.clips import CLIP_COLUMNS, flips_per_frame
from experiments.runner import beh_columns
from experiments.session import check_resume
from experiments.stimuli import session_stimuli
from experiments.trials import insert_repeat

FACTORS = {"character": ["c1", "c2"], "expression": ["anger", "happiness", "surprise"]}
HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def clips(tmp_path_factory):
    """Six 6-frame clips at 30 fps (onset frame 1, apex frame 5)."""
    return make_clip_grid(tmp_path_factory.mktemp("clips"), FACTORS)


def _protocol(path, manifest, *, timing=None, **changes):
    data = {"kind": "protocol", "name": "clips", "task": "clips",
            "stimuli": {"manifest": str(manifest), "factors": list(FACTORS)},
            "screen": {"refresh_hz": 60, "window_size": [640, 512]},
            "timing": {"stimulus_s": 0.3, **(timing or {})}}
    data.update(changes)
    path.write_text(yaml.safe_dump(data))
    return path


def _xvfb(cmd):
    if os.environ.get("DISPLAY"):
        return cmd
    if shutil.which("xvfb-run") is None:
        pytest.fail("GUI tests need a display or xvfb-run")
    return ["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24", *cmd]


def _session(protocol, out, *args, timeout=600):
    """``tests/clip_session.py`` in a subprocess under Xvfb; its STATUS/CRASHED line."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(HERE.parent), os.environ.get("PYTHONPATH", "")])}
    cmd = _xvfb([sys.executable, str(HERE / "clip_session.py"), str(protocol), str(out), *map(str, args)])
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False, env=env)
    assert res.returncode == 0, res.stderr[-3000:]
    return next(ln for ln in res.stdout.splitlines() if ln.startswith(("STATUS", "CRASHED")))


def _beh(out):
    return pd.read_csv(next(Path(out).glob("*_beh.tsv")), sep="\t")


def _flips(out):
    return pd.read_csv(next(Path(out).glob("*_flips.tsv")), sep="\t")


def _check_frame_counts(beh, flips, n_frames=6, per_frame=2):
    """Every clip frame drawn before exactly ``per_frame`` flips, in order; the hold on the last frame."""
    clip_flips = flips[flips["clip_frame"].notna()]
    assert set(clip_flips["trial"]) == set(beh["trial"])
    for trial, hold in zip(beh["trial"], beh["clip_hold_flips"]):
        shown = clip_flips.loc[clip_flips["trial"] == trial, "clip_frame"].astype(int).tolist()
        expected = [k for k in range(n_frames) for _ in range(per_frame)] + [n_frames - 1] * hold
        assert shown == expected, f"trial {trial}: frames per flip {shown}"
    assert (beh["clip_frames_shown"] == n_frames).all() and (beh["clip_flips"] == n_frames * per_frame).all()
    assert (beh["clip_frame_errors"] == 0).all()
    assert (beh["shown_frames"] == beh["duration_frames"]).all()


def _late_intervals(flips, beh, hz=60):
    """Per trial: (fewest, most) flip intervals over 1.5 periods from the clip's first flip to the
    next screen's, allowing for the log's 6-decimal rounding of each flip time."""
    out = {}
    for trial in beh["trial"]:
        t = flips[flips["trial"] == trial]
        clip = t[t["clip_frame"].notna()]
        after = t.loc[t.index > clip.index[-1], "time_s"].iloc[0]
        gaps = np.diff(np.r_[clip["time_s"].to_numpy(), after])
        out[trial] = (int((gaps > 1.5 / hz + 2e-6).sum()), int((gaps > 1.5 / hz - 2e-6).sum()))
    return out


def _rows(path):
    """Complete rows on disk, read without touching the file (a writer may be appending)."""
    return max(path.read_bytes().count(b"\n") - 1, 0) if path.exists() else 0


# ---------------------------------------------------------------------------------------- inputs

def test_clip_manifest_rows_become_clips(clips, tmp_path):
    proto = load_protocol(_protocol(tmp_path / "p.yaml", clips))
    sset = load_stimuli(proto.stimuli)
    assert sset.has_clips and len(sset) == 6
    row = sset.table.iloc[0]
    assert row["stimulus"].startswith("clips/") and row["stimulus"].endswith(".mp4")
    assert Path(row["path"]).is_dir() and row["path"] == row["frames"]
    assert (row["n_frames"], row["fps"], row["onset_frame"], row["apex_frame"]) == (6, 30.0, 1, 5)
    trials = build_trials(proto, sset, seed=1, refresh_hz=60)
    t = trials[0]
    assert t.clip.flips_per_frame == 2 and t.clip.clip_flips == 12 and t.clip.hold_flips == 6  # 0.3 s = 18 flips
    assert t.stimulus_frames == 18 and len(t.clip.frame_paths()) == 6
    assert t.as_dict()["clip_flips_per_frame"] == 2 and "clip" not in t.as_dict()


def test_folder_and_table_source_with_frames_and_fps(clips, tmp_path):
    """A folder + factor table whose table has frames/fps columns is a clip set too; the
    optional columns (n_frames, onset_frame, apex_frame) default to the folder's count, 0, last."""
    table = pd.read_csv(clips)[["file", "frames", "fps", *FACTORS]]
    table.to_csv(tmp_path / "factors.csv", index=False)
    data = {"kind": "protocol", "name": "t", "task": "t",
            "stimuli": {"folder": str(clips.parent), "table": str(tmp_path / "factors.csv"), "factors": list(FACTORS)},
            "timing": {"stimulus_s": 0.1, "clip_end": "end", "clip_trigger": "onset_frame"}}
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(data))
    proto = load_protocol(tmp_path / "t.yaml")
    sset = load_stimuli(proto.stimuli)
    assert sset.has_clips and sset.table["apex_frame"].tolist() == [5] * 6 and sset.table["onset_frame"].tolist() == [0] * 6
    t = build_trials(proto, sset, seed=1, refresh_hz=120)[0]
    assert t.clip.flips_per_frame == 4 and t.clip.hold_flips == 0 and t.stimulus_frames == 24  # clip_end: end
    assert t.clip.trigger_frame == 0  # onset_frame defaults to 0 here


def test_bad_clip_tables_are_one_line_errors(clips, tmp_path):
    base = pd.read_csv(clips)
    cases = {
        "missing_frame": None,
        "n_frames": base.assign(n_frames=[7] + [6] * 5),
        "onset": base.assign(onset_frame=[6] + [1] * 5),
        "fps": base.assign(fps=["fast"] + [30] * 5),
        "no_fps": base.drop(columns="fps"),
    }
    expected = {
        "missing_frame": r"line 2 \(clips/[^)]+\.mp4\): frames: .*frame_00003\.png missing",
        "n_frames": r"line 2 \(.+\): n_frames: 7 in the table but 6 frames in",
        "onset": r"line 2 \(.+\): onset_frame: expected a whole number 0\.\.5 \(got 6\)",
        "fps": r"line 2 \(.+\): fps: expected a frame rate > 0 \(got 'fast'\)",
        "no_fps": r"manifest\.csv: fps: column missing",
    }
    for name, table in cases.items():
        folder = tmp_path / name
        shutil.copytree(clips.parent, folder)
        if table is None:
            first = sorted((folder / "clips").glob("*/frame_00003.png"))[0]
            first.unlink()
            table = pd.read_csv(folder / "manifest.csv")
            table = pd.concat([table[table["frames"] == f"clips/{first.parent.name}"],
                               table[table["frames"] != f"clips/{first.parent.name}"]])
        table.to_csv(folder / "manifest.csv", index=False)
        proto = load_protocol(_protocol(folder / "p.yaml", folder / "manifest.csv"))
        with pytest.raises(AppealInputError) as exc:
            load_stimuli(proto.stimuli)
        assert len(exc.value.lines) == 1, exc.value.lines
        assert re.search(expected[name], exc.value.lines[0]), exc.value.lines[0]
        assert str(folder / "manifest.csv") in exc.value.lines[0]


def test_fps_that_does_not_divide_the_refresh_is_a_one_line_error(clips, tmp_path, capsys):
    """25 fps at 60 Hz: each frame would be 2.4 refreshes. The session refuses to start (before its
    folder exists) and ``appeal validate`` says so when the protocol gives its refresh rate."""
    folder = tmp_path / "g25"
    shutil.copytree(clips.parent, folder)
    pd.read_csv(clips).assign(fps=25).to_csv(folder / "manifest.csv", index=False)
    proto = _protocol(tmp_path / "p25.yaml", folder / "manifest.csv")
    assert main(["run", str(proto), "--participant", "1", "--simulate", "default", "--no-window",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"{folder / 'manifest.csv'}: fps: 25 fps does not divide the refresh rate 60 Hz")
    assert "and 5 more" in err[0] and "screen.refresh_hz" in err[0] and "60, 30, 20, 15, 12, 10" in err[0]
    assert not (tmp_path / "o").exists()
    assert main(["validate", str(proto)]) != 0
    said = capsys.readouterr()
    assert "fps: 25 fps does not divide the refresh rate 60 Hz" in said.out + said.err
    # 50 Hz takes 25 fps (2 refreshes a frame); a measured 59.94 Hz takes 30 fps
    assert run_session(proto, "1", out=tmp_path / "o50", simulate="default", window=False, refresh_hz=50,
                       report=False).status == "complete"
    assert flips_per_frame(30, 59.94) == 2 and flips_per_frame(25, 60) is None and flips_per_frame(24, 60.0) is None


def test_protocol_options_are_validated(clips, tmp_path):
    with pytest.raises(AppealInputError, match="max_repeats is only used with on_dropped_frames: repeat"):
        load_protocol(_protocol(tmp_path / "a.yaml", clips, timing={"max_repeats": 2}))
    with pytest.raises(AppealInputError, match="clip_end"):
        load_protocol(_protocol(tmp_path / "b.yaml", clips, timing={"clip_end": "loop"}))
    proto = load_protocol(_protocol(tmp_path / "c.yaml", clips, timing={"on_dropped_frames": "flag"}))
    cols = beh_columns(proto, clips=True)
    assert cols.index("dropped_frames") < cols.index("clip_frames") < cols.index("dropped_flag") < cols.index("repeat_of")
    assert [c for c in cols if c.startswith("clip_")] == list(CLIP_COLUMNS)
    assert "dropped_flag" not in beh_columns(load_protocol(_protocol(tmp_path / "d.yaml", clips)), clips=True)


def test_repeats_go_to_the_end_of_their_block_and_replay_on_resume(clips, tmp_path):
    proto = load_protocol(_protocol(tmp_path / "p.yaml", clips, order={"order": "blocked", "block_by": ["character"],
                                                                        "block_order": "fixed"},
                                    timing={"stimulus_s": 0.3, "on_dropped_frames": "repeat", "max_repeats": 2}))
    full, main_set = session_stimuli(proto, tmp_path / "p.yaml")
    trials = build_trials(proto, main_set, seed=3, refresh_hz=60, full_set=full)
    assert [t.block for t in trials] == ["c1"] * 3 + ["c2"] * 3
    second = trials[1].stimulus
    copy = insert_repeat(trials, 1, 2)
    assert copy is not None and trials[3] is copy and copy.repeat_of == 2 and copy.stimulus == second
    assert [t.trial for t in trials] == list(range(1, 8)) and [t.block for t in trials] == ["c1"] * 4 + ["c2"] * 3
    assert insert_repeat(trials, 3, 2).repeat_of == 2  # the repeat dropped frames too: repeated again
    assert insert_repeat(trials, 4, 2) is None  # max_repeats reached for planned trial 2
    assert [t.repeat_of for t in trials] == [None, None, None, 2, 2, None, None, None]
    # --resume rebuilds the same list from the rows' flags
    rows = [{"trial": str(t.trial), "stimulus": t.stimulus, "dropped_flag": "1" if t.trial in (2, 4, 5) else "0"}
            for t in trials[:6]]
    again = build_trials(proto, main_set, seed=3, refresh_hz=60, full_set=full)
    check_resume(rows, again, tmp_path / "beh.tsv", proto)
    assert [(t.trial, t.stimulus, t.repeat_of) for t in again] == [(t.trial, t.stimulus, t.repeat_of) for t in trials]
    rows[3]["stimulus"] = "other.mp4"
    with pytest.raises(AppealInputError, match="does not match the session's order"):
        check_resume(rows, build_trials(proto, main_set, seed=3, refresh_hz=60, full_set=full), tmp_path / "b", proto)


def test_virtual_clip_session_and_sigkill_resume(clips, tmp_path):
    """Simulated participants answer clip trials; the fast virtual clock advances flips_per_frame per
    frame; SIGKILL at 6 random trials + --resume loses and repeats nothing (the same order as an
    uninterrupted session), with on_dropped_frames: flag writing its column."""
    proto = _protocol(tmp_path / "p.yaml", clips, order={"repetitions": 4},
                      timing={"stimulus_s": 0.25, "fixation_s": [0.05, 0.1], "on_dropped_frames": "flag"},
                      responses=[{"type": "likert", "name": "appeal", "low": "a", "high": "b"}],
                      triggers={"backend": "file", "codes": [{"code": 1 + i, "expression": e}
                                                             for i, e in enumerate(FACTORS["expression"])]})
    ref = run_session(proto, "07", out=tmp_path / "ref", simulate="default", window=False, seed=5)
    beh = pd.read_csv(ref.beh, sep="\t")
    assert len(beh) == 24 and beh["response_appeal"].between(1, 7).all()
    assert (beh["clip_flips"] == 12).all() and (beh["clip_hold_flips"] == 3).all() and (beh["duration_frames"] == 15).all()
    assert beh["clip_dropped_frames"].isna().all() and (beh["dropped_flag"] == 0).all()
    assert np.allclose(beh["clip_onset_s"] - beh["onset_s"], 2 / 60, atol=2e-6)
    assert np.allclose(beh["clip_apex_s"] - beh["onset_s"], 10 / 60, atol=2e-6)
    trig = pd.read_csv(ref.out / "sub-07_ses-1_task-clips_triggers.tsv", sep="\t")
    assert np.allclose(trig.loc[trig["event"] == "set", "time_s"], beh["onset_s"], atol=1e-6)  # on frame 0's flip
    flips = _flips(ref.out)
    assert flips.loc[flips["trial"] == 1, "clip_frame"].dropna().astype(int).tolist() == [0, 1, 2, 3, 4, 5, 5]

    out = tmp_path / "killed"
    model = tmp_path / "fast.yaml"
    model.write_text(yaml.safe_dump({"kind": "participant_model", "rt": {"median_s": 0.03, "sigma": 0.2, "min_s": 0.01}}))
    cmd = [sys.executable, "-m", "appeal_cli", "-q", "run", str(proto), "--participant", "07", "--out", str(out),
           "--simulate", str(model), "--no-window", "--realtime", "--seed", "5", "--refresh-hz", "240"]
    f = out / "sub-07_ses-1_task-clips_beh.tsv"
    for i, target in enumerate(sorted(np.random.default_rng(7).choice(np.arange(2, 23), 6, replace=False))):
        proc = subprocess.Popen(cmd + (["--resume"] if i else []), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        while proc.poll() is None and _rows(f) < target:
            time.sleep(0.002)
        assert proc.poll() is None, proc.stderr.read().decode()[-500:]
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    done = subprocess.run(cmd + ["--resume"], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    final = pd.read_csv(f, sep="\t")
    assert final["trial"].tolist() == list(range(1, 25)) and final["stimulus"].tolist() == beh["stimulus"].tolist()
    assert (final["clip_frames_shown"] == 6).all() and (final["clip_frame_errors"] == 0).all()
    assert set(final["dropped_flag"]) <= {0, 1}
    assert (final["dropped_flag"] == (final["dropped_frames"] > 0).astype(int)).all()
    assert json.loads(f.with_suffix(".json").read_text())["Status"] == "complete"


# ---------------------------------------------------------------------------------------- windows

@pytest.mark.gui
@pytest.mark.slow
def test_live_window_108_clips_every_frame_exactly_its_flips(clips, tmp_path):
    """108 clip presentations through the real window path (a live, passive session): each of the
    6 frames of every clip was drawn before exactly 2 flips (30 fps at 60 Hz), the trigger went out
    on the flip that showed frame 0, and both drop counts are logged and agree."""
    codes = [{"code": 1 + i, "expression": e} for i, e in enumerate(FACTORS["expression"])]
    proto = _protocol(tmp_path / "live.yaml", clips, order={"repetitions": 18, "no_immediate_repeat": True},
                      timing={"stimulus_s": 0.2, "fixation_s": [0.05, 0.1], "fixation_position": "after",
                              "clip_end": "end"},
                      triggers={"backend": "file", "pulse_ms": 10, "codes": codes})
    out = tmp_path / "o"
    assert _session(proto, out, "--live", "--screenshots", tmp_path / "s").startswith("STATUS: complete 108/108")
    beh, flips = _beh(out), _flips(out)
    assert len(beh) == 108 and (beh["clip_hold_flips"] == 0).all() and (beh["duration_frames"] == 12).all()
    _check_frame_counts(beh, flips)
    # total flips as planned: 12 per clip, and the flip log has nothing else on a clip's screen
    assert (flips[flips["screen"] == "stimulus"].groupby("trial").size() == 12).all()
    # the trigger: sent once per clip, after frame 0's flip and before frame 0's second flip
    trig = pd.read_csv(next(out.glob("*_triggers.tsv")), sep="\t")
    sets = trig[trig["event"] == "set"]
    assert sets["code"].tolist() == beh["trigger"].tolist() and (trig["event"] == "reset").sum() == 108
    first = flips[flips["clip_frame"] == 0].groupby("trial")["time_s"].agg(["first", "last"])
    assert np.allclose(first.loc[beh["trial"], "first"].to_numpy(), beh["onset_s"].to_numpy())
    assert (beh["trigger_s"].to_numpy() >= first.loc[beh["trial"], "first"].to_numpy()).all()
    assert (beh["trigger_s"].to_numpy() <= first.loc[beh["trial"], "last"].to_numpy()).all()
    # the clock-based counts: logged for every clip (no vsync here, so not asserted to be 0), and
    # PsychoPy's own (frameIntervals) equals the runner's count from the same flips' times
    assert beh["clip_dropped_frames"].notna().all() and (beh["clip_dropped_frames"] >= 0).all()
    assert (beh["clip_dropped_frames"] == beh["dropped_frames"]).all()
    late = _late_intervals(flips, beh)
    assert all(late[t][0] <= d <= late[t][1] for t, d in zip(beh["trial"], beh["dropped_frames"]))
    assert beh["clip_preload_ms"].notna().all()
    # screenshots: frame 0 and the apex frame of the first clip, the white bar where the frame has it
    for name, k in (("stimulus", 0), ("stimulus_apex", 5)):
        im = np.asarray(Image.open(tmp_path / "s" / f"{name}.png").convert("RGB")).astype(int)
        box = np.nonzero(np.abs(im[..., 0] - 128) > 3)
        left, width = box[1].min(), box[1].max() - box[1].min() + 1
        assert width == pytest.approx(0.8 * 512, abs=2)  # stimulus_height 0.8 of the 512-pixel window
        white = np.nonzero(im[256, :, 0] > 240)[0]
        assert white.min() == pytest.approx(left + bar_x(k) * width / 64, abs=3), name


@pytest.mark.gui
@pytest.mark.slow
def test_simulated_clips_with_responses_onset_trigger_hold_and_thumbnail(clips, tmp_path):
    """A simulated participant rates and classifies clips in real time: the trigger marks the
    manifest's onset frame (its first flip), the last frame is held to stimulus_s, and the
    response screens show the clip's last frame as the thumbnail."""
    proto = _protocol(tmp_path / "sim.yaml", clips,
                      timing={"stimulus_s": 0.3, "fixation_s": 0.05, "clip_trigger": "onset_frame",
                              "stimulus_visible_during_response": True},
                      responses=[{"type": "classification", "name": "expression", "factor": "expression",
                                  "choices": [{"label": e, "value": e, "key": str(i + 1)}
                                              for i, e in enumerate(FACTORS["expression"])]},
                                 {"type": "likert", "name": "appeal", "low": "a", "high": "b"}],
                      triggers={"backend": "file", "codes": [{"code": 1 + i, "expression": e}
                                                             for i, e in enumerate(FACTORS["expression"])]})
    out = tmp_path / "o"
    assert _session(proto, out, "--screenshots", tmp_path / "s").startswith("STATUS: complete 6/6")
    beh, flips = _beh(out), _flips(out)
    _check_frame_counts(beh, flips)
    assert (beh["clip_hold_flips"] == 6).all() and (beh["duration_frames"] == 18).all()
    assert beh["response_expression"].isin(FACTORS["expression"]).all() and beh["response_appeal"].between(1, 7).all()
    onset = flips[flips["clip_frame"] == 1].groupby("trial")["time_s"].first()
    assert np.allclose(beh["clip_onset_s"], onset.loc[beh["trial"]].to_numpy())
    assert (beh["trigger_s"] >= beh["clip_onset_s"]).all() and (beh["trigger_flip_ms"] >= 0).all()
    assert (beh["trigger_s"] - beh["onset_s"] > 1.5 / 60).all()  # not on frame 0's flip: two flips later
    thumb = np.asarray(Image.open(tmp_path / "s" / "expression.png").convert("RGB")).astype(int)
    upper = thumb[20:256]
    box = np.nonzero(np.abs(upper[..., 0] - 128) > 3)
    assert len(box[0]), "no thumbnail on the response screen"
    left, width = box[1].min(), box[1].max() - box[1].min() + 1
    row = upper[(box[0].min() + box[0].max()) // 2, :, 0]
    white = np.nonzero(row > 240)[0]
    assert white.min() == pytest.approx(left + bar_x(5) * width / 64, abs=3)  # the last frame's bar


@pytest.mark.gui
@pytest.mark.slow
def test_a_real_dropped_frame_is_flagged_or_repeated_and_resumed(clips, tmp_path):
    """A 0.25 s stall before one flip of the 2nd clip: PsychoPy counts the late flip, the frame
    counts stay exact (frame-locked: the frame was late, none was skipped), and the trial is
    flagged (flag) or flagged and repeated at the end of its block (repeat); a crash after the
    repeat was scheduled resumes into the same list."""
    order = {"order": "blocked", "block_by": ["character"], "block_order": "fixed"}
    resp = [{"type": "likert", "name": "appeal", "low": "a", "high": "b"}]
    flag = _protocol(tmp_path / "flag.yaml", clips, order=order, responses=resp,
                     timing={"stimulus_s": 0.2, "on_dropped_frames": "flag"})
    out = tmp_path / "flag"
    assert _session(flag, out, "--slow", "2:3").startswith("STATUS: complete 6/6")
    beh, flips = _beh(out), _flips(out)
    _check_frame_counts(beh, flips)
    second = beh.iloc[1]
    assert second["clip_dropped_frames"] >= 1 and second["dropped_frames"] >= 1 and second["dropped_flag"] == 1
    t2 = flips[(flips["trial"] == 2) & (flips["clip_frame"].notna())]
    k3 = t2.index[t2["clip_frame"] == 3][0]
    assert flips.loc[k3, "time_s"] - flips.loc[k3 - 1, "time_s"] >= 0.25  # the stalled flip, where it was made
    assert (beh["dropped_flag"] == ((beh["clip_dropped_frames"] > 0) | (beh["dropped_frames"] > 0)).astype(int)).all()
    assert (beh["clip_dropped_frames"] == beh["dropped_frames"]).all()

    rep = _protocol(tmp_path / "repeat.yaml", clips, order=order, responses=resp,
                    timing={"stimulus_s": 0.2, "on_dropped_frames": "repeat", "max_repeats": 1})
    out = tmp_path / "repeat"
    assert _session(rep, out, "--slow", "2:3", "--crash-at", 5).startswith("CRASHED")
    assert len(read_completed(next(out.glob("*_beh.tsv")))) == 4
    assert _session(rep, out, "--resume").startswith("STATUS: complete")
    beh = _beh(out)
    assert beh["trial"].tolist() == list(range(1, len(beh) + 1))
    assert beh.iloc[1]["dropped_flag"] == 1
    repeat = beh[beh["repeat_of"] == 2]
    assert len(repeat) == 1 and repeat["stimulus"].iloc[0] == beh.iloc[1]["stimulus"]
    c1 = beh.index[beh["block"] == "c1"]
    assert repeat.index[0] in c1 and repeat.index[0] > 2  # later in its block
    # the whole list is the planned one with a repeat after each flagged row (load may stall other
    # flips too): rebuild it from the rows' flags as --resume does, and compare
    proto = load_protocol(rep)
    full, main_set = session_stimuli(proto, rep)
    seed = json.loads(next(out.glob("*_beh.json")).read_text())["Seed"]
    planned = build_trials(proto, main_set, seed=seed, refresh_hz=60, full_set=full)
    check_resume(read_completed(next(out.glob("*_beh.tsv"))), planned, out / "x", proto)
    assert [(t.trial, t.stimulus) for t in planned] == list(zip(beh["trial"], beh["stimulus"]))
    assert [t.repeat_of for t in planned] == [None if np.isnan(v) else int(v) for v in beh["repeat_of"]]
    assert set(beh["part"]) == {1, 2}


@pytest.mark.gui
def test_preloading_a_45_frame_1024x768_clip_and_freeing_it(tmp_path):
    """A 45-frame 1024x768 clip made into textures before its trial (timed and sized, printed for
    the docs), drawn, then freed: no texture and no pixel buffer of it is left in GL."""
    script = tmp_path / "preload.py"
    script.write_text('''
import os, sys, time
import numpy as np
from PIL import Image
from experiments.clips import ClipPlan, decode_frames
from experiments.screens import ClipTextures, open_window, save_back_buffer
from pyglet import gl

def rss():
    return int(open("/proc/self/statm").read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20

folder = sys.argv[1]
rng = np.random.default_rng(0)
base = (rng.random((768, 1024, 3)) * 40 + 90).astype(np.uint8)
for k in range(45):
    im = base.copy()
    im[100:668, 20 * k + 40: 20 * k + 60] = 255
    Image.fromarray(im).save(os.path.join(folder, f"frame_{k:05d}.png"))
plan = ClipPlan(folder, 45, 30.0, 2, 0, 0, 44)
win = open_window((640, 512), fullscreen=False, background=0.5)
r0 = rss(); t0 = time.perf_counter()
frames = decode_frames(plan.frame_paths())
r1 = rss(); t1 = time.perf_counter()
clip = ClipTextures(win, frames, 0.8)
t2 = time.perf_counter(); r2 = rss()
ids = [(s._texID.value, s._pixbuffID.value) for s in clip.stims]
assert all(gl.glIsTexture(t) for t, _ in ids)
clip.draw(44)
save_back_buffer(win, __import__("pathlib").Path(folder) / "shot.png")
win.flip()
clip.free()
left = [t for t, b in ids if gl.glIsTexture(t) or gl.glIsBuffer(b)]
print(f"decode {1000 * (t1 - t0):.0f} ms (+{r1 - r0:.0f} MiB RSS), textures {1000 * (t2 - t1):.0f} ms "
      f"(+{r2 - r1:.0f} MiB RSS); left after free: {len(left)}")
win.close()
''')
    env = {**os.environ, "PYTHONPATH": str(HERE.parent)}
    res = subprocess.run(_xvfb([sys.executable, str(script), str(tmp_path)]), capture_output=True, text=True,
                         timeout=300, check=False, env=env)
    assert res.returncode == 0, res.stderr[-2000:]
    line = next(ln for ln in res.stdout.splitlines() if ln.startswith("decode"))
    print(line)
    assert line.endswith("left after free: 0")
    shot = np.asarray(Image.open(tmp_path / "shot.png").convert("RGB")).astype(int)
    box = np.nonzero(np.abs(shot[..., 0] - 128) > 3)
    left, width = box[1].min(), box[1].max() - box[1].min() + 1
    white = np.nonzero(shot[256, :, 0] > 240)[0]
    assert white.min() == pytest.approx(left + (20 * 44 + 40) * width / 1024, abs=3)  # frame 44's bar

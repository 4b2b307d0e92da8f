"""Real, non-simulated sessions of every shipped protocol, driven from outside the process.

Each test starts ``appeal run <protocol> --participant NN`` (no ``--simulate``) on its own Xvfb
screen and plays the participant with ``xdotool``: it finds the demographics dialog by its
title, types the answers into the Qt fields (some left empty), presses Enter, then presses
keys (or clicks the scale with the mouse) in the PsychoPy window until the session ends. The
data files are then checked against a simulated session with the same seed (same trial order).

Small drawn stimulus sets (``--stimuli``) keep each session to a few trials; ``--refresh-hz
60`` skips the refresh-rate measurement (Xvfb has no vsync, so frames are not paced).
"""

from __future__ import annotations

import json
import os
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from appeal.assets import protocols_dir
from experiments.drawn_faces import draw_face_grid
from experiments.report import overlapping_texts, session_summary, timing_figure
from experiments.session import load_protocol, run_session

pytestmark = [pytest.mark.gui, pytest.mark.slow]

SEED = 5


@pytest.fixture
def display():
    """A private Xvfb screen (``:N``) for one session, answering before it is used.

    ``-noreset``: an X server resets when its last client leaves (here the readiness probe),
    and refuses connections while it does; the session's window was once refused so ("could not
    connect to display :0").

    One per test, not per module: under pytest-xdist a module's tests are spread over workers
    and interleaved with other modules, and a module-wide server was seen gone (Qt: "could
    not connect to display") when a later test of the module reached it."""
    for tool in ("Xvfb", "xdotool"):
        if shutil.which(tool) is None:
            pytest.fail(f"live-session tests need {tool} (bash scripts/system-deps.sh installs it)")
    read, write = os.pipe()
    proc = subprocess.Popen(["Xvfb", "-displayfd", str(write), "-screen", "0", "1280x1024x24", "-nolisten", "tcp",
                             "-noreset"],
                            pass_fds=(write,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    number = b""
    while not number.endswith(b"\n"):
        chunk = os.read(read, 16)
        if not chunk:
            proc.kill()
            pytest.fail("Xvfb did not start")
        number += chunk
    os.close(read)
    name = f":{number.decode().strip()}"
    deadline = time.monotonic() + 20
    while subprocess.run(["xdotool", "getdisplaygeometry"], env={**os.environ, "DISPLAY": name},
                         capture_output=True).returncode != 0:
        if time.monotonic() > deadline or proc.poll() is not None:
            proc.kill()
            pytest.fail(f"Xvfb {name} does not answer")
        time.sleep(0.1)
    yield name
    proc.terminate()
    proc.wait(timeout=10)


class Participant:
    """Plays a participant on an X display with xdotool (keyboard and mouse, as a person would)."""

    def __init__(self, display: str, proc: subprocess.Popen, timeout: float = 240):
        self.env = {**os.environ, "DISPLAY": display}
        self.proc = proc
        self.deadline = time.monotonic() + timeout

    def xdo(self, *args: object) -> str:
        res = subprocess.run(["xdotool", *map(str, args)], capture_output=True, text=True, env=self.env, timeout=30,
                             check=False)
        return res.stdout.strip()

    def window(self, name: str, *, visible: bool = False) -> str | None:
        """The id of the first (mapped, if ``visible``) window whose name matches the regular expression ``name``."""
        found = self.xdo("search", *(["--onlyvisible"] if visible else []), "--name", name)
        return found.split()[0] if found else None

    def wait_window(self, name: str, *, visible: bool = False) -> str:
        while time.monotonic() < self.deadline:
            wid = self.window(name, visible=visible)
            if wid:
                return wid
            if self.proc.poll() is not None:
                pytest.fail(f"the session ended before window {name!r} appeared: {self.proc.stderr.read()[-2000:]}")
            time.sleep(0.1)
        pytest.fail(f"no window {name!r}")

    def fill_dialog(self, title: str, answers: list[str | None]) -> None:
        """Type one answer per field (None: leave it empty; for a choice, letters select it), then Enter."""
        wid = self.wait_window("^" + "".join("\\" + c if c in ".^$*+?()[]{}|\\" else c for c in title) + "$",
                               visible=True)
        time.sleep(0.5)  # the dialog maps and focuses its first field
        assert self.window("^PsychoPy$") is None, "the PsychoPy window is open behind the dialog"
        self.xdo("windowfocus", "--sync", wid)
        for answer in answers:
            if answer:
                self.xdo("type", "--delay", 30, answer)
            self.xdo("key", "Tab")
        self.xdo("key", "Return")

    def play(self, keys: list[str], click: tuple[float, float] | None = None, *, stop_when=None) -> None:
        """Until the session ends: press ``keys`` (and click at ``click``, in height units) in the PsychoPy window."""
        wid = self.wait_window("^PsychoPy$")
        geometry = dict(ln.split("=", 1) for ln in self.xdo("getwindowgeometry", "--shell", wid).splitlines())
        w, h = int(geometry["WIDTH"]), int(geometry["HEIGHT"])
        while self.proc.poll() is None:
            if time.monotonic() > self.deadline:
                self.proc.kill()
                pytest.fail("the live session did not end in time")
            if stop_when is not None and stop_when():
                keys, click, stop_when = ["Escape"], None, None
            self.xdo("windowfocus", wid)
            for key in keys:
                self.xdo("key", key)
            if click is not None:
                # held for 0.1 s as a person does: PsychoPy polls the button state once per frame
                self.xdo("mousemove", "--window", wid, round(w / 2 + click[0] * h), round(h / 2 - click[1] * h),
                         "mousedown", 1)
                time.sleep(0.1)
                self.xdo("mouseup", 1)
            time.sleep(0.15)


def start(display: str, protocol: Path, participant: str, out: Path, *extra: str,
          refresh: bool = True) -> subprocess.Popen:
    """``appeal run`` on ``display`` (``refresh=False``: the refresh rate is measured, as by default)."""
    cmd = [sys.executable, "-m", "appeal_cli", "run", str(protocol), "--participant", participant, "--out", str(out),
           *(["--refresh-hz", "60"] if refresh else []), *extra]
    return subprocess.Popen(cmd, env={**os.environ, "DISPLAY": display}, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def finish(proc: subprocess.Popen) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=60)
    return proc.returncode, out, err


def reference(protocol: Path, stimuli: Path, out: Path) -> pd.DataFrame:
    """The same session simulated (same seed: same trials in the same order)."""
    res = run_session(protocol, "99", out=out, stimuli=stimuli, simulate="default", window=False, seed=SEED,
                      refresh_hz=60, report=False)
    return pd.read_csv(res.beh, sep="\t")


def session_files(out: Path) -> tuple[pd.DataFrame, dict, pd.DataFrame]:
    beh = pd.read_csv(next(out.glob("*_beh.tsv")), sep="\t", keep_default_na=False, na_values=["n/a"])
    side = json.loads(next(out.glob("*_beh.json")).read_text())
    demo = pd.read_csv(out / "participants.tsv", sep="\t", dtype=str, keep_default_na=False)
    return beh, side, demo


# protocol -> factor levels of a small drawn stimulus set, the dialog answers in YAML order,
# the expected participants.tsv values, the keys pressed, the expected responses
CASES = {
    "exp1a_shape_material": ({"shape": [1.0, 0.0], "material": ["paint2", "original"], "expression": ["neutral"]},
                             ["31", "m", None, "d", "b"],
                             {"age": "31", "gender": "male", "games": "n/a", "vfx_movies": "daily",
                              "graphics_knowledge": "basic"},
                             ["space", "5"], {"appeal": 5, "reassurance": 5, "realism": 5, "attractiveness": 5}),
    "exp1b_shading_lighting": ({"shape": [1.0, 0.0], "material": ["skin"], "shading": ["flat", "smooth"],
                                "lighting": ["studio"], "expression": ["neutral"]},
                               [None, "p", "w", None, None],
                               {"age": "n/a", "gender": "prefer not to say", "games": "weekly", "vfx_movies": "n/a",
                                "graphics_knowledge": "n/a"},
                               ["space", "2"], None),
    "exp1c_texture": ({"shape": [0.0], "material": ["original", "flat"], "expression": ["neutral", "happiness"]},
                      ["45", "f", "m", "w", "e"],
                      {"age": "45", "gender": "female", "games": "monthly", "vfx_movies": "weekly",
                       "graphics_knowledge": "expert"},
                      ["space", "7"], None),
    "exp3_expressions": ({"character": ["c1"], "shape": [1.0, 0.0], "material": ["paint4"],
                          "expression": ["sadness", "neutral"]},
                         ["22", "d", None, None, "g"],
                         {"age": "22", "gender": "diverse", "games": "n/a", "vfx_movies": "n/a",
                          "graphics_knowledge": "good"},
                         ["space", "4"], {"expression": "sadness", "intensity": 4}),
}


def small_stimuli(tmp_path: Path, factors: dict) -> Path:
    return draw_face_grid(tmp_path / "faces", factors, size=(240, 180))


@pytest.mark.parametrize("name", list(CASES))
def test_live_rating_session(tmp_path, display, name):
    """A whole live session of a shipped rating protocol: dialog, instructions, ratings by key."""
    factors, typed, demographics, keys, responses = CASES[name]
    protocol = protocols_dir() / f"{name}.yaml"
    stimuli = small_stimuli(tmp_path, factors)
    out = tmp_path / "sub-01"
    proc = start(display, protocol, "01", out, "--stimuli", str(stimuli), "--windowed", "--seed", str(SEED))
    person = Participant(display, proc)
    person.fill_dialog(load_protocol(protocol).title, typed)
    person.play(keys)
    rc, _, err = finish(proc)
    assert rc == 0, err[-2000:]
    beh, side, demo = session_files(out)
    ref = reference(protocol, stimuli, tmp_path / "ref")
    assert beh["stimulus"].tolist() == ref["stimulus"].tolist() and len(beh) >= 4
    assert side["Status"] == "complete" and side["TimingMode"] == "live" and side["Simulated"] is None
    assert (beh["shown_frames"] == beh["duration_frames"]).all()
    rated = beh[beh["phase"] != "anchor"]
    key = int(keys[-1])
    for col in [c for c in beh if c.startswith("response_")]:
        expected = (responses or {}).get(col.removeprefix("response_"), key)
        assert (rated[col] == expected).all(), (col, rated[col].tolist())
        assert rated[f"rt_{col.removeprefix('response_')}"].notna().all()
    assert demo.iloc[0].to_dict() == {"participant_id": "01", **demographics}


def test_live_session_mouse_then_escape_and_printed_resume(tmp_path, display):
    """Exp. 2 live: ratings by mouse clicks on the scale; Escape aborts after 4 trials; the printed
    'Continue with:' command, pasted as is, resumes (no dialog) and finishes; the report's onset
    asynchronies are taken within each part and its labels do not overlap."""
    protocol = protocols_dir() / "exp2_stylisation.yaml"
    stimuli = small_stimuli(tmp_path, {"character": ["c1"], "shape": [1.0, 0.0], "material": ["paint4", "original"],
                                       "expression": ["neutral", "happiness"]})
    out = tmp_path / "sub-02"
    beh_file = out / "sub-02_ses-1_task-exp2_beh.tsv"

    def rows() -> int:
        return max(0, len(beh_file.read_text().splitlines()) - 1) if beh_file.exists() else 0

    proc = start(display, protocol, "02", out, "--stimuli", str(stimuli), "--windowed")
    person = Participant(display, proc)
    person.fill_dialog(load_protocol(protocol).title, ["27", "f", "d", None, None])
    # the 7-point scale spans x = -0.45..0.45 at y = -0.27 (height units): click its right end (7)
    person.play(["space"], click=(0.45, -0.27), stop_when=lambda: rows() >= 4)
    rc, stdout, err = finish(proc)
    assert rc == 0, err[-2000:]
    assert stdout.startswith("aborted: ")
    side = json.loads(beh_file.with_suffix(".json").read_text())
    assert side["Status"] == "aborted" and side["CompletedTrials"] == rows() >= 4
    line = next(ln for ln in err.splitlines() if ln.startswith("Continue with: "))
    words = shlex.split(line.removeprefix("Continue with: "))
    assert {"--stimuli", "--windowed", "--refresh-hz", "--resume"} <= set(words)
    proc = subprocess.Popen([sys.executable, "-m", "appeal_cli", *words[1:]], env={**os.environ, "DISPLAY": display},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    person = Participant(display, proc)
    person.play(["space", "3"])
    rc, stdout, err = finish(proc)
    assert rc == 0, err[-2000:]
    beh, side, demo = session_files(out)
    assert side["Status"] == "complete" and len(side["Resumed"]) == 1
    assert beh["trial"].tolist() == list(range(1, len(beh) + 1)) and len(beh) == 10  # 2 anchors + 8
    first, second = beh[beh["part"] == 1], beh[beh["part"] == 2]
    assert len(first) >= 4 and len(second) >= 1 and len(first) + len(second) == 10
    rated_1 = first[first["phase"] == "main"]
    assert (rated_1["response_realism"] == 7).all() and (rated_1["response_appeal"] == 7).all()  # clicked
    assert (second["response_realism"] == 3).all()  # typed after the resume
    assert demo.iloc[0].to_dict() == {"participant_id": "02", "age": "27", "gender": "female", "games": "daily",
                                      "vfx_movies": "n/a", "graphics_knowledge": "n/a"}
    summary = pd.read_csv(out / "report" / "summary.csv", index_col=0)["value"]
    assert float(summary["isi_ms_min"]) > 0
    s = session_summary(beh, 60.0, ["character", "shape", "material", "expression"])
    n_main = [int((part["phase"] == "main").sum()) for part in (first, second)]
    assert s["isi_ms"].size == sum(max(n - 1, 0) for n in n_main) and (s["isi_ms"] > 0).all()
    assert overlapping_texts(timing_figure(s, "exp2")) == []


def test_live_erp_session_file_triggers(tmp_path, display):
    """The ERP protocol live, full screen, with the file trigger backend: passive viewing, every
    onset has its trigger code in the trigger log."""
    protocol = protocols_dir() / "erp_stylisation.yaml"
    stimuli = small_stimuli(tmp_path, {"character": ["james"], "stylisation": [0, 5], "emotion": ["neutral"]})
    out = tmp_path / "sub-03"
    proc = start(display, protocol, "03", out, "--stimuli", str(stimuli), "--trigger-backend", "file",
                 "--seed", str(SEED))
    person = Participant(display, proc)
    person.fill_dialog(load_protocol(protocol).title, ["24", None, "r"])
    person.play(["space"])
    rc, _, err = finish(proc)
    assert rc == 0, err[-2000:]
    beh, side, demo = session_files(out)
    ref = reference(protocol, stimuli, tmp_path / "ref")
    assert beh["stimulus"].tolist() == ref["stimulus"].tolist() and len(beh) == 30  # 2 faces x 15
    assert side["Status"] == "complete" and side["Triggers"]["backend"] == "file" and side["Screen"]["fullscreen"]
    trig = pd.read_csv(next(out.glob("*_triggers.tsv")), sep="\t")
    assert trig.loc[trig["event"] == "set", "code"].tolist() == beh["trigger"].tolist()
    assert set(beh["trigger"]) == {13, 63}
    assert np.isfinite(beh["trigger_flip_ms"]).all()
    assert demo.iloc[0].to_dict() == {"participant_id": "03", "age": "24", "gender": "n/a", "handedness": "right"}


def test_required_field_is_asked_again(tmp_path, display):
    """A required field left empty: OK shows the dialog again (answers kept, the field named);
    the session starts once it is answered. Optional fields may stay empty (n/a)."""
    import yaml

    stimuli = small_stimuli(tmp_path, {"kind": ["a"]})
    protocol = tmp_path / "req.yaml"
    protocol.write_text(yaml.safe_dump({
        "kind": "protocol", "name": "req", "title": "Required fields", "task": "req",
        "stimuli": {"manifest": str(stimuli), "factors": ["kind"]}, "timing": {"stimulus_s": 0.1},
        "responses": [{"type": "likert", "name": "appeal", "low": "a", "high": "b"}],
        "demographics": [{"name": "gender", "type": "choice", "choices": ["female", "male"],
                          "prefer_not_to_say": "prefer not to say"},
                         {"name": "age", "type": "int", "required": True}]}))
    out = tmp_path / "o"
    proc = start(display, protocol, "04", out, "--windowed", refresh=False)  # measured: after the dialog
    person = Participant(display, proc)
    person.fill_dialog("Required fields", ["m", None])  # age (required) skipped
    time.sleep(1.0)
    assert proc.poll() is None and person.window("^PsychoPy$") is None  # no session without the answer
    person.fill_dialog("Required fields", [None, "abc"])  # gender kept as 'male'; not a number
    time.sleep(1.0)
    assert person.window("^PsychoPy$") is None
    person.fill_dialog("Required fields", [None, "38"])  # Tab selects the old text: typing replaces it
    person.play(["space", "6"])
    rc, _, err = finish(proc)
    assert rc == 0, err[-2000:]
    beh, side, demo = session_files(out)
    assert side["Status"] == "complete" and beh["response_appeal"].tolist() == [6]
    # the rate was measured after the dialog; Xvfb has no vsync, so its flip speed is not a display's rate.
    # On a loaded machine PsychoPy finds no 10 identical frame intervals and reports no rate: the
    # session then paces at 60 Hz in software, which is what must be recorded
    if side["RefreshRateMeasured"] is None:
        assert side["SoftwarePacing"] and side["RefreshRate"] == 60
    else:
        assert side["RefreshRate"] == (60 if side["SoftwarePacing"] else round(side["RefreshRateMeasured"], 2))
    assert demo.iloc[0].to_dict() == {"participant_id": "04", "gender": "male", "age": "38"}


def test_cancelled_dialog_writes_no_session_data(tmp_path, display):
    """Escape in the dialog: a one-line error (exit 2), no window, no data files."""
    stimuli = small_stimuli(tmp_path, {"shape": [0.0, 1.0], "material": ["flat", "original"], "expression": ["neutral"]})
    protocol = protocols_dir() / "exp1c_texture.yaml"
    out = tmp_path / "o"
    proc = start(display, protocol, "05", out, "--windowed", "--stimuli", str(stimuli))
    person = Participant(display, proc)
    wid = person.wait_window("^Experiment 1c: texture$", visible=True)
    time.sleep(0.5)
    person.xdo("windowfocus", "--sync", wid)
    person.xdo("key", "Escape")
    rc, _, err = finish(proc)
    assert rc == 2 and err.strip().splitlines()[-1] == "participant dialog cancelled: no data recorded"
    assert not list(out.glob("sub-*")) and not (out / "participants.tsv").exists()
    # the log says why; the folder (only that log and the provenance) takes the next attempt, no --force
    assert sorted(p.name for p in out.iterdir()) == ["log.txt", "provenance.json"]
    assert "failed: participant dialog cancelled" in (out / "log.txt").read_text()
    res = run_session(protocol, "05", out=out, stimuli=stimuli, simulate="default", window=False, report=False)
    assert res.beh.is_file()

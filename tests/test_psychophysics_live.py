"""A real (non-simulated) 2AFC session of the shipped realism protocol under Xvfb: the participant
fills the dialog, reads the instructions and answers every pair with the arrow keys (xdotool), as a
person would; the session runs its psi tracks to the end, the reference's side is balanced and
recorded, and the answers fit (issue 34)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from analysis.psychometric import fit_ml
from appeal.assets import protocols_dir
from experiments.drawn_faces import draw_face_grid
from experiments.session import load_protocol
from test_live_session import Participant, display, finish, session_files, start  # noqa: F401 - display: fixture

pytestmark = [pytest.mark.gui, pytest.mark.slow]


def test_live_2afc_session_with_arrow_keys(tmp_path, display):  # noqa: F811 - the fixture
    shipped = protocols_dir() / "realism_2afc.yaml"
    data = yaml.safe_load(shipped.read_text())
    # the shipped protocol, shorter: two expressions, 12 trials a track, 2 practice pairs
    data["psychophysics"]["procedure"]["max_trials"] = 12
    data["psychophysics"]["practice_trials"] = 2
    data["stimuli"]["manifest"] = "faces/manifest.csv"
    data["stimuli"].pop("grid")
    proto = tmp_path / "realism_2afc.yaml"
    proto.write_text(yaml.safe_dump(data, sort_keys=False))
    shapes = [round(float(x), 3) for x in np.linspace(0, 1, 11)]
    draw_face_grid(tmp_path / "faces", {"character": ["lps"], "shape": shapes, "material": ["m"],
                                        "expression": ["happiness", "anger"]}, size=(240, 180))
    out = tmp_path / "sub-01"
    shots = tmp_path / "shots"
    proc = start(display, proto, "01", out, "--windowed", "--seed", "4", "--screenshots", str(shots))
    person = Participant(display, proc)
    person.fill_dialog(load_protocol(proto).title, ["27", "f"])
    # Space past the instructions, then always the left arrow: a person who cannot tell the faces apart
    # picks the reference half the time (it is left in half of every two trials of a track)
    person.play(["space", "Left"])
    rc, _, err = finish(proc)
    assert rc == 0, err[-2000:]
    beh, side, _ = session_files(out)
    assert side["Status"] == "complete" and side["Simulated"] is None and side["TimingMode"] == "live"
    assert (beh["phase"] == "practice").sum() == 2 and len(beh) == 2 + 2 * 12
    assert (beh["response_choice"] == "left").all() and beh["rt_choice"].notna().all()
    main = beh[beh["phase"] == "main"]
    for _, track in main.groupby("procedure"):
        counts = track["reference_side"].value_counts()
        assert counts["left"] == counts["right"] == 6  # balanced and recorded
        assert (track["correct"] == (track["reference_side"] == "left").astype(int)).all()
    assert (beh["shown_frames"] == beh["duration_frames"]).all()
    assert (shots / "stimulus.png").is_file() and (shots / "choice.png").is_file()
    # the answers fit (a pooled ML fit: an observer at chance has a flat function)
    table = main.groupby("difference")["correct"].agg(["sum", "count"]).reset_index()
    fit = fit_ml(table.to_numpy(float), nafc=2)
    assert np.isfinite(fit.estimate["threshold"]) and np.isfinite(fit.log_likelihood)
    expected = (fit.predict(table["difference"]) * table["count"]).sum() / table["count"].sum()
    assert expected == pytest.approx(main["correct"].mean(), abs=0.1)

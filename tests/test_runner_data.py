"""Session data: durable rows, SIGKILL + --resume, simulated participants, triggers, the report."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
import yaml

from appeal_cli import main
from appeal.errors import AppealInputError
from experiments import TsvWriter, read_completed, run_session
from experiments.drawn_faces import draw_face_grid
from experiments.protocol_schema import LikertSpec
from experiments.simulate import DEFAULT_MODEL, SimulatedParticipant, load_participant_model
from experiments.triggers import FileBackend, LslBackend, SerialBackend, TriggerSender

FACTORS = {"character": ["c1", "c2"], "stylisation": [0, 1, 2], "emotion": ["angry", "happy"]}


@pytest.fixture(scope="module")
def manifest(tmp_path_factory):
    return draw_face_grid(tmp_path_factory.mktemp("faces"), FACTORS, size=(64, 48))


def fast_protocol(path, manifest, *, reps=3, respond=True, triggers=True):
    codes = [{"code": 10 * (s + 1) + e + 100 * c, "character": ch, "stylisation": s, "emotion": em}
             for c, ch in enumerate(FACTORS["character"]) for s in FACTORS["stylisation"]
             for e, em in enumerate(FACTORS["emotion"])]
    data = {"kind": "protocol", "name": "fast", "task": "fast",
            "stimuli": {"manifest": str(manifest), "factors": list(FACTORS)},
            "screen": {"refresh_hz": 240},
            "timing": {"stimulus_s": 0.02, "fixation_s": [0.01, 0.02], "fixation_position": "after"},
            "order": {"repetitions": reps, "no_immediate_repeat": True},
            "responses": [{"type": "likert", "name": "appeal", "low": "a", "high": "b"}] if respond else [],
            "demographics": [{"name": "age", "type": "int"}]}
    if triggers:
        data["triggers"] = {"backend": "file", "pulse_ms": 5, "codes": codes}
    path.write_text(yaml.safe_dump(data))
    return path


FAST_MODEL = {"kind": "participant_model", "rt": {"median_s": 0.02, "sigma": 0.2, "min_s": 0.005}}


def test_tsv_writer_rows_durable_and_torn_line_cut(tmp_path):
    f = tmp_path / "x.tsv"
    with TsvWriter(f, ["a", "b"]) as w:
        w.write({"a": 1, "b": None})
        w.write({"a": 2.5, "b": "x\ty"})
    assert f.read_text() == "a\tb\n1\tn/a\n2.5\tx y\n"
    with open(f, "a") as fh:
        fh.write("3\tpart")  # a crash in the middle of a row
    rows = read_completed(f, ["a", "b"])
    assert rows == [{"a": "1", "b": "n/a"}, {"a": "2.5", "b": "x y"}]
    assert f.read_text().endswith("x y\n")  # the torn line is gone from the file
    with pytest.raises(AppealInputError, match="header differs"):
        read_completed(f, ["a", "c"])
    assert pd.read_csv(f, sep="\t")["b"].isna().tolist() == [True, False]


def test_background_fsync_rows_visible_at_once(tmp_path):
    f = tmp_path / "bg.tsv"
    w = TsvWriter(f, ["a"], fsync="background")
    for i in range(50):
        w.write({"a": i})
        assert read_completed(f)[-1] == {"a": str(i)}  # flushed before write() returned
    w.close()
    assert f.read_text().count("\n") == 51
    with pytest.raises(ValueError, match="fsync must be"):
        TsvWriter(tmp_path / "y.tsv", ["a"], fsync="sometimes")


def test_simulated_session_without_window(tmp_path, manifest):
    proto = fast_protocol(tmp_path / "p.yaml", manifest)
    res = run_session(proto, "01", out=tmp_path / "o", simulate="default", window=False)
    assert res.status == "complete" and res.completed == res.n_trials == 36
    beh = pd.read_csv(res.beh, sep="\t")
    needed = ["participant_id", "trial", "block", "stimulus", *FACTORS, "onset_frame", "onset_s", "duration_frames",
              "fixation_frames", "response_appeal", "rt_appeal", "trigger"]
    assert all(c in beh.columns for c in needed)
    assert beh["trial"].tolist() == list(range(1, 37))
    assert (beh["shown_frames"] == beh["duration_frames"]).all() and (beh["duration_frames"] == 5).all()
    assert beh["response_appeal"].between(1, 7).all()
    # onset frames advance by exactly stimulus + fixation + response frames
    side = json.loads(res.sidecar.read_text())
    assert side["TimingMode"] == "virtual" and side["RefreshRate"] == 240 and side["Status"] == "complete"
    assert side["ProtocolSHA256"] and side["Seed"] == res_seed(res) and side["SoftwareVersions"]["numpy"]
    # demographics apart from the ratings
    demo = pd.read_csv(res.out / "participants.tsv", sep="\t", dtype=str)
    assert demo["participant_id"].tolist() == ["01"] and "age" in demo and "age" not in beh
    # one trigger per onset, logged by the file backend
    trig = pd.read_csv(res.out / "sub-01_ses-1_task-fast_triggers.tsv", sep="\t")
    sets = trig[trig["event"] == "set"]
    assert sets["code"].tolist() == beh["trigger"].tolist()
    assert np.allclose(sets["time_s"].to_numpy(), beh["onset_s"].to_numpy(), atol=1e-6)
    resets = trig[trig["event"] == "reset"]
    assert len(resets) == len(sets)  # every pulse was reset
    assert (beh["trigger_flip_ms"].abs() < 1e-6).all()
    report = (res.out / "report" / "index.html").read_text()
    assert "trials_per_condition.csv" in report and "timing.png" in report
    cond = pd.read_csv(res.out / "report" / "trials_per_condition.csv")
    assert len(cond) == 12 and (cond["trials"] == 3).all()


def res_seed(res):
    return json.loads((res.out / "provenance.json").read_text())["seed"]


def test_simulated_sessions_are_seeded(tmp_path, manifest):
    proto = fast_protocol(tmp_path / "p.yaml", manifest)
    a = run_session(proto, "02", out=tmp_path / "a", simulate="default", window=False)
    b = run_session(proto, "02", out=tmp_path / "b", simulate="default", window=False)
    c = run_session(proto, "03", out=tmp_path / "c", simulate="default", window=False)
    cols = ["stimulus", "response_appeal", "rt_appeal", "fixation_frames"]
    ta, tb, tc = (pd.read_csv(r.beh, sep="\t")[cols] for r in (a, b, c))
    pd.testing.assert_frame_equal(ta, tb)
    assert not ta.equals(tc)


def test_model_ratings_follow_factors_and_rts_are_lognormal():
    levels = {"stylisation": ["0", "1", "2", "3", "4", "5"]}
    sim = SimulatedParticipant(DEFAULT_MODEL, levels, seed=0)
    realism = LikertSpec(name="realism", low="a", high="b")
    means = [np.mean([sim.rate(realism, {"stylisation": lv}) for _ in range(300)]) for lv in levels["stylisation"]]
    assert all(b > a for a, b in zip(means, means[1:]))  # realism rises with stylisation level
    appeal = LikertSpec(name="appeal", low="a", high="b")
    ap = [sim.expected_rating(appeal, {"stylisation": lv}) for lv in levels["stylisation"]]
    assert max(ap[1:5]) > ap[0] and max(ap[1:5]) > ap[5]  # inverted U
    rts = np.array([sim.rt() for _ in range(4000)])
    from scipy import stats

    logs = np.log(rts)
    assert abs(np.median(rts) - 1.4) < 0.05 and abs(logs.std() - 0.35) < 0.02
    assert stats.normaltest(logs).pvalue > 0.001


def test_confusion_matrix_classification(tmp_path):
    f = tmp_path / "m.yaml"
    f.write_text(yaml.safe_dump({"kind": "participant_model", "classification": {
        "expr": {"confusion": {"neutral": {"neutral": 0.5, "surprise": 0.5}}, "p_correct": 1.0}}}))
    model = load_participant_model(f)
    from experiments.protocol_schema import ChoiceSpec

    choices = [ChoiceSpec(label=v, value=v) for v in ("anger", "neutral", "surprise")]
    sim = SimulatedParticipant(model, {}, seed=1)
    got = pd.Series([sim.classify("expr", choices, "neutral") for _ in range(2000)]).value_counts(normalize=True)
    assert set(got.index) == {"neutral", "surprise"} and abs(got["neutral"] - 0.5) < 0.05
    assert {sim.classify("expr", choices, "anger") for _ in range(50)} == {"anger"}
    bad = tmp_path / "bad.yaml"
    bad.write_text("rt: {median_s: -1}\n")
    with pytest.raises(AppealInputError) as exc:
        load_participant_model(bad)
    assert exc.value.lines == [f"{bad}: rt.median_s: must be > 0 (got -1)"]


def _rows(path):
    if not path.exists():
        return 0
    return max(path.read_bytes().count(b"\n") - 1, 0)


def test_sigkill_at_20_random_trials_then_resume(tmp_path, manifest):
    """Kill the runner (SIGKILL) at 20 random trials; resume each time; nothing lost or duplicated."""
    proto = fast_protocol(tmp_path / "p.yaml", manifest, reps=4)  # 48 trials
    model = tmp_path / "m.yaml"
    model.write_text(yaml.safe_dump(FAST_MODEL))
    out = tmp_path / "killed"
    beh = out / "sub-07_ses-1_task-fast_beh.tsv"
    cmd = [sys.executable, "-m", "appeal_cli", "-q", "run", str(proto), "--participant", "07", "--out", str(out),
           "--simulate", str(model), "--no-window", "--realtime", "--seed", "11"]
    targets = sorted(np.random.default_rng(20240607).choice(np.arange(2, 47), size=20, replace=False))
    killed_at = []
    for i, target in enumerate(targets):
        proc = subprocess.Popen(cmd + (["--resume"] if i else []), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        while proc.poll() is None and _rows(beh) < target:
            time.sleep(0.002)
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
            killed_at.append(_rows(beh))
        else:
            pytest.fail(f"the session ended before trial {target}: {proc.stderr.read().decode()[-500:]}")
        rows = read_completed(beh)
        assert [int(r["trial"]) for r in rows] == list(range(1, len(rows) + 1))  # complete rows, in order
        assert len(rows) >= target
    assert len(killed_at) == 20
    done = subprocess.run(cmd + ["--resume"], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    final = pd.read_csv(beh, sep="\t")
    assert final["trial"].tolist() == list(range(1, 49))  # none lost, none duplicated
    # the same order as an uninterrupted session with the same seed
    ref = run_session(proto, "07", out=tmp_path / "ref", simulate=str(model), window=False, seed=11)
    assert final["stimulus"].tolist() == pd.read_csv(ref.beh, sep="\t")["stimulus"].tolist()
    assert final["fixation_frames"].tolist() == pd.read_csv(ref.beh, sep="\t")["fixation_frames"].tolist()
    side = json.loads((out / "sub-07_ses-1_task-fast_beh.json").read_text())
    assert side["Status"] == "complete" and len(side["Resumed"]) == 20
    # each resume is a new part with its own clock: onset asynchronies are taken within parts only
    assert final["part"].is_monotonic_increasing and final["part"].iloc[0] == 1 and final["part"].iloc[-1] == 21
    summary = pd.read_csv(out / "report" / "summary.csv", index_col=0)["value"]
    assert float(summary["isi_ms_min"]) > 0  # was -(length of the previous part) across each resume


def test_resume_refuses_changed_protocol(tmp_path, manifest):
    proto = fast_protocol(tmp_path / "p.yaml", manifest, reps=1)
    run_session(proto, "08", out=tmp_path / "o", simulate="default", window=False)
    proto.write_text(proto.read_text().replace("stimulus_s: 0.02", "stimulus_s: 0.03"))
    with pytest.raises(AppealInputError, match="changed since the session started"):
        run_session(proto, "08", out=tmp_path / "o", simulate="default", window=False, resume=True)
    # a complete session resumed is left as it is
    fast_protocol(proto, manifest, reps=1)
    again = run_session(proto, "08", out=tmp_path / "o", simulate="default", window=False, resume=True)
    assert again.status == "complete" and len(pd.read_csv(again.beh, sep="\t")) == 12


def test_cli_bad_inputs(tmp_path, manifest, capsys):
    proto = fast_protocol(tmp_path / "p.yaml", manifest, reps=1)
    assert main(["run", str(proto), "--participant", "a_1", "--simulate", "default", "--no-window",
                 "--out", str(tmp_path / "x")]) == 2
    assert "--participant: expected letters and digits only" in capsys.readouterr().err
    assert main(["run", str(proto), "--participant", "1", "--no-window", "--out", str(tmp_path / "y")]) == 2
    assert "only apply to simulated sessions" in capsys.readouterr().err
    assert main(["run", str(proto), "--participant", "1", "--simulate", "nomodel.yaml", "--no-window",
                 "--out", str(tmp_path / "z")]) == 2
    assert "nomodel.yaml: --simulate: expected 'default'" in capsys.readouterr().err
    assert main(["run", str(proto), "--participant", "1", "--simulate", "default", "--no-window",
                 "--stimuli", str(tmp_path / "missing.csv"), "--out", str(tmp_path / "w")]) == 2
    assert "missing.csv: --stimuli table not found" in capsys.readouterr().err
    assert not (tmp_path / "w").exists() and not (tmp_path / "z").exists()  # nothing half-written
    assert main(["run", str(proto), "--participant", "1", "--simulate", "default", "--no-window",
                 "--out", str(tmp_path / "v")]) == 0
    assert main(["run", str(proto), "--participant", "1", "--simulate", "default", "--no-window",
                 "--out", str(tmp_path / "v")]) == 2
    assert "output folder is not empty" in capsys.readouterr().err


def test_serial_backend_loopback_bytes():
    """pyserial's loop:// device: the bytes a BioSemi/TriggerBox interface would receive."""
    import serial

    port = serial.serial_for_url("loop://", timeout=0.1)
    clock = iter(np.arange(0, 10, 0.5)).__next__
    sender = TriggerSender(SerialBackend("loop://", port=port), lambda: float(clock()))
    sender.send(11)
    sender.reset()
    sender.send(163)
    sender.reset()
    sender.reset()  # already low: nothing sent
    assert port.read(8) == bytes([11, 0, 163, 0])
    assert sender.sent == [(11, 0.0), (163, 0.5)]
    sender.close()
    assert not port.is_open


def test_serial_backend_bad_address():
    with pytest.raises(AppealInputError, match="cannot open serial port /dev/nonexistent-tty"):
        SerialBackend("/dev/nonexistent-tty")


def test_lsl_backend_pushes_markers():
    import pylsl

    backend = LslBackend("appeal-test-markers")
    streams = pylsl.resolve_byprop("name", "appeal-test-markers", timeout=5.0)
    assert streams, "the LSL outlet was not found on the local network"
    inlet = pylsl.StreamInlet(streams[0])
    inlet.open_stream(timeout=5.0)
    time.sleep(0.5)
    for code in (11, 12, 13):
        backend.set(code)
        time.sleep(0.05)
    got = []
    t_end = time.time() + 5
    while len(got) < 3 and time.time() < t_end:
        sample, _ts = inlet.pull_sample(timeout=0.5)
        if sample:
            got.append(sample[0])
    backend.close()
    assert got == [11, 12, 13]


def test_file_backend(tmp_path):
    t = iter([0.1, 0.2]).__next__
    b = FileBackend(tmp_path / "t.tsv", t)
    b.set(5)
    b.reset()
    b.close()
    assert (tmp_path / "t.tsv").read_text() == "event\tcode\ttime_s\nset\t5\t0.100000\nreset\t0\t0.200000\n"


def test_onset_asynchronies_within_parts_and_readable_figure(tmp_path):
    """SOAs are never taken across a resume (the clock restarts at 0); the report figure's labels
    do not overlap even for a very wide SOA range (tick labels '-40000' and '-20000' ran together)."""
    from experiments.report import onset_asynchronies, overlapping_texts, timing_figure

    main = pd.DataFrame({"trial": [1, 2, 3, 4, 5], "part": [1, 1, 1, 2, 2], "onset_s": [10.0, 12.5, 15.0, 3.0, 5.5]})
    assert onset_asynchronies(main).tolist() == [2500.0, 2500.0, 2500.0]
    assert onset_asynchronies(main.drop(columns="part").iloc[:3]).tolist() == [2500.0, 2500.0]
    rng = np.random.default_rng(0)
    summary = {"isi_ms": np.r_[rng.normal(2800, 60, 200), -47016.3, 61234.5],
               "fixation_ms": rng.choice([400, 416.7, 433.3, 450, 466.7, 483.3, 500], 200),
               "trigger_ms": rng.normal(0.05, 0.01, 200)}
    for isi in (summary["isi_ms"], summary["isi_ms"] * 3, np.abs(summary["isi_ms"])):
        fig = timing_figure({**summary, "isi_ms": isi}, "erp_stylisation sub-01 (live timing, 60 Hz)")
        assert overlapping_texts(fig) == []


def test_sigterm_marks_crashed_and_printed_command_resumes(tmp_path, manifest):
    """A session ended by SIGTERM says 'crashed' (not 'running') in its sidecar, and the printed
    'Continue with:' command, pasted as it is, finishes the session (it must repeat --stimuli:
    the protocol's own manifest does not exist here, and every other option given)."""
    import shlex

    proto = fast_protocol(tmp_path / "p.yaml", manifest, reps=4)  # 48 trials
    data = yaml.safe_load(proto.read_text())
    data["stimuli"]["manifest"] = "not_here/manifest.csv"
    data["triggers"].update(backend="parallel", address="0x0378")
    proto.write_text(yaml.safe_dump(data))
    model = tmp_path / "m.yaml"
    model.write_text(yaml.safe_dump({**FAST_MODEL, "rt": {"median_s": 0.05, "sigma": 0.2, "min_s": 0.02}}))
    out = tmp_path / "folder with space"
    beh = out / "sub-09_ses-2_task-fast_beh.tsv"
    cmd = [sys.executable, "-m", "appeal_cli", "run", str(proto), "--participant", "09", "--session", "2",
           "--stimuli", str(manifest), "--out", str(out), "--simulate", str(model), "--no-window", "--realtime",
           "--refresh-hz", "120", "--trigger-backend", "file"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    while proc.poll() is None and _rows(beh) < 5:
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode != 0
    side = json.loads(beh.with_suffix(".json").read_text())
    assert side["Status"] == "crashed" and side["CompletedTrials"] == _rows(beh) >= 5
    assert side["Triggers"]["backend"] == "file"
    line = next(ln for ln in err.splitlines() if ln.startswith("Continue with: "))
    words = shlex.split(line.removeprefix("Continue with: "))
    assert words[:2] == ["appeal", "run"] and "--resume" in words and "--stimuli" in words
    done = subprocess.run([sys.executable, "-m", "appeal_cli", *words[1:]], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    final = pd.read_csv(beh, sep="\t")
    assert final["trial"].tolist() == list(range(1, 49)) and (final["session"] == 2).all()
    side = json.loads(beh.with_suffix(".json").read_text())
    assert side["Status"] == "complete" and side["RefreshRate"] == 120


def test_trigger_backend_override_errors(tmp_path, manifest):
    proto = fast_protocol(tmp_path / "p.yaml", manifest, reps=1, triggers=False)
    with pytest.raises(AppealInputError, match="--trigger-backend: .* sends no triggers"):
        run_session(proto, "08", out=tmp_path / "o", simulate="default", window=False,
                    triggers={"backend": "file", "address": None})
    proto = fast_protocol(tmp_path / "p.yaml", manifest, reps=1)
    with pytest.raises(AppealInputError, match="needs 'address'"):
        run_session(proto, "08", out=tmp_path / "o", simulate="default", window=False, triggers={"backend": "serial"})


def test_measured_refresh_must_be_a_display_rate():
    """Flip speed without vsync (224 Hz measured on Xvfb) is not taken as the refresh rate."""
    from experiments.session import display_refresh

    assert display_refresh(59.94) == 59.94 and display_refresh(143.2) == 143.2 and display_refresh(239.5) == 239.5
    assert display_refresh(223.82) is None and display_refresh(96.0) is None
    assert display_refresh(None) is None and display_refresh(1500.0) is None and display_refresh(12.0) is None


def test_a_session_never_writes_through_a_link_out_of_its_folder(tmp_path, manifest, capsys):
    """The lab runner's labels come from the command line and every file it writes is required inside
    --out: a crafted participant or session is refused, and a session file or report planted as a
    symbolic link to elsewhere is refused before anything is written there."""
    from cli_errors import one_line_error

    proto = fast_protocol(tmp_path / "p.yaml", manifest, triggers=False)
    run = ["run", str(proto), "--simulate", "default", "--no-window"]
    one_line_error(capsys, [*run, "--participant", "x/../../escaped", "--out", str(tmp_path / "a")],
                   "--participant: expected letters and digits only (a BIDS label), got 'x/../../escaped'")
    one_line_error(capsys, [*run, "--participant", "01", "--session", "0", "--out", str(tmp_path / "a")],
                   "--session: expected a session number from 1 to 9999")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "victim.tsv").write_text("precious")
    for name, target in (("sub-01_ses-1_task-fast_beh.tsv", elsewhere / "victim.tsv"), ("report", elsewhere)):
        out = tmp_path / f"o-{name}"
        out.mkdir()
        os.symlink(target, out / name)
        one_line_error(capsys, [*run, "--participant", "01", "--out", str(out), "--force"], "outside the output folder")
    assert (elsewhere / "victim.tsv").read_text() == "precious" and sorted(p.name for p in elsewhere.iterdir()) == [
        "victim.tsv"]

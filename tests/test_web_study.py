"""Online studies: the shipped Exp. 2 and Exp. 3 protocols exported, run by a scripted participant in
headless Chromium (keys and clicks), downloaded, imported into the BIDS layout and analysed.

The stimuli are drawn faces (the shipped protocols' own manifest needs a rendered grid); every
other line of the protocols is the shipped one, shortened in time so a session takes seconds.
"""

from __future__ import annotations

import json
import re
import time

import pandas as pd
import pytest
import yaml

from appeal.assets import protocols_dir
from appeal_cli import main
from experiments.runner import beh_columns
from experiments.session import load_protocol, run_session
from experiments.web import WEB_COLUMNS, export_web, import_web
from web_participant import StudyServer, answer_until, browser, state, wait_for_file
from web_session_files import web_protocol


_protocol = web_protocol


def _trials_js(site):
    text = (site / "trials.js").read_text()
    return json.loads(text[text.index("=") + 1:].rstrip().rstrip(";"))


def test_exported_lists_are_the_lab_runners_lists(tmp_path):
    """The list a browser participant gets is the lab runner's for the same participant and seed:
    same trials, phases, blocks, repetitions, fixation jitter and break positions."""
    proto = _protocol(tmp_path, "exp2_stylisation", characters=("c1", "c2"))
    res = export_web(proto, tmp_path / "site", participants=3)
    lists = _trials_js(res.out)
    assert sorted(lists) == ["01", "02", "03"] and res.participants == ["01", "02", "03"]
    orders = set()
    for p, web in lists.items():
        lab = run_session(proto, p, out=tmp_path / f"lab{p}", simulate="default", window=False, report=False)
        rows = pd.read_csv(lab.beh, sep="\t", dtype=str)
        assert len(rows) == len(web) == lab.n_trials
        for key in ("trial", "phase", "block", "repetition", "stimulus", "fixation_frames"):
            assert rows[key].tolist() == [str(t[key]) for t in web], key
        orders.add(tuple(t["stimulus"] for t in web))
    assert len(orders) == 3  # each participant their own order
    # every image once, at the protocol's stimulus height (0.8 of its 1024-pixel-high window)
    from PIL import Image

    imgs = sorted((res.out / "img").glob("*.png"))
    assert len(imgs) == res.n_images == 24
    assert {Image.open(f).height for f in imgs} == {819}
    assert "MIT" in (res.out / "lib" / "LICENSES.md").read_text()


def test_protocols_a_browser_cannot_run_are_refused_in_one_line(tmp_path, capsys):
    erp = protocols_dir() / "erp_stylisation.yaml"
    assert main(["export", "web", str(erp), "--out", str(tmp_path / "erp")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "passive viewing" in err[0] and "erp_stylisation.yaml" in err[0]
    assert not (tmp_path / "erp").exists()
    proto = _protocol(tmp_path, "exp2_stylisation")
    assert main(["validate", str(proto)]) == 0  # the files a browser runs are lab protocols, validated as such
    capsys.readouterr()
    data = yaml.safe_load(proto.read_text())
    data["triggers"] = {"backend": "file", "codes": [{"code": 1, "shape": 0}, {"code": 2, "shape": 4}]}
    trig = tmp_path / "trig.yaml"
    trig.write_text(yaml.safe_dump(data))
    assert main(["export", "web", str(trig), "--out", str(tmp_path / "t")]) == 2
    assert "triggers: a browser sends no EEG trigger codes" in capsys.readouterr().err
    assert main(["export", "web", str(proto), "--out", str(tmp_path / "u"), "--completion-url", "prolific"]) == 2
    assert "--completion-url: expected an http(s):// URL" in capsys.readouterr().err


def _run(driver, url, downloads, **kw):
    driver.get(url)
    counts = answer_until(driver, lambda d: state(d) == "complete", **kw)
    return counts, wait_for_file(downloads, "sub-*_beh.tsv")


@pytest.mark.slow
def test_exp2_in_chromium_downloads_imports_and_analyses(tmp_path, capsys):
    proto = _protocol(tmp_path, "exp2_stylisation")
    site = tmp_path / "site"
    assert main(["export", "web", str(proto), "--out", str(site), "--participants", "4", "--data-url", "/save",
                 "--completion-code", "C0DE42"]) == 0
    lists = _trials_js(site)
    files = []
    shots = {"likert": tmp_path / "likert.png", "page": tmp_path / "instructions.png"}
    with StudyServer(site) as server:
        for i, query in enumerate(["participant=02", "PROLIFIC_PID=5f1a2b3c4d&STUDY_ID=s77&SESSION_ID=x9"]):
            dl = tmp_path / f"dl{i}"
            with browser(dl) as driver:
                counts, f = _run(driver, server.url + "index.html?" + query, dl, shots=shots)
                end = driver.find_element("css selector", ".appeal-end").text
            assert "C0DE42" in end and "Thank you" in end
            files.append(f)
        posted = server.posted
    assert [p[0] for p in posted] == [f.name for f in files]  # each session also POSTed to --data-url
    assert posted[0][1] == files[0].read_bytes()
    protocol = load_protocol(proto)
    first = pd.read_csv(files[0], sep="\t", dtype=str)
    assert list(first.columns) == [*beh_columns(protocol), *WEB_COLUMNS]
    assert first["stimulus"].tolist() == [t["stimulus"] for t in lists["02"]]
    main_rows = first[first["phase"] == "main"]
    assert main_rows["response_realism"].isin([str(v) for v in range(1, 8)]).all()
    assert (main_rows["shown_frames"] == main_rows["duration_frames"]).all()
    assert (pd.to_numeric(main_rows["refresh_hz"]) > 20).all()
    second = pd.read_csv(files[1], sep="\t", dtype=str)
    assert second["participant_id"].unique().tolist() == ["5f1a2b3c4d"]
    assert second["recruitment_pid"].unique().tolist() == ["5f1a2b3c4d"]
    assert second["study_id"].unique().tolist() == ["s77"] and second["session_id"].unique().tolist() == ["x9"]
    assert second["stimulus"].tolist() == [t["stimulus"] for t in lists[second["list"].iloc[0]]]

    data = tmp_path / "data"
    assert main(["import", "web", *map(str, files), "--protocol", str(proto), "--out", str(data)]) == 0
    out = capsys.readouterr().out
    assert "sub-02: " in out and "(complete)" in out
    beh = data / "sub-02" / "ses-1" / "beh" / "sub-02_ses-1_task-exp2_beh.tsv"
    side = json.loads(beh.with_suffix(".json").read_text())
    assert side["Status"] == "complete" and side["TimingMode"] == "browser" and side["List"] == "02"
    assert (beh.parent / "report" / "index.html").is_file()
    assert main(["import", "web", str(files[0]), "--protocol", str(proto), "--out", str(data)]) == 2
    assert "already imported" in capsys.readouterr().err
    study = tmp_path / "ratings.yaml"
    study.write_text(yaml.safe_dump({"kind": "ratings", "title": "online", "data": "data/sub-*/ses-*/beh/*_task-exp2_beh.tsv",
                                     "within": ["shape", "material"], "scales": ["realism", "appeal"]}))
    assert main(["analyze", "ratings", str(study), "--out", str(tmp_path / "res")]) == 0, capsys.readouterr().err
    res = json.loads((tmp_path / "res" / "results.json").read_text())
    assert {e["effect"] for e in res["scales"]["realism"]["anova"]} >= {"shape", "material", "shape:material"}


@pytest.mark.slow
def test_exp3_classification_and_a_reload_resumes_without_losing_or_repeating_trials(tmp_path):
    proto = _protocol(tmp_path, "exp3_expressions")
    res = export_web(proto, tmp_path / "site", participants=2, fullscreen=False)
    n = res.n_trials["01"]
    dl = tmp_path / "dl"
    shots = {"classification": tmp_path / "classification.png"}
    with StudyServer(res.out) as server, browser(dl) as driver:
        driver.get(server.url + "?participant=01")

        def rows(d):
            return d.execute_script("const k = Object.keys(localStorage)[0]; "
                                    "return k ? JSON.parse(localStorage.getItem(k)).rows.length : 0")

        answer_until(driver, lambda d: rows(d) >= 4, shots=shots)
        driver.refresh()  # mid-session: the page is reloaded (or the browser crashed and came back)
        from selenium.webdriver.support.ui import WebDriverWait

        page = WebDriverWait(driver, 30).until(lambda d: d.find_elements("css selector", ".appeal-page"))[0].text
        assert re.search(rf"continues with trial [5-9] of {n}", page)
        answer_until(driver, lambda d: state(d) == "complete", shots=shots)
        f = wait_for_file(dl, "sub-01_*_beh.tsv")
    t = pd.read_csv(f, sep="\t", dtype=str)
    assert t["trial"].astype(int).tolist() == list(range(1, n + 1))  # none lost, none twice
    assert set(t["part"]) == {"1", "2"} and (t["part"].astype(int).diff().fillna(0) >= 0).all()
    assert t["stimulus"].tolist() == [x["stimulus"] for x in _trials_js(res.out)["01"]]
    # classification by key, the correct column from the stimulus's expression, intensity skipped after neutral
    assert t["response_expression"].isin(["anger", "happiness", "neutral", "sadness", "surprise"]).all()
    truth = (t["response_expression"] == t["expression"]).astype(int).astype(str)
    assert (t["correct_expression"] == truth).all()
    neutral = t["response_expression"] == "neutral"
    assert neutral.any() and (t.loc[neutral, "response_intensity"] == "1").all()
    assert t.loc[neutral, "rt_intensity"].isna().all()
    assert t.loc[~neutral, "response_intensity"].isin([str(v) for v in range(1, 8)]).all()
    # imported with both parts, and the recognition analysis reads it like a lab session
    done = import_web([f], proto, tmp_path / "data")
    assert done[0].complete and json.loads(done[0].sidecar.read_text())["Parts"] == 2


@pytest.mark.slow
def test_no_trial_starts_before_its_images_are_loaded_from_a_slow_server(tmp_path):
    proto = _protocol(tmp_path, "exp2_stylisation")
    res = export_web(proto, tmp_path / "site", participants=1, fullscreen=False)
    with StudyServer(res.out, delay_s=0.15) as server, browser(tmp_path / "dl") as driver:
        driver.get(server.url + "?participant=01")
        end = time.monotonic() + 60
        while not driver.find_elements("css selector", ".appeal-page") and time.monotonic() < end:
            time.sleep(0.01)
        first_page = time.monotonic()
        served = [t for t, path in server.handler.served if path.startswith("/img/")]
        answer_until(driver, lambda d: state(d) == "complete")
    assert len(served) == res.n_images  # every image, each once
    assert max(served) < first_page  # all of them loaded before the instructions (and so any trial)
    # and the preload screen was what the participant saw meanwhile (about 0.15 s x 12 images)
    assert first_page - min(served) > 0.1

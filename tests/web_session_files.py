"""Browser session files for the importer's tests, made without a browser.

:func:`web_protocol` is a shipped protocol on drawn faces (the shipped manifest needs a rendered
grid), shortened in time. :func:`browser_session_file` writes what an exported study's browser
writes for one participant: the lab runner's simulated session of that participant's list (the
browser's list *is* the lab runner's list, tests/test_web_study.py) plus the browser's columns with
plausible values; tests/test_web_study.py checks the real thing in Chromium.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import yaml

from appeal.assets import protocols_dir
from appeal.provenance import file_sha256
from experiments.session import default_seed, load_protocol, run_session
from experiments.web import web_columns

#: A user agent as Chromium sends it.
USER_AGENT = "Mozilla/5.0 (X11; Linux x86_64) AppleWebKit/537.36 (KHTML, like Gecko) Chrome/156.0.0.0 Safari/537.36"


def web_protocol(tmp_path: Path, name: str, *, characters=("c1",), trim: bool = True) -> Path:
    """The shipped protocol ``name`` on drawn faces; ``trim``: 0.2 s faces, jittered fixation, a break
    every 5 trials (the shipped timing, shortened so a session takes seconds)."""
    from experiments.drawn_faces import draw_face_grid

    levels = {"character": list(characters), "shape": [0, 4], "material": [0, 4],
              "expression": ["neutral", "happiness", "anger"]}
    manifest = draw_face_grid(tmp_path / "faces", levels, size=(160, 120))
    proto = yaml.safe_load((protocols_dir() / f"{name}.yaml").read_text())
    proto["stimuli"].pop("levels")
    proto["stimuli"].pop("grid")
    proto["stimuli"]["manifest"] = str(manifest)
    if trim:
        proto["timing"].update(stimulus_s=0.2, fixation_s=[0.1, 0.2])
        proto["breaks"]["every"] = 5
        if "anchors" in proto:
            proto["anchors"].update(stimulus_s=0.2, if_missing="skip")
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(proto, allow_unicode=True))
    return path


def browser_rows(protocol_file: Path, work: Path, slot: str = "01", *, participant: str | None = None,
                 session: int = 1) -> pd.DataFrame:
    """The rows a browser writes for list ``slot`` (participant label ``participant``, default the slot)."""
    protocol = load_protocol(protocol_file)
    lab = run_session(protocol_file, slot, session=session, out=work / f"lab-{slot}-{session}", simulate="default",
                      window=False, report=False)
    rows = pd.read_csv(lab.beh, sep="\t", dtype=str, keep_default_na=False)
    rows["participant_id"] = participant or slot
    web = {"list": slot, "list_trials": str(len(rows)), "seed": str(default_seed(protocol.name, slot, session)),
           "browser": USER_AGENT, "screen_width": "1920", "screen_height": "1080", "window_width": "1280",
           "window_height": "1024", "refresh_hz": "60.01", "intended_s": "0.2", "focus_losses": "0",
           "fullscreen_losses": "0", "recruitment_pid": "n/a", "study_id": "n/a", "session_id": "n/a",
           "started": "2026-12-01T10:00:00.000Z", "protocol_sha256": file_sha256(protocol_file)}
    for c, v in web.items():
        rows[c] = v
    return rows[web_columns(protocol)]


def write_rows(rows: pd.DataFrame, folder: Path, name: str | None = None) -> Path:
    """``rows`` as the browser's file (tab-separated, ``\\n`` line ends, no index) in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    r0 = rows.iloc[0]
    path = folder / (name or f"sub-{r0['participant_id']}_ses-{r0['session']}_beh.tsv")
    text = "\t".join(rows.columns) + "\n" + "".join("\t".join(map(str, r)) + "\n" for r in rows.itertuples(index=False))
    path.write_bytes(text.encode("utf-8"))
    return path

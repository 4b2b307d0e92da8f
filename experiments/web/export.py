"""``appeal export web``: a rating protocol as a self-contained static study folder for a browser.

The folder holds ``index.html``, the study script (``appeal-study.js``: jsPsych plugins that
show each face for a counted number of display frames and ask the protocol's Likert and
classification screens), jsPsych itself (copied from the npm packages ``make`` installs, with
their licences), the stimulus images resized to the protocol's screen geometry, and the trial
lists: one per participant slot, built by :func:`experiments.trials.build_trials` with the
seed the lab runner uses for that participant (:func:`experiments.session.default_seed`), so
the browser presents exactly the lab's order, repetitions, constraints and fixation jitter.

Clips (animated stimuli) are exported as their PNG frames (``img/clips/<clip>/frame_00000.png``
...), preloaded with the images, decoded into bitmaps before their trial and drawn on a canvas one
frame per ``refresh / fps`` animation frames, counted (``requestAnimationFrame``), with the lab
runner's clip columns.

What a browser cannot do is refused with one line: passive viewing, EEG triggers, and repeating
trials with dropped frames (the lists are fixed at export; ``flag`` works).
"""

from __future__ import annotations

import json
import re
import shutil
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from appeal.errors import AppealInputError
from appeal.labels import check_session
from appeal.levels import level_key
from appeal.outputs import output_run
from appeal.provenance import file_sha256
from experiments.clips import FRAME_NAME, RATE_TOLERANCE, ClipPlan
from experiments.display import DROP_THRESHOLD
from experiments.protocol_schema import ClassificationSpec, LikertSpec, Protocol
from experiments.runner import beh_columns
from experiments.session import default_seed, load_protocol
from experiments.stimuli import session_stimuli
from experiments.trials import Trial, build_trials

__all__ = ["WEB_COLUMNS", "WEB_DESCRIPTIONS", "VENDOR", "WebExport", "web_refusal", "web_columns", "export_web", "participant_slots"]

#: The columns the browser writes after the lab runner's, and their sidecar descriptions.
WEB_DESCRIPTIONS: dict[str, str] = {
    "list": "the exported trial list this participant was given (a lab participant label)",
    "list_trials": "trials in that list (the session is complete when it has as many rows)",
    "seed": "seed of that list (the lab runner's seed for that participant and session)",
    "browser": "the browser's user agent", "screen_width": "screen width (CSS px)",
    "screen_height": "screen height (CSS px)", "window_width": "window width (CSS px) at the trial",
    "window_height": "window height (CSS px) at the trial",
    "refresh_hz": "refresh rate measured in the browser (median of 60 animation-frame intervals)",
    "intended_s": "the protocol's stimulus duration (s); duration_frames is it in frames at refresh_hz",
    "focus_losses": "times the window lost the focus during the trial",
    "fullscreen_losses": "times full screen was left during the trial",
    "recruitment_pid": "participant id from the recruitment platform (URL parameter PROLIFIC_PID or workerId)",
    "study_id": "URL parameter STUDY_ID", "session_id": "URL parameter SESSION_ID",
    "started": "when the participant first opened the study (ISO 8601, the browser's clock)",
    "protocol_sha256": "sha256 of the protocol file the study was exported from (the importer compares it)",
}

#: The browser's own columns, in order.
WEB_COLUMNS: tuple[str, ...] = tuple(WEB_DESCRIPTIONS)

#: The npm packages copied into every export: (package, files under it, name in lib/).
VENDOR: tuple[tuple[str, str, str], ...] = (
    ("jspsych", "dist/index.browser.min.js", "jspsych.js"),
    ("jspsych", "css/jspsych.css", "jspsych.css"),
    ("@jspsych/plugin-preload", "dist/index.browser.min.js", "plugin-preload.js"),
    ("@jspsych/plugin-html-keyboard-response", "dist/index.browser.min.js", "plugin-html-keyboard-response.js"),
    ("@jspsych/plugin-fullscreen", "dist/index.browser.min.js", "plugin-fullscreen.js"),
)

_HERE = Path(__file__).resolve().parent
_NODE_MODULES = _HERE / "vendor" / "node_modules"
_STATIC = _HERE / "static"


@dataclass
class WebExport:
    """What :func:`export_web` wrote."""

    out: Path
    index: Path
    participants: list[str]
    n_images: int
    n_trials: dict[str, int]
    n_clips: int = 0


def web_refusal(protocol: Protocol) -> str | None:
    """Why a browser cannot run ``protocol`` (one line), or None when it can."""
    if not protocol.responses:
        return ("responses: none (passive viewing): an ERP study needs EEG and triggers, which a browser "
                "has not; run it in the lab with `appeal run`")
    if protocol.triggers is not None:
        return ("triggers: a browser sends no EEG trigger codes; export a copy of the protocol without "
                "'triggers' for an online rating study")
    if protocol.psychophysics is not None:
        return ("psychophysics: each next pair depends on the answers so far, and a browser study's trial lists are "
                "fixed when it is exported; run it in the lab with `appeal run`")
    if protocol.timing.on_dropped_frames == "repeat":
        return ("timing.on_dropped_frames: repeat: the browser study's trial lists are fixed when it is exported; "
                "export with 'flag' (dropped_flag marks the trials to leave out)")
    return None


def web_columns(protocol: Protocol, clips: bool = False) -> list[str]:
    """The columns of a browser session's ``_beh.tsv``: the lab runner's, then :data:`WEB_COLUMNS`.

    Parameters
    ----------
    protocol : Protocol
        The protocol.
    clips : bool
        Whether its stimuli include clips (the lab runner's clip columns are written too).
    """
    return [*beh_columns(protocol, clips=clips), *WEB_COLUMNS]


def participant_slots(n: int) -> list[str]:
    """Participant labels ``01``, ``02``, ... (as wide as ``n`` needs, at least two digits)."""
    if n < 1:
        raise AppealInputError(f"--participants: expected at least 1 (got {n})")
    width = max(2, len(str(n)))
    return [f"{i:0{width}d}" for i in range(1, n + 1)]


def _vendor_file(package: str, rel: str) -> Path:
    path = _NODE_MODULES / package / rel
    if not path.is_file():
        raise AppealInputError(f"{path}: not installed: the browser libraries come from npm; run `make install` "
                               f"(or `npm ci --prefix {_HERE / 'vendor'}`)")
    return path


def _licences() -> str:
    lines = ["# Libraries in lib/", "",
             "Copied unchanged from the npm registry by `appeal export web`; each under its own licence.", ""]
    for package in dict.fromkeys(pkg for pkg, _, _ in VENDOR):
        meta = json.loads(_vendor_file(package, "package.json").read_text())
        author = meta.get("author", "")
        if isinstance(author, dict):
            author = author.get("name", "")
        lines += [f"## {package} {meta['version']}", "",
                  f"Licence: {meta.get('license', 'see its package')}; author: {author or 'see its package'}; "
                  f"{meta.get('homepage', '')}", ""]
        for name in ("LICENSE", "LICENSE.md", "license"):
            f = _NODE_MODULES / package / name
            if f.is_file():
                lines += ["```", f.read_text().strip(), "```", ""]
                break
        else:
            if meta.get("license") == "MIT":
                lines += ["```", _MIT.format(author=author or package).strip(), "```", ""]
    return "\n".join(lines)


_MIT = """MIT License

Copyright (c) {author}

Permission is hereby granted, free of charge, to any person obtaining a copy of this software and
associated documentation files (the "Software"), to deal in the Software without restriction, including
without limitation the rights to use, copy, modify, merge, publish, distribute, sublicense, and/or sell
copies of the Software, and to permit persons to whom the Software is furnished to do so, subject to the
following conditions:

The above copyright notice and this permission notice shall be included in all copies or substantial
portions of the Software.

THE SOFTWARE IS PROVIDED "AS IS", WITHOUT WARRANTY OF ANY KIND, EXPRESS OR IMPLIED, INCLUDING BUT NOT
LIMITED TO THE WARRANTIES OF MERCHANTABILITY, FITNESS FOR A PARTICULAR PURPOSE AND NONINFRINGEMENT. IN NO
EVENT SHALL THE AUTHORS OR COPYRIGHT HOLDERS BE LIABLE FOR ANY CLAIM, DAMAGES OR OTHER LIABILITY, WHETHER
IN AN ACTION OF CONTRACT, TORT OR OTHERWISE, ARISING FROM, OUT OF OR IN CONNECTION WITH THE SOFTWARE OR THE
USE OR OTHER DEALINGS IN THE SOFTWARE.
"""


def _response_config(spec: LikertSpec | ClassificationSpec) -> dict[str, Any]:
    if isinstance(spec, LikertSpec):
        return {"type": "likert", "name": spec.name, "points": spec.points, "low": spec.low, "high": spec.high,
                "description": spec.description, "keys": bool(spec.keys and spec.points <= 9)}
    return {"type": "classification", "name": spec.name, "prompt": spec.prompt, "factor": spec.factor,
            "choices": [{"label": c.label, "value": level_key(c.value), "key": c.key} for c in spec.choices],
            "intensity": None if spec.intensity is None else _response_config(spec.intensity),
            "skip_intensity_for": [level_key(s) for s in spec.skip_intensity_for], "skip_value": spec.skip_value}


def _markdown_html(text: str) -> str:
    import markdown

    return markdown.markdown(text.strip(), extensions=["sane_lists"])


def _unique_name(stimulus: str, used: dict[str, str], path: str, suffix: str = ".png", fallback: str = "image") -> str:
    """A file or folder name for ``stimulus`` (its stem, made safe, plus ``suffix``) that no other
    source ``path`` in ``used`` has taken (``_2``, ``_3`` ... appended)."""
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(stimulus).stem) or fallback
    name, n = f"{stem}{suffix}", 1
    while name in used and used[name] != path:
        n += 1
        name = f"{stem}_{n}{suffix}"
    used[name] = path
    return name


def _resized(src: str, dst: Path, height: int) -> None:
    from PIL import Image

    with Image.open(src) as im:
        im = im.convert("RGBA") if im.mode in ("RGBA", "LA", "P") else im.convert("RGB")
        if im.height != height:
            width = max(1, round(im.width * height / im.height))
            im = im.resize((width, height), Image.LANCZOS)
        im.save(dst, optimize=False)


def _clip_frames(plan: ClipPlan, dst: Path, height: int) -> None:
    """A clip's PNG frames, resized like the stills, into ``dst``."""
    dst.mkdir(parents=True)
    for k, src in enumerate(plan.frame_paths()):
        _resized(src, dst / FRAME_NAME.format(k), height)


def _trial_record(t: Trial, image: str) -> dict[str, Any]:
    """A trial as the browser reads it: the lab's fields, the image by its path in the study folder.

    A clip's record has ``clip`` (its frames' paths, ``fps``, the flips per frame and hold at the
    protocol's refresh rate, onset and apex frames) and ``image`` = its last frame (the response
    screens' thumbnail); ``image`` then names a folder under ``img/clips/``.
    """
    record = {k: v for k, v in asdict(t).items() if k not in ("path", "trigger", "extra", "clip")}
    if t.clip is None:
        return {**record, "image": f"img/{image}", "clip": None}
    frames = [f"img/clips/{image}/{FRAME_NAME.format(k)}" for k in range(t.clip.n_frames)]
    clip = {"frames": frames, "n_frames": t.clip.n_frames, "fps": t.clip.fps,
            "flips_per_frame": t.clip.flips_per_frame, "hold_flips": t.clip.hold_flips,
            "onset_frame": t.clip.onset_frame, "apex_frame": t.clip.apex_frame}
    return {**record, "image": frames[-1], "clip": clip}


def _script(name: str, value: Any) -> str:
    # JSON inside a <script>: "</" closes the element, so it is escaped
    return f"window.{name} = " + json.dumps(value, indent=1, ensure_ascii=False).replace("</", "<\\/") + ";\n"


def export_web(protocol_file: str | Path, out: str | Path, *, participants: int = 20, session: int = 1,
               stimuli: str | Path | None = None, data_url: str | None = None, completion_url: str | None = None,
               completion_code: str | None = None, fullscreen: bool = True, force: bool = False,
               argv: list[str] | None = None) -> WebExport:
    """Write a static browser study of ``protocol_file`` into ``out``.

    Parameters
    ----------
    protocol_file : path-like
        A rating or classification protocol (``kind: protocol``).
    out : path-like
        The study folder (new, empty, or replaced with ``force``).
    participants : int
        Trial lists for participants ``01`` … ``N``; each equals the lab runner's list for that
        participant and session (same seed). An online participant without one of these labels
        (e.g. a Prolific id) is given list ``hash(id) mod N``.
    session : int
        Session number (part of the seed and the file names).
    stimuli : path-like, optional
        Another manifest or factor table instead of the protocol's (as ``appeal run --stimuli``).
    data_url : str, optional
        Where the finished data file is POSTed (JATOS/Pavlovia-style); it is offered for download
        in any case.
    completion_url, completion_code : str, optional
        Where participants are sent at the end (e.g. Prolific's completion link) and/or a code shown.
    fullscreen : bool
        Ask for full screen before the first trial (and count exits from it per trial).
    force : bool
        Replace an existing folder.

    Returns
    -------
    WebExport
    """
    protocol_file = Path(protocol_file)
    protocol = load_protocol(protocol_file)
    reason = web_refusal(protocol)
    if reason is not None:
        raise AppealInputError(f"{protocol_file}: {reason}")
    if data_url is not None and not re.match(r"^(https?://|/)", data_url):
        raise AppealInputError(f"--data-url: expected an http(s):// URL or a path on the study's server (got {data_url!r})")
    if completion_url is not None and not re.match(r"^https?://", completion_url):
        raise AppealInputError(f"--completion-url: expected an http(s):// URL (got {completion_url!r})")
    session = check_session(session, "--session")
    slots = participant_slots(participants)
    full, main = session_stimuli(protocol, protocol_file, stimuli)
    hz = float(protocol.screen.refresh_hz or 60.0)
    seeds = {p: default_seed(protocol.name, p, session) for p in slots}
    lists = {p: build_trials(protocol, main, seed=seeds[p], refresh_hz=hz, source=str(protocol_file), full_set=full)
             for p in slots}
    vendor = [(_vendor_file(pkg, rel), name) for pkg, rel, name in VENDOR]
    with output_run(out, force=force, seed=seeds, inputs=[protocol_file, full.source], argv=argv) as run:
        root = run.out
        (root / "img").mkdir()
        (root / "lib").mkdir()
        used: dict[str, str] = {}
        names: dict[str, str] = {}
        plans: dict[str, ClipPlan] = {}
        height = round(protocol.screen.stimulus_height * protocol.screen.window_size[1])
        for trials in lists.values():
            for t in trials:
                if t.path not in names:
                    names[t.path] = (_unique_name(t.stimulus, used, t.path) if t.clip is None
                                     else _unique_name(t.stimulus, used, t.path, suffix="", fallback="clip"))
                if t.clip is not None:
                    plans[t.path] = t.clip
        for path, name in names.items():
            if path in plans:
                _clip_frames(plans[path], root / "img" / "clips" / name, height)
            else:
                _resized(path, root / "img" / name, height)
        for src, name in vendor:
            shutil.copyfile(src, root / "lib" / name)
        (root / "lib" / "LICENSES.md").write_text(_licences())
        for f in ("appeal-study.js", "appeal-study.css", "index.html"):
            shutil.copyfile(_STATIC / f, root / f)
        pages = [*protocol.instructions.pages, *(f.read_text(encoding="utf-8") for f in protocol.instructions.files)]
        config = {
            "name": protocol.name, "title": protocol.title or protocol.name, "task": protocol.task, "session": session,
            "protocol_sha256": file_sha256(protocol_file), "nominal_hz": hz,
            "screen": {"background": protocol.screen.background, "text_color": protocol.screen.text_color,
                       "stimulus_height": protocol.screen.stimulus_height,
                       "response_stimulus_height": protocol.screen.response_stimulus_height},
            "timing": {"response_deadline_s": protocol.timing.response_deadline_s,
                       "stimulus_visible_during_response": protocol.timing.stimulus_visible_during_response,
                       "fixation_position": protocol.timing.fixation_position,
                       "clip_end": protocol.timing.clip_end, "on_dropped_frames": protocol.timing.on_dropped_frames,
                       "drop_threshold": DROP_THRESHOLD, "rate_tolerance": RATE_TOLERANCE},
            "instructions": [_markdown_html(p) for p in pages],
            "continue_text": protocol.instructions.continue_text,
            "end_text": _markdown_html(protocol.instructions.end_text),
            "breaks": None if protocol.breaks is None else {"text": protocol.breaks.text, "min_s": protocol.breaks.min_s},
            "responses": [_response_config(r) for r in protocol.responses],
            "factors": list(protocol.stimuli.factors), "columns": web_columns(protocol, clips=full.has_clips),
            "fixation": protocol.timing.fixation_s is not None,
            "participants": slots, "seeds": seeds, "data_url": data_url, "completion_url": completion_url,
            "completion_code": completion_code, "fullscreen": fullscreen,
        }
        (root / "config.js").write_text(_script("APPEAL_CONFIG", config), encoding="utf-8")
        records = {p: [_trial_record(t, names[t.path]) for t in trials] for p, trials in lists.items()}
        (root / "trials.js").write_text(_script("APPEAL_TRIALS", records), encoding="utf-8")
        run.extra.update(participants=len(slots), images=len(names) - len(plans), clips=len(plans))
    return WebExport(out=root, index=root / "index.html", participants=slots, n_images=len(names) - len(plans),
                     n_trials={p: len(t) for p, t in lists.items()}, n_clips=len(plans))

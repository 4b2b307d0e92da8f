"""One session end to end: protocol -> trial list -> window (or none) -> durable data -> report."""

from __future__ import annotations

import hashlib
import platform
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from appeal.errors import AppealInputError
from appeal.logs import logger
from appeal.labels import check_label, check_session
from appeal.outputs import output_run, require_inside
from appeal.progress import progress
from appeal.provenance import file_sha256, now_iso, package_versions
from appeal.studyfile import load_study_file
from experiments.clips import CLIP_DESCRIPTIONS
from experiments.datafile import (TsvWriter, read_completed, read_sidecar, session_stem, write_demographics,
                                 write_sidecar)
from experiments.display import DROP_THRESHOLD, NoWindow, Presenter
from experiments.protocol_schema import Protocol
from experiments.runner import SessionRunner, beh_columns, flip_columns
from experiments.simulate import SimulatedParticipant, load_participant_model
from experiments.stimuli import protocol_input_problems, session_stimuli
from experiments.triggers import TriggerSender, open_backend
from experiments.psychophysics import PSYCHOPHYSICS_DESCRIPTIONS, PsychophysicsPlan
from experiments.trials import Trial, build_trials, insert_repeat, pair_trial_maker

__all__ = ["SessionResult", "run_session", "default_seed", "session_paths", "load_protocol", "column_descriptions",
           "check_resume", "session_input_problems"]

#: Refresh rates outside this range mean the display has no vsync (e.g. a virtual screen).
PLAUSIBLE_HZ = (20.0, 250.0)
#: Refresh rates displays run at; a measured rate far from all of them is flip speed without vsync.
DISPLAY_RATES = (50.0, 56.0, 60.0, 70.0, 72.0, 75.0, 85.0, 90.0, 100.0, 120.0, 144.0, 160.0, 165.0, 170.0, 175.0,
                 180.0, 200.0, 240.0)


def display_refresh(measured: float | None, tolerance: float = 0.02) -> float | None:
    """The measured refresh rate if it is one a display runs at, else None (no vsync).

    Without vsync (a virtual X screen, vsync off in the driver) ``getActualFrameRate`` measures
    how fast frames are drawn, e.g. 224 Hz on Xvfb: taken as the refresh rate, it shortened
    every duration 3.7-fold. A real refresh rate lies within ``tolerance`` (relative) of a
    standard display rate (59.94 Hz counts as 60).

    Parameters
    ----------
    measured : float or None
        Measured frames per second.
    tolerance : float
        Relative distance allowed to the nearest standard rate.

    Returns
    -------
    float or None
        ``measured`` rounded to 0.01 Hz, or None.
    """
    if measured is None or not PLAUSIBLE_HZ[0] <= measured <= PLAUSIBLE_HZ[1]:
        return None
    nearest = min(DISPLAY_RATES, key=lambda r: abs(r - measured))
    return round(measured, 2) if abs(measured - nearest) <= tolerance * nearest else None
SIM_WINDOW = (640, 512)


@dataclass
class SessionResult:
    """What a session produced."""

    out: Path
    beh: Path
    sidecar: Path
    n_trials: int
    completed: int
    status: str
    timing_mode: str
    refresh_hz: float
    report: Path | None = None
    screenshots: dict[str, Path] = field(default_factory=dict)


def default_seed(protocol_name: str, participant: str, session: int) -> int:
    """A seed unique to protocol x participant x session (each participant gets their own order)."""
    digest = hashlib.sha256(f"{protocol_name}|{participant}|{session}".encode()).hexdigest()
    return int(digest[:8], 16) % (2 ** 31)


def session_paths(out: Path, participant: str, session: int, task: str) -> dict[str, Path]:
    """Every file of a session folder."""
    stem = session_stem(participant, session, task)
    return {"beh": out / f"{stem}_beh.tsv", "sidecar": out / f"{stem}_beh.json", "flips": out / f"{stem}_flips.tsv",
            "triggers": out / f"{stem}_triggers.tsv", "demographics": out / "participants.tsv",
            "report": out / "report"}


def load_protocol(path: str | Path) -> Protocol:
    """Load and validate a protocol file (one-line errors)."""
    return load_study_file(path, Protocol)


def _open_window(protocol: Protocol, *, fullscreen: bool, size: tuple[int, int]) -> Any:
    try:
        from experiments.screens import open_window

        return open_window(size, fullscreen=fullscreen, background=protocol.screen.background)
    except Exception as exc:  # noqa: BLE001 - pyglet raises its own display errors
        if "display" in str(exc).lower() or type(exc).__name__ == "NoSuchDisplayException":
            raise AppealInputError("no display to open a window on: run under a desktop session or "
                                   "'xvfb-run -a appeal run ...' (simulated sessions may use --no-window)") from None
        raise


def _measure_refresh(win: Any) -> float | None:
    rate = win.getActualFrameRate(nIdentical=10, nMaxFrames=120, nWarmUpFrames=10, threshold=1)
    return float(rate) if rate else None


def _with_triggers(protocol: Protocol, override: dict[str, str | None], source: Path) -> Protocol:
    """The protocol with ``--trigger-backend``/``--trigger-address`` applied (validated again)."""
    changes = {k: v for k, v in override.items() if v is not None}
    if not changes:
        return protocol
    if protocol.triggers is None:
        opts = ", ".join(f"--trigger-{k}" for k in changes)
        raise AppealInputError(f"{opts}: {source} sends no triggers (it has no 'triggers' section)")
    from experiments.protocol_schema import TriggerSpec

    data = {**protocol.triggers.model_dump(), **changes}
    try:
        spec = TriggerSpec.model_validate(data)
    except ValidationError as exc:
        msg = exc.errors()[0]["msg"].removeprefix("Value error, ")
        raise AppealInputError(f"--trigger-{'/'.join(changes)}: {msg}") from None
    return protocol.model_copy(update={"triggers": spec})


def _refresh_before_window(previous: dict[str, Any], refresh_hz: float | None, protocol: Protocol, *,
                           measured: bool) -> float | None:
    """The refresh rate a session will use when it is known before a window opens (None: measured)."""
    if previous:
        return float(previous["RefreshRate"])
    given = refresh_hz if refresh_hz is not None else protocol.screen.refresh_hz
    if given is not None:
        return float(given)
    return None if measured else 60.0


def session_input_problems(protocol: Protocol, source: str | Path) -> list[str]:
    """Problems with what a protocol needs to run (``appeal validate``): its stimuli
    (:func:`experiments.stimuli.protocol_input_problems`) and, for psychophysics, its levels
    and pairs against the stimulus table (:class:`PsychophysicsPlan`)."""
    problems = protocol_input_problems(protocol, source)
    if problems or protocol.psychophysics is None:
        return problems
    try:
        _, main = session_stimuli(protocol, source)
        PsychophysicsPlan(protocol, main, seed=0, source=str(source))
    except AppealInputError as exc:
        return exc.lines
    return []


def check_resume(rows: list[dict[str, str]], trials: list[Trial], beh: Path, protocol: Protocol,
                 plan: PsychophysicsPlan | None = None, refresh_hz: float = 60.0) -> None:
    """Check the rows on disk against the trial list, replaying the repeats they asked for
    (``timing.on_dropped_frames: repeat`` inserted a trial for each row flagged 1) and, in a
    psychophysics session, the answers that moved its procedures (the list grows as they did)."""
    if plan is not None:
        plan.replay(rows, trials, pair_trial_maker(protocol, refresh_hz), str(beh))
        return
    repeat = protocol.timing.on_dropped_frames == "repeat"
    for i, row in enumerate(rows):
        if i >= len(trials):
            raise AppealInputError(f"{beh}: {len(rows)} rows but the session has only {len(trials)} trials")
        t = trials[i]
        if row["trial"] != str(t.trial) or row["stimulus"] != t.stimulus:
            raise AppealInputError(f"{beh}: trial {row['trial']} ({row['stimulus']}) does not match the session's "
                                   f"order (expected trial {t.trial}: {t.stimulus}); was the seed or stimulus set changed?")
        if repeat and row.get("dropped_flag") == "1":
            insert_repeat(trials, i, protocol.timing.max_repeats)


def run_session(
    protocol_file: str | Path,
    participant: str,
    *,
    session: int = 1,
    out: str | Path | None = None,
    stimuli: str | Path | None = None,
    simulate: str | Path | None = None,
    windowed: bool = False,
    resume: bool = False,
    force: bool = False,
    seed: int | None = None,
    realtime: bool = False,
    window: bool = True,
    screenshot_dir: str | Path | None = None,
    refresh_hz: float | None = None,
    report: bool = True,
    argv: list[str] | None = None,
    triggers: dict[str, str | None] | None = None,
) -> SessionResult:
    """Run (or resume) one session of a protocol.

    Parameters
    ----------
    protocol_file : str | Path
        The ``kind: protocol`` YAML.
    participant : str
        BIDS participant label (letters and digits).
    session : int
        Session number.
    out : str | Path | None
        The session folder (default ``data/sub-<id>/ses-<n>/beh``, the BIDS layout).
    stimuli : str | Path | None
        Replace the protocol's stimulus source (manifest/factor-table CSV or a folder holding one).
    simulate : str | Path | None
        ``"default"`` or a participant-model YAML: answers come from a simulated participant
        and time is virtual (fast) unless ``realtime``.
    windowed : bool
        A window instead of full screen (always windowed when simulating).
    resume : bool
        Continue a crashed/aborted session in the same folder at the next trial.
    force : bool
        Replace an existing session folder.
    seed : int | None
        Seed of orders and jitter (default: derived from protocol, participant and session).
    realtime : bool
        Simulated sessions: flip every frame, paced to the refresh rate.
    window : bool
        False: simulated sessions run without any window (virtual clock only).
    screenshot_dir : str | Path | None
        Save the first frame of each kind of screen as PNG.
    refresh_hz : float | None
        Override the refresh rate (default: protocol's, else measured, else 60).
    report : bool
        Write the session report at the end.
    argv : list of str | None
        Command line for the provenance record.
    triggers : dict | None
        ``backend`` and/or ``address`` replacing the protocol's trigger settings (None values
        keep the protocol's); the sidecar records the settings used.

    Returns
    -------
    SessionResult
        Paths, counts, status.
    """
    check_label(participant, "--participant")
    session = check_session(session, "--session")
    if simulate is None and (realtime or not window):
        raise AppealInputError("--realtime and --no-window only apply to simulated sessions (--simulate MODEL)")
    protocol_file = Path(protocol_file)
    protocol = _with_triggers(load_protocol(protocol_file), triggers or {}, protocol_file)
    model = load_participant_model(simulate) if simulate is not None else None
    full, main = session_stimuli(protocol, protocol_file, stimuli)
    out = Path(out) if out is not None else Path("data") / f"sub-{participant}" / f"ses-{session}" / "beh"
    paths = session_paths(out, participant, session, protocol.task)
    protocol_hash = file_sha256(protocol_file)
    previous: dict[str, Any] = {}
    if resume and paths["sidecar"].is_file():
        previous = read_sidecar(paths["sidecar"])
        if previous.get("ProtocolSHA256") != protocol_hash:
            raise AppealInputError(f"{protocol_file}: changed since the session started (sha256 differs from "
                                   f"{paths['sidecar']}); resume with the original protocol")
        if seed is not None and seed != previous.get("Seed"):
            raise AppealInputError(f"--seed: the session started with seed {previous.get('Seed')}, got {seed}")
        seed = previous.get("Seed")
        if not isinstance(seed, int) or isinstance(seed, bool) or not isinstance(previous.get("RefreshRate", 0.0), (int, float)):
            raise AppealInputError(f"{paths['sidecar']}: Seed/RefreshRate: expected numbers (the sidecar was edited?)")
    elif resume and out.is_dir() and any(out.iterdir()):
        raise AppealInputError(f"{out}: --resume: no session sidecar {paths['sidecar'].name} here to resume from")
    if seed is None:
        seed = default_seed(protocol.name, participant, session)
    if model is not None:
        mode = "realtime" if realtime else "virtual"
    else:
        mode = "live"
    known_hz = _refresh_before_window(previous, refresh_hz, protocol, measured=mode == "live" and window)
    if known_hz is not None:  # bad inputs (e.g. a clip's fps that does not divide it) fail before the folder exists
        build_trials(protocol, main, seed=seed, refresh_hz=known_hz, source=str(protocol_file), full_set=full)
    elif protocol.psychophysics is not None:  # its levels and images are checked before the folder exists
        PsychophysicsPlan(protocol, main, seed=seed, source=str(protocol_file))
    with output_run(out, force=force, resume=resume, seed=seed, inputs=[protocol_file, full.source], argv=argv) as run:
        out = run.out
        paths = session_paths(out, participant, session, protocol.task)
        for what, p in paths.items():
            require_inside(out, p, f"the session's {what} file")
        answers = None
        if model is None and protocol.demographics and not previous:
            # the dialog comes first and alone: before the PsychoPy window (and its frame-rate test)
            from experiments.demographics import ask_demographics

            answers = ask_demographics(protocol.demographics, protocol.title or protocol.name)
        win = None
        if window:
            size = SIM_WINDOW if model is not None else protocol.screen.window_size
            win = _open_window(protocol, fullscreen=not windowed and model is None, size=size)
        measured = None
        pace = mode == "realtime"
        if previous:
            hz = float(previous["RefreshRate"])
        elif refresh_hz is not None:
            hz = float(refresh_hz)
        elif protocol.screen.refresh_hz is not None:
            hz = float(protocol.screen.refresh_hz)
        elif mode == "live" and win is not None:
            measured = _measure_refresh(win)
            shown = display_refresh(measured)
            if shown is None:
                logger.warning("measured refresh %s Hz is no display's rate (no vsync?): using 60 Hz, paced in "
                               "software (give --refresh-hz if the display runs at another rate)", measured)
                hz, pace = 60.0, True
            else:
                hz = shown
        else:
            hz = 60.0
        plan = (PsychophysicsPlan(protocol, main, seed=seed, source=str(protocol_file))
                if protocol.psychophysics is not None else None)
        trials = build_trials(protocol, main, seed=seed, refresh_hz=hz, source=str(protocol_file), full_set=full,
                              plan=plan)
        columns = beh_columns(protocol, clips=full.has_clips)
        done_rows = read_completed(paths["beh"], columns) if resume else []
        check_resume(done_rows, trials, paths["beh"], protocol, plan, hz)
        start = len(done_rows)
        sidecar = {
            "TaskName": protocol.task, "Protocol": str(protocol_file.resolve()), "ProtocolName": protocol.name,
            "ProtocolSHA256": protocol_hash, "Stimuli": str(full.source), "StimuliSHA256": file_sha256(full.source),
            "participant_id": participant, "Session": session, "Seed": seed, "RefreshRate": hz,
            "RefreshRateMeasured": measured, "TimingMode": mode, "SoftwarePacing": pace,
            "Simulated": str(simulate) if simulate is not None else None,
            "Screen": {"size": list(win.size) if win is not None else None,
                       "fullscreen": bool(getattr(win, "_isFullScr", False)) if win is not None else False,
                       "background": protocol.screen.background},
            "Triggers": protocol.triggers.model_dump() if protocol.triggers is not None else None,
            "SoftwareVersions": package_versions(), "Platform": platform.platform(),
            "NumberOfTrials": len(trials), "Started": previous.get("Started", now_iso()),
            "Resumed": [*previous.get("Resumed", []), *([now_iso()] if start else [])],
            "Status": "running", "Columns": column_descriptions(protocol, columns),
            "DroppedFrameThreshold": f"flip intervals over {DROP_THRESHOLD} refresh periods",
        }
        write_sidecar(paths["sidecar"], sidecar)
        status, completed, shots = "running", start, {}
        if start >= len(trials):
            logger.info("session already complete (%d trials)", len(trials))
            status = "complete"
        else:
            with _terminate_as_exit(), _sidecar_on_failure(sidecar, paths):
                status, completed, shots = _present(protocol, trials, start, columns, paths, win, hz, mode, pace,
                                                     model, seed, participant, session, answers, screenshot_dir, full,
                                                     part=len(sidecar["Resumed"]) + 1, plan=plan)
        sidecar.update(Status=status, CompletedTrials=completed, NumberOfTrials=len(trials), Ended=now_iso())
        write_sidecar(paths["sidecar"], sidecar)
        run.extra.update(status_session=status, completed_trials=completed, n_trials=len(trials))
        rep = None
        if report and completed:
            from experiments.report import write_session_report

            rep = write_session_report(paths, hz)
    return SessionResult(out=out, beh=paths["beh"], sidecar=paths["sidecar"], n_trials=len(trials), completed=completed,
                         status=status, timing_mode=mode, refresh_hz=hz, report=rep, screenshots=shots)


@contextmanager
def _sidecar_on_failure(sidecar: dict[str, Any], paths: dict[str, Path]) -> Iterator[None]:
    """Record ``Status: crashed`` (and the trials on disk) when the session ends by an exception."""
    try:
        yield
    except BaseException as exc:
        done = len(read_completed(paths["beh"])) if paths["beh"].is_file() else 0
        sidecar.update(Status="crashed", CompletedTrials=done, Ended=now_iso(),
                       Error=f"{type(exc).__name__}: {exc}".strip().rstrip(":"))
        write_sidecar(paths["sidecar"], sidecar)
        raise


@contextmanager
def _terminate_as_exit() -> Iterator[None]:
    """SIGTERM (e.g. ``kill``, a closing terminal) unwinds like an exception, so files are closed
    and the sidecar says how the session ended; the previous handler is restored after."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def _exit(signum: int, _frame: Any) -> None:
        raise SystemExit(128 + signum)

    old = signal.signal(signal.SIGTERM, _exit)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def _present(protocol: Protocol, trials: list[Trial], start: int, columns: list[str], paths: dict[str, Path],
             win: Any, hz: float, mode: str, pace: bool, model: Any, seed: int, participant: str, session: int,
             answers: dict[str, Any] | None, screenshot_dir: str | Path | None, full: Any,
             part: int = 1, plan: PsychophysicsPlan | None = None) -> tuple[str, int, dict]:
    from experiments.responders import HumanResponder, ModelResponder, SessionAborted

    display = win if win is not None else NoWindow()
    presenter = Presenter(display, hz, mode=mode, pace=pace)
    screens = None
    if win is not None:
        from experiments.screens import Screens

        screens = Screens(win, protocol)
    deadline = protocol.timing.response_deadline_s
    if model is not None:
        levels = {f: full.levels(f) for f in protocol.stimuli.factors}
        sim = SimulatedParticipant(model, levels, int(np.random.SeedSequence([seed, 1]).generate_state(1)[0]))
        responder: Any = ModelResponder(sim, presenter, deadline)
        answers = sim.demographics(protocol.demographics)
    else:
        responder = HumanResponder(win, screens, presenter, deadline)
    if answers:
        write_demographics(paths["demographics"], participant, answers)
    sender = None
    if protocol.triggers is not None:
        backend = open_backend(protocol.triggers, log_path=paths["triggers"], clock=presenter.clock,
                               simulate=model is not None)
        sender = TriggerSender(backend, presenter.clock)
    writer = TsvWriter(paths["beh"], columns, fsync="background")
    flips = TsvWriter(paths["flips"], flip_columns(full.has_clips), fsync="off")
    runner = SessionRunner(protocol, presenter, screens, responder, writer, flips, sender,
                           {"participant_id": participant, "session": session,
                            "part": part},
                           screenshot_dir=Path(screenshot_dir) if screenshot_dir is not None else None)
    status, completed = "crashed", start
    after_trial, total = None, len(trials) - start
    if plan is not None:
        after_trial = _procedure_step(plan, pair_trial_maker(protocol, hz))
        total = None if plan.max_trials is None else plan.max_trials - start
    try:
        completed = runner.run(trials, start, after_trial=after_trial, progress=lambda it: progress(
            it, total=total, desc=f"sub-{participant} {protocol.name}"))
        status = "complete"
    except SessionAborted:
        completed = len(read_completed(paths["beh"]))
        status = "aborted"
        logger.warning("session aborted after %d of %d trials; continue with --resume", completed, len(trials))
    finally:
        writer.close()
        flips.close()
        if sender is not None:
            sender.close()
        if win is not None:
            win.close()
    return status, completed, dict(runner.shots)


def _procedure_step(plan: PsychophysicsPlan, make: Any) -> Any:
    """The runner's ``after_trial`` of a psychophysics session: score the answer, update the
    track's procedure (its state and estimate go in the row) and append the next trial."""
    answer = f"response_{plan.response.name}"

    def after_trial(trials: list[Trial], i: int, row: dict[str, Any]) -> None:
        row.update(plan.answered(trials, i, row.get(answer), make))
    return after_trial


def column_descriptions(protocol: Protocol, columns: list[str]) -> dict[str, dict[str, str]]:
    """BIDS sidecar descriptions (``{column: {"Description": ...}}``) of a session file's columns."""
    desc = {
        "participant_id": "BIDS participant label", "session": "session number",
        "part": "session part: 1, then +1 after each --resume (times and frames restart at 0 in each part)",
        "trial": "trial number in presentation order (1-based)", "phase": "anchor, practice, main or end",
        "block": "block label", "repetition": "repetition of this stimulus (1-based)",
        "stimulus": "image file as named in the stimulus table",
        "fixation_frames": "fixation cross duration in frames", "fixation_onset_s": "fixation onset flip time",
        "onset_frame": "frame index of the stimulus onset flip", "onset_s": "stimulus onset flip time (s)",
        "offset_s": "time of the first flip after the stimulus (s)", "duration_frames": "intended stimulus frames",
        "shown_frames": "flips the stimulus was drawn for", "shown_s": "offset_s - onset_s",
        "dropped_frames": "flip intervals longer than 1.5 frames while the stimulus was up",
        "trigger": "EEG trigger code sent on the onset flip", "trigger_s": "time the trigger was sent (s)",
        "trigger_flip_ms": "trigger_s - onset_s in ms (clips: minus the flip time of the frame the trigger marks)",
        "dropped_flag": "1 if the stimulus had dropped frames (dropped_frames, clip_dropped_frames or "
                        "clip_frame_errors > 0; timing.on_dropped_frames: flag | repeat)",
        "repeat_of": "this trial repeats trial N, whose stimulus had dropped frames (timing.on_dropped_frames: repeat)",
        **CLIP_DESCRIPTIONS,
    }
    for f in protocol.stimuli.factors:
        desc[f] = f"factor '{f}' level"
    if protocol.psychophysics is not None:
        desc.update(PSYCHOPHYSICS_DESCRIPTIONS, second_onset_s="onset flip time of the second face (sequence)")
    for name in protocol.response_names:
        desc[f"response_{name}"] = f"answer on '{name}'"
        desc[f"rt_{name}"] = f"response time on '{name}' (s from screen onset)"
        desc[f"correct_{name}"] = f"1 if '{name}' matched the stimulus's level"
    return {c: {"Description": desc.get(c, c)} for c in columns}

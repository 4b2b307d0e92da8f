"""Walk a trial list on a :class:`~experiments.display.Presenter`: fixation, stimulus (trigger on
the onset flip), responses, ITI — one durable TSV row per completed trial.

A clip (an animated stimulus, :mod:`experiments.clips`) is decoded ahead on a helper thread,
made into textures before its trial's first screen, shown one frame per ``flips_per_frame``
flips (each flip logged with the frame it showed) and freed after it; a trial with dropped
frames is flagged or repeated at the end of its block (``timing.on_dropped_frames``)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from appeal.levels import level_key
from experiments.clips import CLIP_COLUMNS, ClipPlan, FramePrefetcher
from experiments.datafile import TsvWriter
from experiments.display import DROP_THRESHOLD, ClipTiming, PhaseTiming, Presenter
from experiments.protocol_schema import ClassificationSpec, LikertSpec, Protocol
from experiments.psychophysics import PSYCHOPHYSICS_COLUMNS
from experiments.screens import markdown_to_text, save_back_buffer
from experiments.triggers import TriggerSender
from experiments.trials import Trial, insert_repeat

__all__ = ["beh_columns", "flip_columns", "SessionRunner", "FLIP_COLUMNS", "DROP_COLUMNS", "had_dropped_frames"]

FLIP_COLUMNS = ["trial", "screen", "frame", "time_s"]
#: The columns ``timing.on_dropped_frames: flag | repeat`` adds.
DROP_COLUMNS = ("dropped_flag", "repeat_of")


def flip_columns(clips: bool = False) -> list[str]:
    """The flip log's columns (a session with clips adds ``clip_frame``: the frame each flip showed)."""
    return [*FLIP_COLUMNS, *(["clip_frame"] if clips else [])]


def beh_columns(protocol: Protocol, clips: bool = False) -> list[str]:
    """The ``_beh.tsv`` columns a protocol produces, in order.

    Parameters
    ----------
    protocol : Protocol
        The protocol.
    clips : bool
        Whether its stimulus set holds clips (adds :data:`experiments.clips.CLIP_COLUMNS`).
    """
    cols = ["participant_id", "session", "part", "trial", "phase", "block", "repetition", "stimulus", *protocol.stimuli.factors]
    if protocol.timing.fixation_s is not None:
        cols += ["fixation_frames", "fixation_onset_s"]
    cols += ["onset_frame", "onset_s", "offset_s", "duration_frames", "shown_frames", "shown_s", "dropped_frames"]
    if clips:
        cols += CLIP_COLUMNS
    if protocol.timing.on_dropped_frames != "log":
        cols += DROP_COLUMNS
    for r in protocol.responses:
        cols += [f"response_{r.name}", f"rt_{r.name}"]
        if isinstance(r, ClassificationSpec):
            if r.factor is not None:
                cols.append(f"correct_{r.name}")
            if r.intensity is not None:
                cols += [f"response_{r.intensity.name}", f"rt_{r.intensity.name}"]
    if protocol.psychophysics is not None:
        cols += PSYCHOPHYSICS_COLUMNS
        if protocol.psychophysics.presentation == "sequence":
            cols.append("second_onset_s")
    cols += ["trigger", "trigger_s", "trigger_flip_ms"]
    return cols


def had_dropped_frames(row: dict[str, Any]) -> bool:
    """Whether a trial's row counts a late flip or a clip frame not shown for its flips."""
    return any((row.get(c) or 0) > 0 for c in ("dropped_frames", "clip_dropped_frames", "clip_frame_errors"))


class SessionRunner:
    """Presents trials and writes each completed one.

    Parameters
    ----------
    protocol : Protocol
        The protocol.
    presenter : Presenter
        Frames and clock.
    screens : experiments.screens.Screens or None
        Drawing (None: window-less virtual mode).
    responder : HumanResponder or ModelResponder
        Who answers.
    writer : TsvWriter
        The ``_beh.tsv``.
    flips : TsvWriter or None
        The flip log (every flip of every screen).
    sender : TriggerSender or None
        EEG triggers.
    ids : dict
        ``participant_id``, ``session`` and ``part`` (1, +1 after each resume) written on every row.
    screenshot_dir : Path or None
        Save the first frame of every kind of screen as PNG here.
    """

    def __init__(self, protocol: Protocol, presenter: Presenter, screens: Any, responder: Any, writer: TsvWriter,
                 flips: TsvWriter | None, sender: TriggerSender | None, ids: dict[str, Any],
                 screenshot_dir: Path | None = None):
        self.protocol = protocol
        self.p = presenter
        self.screens = screens
        self.responder = responder
        self.writer = writer
        self.flips = flips
        self.sender = sender
        self.ids = ids
        self.screenshot_dir = screenshot_dir
        self.shots: dict[str, Path] = {}
        self._flip_rows: list[dict[str, Any]] = []
        self._trial = 0
        self.prefetcher = FramePrefetcher()
        self._upcoming: ClipPlan | None = None
        pulse = protocol.triggers.pulse_ms if protocol.triggers is not None else 10.0
        self.pulse_frames = max(1, math.ceil(pulse / 1000 * presenter.hz - 1e-9))

    # ------------------------------------------------------------------ screens
    def show(self, kind: str, draw: Callable[[], None] | None, n_frames: int, *,
             until: Callable[[int], bool] | None = None, on_onset: Callable[[], None] | None = None) -> PhaseTiming:
        """Show one screen; log its flips; save its first frame if it is the first of its kind."""
        shot = self._shot(kind) if draw is not None else None
        timing = self.p.show(draw if self.screens is not None else None, n_frames, on_onset=on_onset, until=until,
                             screenshot=shot)
        for i, t in enumerate(timing.flips):
            frame = timing.onset_frame + (i if not self.p.virtual else 0)
            self._flip_rows.append({"trial": self._trial, "screen": kind, "frame": frame, "time_s": t})
        return timing

    def _shot(self, kind: str) -> Callable[[], None] | None:
        """A screenshot of the back buffer as ``kind.png``, unless one was taken (or none are wanted)."""
        if self.screenshot_dir is None or kind in self.shots or self.screens is None:
            return None
        path = self.screenshot_dir / f"{kind}.png"

        def shot() -> None:
            self.shots[kind] = save_back_buffer(self.screens.win, path)
        return shot

    def show_clip(self, kind: str, plan: ClipPlan, title: str, on_onset: Callable[[], None] | None) -> ClipTiming:
        """Show a clip (frame-locked, :meth:`Presenter.show_clip`); log its flips with the frame each showed.

        Screenshots: frame 0 as ``KIND.png`` and the apex frame as ``KIND_apex.png``.
        """
        sc = self.screens
        draws = None
        if sc is not None:
            def frame(k: int) -> Callable[[], None]:
                def draw() -> None:
                    sc.draw_clip_frame(k)
                    if title:
                        sc.title.text = title
                        sc.title.draw()
                return draw
            draws = [frame(k) for k in range(plan.n_frames)]
        shots = {k: fn for k, fn in ((0, self._shot(kind)), (plan.apex_frame, self._shot(f"{kind}_apex"))) if fn}
        marks = {plan.trigger_frame: on_onset} if on_onset is not None else {}
        timing = self.p.show_clip(draws, plan.n_frames, plan.flips_per_frame, plan.hold_flips, marks=marks, shots=shots)
        for t, k, number in zip(timing.flips, timing.flip_frames, timing.flip_numbers):
            self._flip_rows.append({"trial": self._trial, "screen": kind, "frame": number, "time_s": t, "clip_frame": k})
        return timing

    def page(self, kind: str, text: str, *, title: str = "", min_s: float = 0.0) -> None:
        """An instruction/break page the participant continues from (Space)."""
        hint = self.protocol.instructions.continue_text
        draw = None if self.screens is None else (lambda: self.screens.draw_text(markdown_to_text(text), title=title, hint=hint))
        self.responder.wait_continue(kind, self.show, draw, min_frames=max(1, round(min_s * self.p.hz)))
        self._flush_flips()

    def _flush_flips(self) -> None:
        if self.flips is not None and self._flip_rows:
            self.flips.write_many(self._flip_rows)
        self._flip_rows = []

    # ------------------------------------------------------------------ responses
    def _ask(self, trial: Trial, row: dict[str, Any]) -> None:
        sc = self.screens
        visible = self.protocol.timing.stimulus_visible_during_response

        def likert_draw(spec: LikertSpec) -> Callable[[int | None], None] | None:
            return None if sc is None else (lambda m: sc.draw_likert(spec, with_stimulus=visible, marker=m))

        for spec in self.protocol.responses:
            if isinstance(spec, LikertSpec):
                v, rt = self.responder.likert(spec, trial.factors, self.show, likert_draw(spec))
                row[f"response_{spec.name}"], row[f"rt_{spec.name}"] = v, rt
                continue
            draw = None if sc is None else (lambda c, s=spec: sc.draw_classification(s, with_stimulus=visible, chosen=c))
            if trial.pair is not None:
                v, rt = self.responder.discriminate(spec, trial.extra["psy"], trial.factors, self.show, draw)
            else:
                v, rt = self.responder.classify(spec, trial.factors, self.show, draw)
            row[f"response_{spec.name}"], row[f"rt_{spec.name}"] = v, rt
            if spec.factor is not None:
                truth = trial.factors.get(spec.factor)
                row[f"correct_{spec.name}"] = None if v is None else int(v == truth)
            if spec.intensity is not None:
                skip = v is None or v in {level_key(s) for s in spec.skip_intensity_for}
                if skip:
                    iv, irt = (spec.skip_value if v is not None else None), None
                else:
                    iv, irt = self.responder.likert(spec.intensity, trial.factors, self.show, likert_draw(spec.intensity))
                row[f"response_{spec.intensity.name}"], row[f"rt_{spec.intensity.name}"] = iv, irt

    # ------------------------------------------------------------------ trials
    def run_trial(self, trial: Trial, *, lead_in: bool = False) -> dict[str, Any]:
        """Present one trial and return its row (not yet written)."""
        self._trial = trial.trial
        sc = self.screens
        row: dict[str, Any] = {**self.ids, **trial.as_dict(), "duration_frames": trial.stimulus_frames}
        if trial.break_before and self.protocol.breaks is not None:
            self.page("break", self.protocol.breaks.text, min_s=self.protocol.breaks.min_s)
            lead_in = True
        if trial.clip is not None:
            row["clip_preload_ms"] = self._preload_clip(trial.clip)
        elif trial.pair is not None and sc is not None:
            sc.load_pair(trial.pair.paths)
        elif sc is not None:
            sc.load(trial.path)
        fix_after = self.protocol.timing.fixation_position == "after"
        draw_fix = None if sc is None else sc.draw_fixation
        if trial.fixation_frames and (not fix_after or lead_in):
            fix = self.show("fixation", draw_fix, trial.fixation_frames)
            if not fix_after:
                row["fixation_onset_s"] = fix.onset_s
        on_onset = None
        if trial.trigger is not None and self.sender is not None:
            code = trial.trigger
            on_onset = lambda: self.sender.send(code)  # noqa: E731 - runs on the onset flip
            marked = 0 if trial.clip is None else trial.clip.trigger_frame * trial.clip.flips_per_frame
            self.p.at_frame(self.p.frame + marked + self.pulse_frames, self.sender.reset)
            n_sent = len(self.sender.sent)
        title = trial.title

        def draw_stim() -> None:
            sc.draw_stimulus()
            if title:
                sc.title.text = title
                sc.title.draw()

        kind = "stimulus" if trial.phase == "main" else trial.phase
        if trial.pair is not None:
            stim = self._show_pair(kind, trial, row, on_onset)
        elif trial.clip is not None:
            stim: PhaseTiming = self.show_clip(kind, trial.clip, title, on_onset)
            if sc is not None:
                sc.end_clip()
        else:
            stim = self.show(kind, None if sc is None else draw_stim, trial.stimulus_frames, on_onset=on_onset)
        # the next clip decodes on the helper thread while this trial's other screens run; it starts on
        # the first flip after the stimulus, which closes the stimulus's last frame interval first
        if sc is not None and self._upcoming is not None:
            self.p.at_frame(self.p.frame, self.prefetcher.prefetch, self._upcoming)
        row.update(onset_frame=stim.onset_frame, onset_s=stim.onset_s, shown_frames=stim.frames)
        if isinstance(stim, ClipTiming):
            row.update(_clip_counts(trial.clip, stim))
        if on_onset is not None:
            sent = self.sender.sent[n_sent:]
            if len(sent) != 1:
                raise RuntimeError(f"trial {trial.trial}: {len(sent)} triggers sent on the onset flip (expected 1)")
            marked_s = stim.onset_s if not isinstance(stim, ClipTiming) else stim.frame_onsets[trial.clip.trigger_frame]
            row["trigger_s"] = sent[0][1]
            row["trigger_flip_ms"] = (sent[0][1] - marked_s) * 1000
        else:
            row["trigger"] = None
        after: PhaseTiming | None = None
        if trial.fixation_frames and fix_after:
            after = self.show("fixation", draw_fix, trial.fixation_frames)
            row["fixation_onset_s"] = after.onset_s
        if trial.respond:
            n_flips = len(self._flip_rows)
            self._ask(trial, row)
            if after is None and len(self._flip_rows) > n_flips:
                after = PhaseTiming(0, self._flip_rows[n_flips]["time_s"], 0)
        if trial.iti_frames or after is None:
            iti = self.show("blank", None, max(trial.iti_frames, 1))
            after = after or iti
        row["offset_s"] = after.onset_s
        row["shown_s"] = after.onset_s - stim.onset_s
        period = 1.0 / self.p.hz
        edges = [*stim.flips, after.onset_s] if not self.p.virtual else []
        row["dropped_frames"] = sum(1 for a, b in zip(edges, edges[1:]) if b - a > DROP_THRESHOLD * period)
        if isinstance(stim, ClipTiming):
            row["clip_dropped_frames"] = self.p.dropped_since(stim.intervals_from)
        return row

    def _show_pair(self, kind: str, trial: Trial, row: dict[str, Any],
                   on_onset: Callable[[], None] | None) -> PhaseTiming:
        """A pair trial's faces: side by side, or the first, a blank (``isi_s``) and the second.

        Returns the first face's timing (the trial's onset); a sequence's second onset goes in
        ``row["second_onset_s"]``.
        """
        sc, pair = self.screens, trial.pair
        if pair.layout == "side_by_side":
            return self.show(kind, None if sc is None else sc.draw_pair, trial.stimulus_frames, on_onset=on_onset)
        first = self.show(kind, None if sc is None else (lambda: sc.draw_pair(0)), trial.stimulus_frames,
                          on_onset=on_onset)
        isi = self.show("isi", None, pair.isi_frames).flips if pair.isi_frames else []
        second = self.show(f"{kind}_second", None if sc is None else (lambda: sc.draw_pair(1)), trial.stimulus_frames)
        row["second_onset_s"] = second.onset_s
        return PhaseTiming(first.onset_frame, first.onset_s, first.frames + pair.isi_frames + second.frames,
                           [*first.flips, *isi, *second.flips])

    def _preload_clip(self, plan: ClipPlan) -> float | None:
        """Make the clip's textures before the trial's first screen; the time it took (ms)."""
        if self.screens is None:
            return None
        t0 = time.perf_counter()
        self.screens.load_clip(self.prefetcher.take(plan))
        return (time.perf_counter() - t0) * 1000

    def _handle_drops(self, trials: list[Trial], index: int, row: dict[str, Any]) -> None:
        """``timing.on_dropped_frames``: flag the row, and repeat the trial at the end of its block."""
        timing = self.protocol.timing
        if timing.on_dropped_frames == "log":
            return
        row["dropped_flag"] = int(had_dropped_frames(row))
        if timing.on_dropped_frames == "repeat" and row["dropped_flag"]:
            insert_repeat(trials, index, timing.max_repeats)

    def run(self, trials: list[Trial], start: int = 0, *, progress: Callable[[Any], Any] = iter,
            after_trial: Callable[[list[Trial], int, dict[str, Any]], None] | None = None) -> int:
        """Present ``trials[start:]``, writing each row durably; returns the number completed.

        ``trials`` grows when a trial is repeated (``timing.on_dropped_frames: repeat``), and
        ``after_trial(trials, index, row)`` (a psychophysics session's procedures) may complete
        the row and append the next trial before the row is written.
        """
        pr = self.protocol
        if start == 0:
            for i, text in enumerate([*pr.instructions.pages, *(f.read_text(encoding="utf-8") for f in pr.instructions.files)]):
                self.page(f"instructions{'' if i == 0 else i + 1}", text)
        else:
            self.page("resume", f"The session continues at trial {start + 1} of {len(trials)}.")
        done = start
        lead_in = True
        self.prefetcher.prefetch(_next_clip(trials, start) if self.screens is not None else None)
        try:
            for i in progress(_positions(trials, start)):
                self._upcoming = _next_clip(trials, i + 1)
                row = self.run_trial(trials[i], lead_in=lead_in)
                lead_in = False
                self._handle_drops(trials, i, row)
                if after_trial is not None:
                    after_trial(trials, i, row)
                self.writer.write(row)
                self._flush_flips()
                done += 1
        finally:
            self.prefetcher.close()
            if self.screens is not None:
                self.screens.free_clip()
        # the closing page is timed (no key needed), so an unattended session ends by itself
        end_frames = 1 if self.p.virtual else max(1, round(2.0 * self.p.hz))
        draw = None if self.screens is None else (lambda: self.screens.draw_text(markdown_to_text(pr.instructions.end_text)))
        self.show("end", draw, end_frames)
        self._flush_flips()
        return done


def _positions(trials: list[Trial], start: int) -> Iterator[int]:
    """``start, start + 1, ...`` while the (growing) list has trials there."""
    i = start
    while i < len(trials):
        yield i
        i += 1


def _next_clip(trials: list[Trial], start: int) -> ClipPlan | None:
    """The clip of the first trial from ``start`` on that shows one."""
    return next((t.clip for t in trials[start:] if t.clip is not None), None)


def _clip_counts(plan: ClipPlan, timing: ClipTiming) -> dict[str, Any]:
    """A clip trial's frame counts and mark times, from what each flip showed."""
    shown = timing.frame_flips
    errors = sum(1 for n in shown if n != plan.flips_per_frame) + (plan.n_frames - len(shown))
    return {"clip_frames_shown": sum(1 for n in shown if n > 0), "clip_flips": sum(shown),
            "clip_hold_flips": timing.hold_flips, "clip_frame_errors": errors,
            "clip_onset_s": timing.frame_onsets[plan.onset_frame], "clip_apex_s": timing.frame_onsets[plan.apex_frame]}

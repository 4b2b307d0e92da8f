"""Frame-counted presentation: a PsychoPy window, or no window, with a real or virtual clock.

Three timing modes (the session sidecar records which one ran):

``live``
    Every frame is drawn and flipped; durations are counted in flips; each flip time is the
    ``win.flip()`` timestamp. This is how participants are tested.
``realtime``
    Like ``live`` but responses come from a simulated participant; when the display has no
    vsync (virtual screens), flips are paced in software to the nominal refresh rate.
``virtual``
    The fast simulated mode: each screen is drawn and flipped ONCE (so images, scales and
    text really render), then a virtual frame counter advances by the intended number of
    frames; all times are ``frame / refresh_hz``. A 540-trial ERP session takes seconds.
    Without a window (``no_window``) nothing is drawn and only the virtual clock runs.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = ["PhaseTiming", "ClipTiming", "Presenter", "NoWindow", "DROP_THRESHOLD"]

#: A flip interval longer than this many refresh periods is a dropped frame (PsychoPy's
#: ``win.refreshThreshold`` is set to it while a clip is up; the still stimuli's count uses it too).
DROP_THRESHOLD = 1.5


@dataclass
class PhaseTiming:
    """When one screen (fixation, stimulus, response, ...) was shown."""

    onset_frame: int
    onset_s: float
    frames: int
    flips: list[float] = field(default_factory=list)


@dataclass
class ClipTiming(PhaseTiming):
    """When a clip was shown: the stimulus screen's timing plus what each flip showed.

    Attributes
    ----------
    flip_frames : list of int
        The clip frame drawn before each flip (the held last frame's flips included).
    flip_numbers : list of int
        The session frame number of each flip.
    frame_flips : list of int
        Refreshes per clip frame, counted as its flips happen (the hold not included; the
        virtual mode flips a frame once and counts the frames it advances the clock by).
    frame_onsets : list of float
        Time of each clip frame's first flip.
    hold_flips : int
        Flips of the held last frame.
    intervals_from : tuple of int or None
        ``(len(win.frameIntervals), win.nDroppedFrames)`` when PsychoPy's recording started
        (None: no PsychoPy window, or the virtual mode); see :meth:`Presenter.dropped_since`.
    """

    flip_frames: list[int] = field(default_factory=list)
    flip_numbers: list[int] = field(default_factory=list)
    frame_flips: list[int] = field(default_factory=list)
    frame_onsets: list[float] = field(default_factory=list)
    hold_flips: int = 0
    intervals_from: tuple[int, int] | None = None


class NoWindow:
    """The window-less display of the virtual mode: flips run the on-flip callbacks only."""

    def __init__(self) -> None:
        self._calls: list[tuple[Callable[..., Any], tuple]] = []

    def callOnFlip(self, fn: Callable[..., Any], *args: Any) -> None:  # noqa: N802 - PsychoPy's name
        self._calls.append((fn, args))

    def flip(self) -> float:
        calls, self._calls = self._calls, []
        for fn, args in calls:
            fn(*args)
        return 0.0

    def getMovieFrame(self, buffer: str = "front") -> None:  # noqa: N802 - PsychoPy's name
        return None

    def close(self) -> None:
        return None


class Presenter:
    """Shows screens for whole numbers of frames and stamps every flip.

    Parameters
    ----------
    win : psychopy.visual.Window or NoWindow
        Where to draw.
    refresh_hz : float
        Frames per second (measured or nominal).
    mode : {"live", "realtime", "virtual"}
        See the module docstring.
    pace : bool
        In ``live``/``realtime``: wait until each frame's nominal time before flipping
        (for displays without vsync).
    """

    def __init__(self, win: Any, refresh_hz: float, *, mode: str = "live", pace: bool = False):
        if mode not in ("live", "realtime", "virtual"):
            raise ValueError(f"mode must be live, realtime or virtual (got {mode!r})")
        self.win = win
        self.hz = float(refresh_hz)
        self.period = 1.0 / self.hz
        self.mode = mode
        self.pace = pace and mode != "virtual"
        self.frame = 0
        self._t0 = time.perf_counter()
        self._next_flip = 0.0
        self._pending: list[tuple[int, Callable[..., Any], tuple]] = []
        # PsychoPy stamps flips with logging.defaultClock; map those stamps onto our clock
        self._ps_clock = None
        if not isinstance(win, NoWindow) and mode != "virtual":
            from psychopy import logging as ps_logging

            self._ps_clock = ps_logging.defaultClock
            self._ps_offset = time.perf_counter() - self._ps_clock.getTime()
        self.flip_log: list[tuple[int, float]] = []
        self._stop_recording = False

    @property
    def virtual(self) -> bool:
        """Whether time is the virtual frame clock."""
        return self.mode == "virtual"

    def clock(self) -> float:
        """Session time in seconds (virtual: frame / refresh rate)."""
        if self.virtual:
            return self.frame * self.period
        return time.perf_counter() - self._t0

    def at_frame(self, frame: int, fn: Callable[..., Any], *args: Any) -> None:
        """Call ``fn(*args)`` on the flip of global frame ``frame`` (or the first flip after it)."""
        self._pending.append((frame, fn, args))

    def _flip(self, frames_advanced: int, on_flip: Callable[[], None] | None = None) -> float:
        due = [p for p in self._pending if p[0] <= self.frame]
        self._pending = [p for p in self._pending if p[0] > self.frame]
        for _, fn, args in due:
            self.win.callOnFlip(fn, *args)
        if on_flip is not None:
            self.win.callOnFlip(on_flip)
        if self.pace:
            wait = self._next_flip - self.clock()
            if wait > 0:
                time.sleep(wait)
        stamp = self.win.flip()
        if self._stop_recording:  # the first flip after a clip: it closed the clip's last interval
            self.win.recordFrameIntervals = False
            self._stop_recording = False
        if self.virtual:
            t = self.frame * self.period
        elif self._ps_clock is not None and stamp:
            t = stamp + self._ps_offset - self._t0
        else:
            t = self.clock()
        self._next_flip = max(self._next_flip + self.period, t + self.period * 0.5) if self.pace else 0.0
        self.flip_log.append((self.frame, t))
        self.frame += frames_advanced
        return t

    def _record_intervals(self) -> tuple[int, int] | None:
        """Switch PsychoPy's frame-interval recording on (a real window, not virtual)."""
        if self._ps_clock is None:
            return None
        self.win.refreshThreshold = DROP_THRESHOLD * self.period
        self.win.recordFrameIntervals = True  # the next flip only starts the count (PsychoPy skips it)
        return len(self.win.frameIntervals), int(self.win.nDroppedFrames)

    def dropped_since(self, start: tuple[int, int] | None) -> int | None:
        """PsychoPy's dropped-frame count since ``start`` (the increase of ``win.nDroppedFrames``).

        Call after the first flip that followed the clip (it closes the last frame's interval
        and switches the recording off); ``win.frameIntervals[start[0]:]`` holds the intervals.

        Returns
        -------
        int or None
            Late flips, or None without recording (no PsychoPy window, or the virtual mode).
        """
        if start is None:
            return None
        return int(self.win.nDroppedFrames) - start[1]

    def show_clip(self, draws: Sequence[Callable[[], None]] | None, n_frames: int, flips_per_frame: int,
                  hold_flips: int = 0, *, marks: Mapping[int, Callable[[], None]] | None = None,
                  shots: Mapping[int, Callable[[], None]] | None = None) -> ClipTiming:
        """Show a clip: frame k drawn before each of its ``flips_per_frame`` flips, then the hold.

        Parameters
        ----------
        draws : sequence of callable or None
            ``draws[k]()`` draws clip frame k (None: no window, the clock only).
        n_frames : int
            Frames in the clip.
        flips_per_frame : int
            Flips each frame stays up (the virtual mode flips each frame once and advances
            the clock by this many frames).
        hold_flips : int
            Flips of the last frame after the clip.
        marks : mapping of int to callable, optional
            ``{k: fn}``: ``fn`` runs on the first flip of frame k (``win.callOnFlip``), e.g. the trigger.
        shots : mapping of int to callable, optional
            ``{k: fn}``: ``fn`` runs once after frame k is first drawn, before its flip (screenshots).

        Returns
        -------
        ClipTiming
        """
        marks, shots = marks or {}, shots or {}
        timing = ClipTiming(self.frame, 0.0, 0)
        timing.intervals_from = None if self.virtual else self._record_intervals()
        per_flip = 1 if not self.virtual else flips_per_frame
        repeats = flips_per_frame if not self.virtual else 1
        for k in range(n_frames):
            timing.frame_flips.append(0)
            for j in range(repeats):
                if draws is not None:
                    draws[k]()
                if j == 0 and k in shots:
                    shots[k]()
                timing.flip_numbers.append(self.frame)
                t = self._flip(per_flip, marks.get(k) if j == 0 else None)
                timing.flips.append(t)
                timing.flip_frames.append(k)
                timing.frame_flips[k] += per_flip
                if j == 0:
                    timing.frame_onsets.append(t)
        if hold_flips:
            for _ in range(hold_flips if not self.virtual else 1):
                if draws is not None:
                    draws[n_frames - 1]()
                timing.flip_numbers.append(self.frame)
                timing.flips.append(self._flip(1 if not self.virtual else hold_flips))
                timing.flip_frames.append(n_frames - 1)
        timing.hold_flips = hold_flips
        timing.onset_s = timing.flips[0]
        timing.frames = self.frame - timing.onset_frame if self.virtual else len(timing.flips)
        self._stop_recording = timing.intervals_from is not None
        return timing

    def show(self, draw: Callable[[], None] | None, n_frames: int, *, on_onset: Callable[[], None] | None = None,
             until: Callable[[int], bool] | None = None, screenshot: Callable[[], None] | None = None) -> PhaseTiming:
        """Show ``draw`` for ``n_frames`` frames.

        Parameters
        ----------
        draw : callable or None
            Draws the screen (called before every flip; None = blank background).
        n_frames : int
            Frames to show (live/realtime) or to advance the virtual clock by.
        on_onset : callable, optional
            Run on the onset flip (``win.callOnFlip``), e.g. sending the trigger.
        until : callable, optional
            ``until(k)`` after the k-th flip; True ends the screen early (a response).
        screenshot : callable, optional
            Called once after the first draw, before its flip (back buffer holds the frame).

        Returns
        -------
        PhaseTiming
            Onset frame and time and every flip time.
        """
        n_frames = max(int(n_frames), 1)
        onset_frame = self.frame
        flips: list[float] = []
        if self.virtual:
            if draw is not None:
                draw()
            if screenshot is not None:
                screenshot()
            flips.append(self._flip(n_frames, on_onset))
            return PhaseTiming(onset_frame, flips[0], n_frames, flips)
        for k in range(n_frames):
            if draw is not None:
                draw()
            if k == 0 and screenshot is not None:
                screenshot()
            flips.append(self._flip(1, on_onset if k == 0 else None))
            if until is not None and until(k + 1):
                break
        return PhaseTiming(onset_frame, flips[0], len(flips), flips)

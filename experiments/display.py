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
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

__all__ = ["PhaseTiming", "Presenter", "NoWindow"]


@dataclass
class PhaseTiming:
    """When one screen (fixation, stimulus, response, ...) was shown."""

    onset_frame: int
    onset_s: float
    frames: int
    flips: list[float] = field(default_factory=list)


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

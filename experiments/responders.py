"""Who answers: a person (keyboard/mouse in the PsychoPy window) or a simulated participant."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from appeal.levels import level_key
from experiments.display import PhaseTiming, Presenter
from experiments.protocol_schema import ClassificationSpec, LikertSpec
from experiments.simulate import SimulatedParticipant

__all__ = ["SessionAborted", "HumanResponder", "ModelResponder", "ShowFn"]

#: ``show(kind, draw, n_frames, until=None, on_onset=None) -> PhaseTiming`` (the runner's).
ShowFn = Callable[..., PhaseTiming]
FOREVER = 10 ** 9


class SessionAborted(Exception):
    """The experimenter pressed Escape; completed trials are on disk and --resume continues."""


class ModelResponder:
    """Answers from a :class:`~experiments.simulate.SimulatedParticipant`.

    The response screen is shown for the model's response time (whole frames), with the
    chosen value marked, so screenshots and flip logs show what was answered.
    """

    human = False

    def __init__(self, participant: SimulatedParticipant, presenter: Presenter, deadline_s: float | None):
        self.p = participant
        self.presenter = presenter
        self.deadline_s = deadline_s

    def _timed(self) -> tuple[int, bool]:
        rt = self.p.rt()
        if self.deadline_s is not None and rt > self.deadline_s:
            return max(1, round(self.deadline_s * self.presenter.hz)), False
        return max(1, math.ceil(rt * self.presenter.hz)), True

    def likert(self, spec: LikertSpec, factors: dict[str, str], show: ShowFn,
               draw: Callable[[int | None], None] | None) -> tuple[int | None, float | None]:
        value = self.p.rate(spec, factors)
        frames, answered = self._timed()
        shown = show(spec.name, None if draw is None else (lambda: draw(value if answered else None)), frames)
        return (value, shown.frames / self.presenter.hz) if answered else (None, None)

    def classify(self, spec: ClassificationSpec, factors: dict[str, str], show: ShowFn,
                 draw: Callable[[str | None], None] | None) -> tuple[str | None, float | None]:
        truth = factors.get(spec.factor) if spec.factor else None
        value = self.p.classify(spec.name, spec.choices, truth, factors)
        frames, answered = self._timed()
        shown = show(spec.name, None if draw is None else (lambda: draw(value if answered else None)), frames)
        return (value, shown.frames / self.presenter.hz) if answered else (None, None)

    def discriminate(self, spec: ClassificationSpec, psy: dict[str, Any], factors: dict[str, str], show: ShowFn,
                     draw: Callable[[str | None], None] | None) -> tuple[str | None, float | None]:
        """A pair trial's answer from the model's psychometric function (:meth:`SimulatedParticipant.discriminate`)."""
        value = self.p.discriminate(spec, psy, factors)
        frames, answered = self._timed()
        shown = show(spec.name, None if draw is None else (lambda: draw(value if answered else None)), frames)
        return (value, shown.frames / self.presenter.hz) if answered else (None, None)

    def wait_continue(self, kind: str, show: ShowFn, draw: Callable[[], None] | None, min_frames: int = 1) -> None:
        show(kind, draw, max(min_frames, 1))


class HumanResponder:
    """Keyboard and mouse in the PsychoPy window; Escape aborts the session."""

    human = True

    def __init__(self, win: Any, screens: Any, presenter: Presenter, deadline_s: float | None):
        from psychopy import core, event

        self.win = win
        self.screens = screens
        self.presenter = presenter
        self.event = event
        self.core = core
        self.mouse = event.Mouse(win=win)
        self.deadline_frames = FOREVER if deadline_s is None else max(1, round(deadline_s * presenter.hz))

    def _keys(self, keys: list[str], clock: Any) -> list[tuple[str, float]]:
        got = self.event.getKeys(keyList=[*keys, "escape"], timeStamped=clock)
        if any(k == "escape" for k, _ in got):
            raise SessionAborted("escape pressed")
        return got

    def likert(self, spec: LikertSpec, factors: dict[str, str], show: ShowFn,
               draw: Callable[[int | None], None]) -> tuple[int | None, float | None]:
        slider = self.screens.likert(spec)
        slider.reset()
        self.event.clearEvents()
        clock = self.core.Clock()
        keys = [str(k) for k in range(1, spec.points + 1)] if spec.keys and spec.points <= 9 else []
        got: dict[str, Any] = {}

        def until(_k: int) -> bool:
            pressed = self._keys(keys, clock)
            if pressed:
                got["v"], got["rt"] = int(pressed[0][0]), pressed[0][1]
            elif slider.getRating() is not None:
                got["v"], got["rt"] = int(slider.getRating()), clock.getTime()
            return "v" in got

        show(spec.name, lambda: draw(None), self.deadline_frames, until=until, on_onset=clock.reset)
        return got.get("v"), got.get("rt")

    def classify(self, spec: ClassificationSpec, factors: dict[str, str], show: ShowFn,
                 draw: Callable[[str | None], None]) -> tuple[str | None, float | None]:
        buttons = self.screens.choices(spec)
        by_key = {c.key: level_key(c.value) for c in spec.choices if c.key}
        self.event.clearEvents()
        self.mouse.clickReset()
        clock = self.core.Clock()
        got: dict[str, Any] = {}

        def until(_k: int) -> bool:
            pressed = self._keys(list(by_key), clock)
            if pressed:
                got["v"], got["rt"] = by_key[pressed[0][0]], pressed[0][1]
                return True
            for box, _text, c in buttons:
                if self.mouse.isPressedIn(box, buttons=[0]):
                    got["v"], got["rt"] = level_key(c.value), clock.getTime()
                    return True
            return False

        show(spec.name, lambda: draw(None), self.deadline_frames, until=until, on_onset=clock.reset)
        return got.get("v"), got.get("rt")

    def discriminate(self, spec: ClassificationSpec, psy: dict[str, Any], factors: dict[str, str], show: ShowFn,
                     draw: Callable[[str | None], None]) -> tuple[str | None, float | None]:
        """A pair trial's answer: the classification's keys or buttons (e.g. left/right arrows)."""
        return self.classify(spec, factors, show, draw)

    def wait_continue(self, kind: str, show: ShowFn, draw: Callable[[], None], min_frames: int = 1) -> None:
        self.event.clearEvents()
        clock = self.core.Clock()
        pressed: list[bool] = []

        def until(k: int) -> bool:
            if self._keys(["space"], clock):
                pressed.append(True)
            return bool(pressed) and k >= min_frames

        show(kind, draw, FOREVER, until=until)

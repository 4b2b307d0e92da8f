"""What is drawn: stimulus, fixation cross, text pages, Likert scales, classification buttons.

PsychoPy is imported here (and in :mod:`experiments.responders`) only; a window-less
simulated session never imports it.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from experiments.protocol_schema import ChoiceSpec, ClassificationSpec, LikertSpec, Protocol

__all__ = ["Screens", "ClipTextures", "markdown_to_text", "open_window", "clamp_to_edge", "save_back_buffer",
           "free_image_stim"]


def markdown_to_text(md: str) -> str:
    """Instruction Markdown as plain text for the screen (headings, emphasis and bullets kept readable)."""
    lines: list[str] = []
    for raw in md.strip().splitlines():
        line = re.sub(r"^#{1,6}\s*", "", raw)
        line = re.sub(r"\*\*(.+?)\*\*|__(.+?)__", lambda m: m.group(1) or m.group(2), line)
        line = re.sub(r"(?<!\*)\*(?!\*)(.+?)\*|_(.+?)_", lambda m: m.group(1) or m.group(2), line)
        bullet = re.match(r"^\s*[-*+]\s+", line)
        line = re.sub(r"^\s*[-*+]\s+", "\u2022 ", line).strip()
        heading = raw.lstrip().startswith("#")
        # soft-wrapped lines of one paragraph are joined (the screen wraps them)
        if line and lines and lines[-1] and not bullet and not heading and not lines[-1].startswith("\x00"):
            lines[-1] += " " + line
        else:
            lines.append(("\x00" if heading else "") + line)
    lines = [ln.removeprefix("\x00") for ln in lines]
    return "\n".join(lines)


def open_window(size: tuple[int, int], *, fullscreen: bool, background: float) -> Any:
    """A PsychoPy window in height units with a grey-level background (0..1)."""
    from psychopy import logging as ps_logging
    from psychopy import visual

    ps_logging.console.setLevel(ps_logging.ERROR)
    grey = background * 2 - 1
    return visual.Window(size=list(size), fullscr=fullscreen, units="height", color=[grey] * 3, colorSpace="rgb",
                         allowGUI=not fullscreen, checkTiming=False, winType="pyglet")


class Screens:
    """Stimuli and response screens of one protocol, built once and reused every trial."""

    def __init__(self, win: Any, protocol: Protocol):
        from psychopy import visual

        self.win = win
        self.visual = visual
        self.protocol = protocol
        fg = protocol.screen.text_color * 2 - 1
        self.fg = [fg] * 3
        self.text = visual.TextStim(win, "", height=0.035, wrapWidth=1.1, color=self.fg)
        self.title = visual.TextStim(win, "", height=0.04, pos=(0, 0.45), color=self.fg)
        self.hint = visual.TextStim(win, "", height=0.025, pos=(0, -0.45), color=self.fg)
        self.fixation = visual.ShapeStim(win, vertices="cross", size=0.05, lineColor=self.fg, fillColor=self.fg)
        self._image: Any = None
        self._image_path: str | None = None
        self._aspect = 1.0
        self._likert: dict[str, tuple[Any, Any, Any, Any]] = {}
        self._choices: dict[str, list[tuple[Any, Any, ChoiceSpec]]] = {}
        self.clip: ClipTextures | None = None
        self._pair: list[Any] = []
        self._pair_aspects: list[float] = []
        self._pair_paths: tuple[str, ...] = ()
        self._warm_up()

    def _warm_up(self) -> None:
        """Build and draw every response screen once, into the back buffer, which is then cleared.

        Building a Slider (~0.2 s) and drawing it the first time (~50 ms) on the first trial's
        first response screen held that trial's stimulus on screen longer: a dropped frame in
        every session's first trial.
        """
        for spec in self.protocol.responses:
            if isinstance(spec, LikertSpec):
                self.draw_likert(spec, with_stimulus=False)
                continue
            self.draw_classification(spec, with_stimulus=False)
            if spec.intensity is not None:
                self.draw_likert(spec.intensity, with_stimulus=False)
        self.win.clearBuffer()

    # ------------------------------------------------------------------ stimulus
    def load(self, path: str) -> None:
        """Load the image of a trial (kept until the next one)."""
        self.free_clip()
        if path == self._image_path:
            return
        from PIL import Image

        with Image.open(path) as im:
            w, h = im.size
        self._aspect = w / h
        if self._image is None:
            self._image = self.visual.ImageStim(self.win, image=path, units="height", interpolate=True)
        else:
            self._image.image = path
        clamp_to_edge(self._image)
        self._image_path = path

    def draw_stimulus(self, height: float | None = None, y: float = 0.0) -> None:
        """Draw the loaded image ``height`` (fraction of the screen height) tall at ``y``."""
        h = height or self.protocol.screen.stimulus_height
        self._image.size = (h * self._aspect, h)
        self._image.pos = (0, y)
        self._image.draw()

    # ------------------------------------------------------------------ pairs
    def load_pair(self, paths: Sequence[str]) -> None:
        """Load the two images of a pair trial (in presentation order: left, right or first, second)."""
        if tuple(paths) == self._pair_paths:
            return
        from PIL import Image

        while len(self._pair) < len(paths):
            self._pair.append(self.visual.ImageStim(self.win, image=paths[len(self._pair)], units="height",
                                                    interpolate=True))
        self._pair_aspects = []
        for stim, path in zip(self._pair, paths):
            with Image.open(path) as im:
                w, h = im.size
            stim.image = path
            self._pair_aspects.append(w / h)
            clamp_to_edge(stim)
        self._pair_paths = tuple(paths)

    def draw_pair(self, which: int | None = None) -> None:
        """Draw both faces side by side (``which`` None) or one of them centred.

        Side by side, each face is as tall as ``screen.stimulus_height`` allows with both
        and a gap of 4 % of the screen height fitting the window's width.
        """
        h = self.protocol.screen.stimulus_height
        if which is not None:
            stim = self._pair[which]
            stim.size, stim.pos = (h * self._pair_aspects[which], h), (0, 0)
            stim.draw()
            return
        half_width = self.win.size[0] / self.win.size[1] / 2
        gap = 0.04
        h = min(h, (2 * half_width - 3 * gap) / (2 * max(self._pair_aspects)))
        for sign, stim, aspect in zip((-1, 1), self._pair[:2], self._pair_aspects):
            w = h * aspect
            stim.size, stim.pos = (w, h), (sign * (gap / 2 + w / 2), 0)
            stim.draw()

    # ------------------------------------------------------------------ clips
    def load_clip(self, images: Sequence[Any]) -> ClipTextures:
        """Make a clip's frames into textures (one ImageStim each) before its trial starts.

        Parameters
        ----------
        images : sequence of PIL.Image.Image
            The decoded frames (:func:`experiments.clips.decode_frames`).

        Returns
        -------
        ClipTextures
            Kept as :attr:`clip` until :meth:`end_clip` / :meth:`free_clip`.
        """
        self.free_clip()
        self.clip = ClipTextures(self.win, images, self.protocol.screen.stimulus_height)
        return self.clip

    def draw_clip_frame(self, k: int) -> None:
        """Draw frame ``k`` of the loaded clip at the stimulus size."""
        self.clip.draw(k)

    def end_clip(self) -> None:
        """The clip has left the screen: free its textures (the last frame's stays when the
        response screens show a thumbnail of the stimulus)."""
        if self.clip is None:
            return
        if self.protocol.timing.stimulus_visible_during_response:
            self.clip.free(keep=len(self.clip.stims) - 1)
        else:
            self.free_clip()

    def free_clip(self) -> None:
        """Free every texture of the loaded clip."""
        if self.clip is not None:
            self.clip.free()
            self.clip = None

    def draw_fixation(self) -> None:
        """Draw the fixation cross."""
        self.fixation.draw()

    def draw_text(self, text: str, *, title: str = "", hint: str = "") -> None:
        """Draw a text page (instructions, breaks)."""
        self.text.text = text
        self.text.pos = (0, 0.05)
        self.text.draw()
        if title:
            self.title.text = title
            self.title.draw()
        if hint:
            self.hint.text = hint
            self.hint.draw()

    def _thumb(self, with_stimulus: bool) -> None:
        if not with_stimulus:
            return
        h = self.protocol.screen.response_stimulus_height
        if self.clip is not None:  # a clip's thumbnail: its last frame
            self.clip.draw_last(h, y=0.5 - 0.03 - h / 2)
        elif self._image is not None:
            self.draw_stimulus(h, y=0.5 - 0.03 - h / 2)

    # ------------------------------------------------------------------ Likert
    def likert(self, spec: LikertSpec) -> Any:
        """The (cached) Slider of a Likert scale."""
        if spec.name not in self._likert:
            v = self.visual
            ticks = list(range(1, spec.points + 1))
            slider = v.Slider(self.win, ticks=ticks, labels=[str(t) for t in ticks], granularity=1, style="rating",
                              size=(0.9, 0.04), pos=(0, -0.27), labelHeight=0.03, color=self.fg, fillColor="red",
                              borderColor=self.fg, font="Open Sans")
            low = v.TextStim(self.win, spec.low, height=0.028, pos=(-0.45, -0.35), anchorHoriz="left", alignText="left",
                             color=self.fg, wrapWidth=0.45)
            high = v.TextStim(self.win, spec.high, height=0.028, pos=(0.45, -0.35), anchorHoriz="right",
                              alignText="right", color=self.fg, wrapWidth=0.45)
            desc = v.TextStim(self.win, spec.description, height=0.026, pos=(0, -0.16), wrapWidth=1.15, color=self.fg)
            self._likert[spec.name] = (slider, low, high, desc)
        return self._likert[spec.name][0]

    def draw_likert(self, spec: LikertSpec, *, with_stimulus: bool, marker: int | None = None) -> None:
        """Draw a Likert screen; ``marker`` shows a chosen value (simulated answers)."""
        slider = self.likert(spec)
        _, low, high, desc = self._likert[spec.name]
        self._thumb(with_stimulus)
        if marker is not None:
            slider.markerPos = marker
        for stim in (desc, slider, low, high):
            stim.draw()
        if spec.keys and spec.points <= 9:
            self.hint.text = f"Click on the scale or press 1-{spec.points}"
            self.hint.draw()

    # ------------------------------------------------------------------ classification
    def choices(self, spec: ClassificationSpec) -> list[tuple[Any, Any, ChoiceSpec]]:
        """The (cached) buttons of a classification: (box, label, choice)."""
        if spec.name not in self._choices:
            n = len(spec.choices)
            width = min(0.24, 1.2 / n - 0.02)
            buttons = []
            for i, c in enumerate(spec.choices):
                x = (i - (n - 1) / 2) * (width + 0.02)
                box = self.visual.Rect(self.win, width=width, height=0.08, pos=(x, -0.3), lineColor=self.fg,
                                       fillColor=None, lineWidth=2)
                label = f"[{c.key}] {c.label}" if c.key else c.label
                text = self.visual.TextStim(self.win, label, height=0.028, pos=(x, -0.3), color=self.fg,
                                            wrapWidth=width)
                buttons.append((box, text, c))
            self._choices[spec.name] = buttons
        return self._choices[spec.name]

    def draw_classification(self, spec: ClassificationSpec, *, with_stimulus: bool, chosen: str | None = None) -> None:
        """Draw the choice buttons (``chosen``: the value to highlight)."""
        from appeal.levels import level_key

        self._thumb(with_stimulus)
        if spec.prompt:
            self.text.text = spec.prompt
            self.text.pos = (0, -0.17)
            self.text.draw()
        for box, text, c in self.choices(spec):
            box.fillColor = [0.2, 0.6, 0.2] if chosen is not None and level_key(c.value) == chosen else None
            box.draw()
            text.draw()


class ClipTextures:
    """A clip's frames as PsychoPy textures: one ImageStim per frame, sized once.

    Made before the trial from decoded frames (8-bit RGBA: a 1024x768 frame is a 3 MiB
    texture, 4 MiB with its mipmaps) and freed when the clip has been shown.

    Parameters
    ----------
    win : psychopy.visual.Window
        The window.
    images : sequence of PIL.Image.Image
        The frames, in order.
    height : float
        Height on screen as a fraction of the screen height.
    """

    def __init__(self, win: Any, images: Sequence[Any], height: float):
        from psychopy import visual

        w, h = images[0].size
        self.aspect = w / h
        self.height = height
        self.stims: list[Any] = []
        for im in images:
            stim = visual.ImageStim(win, image=im, units="height", size=(height * self.aspect, height), pos=(0, 0),
                                    interpolate=True)
            clamp_to_edge(stim)
            self.stims.append(stim)

    def draw(self, k: int) -> None:
        """Draw frame ``k``."""
        self.stims[k].draw()

    def draw_last(self, height: float, y: float) -> None:
        """Draw the last frame ``height`` tall at ``y`` (the response screens' thumbnail)."""
        stim = self.stims[-1]
        stim.size = (height * self.aspect, height)
        stim.pos = (0, y)
        stim.draw()

    def free(self, keep: int | None = None) -> None:
        """Delete the textures of every frame (but frame ``keep``)."""
        kept = []
        for k, stim in enumerate(self.stims):
            if k == keep:
                kept.append(stim)
            elif stim is not None:
                free_image_stim(stim)
        self.stims = kept


def free_image_stim(stim: Any) -> None:
    """Delete an ImageStim's GL objects now: its textures and its pixel-unpack buffer.

    ``ImageStim.clearTextures`` deletes the textures but looks for the pixel buffer under
    another name (``_pixBuffID``; the stimulus stores ``_pixbuffID``), so the buffer outlived
    every stimulus (PsychoPy 2026.2.5; ``glIsBuffer`` is still true after ``clearTextures``).
    """
    from pyglet import gl

    stim.clearTextures()
    pbo = getattr(stim, "_pixbuffID", None)
    if pbo is not None:
        gl.glDeleteBuffers(1, pbo)


def clamp_to_edge(stim: Any) -> None:
    """Sample an image stimulus's texture edge-clamped, so its outermost pixels keep their colour.

    PsychoPy creates ImageStim textures with ``GL_CLAMP_TO_BORDER`` and the default (black)
    border colour. With linear interpolation, the texels sampled at the image's edges are
    blended with that border, which drew a dark 1-pixel line along the edges of every
    stimulus (grey 97-100 around a grey-128 image). ``GL_CLAMP_TO_EDGE`` repeats the edge texels
    instead. Call after every change of the stimulus's image (PsychoPy re-creates the texture).
    """
    from pyglet import gl

    gl.glActiveTexture(gl.GL_TEXTURE0)
    gl.glBindTexture(gl.GL_TEXTURE_2D, stim._texID)
    gl.glTexParameteri(gl.GL_TEXTURE_2D, gl.GL_TEXTURE_WRAP_S, gl.GL_CLAMP_TO_EDGE)
    gl.glTexParameteri(gl.GL_TEXTURE_2D, gl.GL_TEXTURE_WRAP_T, gl.GL_CLAMP_TO_EDGE)
    gl.glBindTexture(gl.GL_TEXTURE_2D, 0)


def save_back_buffer(win: Any, path: Path) -> Path:
    """Save the frame in the back buffer (drawn, not yet flipped) as a PNG."""
    img = win.getMovieFrame(buffer="back")
    win.movieFrames = []
    path.parent.mkdir(parents=True, exist_ok=True)
    img.save(path)
    return path

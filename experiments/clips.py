"""Animated stimuli (clips): folders of lossless PNG frames shown one per N display refreshes.

A clip is a folder of ``frame_00000.png``, ``frame_00001.png``, ... with a frame rate
(``fps``). It is presented frame-locked: every frame stays on screen for exactly
``N = refresh_hz / fps`` flips, so ``fps`` must divide the refresh rate (60 Hz: 60, 30, 20, 15,
12, 10 ... fps). Everything here is pure (no window): reading and checking the frame folders,
the per-trial plan (:class:`ClipPlan`), decoding frames ahead of their trial
(:class:`FramePrefetcher`), and the data columns a clip trial adds.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["FRAME_NAME", "CLIP_COLUMNS", "CLIP_DESCRIPTIONS", "ClipPlan", "clip_frame_files", "flips_per_frame",
           "rate_problem", "plan_clip", "decode_frames", "FramePrefetcher", "RATE_TOLERANCE"]

#: How the frames of a clip are named inside its folder (``frame_00000.png`` ...).
FRAME_NAME = "frame_{:05d}.png"
_FRAME_RE = re.compile(r"^frame_(\d{5,})\.png$")

#: Relative distance of ``refresh_hz / fps`` to a whole number still taken as whole (59.94 Hz / 30 fps = 1.998).
RATE_TOLERANCE = 0.02

#: The ``_beh.tsv`` columns of a protocol whose stimuli include clips, with their sidecar descriptions.
CLIP_DESCRIPTIONS: dict[str, str] = {
    "clip_frames": "frames in the clip (n/a: a still image)",
    "clip_fps": "the clip's frame rate (frames per second)",
    "clip_flips_per_frame": "display refreshes (flips) each clip frame is shown for: refresh_hz / clip_fps",
    "clip_frames_shown": "clip frames that were drawn and flipped (all of them: clip_frames)",
    "clip_flips": "flips while the clip's frames were up, the held last frame excluded (clip_frames x clip_flips_per_frame)",
    "clip_hold_flips": "flips the last frame was held after the clip (timing.clip_end: hold, up to stimulus_s)",
    "clip_frame_errors": "clip frames NOT on screen for exactly clip_flips_per_frame flips (counted per flip; 0)",
    "clip_dropped_frames": "PsychoPy's own count of late flips while the clip was up (win.nDroppedFrames with "
                           "win.recordFrameIntervals on and win.refreshThreshold = 1.5 refresh periods; n/a "
                           "without a window or in the virtual mode); the browser counts requestAnimationFrame "
                           "intervals over 1.5 periods",
    "clip_onset_s": "flip time of the manifest's onset_frame (the expression's onset)",
    "clip_apex_s": "flip time of the manifest's apex_frame",
    "clip_preload_ms": "time from the trial's start until the clip's textures were made, before its first screen "
                       "(ms; waiting for frames not yet decoded ahead included)",
}
CLIP_COLUMNS: tuple[str, ...] = tuple(CLIP_DESCRIPTIONS)


@dataclass(frozen=True)
class ClipPlan:
    """How one clip is presented in one trial.

    Attributes
    ----------
    frames_dir : str
        The folder of PNG frames (absolute).
    n_frames : int
        Frames in the clip.
    fps : float
        The clip's frame rate.
    flips_per_frame : int
        Flips each frame stays on screen (``refresh_hz / fps``).
    hold_flips : int
        Flips the last frame is held after the clip (``timing.clip_end: hold``).
    onset_frame, apex_frame : int
        The manifest's expression onset and apex (0-based frame indices).
    trigger_frame : int
        The frame whose first flip sends the trigger (0, or ``onset_frame``).
    """

    frames_dir: str
    n_frames: int
    fps: float
    flips_per_frame: int
    hold_flips: int
    onset_frame: int
    apex_frame: int
    trigger_frame: int = 0

    @property
    def clip_flips(self) -> int:
        """Flips while the clip's frames are up (the hold excluded)."""
        return self.n_frames * self.flips_per_frame

    @property
    def total_flips(self) -> int:
        """Flips of the whole stimulus screen (clip + hold)."""
        return self.clip_flips + self.hold_flips

    def frame_paths(self) -> list[str]:
        """The frames' PNG files, in order."""
        return [str(Path(self.frames_dir) / FRAME_NAME.format(k)) for k in range(self.n_frames)]


def clip_frame_files(folder: Path) -> list[Path] | str:
    """The frame files of a clip folder, in order, or why they are not a clip (one phrase).

    Parameters
    ----------
    folder : Path
        Holds ``frame_00000.png``, ``frame_00001.png``, ... (numbered from 0 without gaps).

    Returns
    -------
    list of Path or str
        The files; or a phrase saying what is wrong (no folder, no frames, a gap).
    """
    if not folder.is_dir():
        return f"folder not found: {folder}"
    numbered = sorted((int(m.group(1)), p) for p in folder.iterdir() if (m := _FRAME_RE.match(p.name)))
    if not numbered:
        return f"no frame_00000.png ... in {folder}"
    for expected, (k, p) in enumerate(numbered):
        if k != expected:
            return f"{folder}: frame {FRAME_NAME.format(expected)} missing (frames must be numbered from 0 without gaps)"
    return [p for _, p in numbered]


def flips_per_frame(fps: float, refresh_hz: float) -> int | None:
    """``refresh_hz / fps`` when it is a whole number (within :data:`RATE_TOLERANCE`), else None."""
    ratio = refresh_hz / fps
    n = round(ratio)
    if n < 1 or abs(ratio - n) > RATE_TOLERANCE * n:
        return None
    return int(n)


def _dividing_rates(refresh_hz: float, most: int = 6) -> str:
    rates = [refresh_hz / n for n in range(1, 13) if abs(refresh_hz / n - round(refresh_hz / n)) < 1e-9]
    return ", ".join(f"{r:g}" for r in rates[:most])


def rate_problem(fps: float, refresh_hz: float, source: str, example: str, n: int = 1) -> str | None:
    """The one-line error for a clip frame rate that does not divide the refresh rate, or None.

    Parameters
    ----------
    fps : float
        The clips' frame rate (the stimulus table's ``fps``).
    refresh_hz : float
        The session's refresh rate.
    source : str
        The stimulus table (named in the message).
    example : str
        One clip with this rate (named in the message).
    n : int
        How many clips have it.
    """
    if flips_per_frame(fps, refresh_hz) is not None:
        return None
    more = f" and {n - 1} more" if n > 1 else ""
    return (f"{source}: fps: {fps:g} fps does not divide the refresh rate {refresh_hz:g} Hz ({example}{more}); each "
            f"frame must last a whole number of refreshes: use {_dividing_rates(refresh_hz)} ... fps, or a "
            f"screen.refresh_hz that {fps:g} fps divides")


def plan_clip(row: dict[str, Any], refresh_hz: float, stimulus_frames: int, *, clip_end: str,
              trigger_at: str) -> ClipPlan:
    """The presentation of the clip in a stimulus-table row at ``refresh_hz``.

    Parameters
    ----------
    row : dict
        A row of :attr:`experiments.stimuli.StimulusSet.table` with ``frames``, ``n_frames``,
        ``fps``, ``onset_frame`` and ``apex_frame``.
    refresh_hz : float
        The session's refresh rate.
    stimulus_frames : int
        ``timing.stimulus_s`` in frames: with ``clip_end: hold`` the last frame is held until
        the stimulus screen has lasted this long (a longer clip is shown whole).
    clip_end : {"hold", "end"}
        ``timing.clip_end``.
    trigger_at : {"first_frame", "onset_frame"}
        ``timing.clip_trigger``.

    Returns
    -------
    ClipPlan

    Raises
    ------
    ValueError
        When ``fps`` does not divide ``refresh_hz`` (callers check first with :func:`rate_problem`).
    """
    n = flips_per_frame(float(row["fps"]), refresh_hz)
    if n is None:
        raise ValueError(f"{row['fps']} fps does not divide {refresh_hz} Hz")
    n_frames = int(row["n_frames"])
    hold = max(0, stimulus_frames - n_frames * n) if clip_end == "hold" else 0
    onset, apex = int(row["onset_frame"]), int(row["apex_frame"])
    return ClipPlan(frames_dir=str(row["frames"]), n_frames=n_frames, fps=float(row["fps"]), flips_per_frame=n,
                    hold_flips=hold, onset_frame=onset, apex_frame=apex,
                    trigger_frame=onset if trigger_at == "onset_frame" else 0)


def decode_frames(paths: Sequence[str]) -> list[Any]:
    """Decode PNG frames into RGBA PIL images (what PsychoPy uploads as 8-bit textures).

    A numpy array given to an ImageStim becomes a 32-bit float texture (four times the
    memory); a PIL image stays 8 bits per channel.
    """
    from PIL import Image

    out = []
    for p in paths:
        with Image.open(p) as im:
            out.append(im.convert("RGBA"))
    return out


class FramePrefetcher:
    """Decodes the next clip's frames on a helper thread while the current trial runs.

    The runner asks for a clip's frames with :meth:`prefetch` as soon as the previous clip
    has left the screen (during the response screens, ITI or fixation), and takes them with
    :meth:`take` before the clip's trial starts; PNG decoding (~11 ms a 1024x768 frame here)
    then costs the inter-trial interval nothing. Only one clip is kept ahead.
    """

    def __init__(self) -> None:
        self._pool: ThreadPoolExecutor | None = None
        self._ahead: tuple[str, Future] | None = None

    def prefetch(self, plan: ClipPlan | None) -> None:
        """Start decoding ``plan``'s frames (None: nothing; an earlier request is dropped)."""
        if plan is None or (self._ahead is not None and self._ahead[0] == plan.frames_dir):
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="clip-frames")
        self._ahead = (plan.frames_dir, self._pool.submit(decode_frames, plan.frame_paths()))

    def take(self, plan: ClipPlan) -> list[Any]:
        """``plan``'s decoded frames: the prefetched ones (waiting for the rest), else decoded now."""
        ahead, self._ahead = self._ahead, None
        if ahead is not None and ahead[0] == plan.frames_dir:
            return ahead[1].result()
        return decode_frames(plan.frame_paths())

    def close(self) -> None:
        """Stop the helper thread."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        self._ahead = None


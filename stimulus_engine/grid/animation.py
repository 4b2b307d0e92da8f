"""Animated grid cells (``animation:``): one weight curve for every clip, its frames, their rendering.

**The curve.** Every clip of an animated grid (:class:`~stimulus_engine.grid.schema.AnimationSpec`)
follows one weight curve w in [0, 1] over its frames (:func:`weight_curve`). Frame k is shown at
``k / fps`` seconds; ``L = round(lead * fps)`` is the onset's first frame (still neutral) and
``A = round((lead + onset) * fps)`` the apex's (both rounded half up, A > L); a clip has
``n = round((lead + onset + hold) * fps) + 1`` frames::

    w_k = 0                        for k <= L   (frame 0 .. L: neutral)
    w_k = ease((k - L) / (A - L))  for L < k < A
    w_k = 1                        for k >= A   (frame A .. n - 1: the apex, held)

with ``ease`` one of :data:`EASINGS` of u in [0, 1] (each 0 at 0, 1 at 1, increasing):
``linear`` u; ``smoothstep`` 3u² − 2u³ (starts and stops gently); ``cosine`` (1 − cos πu) / 2
(a half cosine, like smoothstep a little steeper in the middle); ``ease_out`` 1 − (1 − u)³ (fast
from neutral, settling into the apex, as a spontaneous expression's onset).

**A frame's geometry.** Frame k of a cell is the cell's expression weights at the grid's
``render.intensity`` times w_k (:func:`frame_weights`), posed and finished by the same chain as a
still image (:func:`stimulus_engine.grid.prepare.cell_vertices`): a frame at w = 0 is the
neutral still, one at w = 1 the cell's still. The frames' vertices (float32, ``(n, N, 3)``) are
kept in ``DIR/.cache/clips/<hash>.npy`` (:func:`clip_geometry`; a run of frames of one weight posed
once).

**Rendering.** A :class:`ClipItem` renders every frame of one cell in one worker call
(:func:`render_clip`: the rig and textures loaded once, a run of frames of one weight drawn once, by
either engine of :data:`~stimulus_engine.grid.worker.ENGINES`) into the lossless master
``DIR/clips/<stem>/frame_00000.png ...`` and ``DIR/clips/<stem>.mp4``
(:mod:`stimulus_engine.render.clip_video`), one frame at a time. The frames are written into a
temporary folder that replaces the old one whole, and the MP4 is moved in after them: a failed
render leaves no half-written clip.

**The manifest** (:func:`clip_columns`, :func:`clip_checksums`): one row per clip, ``file`` its
MP4, ``frames`` its PNG folder, ``n_frames``, ``fps``, ``onset_frame`` (L), ``apex_frame`` (A),
``weight_curve`` (w_k, ';'-separated, 4 decimals), ``frames_sha256`` (:func:`frames_digest`) and
``mp4_sha256``.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from appeal.revcorr.grammar import Trial
from stimulus_engine.grid.cache import GRID_VERSION, file_sha, sha
from stimulus_engine.grid.schema import AnimationSpec
from stimulus_engine.grid.worker import RenderItem, render_image

__all__ = ["EASINGS", "ClipItem", "apex_view", "clip_checksums", "clip_columns", "clip_frame_weights", "clip_geometry",
           "cosine", "clip_frames", "curve_text", "ease_out", "frame_file", "frame_keys", "frame_weights",
           "frames_curve", "frames_digest", "linear", "performance_curve", "revcorr_clip", "revcorr_pool", "revcorr_trial_table", "performance_weights", "prepare_clip", "render_clip",
           "smoothstep", "timeline", "weight_curve"]


# ------------------------------------------------------------------------------------ the curve
def linear(u: np.ndarray) -> np.ndarray:
    """``u``: constant speed.

    Examples
    --------
    >>> linear(np.array([0.0, 0.25, 1.0])).tolist()
    [0.0, 0.25, 1.0]
    """
    return np.asarray(u, np.float64)


def smoothstep(u: np.ndarray) -> np.ndarray:
    """``3u² − 2u³``: starts and stops with zero speed.

    Examples
    --------
    >>> smoothstep(np.array([0.0, 0.25, 0.5, 1.0])).tolist()
    [0.0, 0.15625, 0.5, 1.0]
    """
    u = np.asarray(u, np.float64)
    return u * u * (3.0 - 2.0 * u)


def cosine(u: np.ndarray) -> np.ndarray:
    """``(1 − cos πu) / 2``: a half cosine, zero speed at both ends.

    Examples
    --------
    >>> cosine(np.array([0.0, 0.25, 0.5, 1.0])).round(6).tolist()
    [0.0, 0.146447, 0.5, 1.0]
    """
    return (1.0 - np.cos(np.pi * np.asarray(u, np.float64))) / 2.0


def ease_out(u: np.ndarray) -> np.ndarray:
    """``1 − (1 − u)³``: fastest at neutral, settling into the apex.

    Examples
    --------
    >>> ease_out(np.array([0.0, 0.5, 1.0])).tolist()
    [0.0, 0.875, 1.0]
    """
    return 1.0 - (1.0 - np.asarray(u, np.float64)) ** 3


#: The easing curves by the name ``animation.easing`` gives.
EASINGS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "linear": linear, "smoothstep": smoothstep, "cosine": cosine, "ease_out": ease_out}


def weight_curve(spec: AnimationSpec) -> np.ndarray:
    """The weight w_k of every frame of a clip (module docstring): ``(n_frames,)`` in [0, 1]; for a
    ``performance``, its activation (:func:`performance_curve`).

    Examples
    --------
    >>> weight_curve(AnimationSpec(fps=4, onset=1.0, hold=0.5, easing="linear")).tolist()
    [0.0, 0.25, 0.5, 0.75, 1.0, 1.0, 1.0]
    >>> weight_curve(AnimationSpec(fps=2, lead=1.0, onset=1.0, hold=0.0)).tolist()
    [0.0, 0.0, 0.0, 0.5, 1.0]
    """
    if spec.performance is not None:
        return performance_curve(performance_weights(spec.performance, spec.fps)[1])
    k = np.arange(spec.n_frames, dtype=np.float64)
    lo, hi = spec.onset_frame, spec.apex_frame
    w = EASINGS[spec.easing](np.clip((k - lo) / (hi - lo), 0.0, 1.0))
    w[k <= lo] = 0.0  # exact ends, whatever the easing's rounding
    w[k >= hi] = 1.0
    return w


def timeline(spec: AnimationSpec, curve: np.ndarray | None = None) -> tuple[int, int, int]:
    """``(n_frames, onset_frame, apex_frame)`` of a clip: the spec's, or a performance's or a
    reverse-correlation trial's (``curve``, its activation: the last frame before it first passes
    5 % of its largest; the frame of the largest)."""
    if spec.performance is None and curve is None:
        return spec.n_frames, spec.onset_frame, spec.apex_frame
    curve = weight_curve(spec) if curve is None else curve
    moving = np.flatnonzero(curve > 0.05)
    return len(curve), max(int(moving[0]) - 1, 0) if len(moving) else 0, int(np.argmax(curve))


#: A performance's rows a clip may have (60 s at 120 fps).
MAX_PERFORMANCE_FRAMES = 7200


@functools.lru_cache(maxsize=8)
def _performance_table(path: str, stamp: float, fps: int) -> tuple[tuple[str, ...], np.ndarray]:
    from appeal.errors import AppealInputError

    try:
        df = pd.read_csv(path)
    except (OSError, ValueError, pd.errors.ParserError) as exc:
        raise AppealInputError(f"{path}: cannot read the performance ({str(exc).splitlines()[0]})") from None
    names = tuple(c for c in df.columns if c not in ("frame", "time"))
    if "frame" not in df.columns or not names:
        raise AppealInputError(f"{path}: expected columns frame, optional time, and one per blendshape (as "
                               "'appeal stimuli retarget' writes)")
    if not 2 <= len(df) <= MAX_PERFORMANCE_FRAMES:
        raise AppealInputError(f"{path}: {len(df)} frames (expected 2..{MAX_PERFORMANCE_FRAMES})")
    w = df[list(names)].apply(pd.to_numeric, errors="coerce").to_numpy(np.float64)
    if not np.isfinite(w).all():
        r, c = np.argwhere(~np.isfinite(w))[0]
        raise AppealInputError(f"{path}: {names[c]}: row {r + 1} is not a number (expected a weight in every cell)")
    if "time" in df.columns:
        step = np.diff(pd.to_numeric(df["time"], errors="coerce").to_numpy(np.float64))
        rate = 1.0 / float(np.median(step)) if len(step) and np.median(step) > 0 else float("nan")
        if not abs(rate - fps) <= 0.01 * fps:
            raise AppealInputError(f"{path}: time: steps at {rate:.4g} fps, expected animation.fps {fps} "
                                   "(one row per frame)")
    return names, w


def performance_weights(path: str | os.PathLike, fps: int) -> tuple[tuple[str, ...], np.ndarray]:
    """A performance CSV's blendshape names and weights ``(n_frames, K)``, checked (one-line
    errors naming the file and column; a ``time`` column must step at ``fps``)."""
    p = str(path)
    return _performance_table(p, os.stat(p).st_mtime, int(fps))


def performance_curve(weights: np.ndarray) -> np.ndarray:
    """A performance's activation per frame: its weights' absolute sum over the largest, in [0, 1].

    Examples
    --------
    >>> performance_curve(np.array([[0.0, 0.0], [0.2, 0.3], [1.0, -1.0]])).tolist()
    [0.0, 0.25, 1.0]
    """
    a = np.abs(np.asarray(weights, np.float64)).sum(axis=1)
    return a / a.max() if a.max() > 0 else a


def clip_frame_weights(spec: AnimationSpec, apex: dict[str, float]) -> list[dict[str, float]]:
    """Every frame's blendshape weights: the curve times the cell's ``apex`` weights, or the
    performance's rows."""
    if spec.performance is None:
        return [frame_weights(apex, float(w)) for w in weight_curve(spec)]
    names, w = performance_weights(spec.performance, spec.fps)
    return [{n: float(x) for n, x in zip(names, row) if x != 0.0} for row in w]


def revcorr_clip(spec: AnimationSpec, index: int) -> tuple[Trial, list[dict[str, float]]]:
    """Trial ``index`` of ``spec.revcorr``'s pool (:func:`appeal.revcorr.grammar.draw_trial`) and its
    frames' blendshape weights (``spec.revcorr.seconds`` at ``spec.fps``, both ends shown)."""
    from appeal.revcorr.grammar import action_units, draw_trial
    from stimulus_engine.characters.au_poses import clip_frames, trial_frame_weights

    pool = spec.revcorr
    trial = draw_trial(pool.seed, index, aus=action_units(pool.lateralised))
    return trial, trial_frame_weights(trial, clip_frames(pool.seconds, spec.fps))


def revcorr_pool(spec: AnimationSpec) -> tuple[tuple[Trial, list[dict[str, float]]], ...]:
    """Every trial of ``spec.revcorr``'s pool with its frames' weights (:func:`revcorr_clip`), drawn
    once for all the grid's cells."""
    pool = spec.revcorr
    return _revcorr_pool(spec.fps, pool.seed, pool.first, pool.trials, pool.seconds, pool.lateralised)


@functools.lru_cache(maxsize=2)
def _revcorr_pool(fps: int, seed: int, first: int, trials: int, seconds: float,
                  lateralised: bool) -> tuple[tuple[Trial, list[dict[str, float]]], ...]:
    from stimulus_engine.grid.schema import RevcorrPoolSpec

    spec = AnimationSpec(fps=fps, revcorr=RevcorrPoolSpec(seed=seed, trials=trials, first=first, seconds=seconds,
                                                          lateralised=lateralised))
    return tuple(revcorr_clip(spec, i) for i in range(first, first + trials))


def revcorr_trial_table(spec: AnimationSpec) -> pd.DataFrame:
    """``revcorr_trials.csv`` of a pool: one row per trial and AU, the AU's six temporal parameters
    (fractions of the clip; ``peak_amplitude`` of the AU), with the pool's seed, the clip's
    ``seconds`` and ``fps``."""
    from appeal.revcorr.grammar import action_units, draw_trial

    pool = spec.revcorr
    aus = action_units(pool.lateralised)
    rows = [{"revcorr_seed": pool.seed, "revcorr_trial": i, "revcorr_lateralised": int(pool.lateralised),
             **m.as_dict(), "seconds": pool.seconds, "fps": spec.fps}
            for i in range(pool.first, pool.first + pool.trials) for m in draw_trial(pool.seed, i, aus=aus).motions]
    return pd.DataFrame(rows)


def frames_curve(frames: list[dict[str, float]]) -> np.ndarray:
    """The activation of a clip given by its frames' weights (:func:`performance_curve` of them)."""
    names = sorted({n for f in frames for n in f})
    return performance_curve(np.array([[f.get(n, 0.0) for n in names] for f in frames]).reshape(len(frames), -1))


def frame_keys(frames: list[dict[str, float]]) -> tuple[int, ...]:
    """For each frame the first frame with the same weights (a frame like an earlier one is posed
    and drawn once).

    Examples
    --------
    >>> frame_keys([{}, {}, {"a": 1.0}, {}, {"a": 1.0}])
    (0, 0, 2, 0, 2)
    """
    seen: dict[tuple, int] = {}
    return tuple(seen.setdefault(tuple(sorted(f.items())), k) for k, f in enumerate(frames))


def curve_text(curve: np.ndarray) -> str:
    """The manifest's ``weight_curve``: the weights ';'-separated with 4 decimals.

    Examples
    --------
    >>> curve_text(np.array([0.0, 0.15625, 1.0]))
    '0.0000;0.1562;1.0000'
    """
    return ";".join(f"{x:.4f}" for x in curve)


def frame_weights(weights: dict[str, float], w: float) -> dict[str, float]:
    """A frame's blendshape weights: the apex ``weights`` times ``w`` (the apex's own at w = 1,
    none at w = 0: the neutral's).

    Examples
    --------
    >>> frame_weights({"jawOpen": 0.8, "mouthSmile_L": 1.0}, 0.5)
    {'jawOpen': 0.4, 'mouthSmile_L': 0.5}
    >>> frame_weights({"jawOpen": 0.8}, 0.0)
    {}
    """
    if w == 1.0:
        return weights
    return {k: v * w for k, v in weights.items() if v * w != 0.0}


def frame_file(k: int) -> str:
    """The PNG of frame ``k`` inside a clip's ``frames`` folder.

    Examples
    --------
    >>> frame_file(12)
    'frame_00012.png'
    """
    return f"frame_{k:05d}.png"


# ------------------------------------------------------------------------------ preparation
@dataclass(frozen=True)
class ClipItem:
    """Everything a worker needs to render one clip (paths and settings; picklable).

    Attributes
    ----------
    still : RenderItem
        The cell as a still image, but its ``file`` is the clip's MP4 (``clips/<stem>.mp4``) and
        its ``geometry_npy`` the clip's frames, ``(n_frames, N, 3)`` (:func:`clip_geometry`).
    frames : str
        The PNG folder, relative to ``out_dir`` (``clips/<stem>``).
    fps : int
    weights : tuple of float
        w_k of every frame (:func:`weight_curve`).
    keys : tuple of int
        Per frame, the first frame with the same blendshape weights (:func:`frame_keys`): such
        frames are drawn once.
    """

    still: RenderItem
    frames: str
    fps: int
    weights: tuple[float, ...]
    keys: tuple[int, ...]
    #: the frames at rest (no blendshape moved): drawn once per process for every clip of the cell
    #: (a reverse-correlation pool's clips start and end at rest)
    rest: tuple[int, ...] = ()

    @property
    def file(self) -> str:
        """The MP4, relative to ``out_dir``."""
        return self.still.file

    @property
    def out_dir(self) -> str:
        return self.still.out_dir

    @property
    def albedo_png(self) -> str:
        return self.still.albedo_png

    @property
    def rig_npz(self) -> str:
        return self.still.rig_npz

    def outputs(self) -> list[str]:
        """The files the render writes, relative to ``out_dir``: every frame, then the MP4."""
        return [f"{self.frames}/{frame_file(k)}" for k in range(len(self.weights))] + [self.file]


def clip_geometry(path: Path, frames: list[dict[str, float]], pose: Callable[[dict[str, float]], np.ndarray]) -> Path:
    """The drawn vertices of every frame, ``pose(weights_k)`` stacked ``(n_frames, N, 3)`` float32,
    in ``path`` (kept: a re-run reads nothing else). A run of frames of one weight is posed once, and
    the frames go straight to a memory-mapped temporary file renamed into place when all are
    there (no clip held in memory, nothing half-written left)."""
    from appeal.atomic import current_umask

    if path.exists():
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        keys = frame_keys(frames)
        last, v = keys[0], pose(frames[0])
        out = np.lib.format.open_memmap(tmp, mode="w+", dtype=np.float32, shape=(len(frames), *v.shape))
        for k, (key, w) in enumerate(zip(keys, frames)):
            if key != last:
                last, v = key, pose(w)
            out[k] = v
        out.flush()
        del out
        os.chmod(tmp, 0o666 & ~current_umask())  # as a plain file's, not mkstemp's private 0o600
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def clip_columns(spec: AnimationSpec, stem: str, curve: np.ndarray | None = None) -> dict[str, object]:
    """The manifest's clip columns of the cell ``stem`` (but its checksums, :func:`clip_checksums`);
    ``curve``: a reverse-correlation trial's activation (:func:`frames_curve`)."""
    n, onset, apex = timeline(spec, curve)
    return {"file": f"clips/{stem}.mp4", "frames": f"clips/{stem}", "n_frames": n, "fps": spec.fps,
            "onset_frame": onset, "apex_frame": apex,
            "weight_curve": curve_text(weight_curve(spec) if curve is None else curve)}


def prepare_clip(still: RenderItem, row: dict, spec: AnimationSpec, cache: Path, frames: list[dict[str, float]],
                 pose: Callable[[dict[str, float]], np.ndarray], trial: Trial | None = None) -> tuple[ClipItem, dict]:
    """A prepared still cell (its render item and manifest row) as a clip: its ``frames``' geometry
    (each frame's blendshape weights, :func:`clip_frame_weights`; ``pose``: weights -> the drawn
    vertices) in ``cache/clips``, its render item and its row; ``trial``: the reverse-correlation
    trial the frames play (:func:`revcorr_clip`; the row's file then ends in ``_rc<seed>-<trial>``).

    The clip's ``geometry_hash`` is that of the still's drawn geometry (everything deciding the
    apex) with the curve (and a performance's content or a trial's frames); its ``input_hash`` adds
    that to the still's and the video settings.
    """
    from stimulus_engine.render.clip_video import VIDEO_SETTINGS

    curve = weight_curve(spec) if trial is None else frames_curve(frames)
    text = curve_text(curve)
    played = (() if spec.performance is None else ("performance", file_sha(spec.performance))) + (
        () if trial is None else ("revcorr", sha(*(sorted(f.items()) for f in frames))))
    gh = sha(GRID_VERSION, "clip", Path(still.geometry_npy).stem, row["expression"], text, *played)
    path = clip_geometry(Path(cache) / "clips" / f"{gh}.npy", frames, pose)
    stem = Path(row["file"]).stem + ("" if trial is None else f"_rc{trial.seed}-{trial.index:05d}")
    cols = clip_columns(spec, stem, None if trial is None else curve)
    blend = () if spec.occlusion == "frame" else (int(cols["apex_frame"]),)
    item = ClipItem(dataclasses.replace(still, file=str(cols["file"]), geometry_npy=str(path), occlusion_blend=blend),
                    str(cols["frames"]), spec.fps, tuple(curve.tolist()), frame_keys(frames),
                    tuple(k for k, f in enumerate(frames) if not f) if trial is not None else ())
    ih = sha(row["input_hash"], "clip", gh, spec.fps, VIDEO_SETTINGS, *(("occlusion", *blend) if blend else ()))
    out = {**row, **cols, "geometry_hash": gh, "input_hash": ih}
    if trial is not None:
        out.update(revcorr_seed=trial.seed, revcorr_trial=trial.index,
                   revcorr_lateralised=int(spec.revcorr.lateralised), revcorr_aus=";".join(trial.aus))
    return item, out


# ---------------------------------------------------------------------------------- rendering
def clip_frames(item: ClipItem, folder: Path) -> Iterator[np.ndarray]:
    """Every frame of ``item`` in order, each also written to ``folder`` as its PNG; a frame with
    the same weights as the one before it (the lead's, the hold's) is not drawn again."""
    from stimulus_engine.render import save_png

    last, image = None, None
    for k, key in enumerate(item.keys):
        if key != last:
            image, last = _frame_image(item, k), key
        save_png(image, folder / frame_file(k))
        yield image


#: Rendered rest frames by their cell (:attr:`ClipItem.rest`), a few kept per worker process.
_REST_IMAGES: dict[str, np.ndarray] = {}


def _frame_image(item: ClipItem, k: int) -> np.ndarray:
    """Frame ``k`` of ``item`` rendered, or the cell's rest frame drawn before (same rig, look and
    camera, no blendshape moved: the same pixels)."""
    frame = dataclasses.replace(item.still, frame=k)
    if k not in item.rest:
        return render_image(frame)
    key = sha(dataclasses.replace(item.still, file="", geometry_npy="", occlusion_blend=()),
              np.asarray(frame.geometry(), np.float32).tobytes())
    if key not in _REST_IMAGES:
        if len(_REST_IMAGES) >= 8:
            _REST_IMAGES.pop(next(iter(_REST_IMAGES)))
        _REST_IMAGES[key] = render_image(frame)
    return _REST_IMAGES[key]


def _fresh_folder(final: Path) -> Path:
    """An empty folder beside ``final`` to write into, with a plain folder's permissions."""
    from appeal.atomic import current_umask

    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".tmp", dir=final.parent))
    os.chmod(tmp, 0o777 & ~current_umask())
    return tmp


def render_clip(item: ClipItem) -> float:
    """Render every frame of ``item`` to its ``frames`` folder and its MP4; the seconds it took.

    Frames are rendered, written and encoded one at a time (a clip is never held in memory) into
    a temporary folder, which then replaces the clip's folder (the old MP4 removed first); the
    MP4 is moved in last. An interrupted render leaves the old clip or an incomplete one (no MP4,
    rendered again by ``--resume``), never a wrong one.
    """
    from stimulus_engine.render.clip_video import encode_mp4

    t0 = time.perf_counter()
    out = Path(item.out_dir)
    final = out / item.frames
    tmp = _fresh_folder(final)
    try:
        video = encode_mp4(clip_frames(item, tmp), tmp.with_name(tmp.name + ".mp4"), item.fps)
        (out / item.file).unlink(missing_ok=True)
        if final.exists():
            shutil.rmtree(final)
        os.replace(tmp, final)
        os.replace(video, out / item.file)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)  # gone already where the render succeeded
        tmp.with_name(tmp.name + ".mp4").unlink(missing_ok=True)
    return time.perf_counter() - t0


# ----------------------------------------------------------------------------------- manifest
def frames_digest(paths: list[Path]) -> str:
    """The manifest's ``frames_sha256``: the SHA-256 (hex) of the frames' own SHA-256 hex digests,
    lowercase, concatenated in frame order without separators (ASCII)."""
    return hashlib.sha256("".join(file_sha(p) for p in paths).encode("ascii")).hexdigest()


def clip_checksums(out: Path, manifest: pd.DataFrame) -> pd.DataFrame:
    """``manifest`` with ``frames_sha256`` and ``mp4_sha256`` of every clip rendered or up to date
    (empty where it failed)."""
    ok = manifest["status"].isin(["rendered", "up to date"])
    frames, mp4 = [], []
    for good, folder, n, f in zip(ok, manifest["frames"], manifest["n_frames"], manifest["file"]):
        frames.append(frames_digest([Path(out) / folder / frame_file(k) for k in range(int(n))]) if good else "")
        mp4.append(file_sha(Path(out) / f) if good else "")
    return manifest.assign(frames_sha256=frames, mp4_sha256=mp4)


def apex_view(manifest: pd.DataFrame) -> pd.DataFrame:
    """``manifest`` with each clip's ``file`` its apex frame's PNG (what contact sheets and the
    continuum report show of a clip); a manifest of stills as it is."""
    if "frames" not in manifest:
        return manifest
    apex = [f"{folder}/{frame_file(int(k))}" for folder, k in zip(manifest["frames"], manifest["apex_frame"])]
    return manifest.assign(file=apex)

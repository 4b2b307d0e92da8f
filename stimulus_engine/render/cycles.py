"""The path-traced tier: Blender's Cycles, run in its own Python.

Blender's ``bpy`` wheel (PyPI, Python 3.11) pins numpy < 2, which the rest of the platform has
outgrown, so Cycles runs in a separate environment: ``make cycles`` creates ``.venv-cycles``
beside ``.venv`` with ``bpy``; ``$APPEAL_CYCLES_PYTHON`` names any other interpreter that has it.
A render exports the scene (:func:`~.scene_export.export_scene`) into a temporary folder and runs
:mod:`.cycles_worker` there as a script (no package imports), then composites the RGBA result
onto the background.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from appeal.errors import AppealInputError

__all__ = ["CYCLES_HINT", "cycles_python", "check_cycles", "render_cycles", "composite"]

_WORKER = Path(__file__).with_name("cycles_worker.py")

#: What to do when Cycles is missing (the end of the one-line error).
CYCLES_HINT = ("run 'make cycles' (a .venv-cycles with Blender's bpy wheel: bpy pins numpy < 2, so it gets its own "
               "environment) or set APPEAL_CYCLES_PYTHON to a Python 3.11 that has bpy")


def cycles_python() -> Path | None:
    """The interpreter with ``bpy``: ``$APPEAL_CYCLES_PYTHON``, else ``.venv-cycles`` beside this environment."""
    env = os.environ.get("APPEAL_CYCLES_PYTHON")
    if env:
        return Path(env) if Path(env).exists() or shutil.which(env) else None
    for root in (Path(sys.prefix).parent, Path(__file__).resolve().parents[2]):
        exe = root / ".venv-cycles" / "bin" / "python"
        if exe.exists():
            return exe
    return None


def check_cycles(what: str = "render.engine") -> Path:
    """The Cycles interpreter, or a one-line :class:`AppealInputError` naming ``what``."""
    exe = cycles_python()
    if exe is None:
        raise AppealInputError(f"{what}: 'cycles' is not installed ({CYCLES_HINT})")
    return exe


def composite(rgba: np.ndarray, background) -> np.ndarray:
    """Straight-alpha RGBA uint8 over a flat background (0..1 RGB) → RGB uint8."""
    a = rgba[..., 3:4].astype(np.float32) / 255.0
    bg = np.asarray(background, np.float32) * 255.0
    return np.clip(rgba[..., :3].astype(np.float32) * a + bg * (1 - a) + 0.5, 0, 255).astype(np.uint8)


def render_cycles(parts: list, *, width: int, height: int, lighting, camera, background=(0.5, 0.5, 0.5),
                  samples: int = 16, seed: int = 0, threads: int | None = None, keep: str | Path | None = None,
                  ) -> np.ndarray:
    """Path-trace render parts with Cycles; the ``(height, width, 3)`` uint8 image.

    Parameters
    ----------
    parts, width, height, lighting, camera, background
        As for :func:`~stimulus_engine.render.renderer.render_mesh` (``camera`` required).
    samples : int
        Samples per pixel before denoising.
    seed : int
        Cycles' sampling seed (same seed, same scene: the same image).
    threads : int, optional
        CPU threads (default: all cores).
    keep : path, optional
        Export the scene there (and keep it) instead of a temporary folder.
    """
    from stimulus_engine.render.lighting import lighting_preset
    from stimulus_engine.render.scene_export import export_scene

    if samples < 1:
        raise AppealInputError(f"render.samples: expected a positive number of samples (got {samples})")
    exe = check_cycles()
    lights, ambient = lighting_preset(lighting) if isinstance(lighting, str) else lighting
    with tempfile.TemporaryDirectory(prefix="appeal-cycles-") as tmp:
        folder = Path(keep) if keep is not None else Path(tmp)
        scene = export_scene(parts, lights, ambient, camera, folder, width=width, height=height, background=background)
        out = folder / "render.png"
        cmd = [str(exe), str(_WORKER), str(scene), str(out), "--samples", str(samples), "--seed", str(seed),
               "--threads", str(threads or os.cpu_count() or 1)]
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0 or not out.exists():
            tail = (res.stderr or res.stdout).strip().splitlines()[-1:] or ["no output"]
            raise RuntimeError(f"Cycles failed (exit {res.returncode}): {tail[0]}")
        with Image.open(out) as im:
            rgba = np.asarray(im.convert("RGBA"))
    return composite(rgba, background)

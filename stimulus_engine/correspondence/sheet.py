"""Contact sheet of a correspondence: source, faired meshes, registered base, result, target.

Rendered with the stimulus renderer (:func:`stimulus_engine.render.render_mesh`) from the
front and from two sides (a small turntable), all with one camera fitted to the target.
Vertices of fold-over triangles of the result are painted red.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

__all__ = ["correspondence_sheet", "result_panels"]

_GREY = np.array([200, 200, 200, 255], dtype=np.uint8)
_RED = np.array([230, 30, 30, 255], dtype=np.uint8)
_BLUE = np.array([150, 175, 220, 255], dtype=np.uint8)


def _coloured(vertices, faces, colour, red_faces=None) -> trimesh.Trimesh:
    m = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    vc = np.tile(colour, (len(vertices), 1))
    if red_faces is not None and np.any(red_faces):
        vc[np.unique(np.asarray(faces)[red_faces])] = _RED
    m.visual = trimesh.visual.ColorVisuals(m, vertex_colors=vc)
    return m


def correspondence_sheet(
    panels: list[tuple[str, np.ndarray, np.ndarray]],
    path: str | Path | None = None,
    *,
    frame_points: np.ndarray | None = None,
    flipped: np.ndarray | None = None,
    views: tuple[float, ...] = (0.0, 35.0, -35.0),
    thumb_width: int = 220,
    title: str | None = None,
) -> np.ndarray:
    """Render ``panels`` (label, vertices, faces) in columns, one row per view angle.

    Parameters
    ----------
    panels : list of (str, (N, 3) array, (F, 3) array)
        Meshes in a common frame. Labels containing "result" get ``flipped`` faces in red.
    path : path-like, optional
        Where to write the PNG.
    frame_points : (K, 3) array, optional
        Points the camera frames (default: the last panel, usually the target).
    flipped : bool (F,) array, optional
        Fold-over mask for the result panel.
    views : tuple of float
        Yaw angles in degrees (0 = front).
    """
    from stimulus_engine.render import contact_sheet, fit_camera, render_mesh, save_png

    pts = frame_points if frame_points is not None else panels[-1][1]
    images, labels = [], []
    for yaw in views:
        a = np.deg2rad(yaw)
        cam = fit_camera(pts, 4 / 3, view_dir=(float(np.sin(a)), 0.0, float(np.cos(a))), margin=1.05)
        for label, v, f in panels:
            is_result = "result" in label
            colour = _BLUE if label.lower().startswith(("target", "faired target")) else _GREY
            mesh = _coloured(v, f, colour, flipped if (is_result and flipped is not None) else None)
            images.append(render_mesh(mesh, width=400, height=300, camera=cam, lighting="direct_soft", shadows=False))
            labels.append(f"{label} ({yaw:+.0f}°)")
    sheet = contact_sheet(images, ncols=len(panels), thumb_width=thumb_width, labels=labels, title=title)
    if path is not None:
        save_png(sheet, path)
    return sheet


def result_panels(result, source, target) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The standard panels of a :class:`CorrespondenceResult`: source (aligned), faired source,
    faired target, registered base, result, target (cropped-away target parts left out)."""
    ft = np.asarray(target.faces)
    keep = np.isfinite(result.faired_target[ft]).all(axis=(1, 2))
    return [
        ("source", result.alignment.apply(source.vertices), result.faces),
        ("faired source", result.faired_source, result.faces),
        ("faired target", np.nan_to_num(result.faired_target), ft[keep]),
        ("registered base", result.registered_base, result.faces),
        ("result", result.vertices, result.faces),
        ("target", np.asarray(target.vertices), ft),
    ]

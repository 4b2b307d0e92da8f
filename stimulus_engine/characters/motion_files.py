"""Reading an actor's performance for retargeting: C3D marker files (ezc3d) or CSV tables.

:func:`read_motion` returns marker trajectories as an (F, M, 3) array in centimetres, the actor's
neutral (a marker file's frame 0, the calibration frame ``a_0`` of §4.2) and the rig vertex each
marker sits on.

- **C3D** (``.c3d``): the file's 3-D points with their labels and ``POINT:UNITS`` (mm, cm or m),
  and a marker map (CSV ``marker,vertex``) that puts each label on a rig vertex.
- **CSV of markers**: a long table ``frame,marker,x,y,z`` (centimetres) with the same marker map;
  or markers named ``v<index>`` (a rig vertex index) without one.
- **CSV of weights**: ``frame`` plus one column per blendshape of the rig (e.g. a face tracker's
  ARKit coefficients): the performance is the rig's own, posed by those weights.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from appeal.errors import AppealInputError
from stimulus_engine.characters.rig import FaceRig

__all__ = ["read_marker_map", "read_motion"]

_UNITS_CM = {"mm": 0.1, "cm": 1.0, "m": 100.0}


def read_marker_map(path: Path, n_vertices: int) -> dict[str, int]:
    """A marker map CSV (``marker,vertex``) as label -> vertex index, checked against the rig."""
    try:
        df = pd.read_csv(path, dtype={"marker": str})
    except (OSError, ValueError, pd.errors.ParserError) as exc:
        raise AppealInputError(f"{path}: cannot read the marker map ({str(exc).splitlines()[0]})") from None
    if not {"marker", "vertex"} <= set(df.columns):
        raise AppealInputError(f"{path}: columns marker, vertex expected (got {', '.join(map(str, df.columns))})")
    bad = df[(pd.to_numeric(df["vertex"], errors="coerce").isna()) | (pd.to_numeric(df["vertex"], errors="coerce") < 0)
             | (pd.to_numeric(df["vertex"], errors="coerce") >= n_vertices)]
    if len(bad):
        raise AppealInputError(f"{path}: vertex: expected a rig vertex index 0..{n_vertices - 1} "
                               f"(marker '{bad['marker'].iloc[0]}' has '{bad['vertex'].iloc[0]}')")
    return dict(zip(df["marker"].astype(str), df["vertex"].astype(int)))


def _from_c3d(path: Path) -> tuple[np.ndarray, list[str], float]:
    import ezc3d

    try:
        c = ezc3d.c3d(str(path))
    except Exception as exc:  # ezc3d raises plain RuntimeError/IOError on a bad file
        raise AppealInputError(f"{path}: cannot read as C3D ({str(exc).splitlines()[0]})") from None
    pts = np.asarray(c["data"]["points"][:3], np.float64).transpose(2, 1, 0)  # (F, M, 3)
    labels = [str(x) for x in c["parameters"]["POINT"]["LABELS"]["value"]]
    units = str(c["parameters"]["POINT"].get("UNITS", {}).get("value", ["mm"])[0]).strip().lower()
    if units not in _UNITS_CM:
        raise AppealInputError(f"{path}: POINT:UNITS '{units}': expected mm, cm or m")
    fps = float(c["header"]["points"]["frame_rate"])
    return pts * _UNITS_CM[units], labels, fps


def _from_marker_csv(df: pd.DataFrame, path: Path) -> tuple[np.ndarray, list[str]]:
    need = {"frame", "marker", "x", "y", "z"}
    if not need <= set(df.columns):
        raise AppealInputError(f"{path}: columns frame, marker, x, y, z expected for markers "
                               f"(or frame plus blendshape columns for weights)")
    df = df.assign(marker=df["marker"].astype(str))
    wide = df.pivot_table(index="frame", columns="marker", values=["x", "y", "z"], aggfunc="first")
    labels = sorted(df["marker"].unique(), key=str)
    arr = np.stack([wide[c][labels].to_numpy(np.float64) for c in ("x", "y", "z")], axis=2)
    if np.isnan(arr).any():
        f, m = np.argwhere(np.isnan(arr).any(axis=2))[0]
        raise AppealInputError(f"{path}: marker '{labels[m]}' has no x, y, z in frame {wide.index[f]} "
                               "(expected every marker in every frame)")
    return arr, labels


def read_motion(path: Path, rig: FaceRig, marker_map: Path | None = None,
                fps: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray | None]:
    """An actor's performance for :func:`~stimulus_engine.characters.retarget.retarget_frames`.

    Returns
    -------
    neutral : (M, 3) array
        The actor's neutral marker positions (a marker file's frame 0; a weights file's rig).
    positions : (F, M, 3) array
        Marker positions in centimetres.
    vertices : (M,) int array
        The rig vertex of each marker.
    fps : float
        Frames per second (the C3D's, else ``fps``, else 30).
    weights : (F, K) array or None
        The given weights (a weights CSV, in ``sorted(rig.blendshapes)`` order), else None.
    """
    path = Path(path)
    if not path.is_file():
        raise AppealInputError(f"{path}: motion file not found (expected a .c3d or .csv file)")
    rate = 30.0 if fps is None else float(fps)
    if path.suffix.lower() == ".c3d":
        pos, labels, rate = _from_c3d(path)
    elif path.suffix.lower() == ".csv":
        try:
            df = pd.read_csv(path)
        except (OSError, ValueError, pd.errors.ParserError) as exc:
            raise AppealInputError(f"{path}: cannot read as a table ({str(exc).splitlines()[0]})") from None
        names = sorted(rig.blendshapes)
        shapes = [c for c in df.columns if c in rig.blendshapes]
        if "frame" in df.columns and shapes and "marker" not in df.columns:
            unknown = [c for c in df.columns if c not in rig.blendshapes and c not in ("frame", "time")]
            if unknown:
                raise AppealInputError(f"{path}: column '{unknown[0]}' is not a blendshape of rig '{rig.name}' "
                                       f"(expected frame and any of: {', '.join(names)})")
            w = np.zeros((len(df), len(names)))
            for c in shapes:
                w[:, names.index(c)] = pd.to_numeric(df[c], errors="coerce").to_numpy()
            if np.isnan(w).any():
                raise AppealInputError(f"{path}: a weight is not a number (expected numbers in every blendshape column)")
            from stimulus_engine.characters.markers import marker_vertices

            mk = marker_vertices(rig)
            deltas = np.stack([rig.blendshapes[n][mk] for n in names])
            return rig.vertices[mk], rig.vertices[mk][None] + np.einsum("fk,kmc->fmc", w, deltas), mk, rate, w
        pos, labels = _from_marker_csv(df, path)
    else:
        raise AppealInputError(f"{path}: unknown motion format '{path.suffix}' (expected .c3d or .csv)")
    if marker_map is not None:
        where = read_marker_map(marker_map, len(rig.vertices))
        missing = [lb for lb in labels if lb not in where]
        if missing:
            raise AppealInputError(f"{marker_map}: marker '{missing[0]}' of {path.name} has no vertex "
                                   "(expected a row for every marker)")
        verts = np.array([where[lb] for lb in labels])
    elif all(lb.startswith("v") and lb[1:].isdigit() for lb in labels):
        verts = np.array([int(lb[1:]) for lb in labels])
        if verts.max() >= len(rig.vertices):
            raise AppealInputError(f"{path}: marker 'v{verts.max()}' is not a vertex of rig '{rig.name}' "
                                   f"({len(rig.vertices)} vertices)")
    else:
        raise AppealInputError(f"{path}: markers are named (e.g. '{labels[0]}'): give --marker-map "
                               "(a CSV marker,vertex), or name them v<vertex index>")
    return pos[0], pos, verts, rate, None

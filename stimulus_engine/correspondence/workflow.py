"""The correspondence run as one workflow: checked inputs in, result files out.

``appeal stimuli correspond`` reads and checks its inputs with :func:`read_correspondence_job`
(meshes, landmark pairs, boundary anchors, parameters: every problem is a one-line error before
an output folder exists) and calls :func:`run_correspondence`, which fits the source onto the
target (:func:`stimulus_engine.correspondence.pipeline.correspond`) and writes
``deformed.obj``, ``correspondence.npz``, ``metrics.json`` and ``contact_sheet.png``.
"""

from __future__ import annotations

import dataclasses
import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from appeal.atomic import atomic_write_bytes, atomic_write_text
from appeal.errors import AppealInputError
from appeal.logs import logger
from stimulus_engine.correspondence.boundary import boundary_correspondences
from stimulus_engine.correspondence.pipeline import CorrespondParams, correspond, deformed_mesh
from stimulus_engine.correspondence.points import Correspondences, load_pairs_file, parse_pairs

__all__ = ["CorrespondenceJob", "auto_pairs", "read_correspondence_job", "run_correspondence"]


@dataclass
class CorrespondenceJob:
    """A checked correspondence run: the two meshes, their point pairs and the parameters."""

    source: trimesh.Trimesh
    target: trimesh.Trimesh
    corr: Correspondences
    params: CorrespondParams
    files: tuple[Path, Path]


#: Automatic landmarks used as pairs: the inner iBUG points (brows, nose, eyes, mouth; the jaw
#: line is a silhouette for the detector) found with at least this confidence on both meshes.
AUTO_PAIR_POINTS, AUTO_MIN_CONFIDENCE = range(17, 68), 0.4


def auto_pairs(src: trimesh.Trimesh, tgt: trimesh.Trimesh, names: tuple[str, str] = ("source", "target"),
               min_confidence: float = AUTO_MIN_CONFIDENCE) -> Correspondences:
    """Point pairs from the 68 iBUG landmarks found automatically on both meshes
    (:func:`stimulus_engine.correspondence.auto_landmarks.detect_mesh_landmarks`)."""
    from stimulus_engine.correspondence.auto_landmarks import detect_mesh_landmarks

    a = detect_mesh_landmarks(src, name=names[0])
    b = detect_mesh_landmarks(tgt, name=names[1])
    idx = np.array([i for i in AUTO_PAIR_POINTS
                    if a.confidence[i] >= min_confidence and b.confidence[i] >= min_confidence])
    if len(idx) < 6:
        raise AppealInputError(f"--landmarks auto: only {len(idx)} landmarks found with confidence >= {min_confidence} "
                               "on both meshes (expected at least 6; give the pairs by hand)")
    logger.info("automatic landmarks: %d pairs (fronts %s / %s)", len(idx), a.front, b.front)
    return Correspondences(a.surface.subset(idx), b.surface.subset(idx))


def _landmark_pairs(spec: str, src: trimesh.Trimesh, tgt: trimesh.Trimesh, names: tuple[str, str]) -> Correspondences:
    if spec == "auto":
        return auto_pairs(src, tgt, names)
    p = Path(spec)
    if p.suffix.lower() == ".json" or p.exists():
        return load_pairs_file(p, src, tgt)
    try:
        data = json.loads(spec)
    except json.JSONDecodeError as exc:
        raise AppealInputError(
            f"--landmarks: expected a JSON file or inline JSON {{\"source\": [...], \"target\": [...]}} ({exc.msg})"
        ) from None
    return parse_pairs(data, src, tgt, where="--landmarks")


def _boundary_pairs(spec: str, src: trimesh.Trimesh, tgt: trimesh.Trimesh) -> Correspondences:
    try:
        anchors = json.loads(Path(spec).read_text() if Path(spec).exists() else spec)
    except json.JSONDecodeError as exc:
        raise AppealInputError(f"--boundary: expected JSON [[src_vertex, tgt_vertex], ...] ({exc.msg})") from None
    if not isinstance(anchors, list) or not all(isinstance(a, list) and len(a) == 2 for a in anchors):
        raise AppealInputError("--boundary: expected JSON [[src_vertex, tgt_vertex], ...]")
    return boundary_correspondences(src.vertices, src.faces, tgt.vertices, tgt.faces, anchors)


def read_correspondence_job(source: Path, target: Path, landmarks: str, *, boundary: str | None = None,
                            lambda1: float = 0.1, fairing_iterations: int = 5) -> CorrespondenceJob:
    """Load the meshes and parse the point pairs of a correspondence run.

    Parameters
    ----------
    source, target : Path
        Mesh files (see :func:`stimulus_engine.geometry.mesh_io.load_mesh`).
    landmarks : str
        A pairs file (``.json``), inline JSON ``{"source": [...], "target": [...]}``, or
        ``"auto"`` (:func:`auto_pairs`).
    boundary : str, optional
        Boundary-loop anchors, JSON ``[[src_vertex, tgt_vertex], ...]`` (inline or a file).
    lambda1, fairing_iterations
        Fairing smoothness and most joint-fairing solves.

    Raises
    ------
    AppealInputError
        One line naming the file or option and what was expected.
    """
    from stimulus_engine.geometry.mesh_io import load_mesh

    if lambda1 <= 0 or fairing_iterations < 1:
        raise AppealInputError("--lambda1 must be > 0 and --fairing-iterations >= 1")
    src = load_mesh(source)
    tgt = load_mesh(target)
    corr = _landmark_pairs(landmarks, src, tgt, (str(source), str(target)))
    if boundary:
        corr = corr.concat(_boundary_pairs(boundary, src, tgt))
    params = dataclasses.replace(CorrespondParams(), lambda1=lambda1, fairing_iterations=fairing_iterations)
    return CorrespondenceJob(src, tgt, corr, params, (Path(source), Path(target)))


def run_correspondence(job: CorrespondenceJob, out: Path, *, sheet: bool = True) -> dict:
    """Fit the job's source onto its target and write the results into ``out`` (an existing folder).

    Writes ``deformed.obj`` (the source's vertices moved onto the target; vertex order, faces and
    UVs kept), ``correspondence.npz`` (per source vertex: target triangle, barycentric weights,
    valid), ``metrics.json`` and, with ``sheet``, ``contact_sheet.png``.

    Returns
    -------
    dict
        The fit metrics (:func:`~stimulus_engine.correspondence.metrics.fit_metrics`) with
        ``stage_seconds``.
    """
    from stimulus_engine.geometry.mesh_io import save_mesh

    src, tgt = job.source, job.target
    res = correspond(src, tgt, job.corr, job.params)
    save_mesh(deformed_mesh(src, res.vertices), out / "deformed.obj")
    buf = io.BytesIO()
    np.savez_compressed(buf, target_face=res.target_face, target_bary=res.target_bary, valid=res.valid)
    atomic_write_bytes(out / "correspondence.npz", buf.getvalue())
    metrics = dict(res.metrics)
    metrics["stage_seconds"] = res.seconds
    atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=2))
    if sheet:
        from stimulus_engine.correspondence.metrics import flipped_triangles
        from stimulus_engine.correspondence.sheet import correspondence_sheet, result_panels

        correspondence_sheet(result_panels(res, src, tgt), out / "contact_sheet.png",
                             flipped=flipped_triangles(res.vertices, res.faces, res.alignment.apply(src.vertices)))
    return metrics
